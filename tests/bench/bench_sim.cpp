// Benchmark: `roe simulate` cost. Simulating paper-seq4 (60 s: 12001 IMU samples, 1801 frames, 7201
// mocap poses) in memory, writing it as a dataset folder, and --from-groundtruth on the shared EuRoC
// V1_02 snippet when present. Best of 5. Figures: docs/benchmarks/sim.md.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>

#include "bench_util.hpp"
#include "roe/app/simulate.hpp"
#include "roe/store/dataset.hpp"

namespace fs = std::filesystem;
using namespace roe;

namespace {
using roe::bench::best_of;
}  // namespace

int main() {
  const sim::SimConfig cfg = app::sim_config_from_preset("paper-seq4");
  std::size_t dets = 0;
  const double t_sim = best_of(5, [&] { dets = sim::simulate_run(cfg, 1).stats.detections; });
  std::printf("simulate paper-seq4 60 s in memory:   %.3f s  (%zu detections)\n", t_sim, dets);

  const fs::path dir = fs::temp_directory_path() / ("roe_bench_sim_" + std::to_string(::getpid()));
  app::SimulateOptions opt;
  opt.preset = "paper-seq4";
  opt.force = true;
  const double t_app = best_of(5, [&] { app::simulate(opt, dir / "seq4"); });
  std::uintmax_t bytes = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir / "seq4"))
    if (e.is_regular_file()) bytes += e.file_size();
  std::printf("simulate + write dataset folder:       %.3f s  (%.1f MB)\n", t_app, bytes / 1e6);

  const fs::path mav0 = fs::path(ROE_SOURCE_DIR) / ".." / "shared" / "data" / "euroc_v102_snippet" / "mav0";
  if (fs::exists(mav0 / "imu0" / "data.csv")) {
    const auto imu = store::read_imu_csv(mav0 / "imu0" / "data.csv");
    const auto gt = store::read_groundtruth_csv(mav0 / "state_groundtruth_estimate0" / "data.csv");
    sim::FromGroundtruthConfig g;
    const double t_gt =
        best_of(5, [&] { dets = sim::simulate_from_groundtruth(imu, gt, g, 1).stats.detections; });
    std::printf("from-groundtruth EuRoC V1_02 (40 s):   %.3f s  (%zu detections)\n", t_gt, dets);
  } else {
    std::printf("from-groundtruth: skipped (%s not found)\n", mav0.c_str());
  }
  fs::remove_all(dir);
  return 0;
}
