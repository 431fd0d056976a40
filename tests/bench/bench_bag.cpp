// Benchmark: ROS bag read throughput (open + iterate every message in time order + decode the
// images/IMU samples), for uncompressed and LZ4 (and bz2) D435i-layout bags made by the committed
// generator, plus the real RealSense bag of ../shared/data when present.
// Usage: bench_bag [frames=60] [width=1280] [height=720]. Figures: docs/benchmarks/import.md.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "../fixtures/gen_d435i_bag.hpp"
#include "roe/io/ros/msgs.hpp"
#include "roe/io/ros/ros1_bag.hpp"

namespace fs = std::filesystem;
using namespace roe;
namespace msg = roe::io::ros::msg;
using roe::io::ros::Wire;

namespace {

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

struct Stat {
  double seconds;
  std::size_t messages;
  std::size_t payload;
};

Stat read_all(const fs::path& file) {
  const double t0 = now();
  io::ros1::Reader r(file);
  std::size_t n = 0, bytes = 0;
  r.for_each([](const io::ros1::Connection&) { return true; },
             [&](const io::ros1::MessageView& m) {
               ++n;
               bytes += m.data.size();
               if (m.connection->type == "sensor_msgs/Image") {
                 const auto im = io::ros::decode<msg::Image>(Wire::ros1, m.data, "bench");
                 bytes += im.data[im.data.size() / 2] == 0x7f;  // touch the payload
               } else if (m.connection->type == "sensor_msgs/Imu") {
                 (void)io::ros::decode<msg::Imu>(Wire::ros1, m.data, "bench");
               }
               return true;
             });
  return {now() - t0, n, bytes};
}

void report(const char* label, const fs::path& file, int reps) {
  const double size_mb = static_cast<double>(fs::file_size(file)) / 1e6;
  double best = 1e30;
  Stat s{};
  for (int i = 0; i < reps; ++i) {
    s = read_all(file);
    best = std::min(best, s.seconds);
  }
  std::printf("%-34s file %8.1f MB  payload %8.1f MB  msgs %7zu  best of %d: %7.3f s  %8.1f MB/s (file)  %8.1f MB/s (payload)\n",
              label, size_mb, static_cast<double>(s.payload) / 1e6, s.messages, reps, best, size_mb / best,
              static_cast<double>(s.payload) / 1e6 / best);
}

}  // namespace

int main(int argc, char** argv) {
  testing::D435iBagSpec spec;
  spec.n_frames = argc > 1 ? std::atoi(argv[1]) : 60;
  spec.width = argc > 2 ? std::atoi(argv[2]) : 1280;
  spec.height = argc > 3 ? std::atoi(argv[3]) : 720;
  spec.imu_duration_s = spec.n_frames / 30.0;
  std::random_device rd;
  const fs::path dir = fs::temp_directory_path() / ("roe_bench_bag_" + std::to_string(rd()));
  fs::create_directories(dir);
  std::printf("D435i-layout bag: %d frames %dx%d rgb8 + %.1f s IMU (accel 250 Hz, gyro 400 Hz)\n", spec.n_frames,
              spec.width, spec.height, spec.imu_duration_s);
  for (const char* comp : {"none", "lz4", "bz2"}) {
    spec.compression = comp;
    const double t0 = now();
    const std::string bytes = testing::generate_d435i_bag(spec);
    const fs::path f = dir / (std::string(comp) + ".bag");
    std::ofstream(f, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    std::printf("  generated %s in %.2f s\n", comp, now() - t0);
    report((std::string("generated, ") + comp).c_str(), f, 3);
  }
  const fs::path real = fs::path(ROE_SOURCE_DIR) / "../shared/data/realsense/single_depth_color_640x480.bag";
  if (fs::exists(real)) report("real D435 recorder bag (lz4)", real, 20);
  const fs::path evo = fs::path(ROE_SOURCE_DIR) / "../shared/data/rosbag/evo_ROS_example.bag";
  if (fs::exists(evo)) report("real evo bag (none, 26k small msgs)", evo, 5);
  fs::remove_all(dir);
  return 0;
}
