// Benchmark: dataset-folder CSV throughput (write_dataset / read_dataset) on a synthetic
// 10-minute sequence (IMU 200 Hz, ground truth 200 Hz, mocap 120 Hz, 3 detections per frame at
// 30 Hz), plus reading the real EuRoC V1_02 ground truth of ../shared/data when present.
// Usage: bench_io [minutes=10]. Figures: docs/benchmarks/io.md.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>

#include "bench_util.hpp"
#include "roe/io/csv.hpp"
#include "roe/store/dataset.hpp"
#include "roe/math/so3.hpp"

namespace fs = std::filesystem;
using namespace roe;

namespace {

using roe::bench::best_of;

Dataset synthetic(double minutes) {
  std::mt19937 rng(1);
  std::normal_distribution<double> n(0.0, 1.0);
  auto pose = [&] {
    return Pose(math::exp_quat(Eigen::Vector3d(n(rng), n(rng), n(rng))),
                Eigen::Vector3d(n(rng), n(rng), n(rng)));
  };
  Dataset d;
  d.manifest.name = "bench";
  const Timestamp t0 = 1'700'000'000'000'000'000LL;
  const auto dur = static_cast<Timestamp>(minutes * 60e9);
  for (Timestamp t = t0; t < t0 + dur; t += 5'000'000) {
    d.imu.push_back(
        {t, Eigen::Vector3d(n(rng), n(rng), n(rng)), Eigen::Vector3d(n(rng), n(rng), 9.81 + n(rng))});
    d.groundtruth.push_back({t, pose(), Eigen::Vector3d(n(rng), n(rng), n(rng)), Eigen::Vector3d::Zero(),
                             Eigen::Vector3d::Zero()});
  }
  for (Timestamp t = t0; t < t0 + dur; t += 8'333'333) d.mocap.push_back({t, pose()});
  for (Timestamp t = t0; t < t0 + dur; t += 33'333'333) {
    d.frames.push_back({t, std::to_string(t) + ".png"});
    for (int id : {1, 5, 13}) {
      Detection det;
      det.t_ns = t;
      det.object_id = id;
      det.T_C_O = pose();
      det.score = 0.9;
      d.detections["sim"].push_back(det);
    }
  }
  return d;
}

std::size_t rows(const Dataset& d) {
  return d.imu.size() + d.groundtruth.size() + d.mocap.size() + d.frames.size() +
         d.detections.at("sim").size();
}

std::uintmax_t folder_bytes(const fs::path& p) {
  std::uintmax_t total = 0;
  for (const auto& e : fs::recursive_directory_iterator(p))
    if (e.is_regular_file()) total += e.file_size();
  return total;
}

}  // namespace

int main(int argc, char** argv) {
  const double minutes = argc > 1 ? std::atof(argv[1]) : 10.0;
  const Dataset d = synthetic(minutes);
  const fs::path dir = fs::temp_directory_path() / ("roe_bench_io_" + std::to_string(::getpid()));
  const double t_write = best_of(3, [&] { store::write_dataset(d, dir, true); });
  Dataset back;
  const double t_read = best_of(3, [&] { back = store::read_dataset(dir); });
  const double mb = static_cast<double>(folder_bytes(dir)) / 1e6;
  std::printf("synthetic %.1f min: %zu rows, %.1f MB\n", minutes, rows(d), mb);
  std::printf("  write_dataset: %.3f s (%.2f us/row, %.1f MB/s)\n", t_write, 1e6 * t_write / rows(d),
              mb / t_write);
  std::printf("  read_dataset:  %.3f s (%.2f us/row, %.1f MB/s)\n", t_read, 1e6 * t_read / rows(back),
              mb / t_read);
  fs::remove_all(dir);

  // The run files' writer (trajectory, states, objects, reprojection: io::CsvWriter) in memory: a
  // states.csv-like table of 45 shortest-round-trip doubles per row. Thread CPU time, so that the
  // figure does not depend on other load on the machine.
  {
    std::mt19937 rng(2);
    std::normal_distribution<double> n(0.0, 1.0);
    std::vector<double> values(45 * 20000);
    for (double& v : values) v = n(rng) * 0.1;
    std::size_t bytes = 0;
    const double t = roe::bench::best_cpu_of(5, [&] {
      io::CsvWriter w;
      for (std::size_t r = 0; r < values.size() / 45; ++r) {
        w.add(static_cast<std::int64_t>(1'700'000'000'000'000'000LL + static_cast<std::int64_t>(r) * 2'500'000));
        for (std::size_t c = 0; c < 45; ++c) w.add(values[45 * r + c]);
        w.end_row();
      }
      bytes = w.str().size();
    });
    std::printf("CsvWriter (run files), 20000 rows x 46 fields: %.1f MB in %.1f ms CPU, %.0f MB/s\n", bytes / 1e6,
                1e3 * t, bytes / 1e6 / t);
  }

  const fs::path gt = fs::path(ROE_SOURCE_DIR) / ".." / "shared" / "data" / "eval" / "V102_groundtruth.csv";
  if (fs::exists(gt)) {
    std::vector<ImuState> states;
    const double t = best_of(10, [&] { states = store::read_groundtruth_csv(gt); });
    std::printf("real EuRoC V1_02 ground truth: %zu rows (17 columns) in %.2f ms (%.2f us/row)\n",
                states.size(), 1e3 * t, 1e6 * t / states.size());
  } else {
    std::printf("real EuRoC ground truth not found (skipped): %s\n", gt.c_str());
  }
  return 0;
}
