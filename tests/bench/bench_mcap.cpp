// Benchmark: MCAP read throughput and peak memory (docs/BENCHMARKS.md, "ROS 2 bags").
// Writes a realsense-like MCAP of >= 200 MB of message data (640x480 rgb8 images at 30 Hz and IMU
// samples at 200 Hz, CDR) twice, with uncompressed and with zstd chunks of ~4 MB, then reads each in
// a fresh process (fork + exec of this program with --read) that iterates every message in log-time
// order and touches its bytes, and reports MB/s of message data and the reader's peak RSS
// (getrusage of the child) next to the largest chunk.
// Usage: bench_mcap [message_MB=210] [folder=/tmp]   (bench_mcap --read FILE: the child)
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <string>

#include "roe/io/ros/cdr.hpp"
#include "roe/io/ros/compression.hpp"
#include "roe/io/ros/mcap.hpp"
#include "../fixtures/mcap_writer.hpp"

namespace fs = std::filesystem;
using namespace roe;
namespace msg = roe::io::ros::msg;
using roe::io::ros::Wire;

namespace {

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

std::uint64_t write_bag(const fs::path& file, bool zstd, double message_mb) {
  testing::McapWriter w(file, zstd);
  w.channel(1, "/camera/camera/color/image_raw", "sensor_msgs/msg/Image");
  w.channel(2, "/camera/camera/imu", "sensor_msgs/msg/Imu");
  std::mt19937 rng(7);
  std::string pixels(640 * 480 * 3, '\0');
  const Timestamp t0 = 1'700'000'000'000'000'000;
  std::uint64_t payload = 0;
  for (int k = 0; payload < message_mb * 1e6; ++k) {
    // A smooth gradient with sensor-like noise: compresses about as well as a real colour frame.
    for (std::size_t i = 0; i < pixels.size(); ++i) pixels[i] = static_cast<char>((i / 3 % 640) / 3 + k + ((i % 61 == 0) ? (rng() & 3) : 0));
    io::cdr::Writer im;
    im.header({0, t0 + k * 33'333'333LL, "camera_color_optical_frame"}).u32(480).u32(640).str("rgb8").u8(0).u32(1920)
        .byte_sequence(pixels);
    w.message(1, static_cast<std::uint64_t>(t0 + k * 33'333'333LL), im.bytes());
    payload += im.bytes().size();
    for (int j = 0; j < 7; ++j) {
      io::ros::Imu m;
      m.header.stamp_ns = t0 + k * 33'333'333LL + j * 5'000'000LL;
      m.angular_velocity = Eigen::Vector3d(0.01 * j, 0.02, -0.03);
      const std::string b = io::ros::encode<msg::Imu>(Wire::cdr, m);
      w.message(2, static_cast<std::uint64_t>(m.header.stamp_ns), b);
      payload += b.size();
    }
  }
  w.finish();
  std::printf("  wrote %s: %.1f MB file, largest chunk %.1f MB uncompressed\n", file.c_str(), fs::file_size(file) / 1e6,
              w.largest_chunk() / 1e6);
  return payload;
}

/// Peak resident memory of this process image (VmHWM: reset by exec, unlike getrusage's ru_maxrss,
/// which would include the parent's pages at fork time), in MB.
double status_mb(const char* key) {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind(key, 0) == 0) return std::atof(line.c_str() + std::strlen(key)) / 1024.0;
  return -1;
}

/// The child: read every message, print "messages bytes wall_s cpu_s peak_rss_mb".
int read_child(const char* file) {
  // The program links all of roe (OpenCV, LibTorch): its image alone is resident before any read.
  const double base = status_mb("VmHWM:");
  const double t0 = now();
  const std::clock_t c0 = std::clock();
  io::mcap::Reader r{fs::path(file)};
  std::size_t n = 0, bytes = 0, touch = 0;
  r.for_each([](const io::mcap::Channel&) { return true; },
             [&](const io::mcap::MessageView& m) {
               ++n;
               bytes += m.data.size();
               touch += static_cast<unsigned char>(m.data[m.data.size() / 2]);
               return true;
             });
  const double cpu = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
  std::printf("%zu %zu %.6f %.6f %.2f %.2f %zu\n", n, bytes, now() - t0, cpu, status_mb("VmHWM:"), base, touch & 1);
  return r.damaged() ? 1 : 0;
}

void measure(const char* self, const fs::path& file, const char* label) {
  for (int rep = 0; rep < 3; ++rep) {
    int fds[2];
    if (pipe(fds) != 0) return;
    const pid_t pid = fork();
    if (pid == 0) {
      dup2(fds[1], 1);
      execl(self, self, "--read", file.c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
    close(fds[1]);
    char buf[256] = {};
    const auto got = read(fds[0], buf, sizeof buf - 1);
    close(fds[0]);
    int status = 0;
    rusage ru{};
    wait4(pid, &status, 0, &ru);
    std::size_t n = 0, bytes = 0, touch = 0;
    double s = 0, cpu = 0, rss = 0, base = 0;
    if (got <= 0 || std::sscanf(buf, "%zu %zu %lf %lf %lf %lf %zu", &n, &bytes, &s, &cpu, &rss, &base, &touch) != 7 ||
        status != 0) {
      std::printf("%s: child failed (status %d)\n", label, status);
      return;
    }
    (void)ru;
    std::printf("%-18s run %d: %zu msgs, %.1f MB of message data: %.3f s wall = %6.1f MB/s, %.3f s CPU = %6.1f MB/s "
                "per CPU second, peak RSS %.1f MB = %.1f MB before reading + %.1f MB\n",
                label, rep + 1, n, bytes / 1e6, s, bytes / 1e6 / s, cpu, bytes / 1e6 / cpu, rss, base, rss - base);
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 3 && std::strcmp(argv[1], "--read") == 0) return read_child(argv[2]);
  const double mb = argc > 1 ? std::atof(argv[1]) : 210.0;
  const fs::path dir = argc > 2 ? fs::path(argv[2]) : fs::temp_directory_path();
  const fs::path plain = dir / "roe_bench_plain.mcap", z = dir / "roe_bench_zstd.mcap";
  write_bag(plain, false, mb);
  write_bag(z, true, mb);
  measure(argv[0], plain, "MCAP uncompressed");
  measure(argv[0], z, "MCAP zstd chunks");
  fs::remove(plain);
  fs::remove(z);
  return 0;
}
