// Pose-only ground truth for `roe simulate --from-groundtruth` (docs/simulator.md §9, "Pose-only ground
// truth"): the velocity from the poses, checked on analytic motion and against the real EuRoC snippet's
// own velocity; the real TUM-VI room1 recording (IMU + 8-column mocap, ../shared/data/tumvi) simulated and
// run with 4 objects and the default config.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "roe/app/run.hpp"
#include "roe/app/simulate.hpp"
#include "roe/core/error.hpp"
#include "roe/eval/align.hpp"
#include "roe/eval/associate.hpp"
#include "roe/eval/metrics.hpp"
#include "roe/store/dataset.hpp"
#include "roe/sim/pose_groundtruth.hpp"
#include "support/euroc_snippet.hpp"
#include "support/test_util.hpp"

namespace fs = std::filesystem;
using namespace roe;

namespace {

// p(t) = (sin t, 0.5 t², cos 2t) at `rate` Hz over [0, 10] s, with the samples in (gap_from, gap_to) left out.
std::vector<StampedPose> analytic(double rate, double gap_from = -1, double gap_to = -1) {
  std::vector<StampedPose> out;
  for (int k = 0; k <= static_cast<int>(10 * rate); ++k) {
    const double t = k / rate;
    if (t > gap_from && t < gap_to) continue;
    out.push_back({static_cast<Timestamp>(std::llround(t * 1e9)),
                   Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(std::sin(t), 0.5 * t * t, std::cos(2 * t)))});
  }
  return out;
}
Eigen::Vector3d analytic_velocity(Timestamp t_ns) {
  const double t = t_ns * 1e-9;
  return {std::cos(t), t, -2 * std::sin(2 * t)};
}

// The TUM-VI room1 files as a TUM-VI mav0 folder (imu0/data.csv, mocap0/data.csv), or nothing when absent.
std::optional<fs::path> tumvi_mav0(const test::TempDir& d) {
  const fs::path src = fs::path(ROE_SHARED_DATA_DIR) / "tumvi";
  if (!fs::exists(src / "dataset-room1_512_imu.txt")) return std::nullopt;
  fs::create_directories(d / "room1/mav0/imu0");
  fs::create_directories(d / "room1/mav0/mocap0");
  fs::create_symlink(src / "dataset-room1_512_imu.txt", d / "room1/mav0/imu0/data.csv");
  fs::create_symlink(src / "dataset-room1_512_16_gt.csv", d / "room1/mav0/mocap0/data.csv");
  // The BMI160's noise as TUM-VI publishes it for its recordings (the values ORB-SLAM3's TUM-VI configs
  // and TUM-VI's imu_config.yaml carry), in EuRoC's sensor.yaml keys.
  d.write("room1/mav0/imu0/sensor.yaml",
          "sensor_type: imu\nrate_hz: 200\ngyroscope_noise_density: 0.00016\ngyroscope_random_walk: 0.000022\n"
          "accelerometer_noise_density: 0.0028\naccelerometer_random_walk: 0.00086\n");
  return d / "room1";
}

// Worst-axis position RMSE (m) of `states` against the dataset's ground truth after SE(3) alignment, as roe eval.
double worst_axis(const Dataset& d, const std::vector<app::RecordedState>& states) {
  std::vector<Timestamp> t_est, t_gt;
  std::vector<Pose> est_all, gt_all, est, gt;
  for (const auto& s : states) {
    t_est.push_back(s.t_ns);
    est_all.push_back(Pose(s.x.q_W_I, s.x.p_W_I));
  }
  for (const auto& g : d.groundtruth) {
    t_gt.push_back(g.t_ns);
    gt_all.push_back(g.T_W_I);
  }
  const eval::Association a = eval::associate(t_est, t_gt);
  for (std::size_t k = 0; k < a.size(); ++k) {
    est.push_back(est_all[a.est_index[k]]);
    gt.push_back(gt_all[a.gt_index[k]]);
  }
  eval::apply_alignment(eval::compute_alignment(eval::AlignType::kSe3, est, gt), est);
  return eval::compute_ape(est, gt).pos_rmse_m.maxCoeff();
}

}  // namespace

TEST_CASE("velocity from poses: the local quadratic's slope, across gaps and at the ends", "[sim][groundtruth]") {
  const auto poses = analytic(120.0, 4.0, 5.06);  // a 1.06 s gap, as TUM-VI room1's longest
  const auto states = sim::states_from_poses(poses);
  REQUIRE(states.size() == poses.size());
  double worst = 0.0, worst_edge = 0.0;
  for (const auto& s : states) {
    const double e = (s.v_W_I - analytic_velocity(s.t_ns)).norm();
    const double t = s.t_ns * 1e-9;
    const bool edge = t < 0.05 || t > 9.95 || std::abs(t - 4.0) < 0.05 || std::abs(t - 5.06) < 0.05;
    (edge ? worst_edge : worst) = std::max(edge ? worst_edge : worst, e);
    CHECK(s.b_g.isZero());
    CHECK(s.b_a.isZero());
    CHECK(s.T_W_I.p == poses[&s - states.data()].T.p);
  }
  // Truncation: the cubic term, |p'''| h²/10 ≤ 8 · 0.05² / 10 = 2 mm/s inside; one-sided at the ends.
  CHECK(worst < 2.5e-3);
  CHECK(worst_edge < 0.03);
  CHECK_THROWS_AS(sim::states_from_poses({poses.front()}), DataError);
}

TEST_CASE("velocity from poses on the real EuRoC snippet matches EuRoC's own velocity", "[sim][groundtruth][real]") {
  const auto snippet = test::load_euroc_snippet();
  if (!snippet) {
    WARN("skipped: ../shared/data/euroc_v102_snippet absent");
    return;
  }
  std::vector<StampedPose> poses;
  for (const auto& g : snippet->groundtruth) poses.push_back({g.t_ns, g.T_W_I});
  const auto states = sim::states_from_poses(poses);
  double sum2 = 0.0, worst = 0.0;
  for (std::size_t k = 0; k < states.size(); ++k) {
    const double e = (states[k].v_W_I - snippet->groundtruth[k].v_W_I).norm();
    sum2 += e * e;
    worst = std::max(worst, e);
  }
  const double rms = std::sqrt(sum2 / states.size());
  WARN("EuRoC V1_02 snippet, velocity from poses vs state_groundtruth_estimate0: RMS " << rms << " m/s, max " << worst
                                                                                        << " m/s");
  // numpy's lstsq on the same rule (±50 ms in integer ns, docs/simulator.md), computed independently of roe:
  // RMS 6.2494651 mm/s, max 70.917948 mm/s, at speeds of 1.02 m/s RMS.
  CHECK(rms == Approx(0.0062494651).epsilon(1e-6));
  CHECK(worst == Approx(0.070917948).epsilon(1e-6));
}

TEST_CASE("pose-only ground truth files: EuRoC 8 columns and TUM read as poses, 17 columns as the state",
          "[sim][groundtruth][io]") {
  test::TempDir d;
  const fs::path euroc8 = d.write("gt8.csv",
                                  "#timestamp [ns], p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], "
                                  "q_RS_y [], q_RS_z []\n"
                                  "1000000000,1,2,3,1,0,0,0\n2000000000,2,2,3,1,0,0,0\n3000000000,3,2,3,1,0,0,0\n");
  auto g = store::read_groundtruth_file(euroc8);
  CHECK(g.pose_only());
  CHECK(g.layout == "euroc");
  REQUIRE(g.poses.size() == 3);
  CHECK(g.poses[2].T.p.x() == 3.0);
  const fs::path tum = d.write("gt.tum", "# t x y z qx qy qz qw\n1.0 1 2 3 0 0 0 1\n2.0 2 2 3 0 0 0 1\n2.0 9 9 9 0 0 0 1\n");
  g = store::read_groundtruth_file(tum);
  CHECK(g.pose_only());
  CHECK(g.layout == "tum");
  CHECK(g.poses.size() == 2);
  CHECK(g.duplicate_stamps == 1);
  const auto snippet = test::load_euroc_snippet();
  if (snippet) {
    g = store::read_groundtruth_file(snippet->mav0 / "state_groundtruth_estimate0" / "data.csv");
    CHECK_FALSE(g.pose_only());
    CHECK(g.states.size() == snippet->groundtruth.size());
  }
  // A malformed row is named with its line, as every trajectory reader does.
  const fs::path bad = d.write("bad.csv", "#timestamp [ns], p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], "
                                          "q_RS_x [], q_RS_y [], q_RS_z []\n1000000000,1,2,x,1,0,0,0\n");
  CHECK_THROWS_WITH(store::read_groundtruth_file(bad), Catch::Contains("bad.csv") && Catch::Contains(":2"));
}

TEST_CASE("simulate --from-groundtruth on the real TUM-VI room1 (8-column mocap) and roe run with 4 objects",
          "[sim][groundtruth][real][tumvi]") {
  test::TempDir d;
  const auto room1 = tumvi_mav0(d);
  if (!room1) {
    WARN("skipped: ../shared/data/tumvi absent");
    return;
  }
  std::vector<double> smoothed, causal;
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    app::SimulateOptions so;
    so.from_groundtruth = room1->string();
    so.objects = 4;
    so.seed = seed;
    const sim::SimRun s = app::simulate_dataset(so);
    const Dataset& ds = s.dataset;
    const auto& src = ds.manifest.sources.back().options;
    CHECK(src.at("groundtruth_layout") == "euroc");
    CHECK(src.at("groundtruth_biases").find("unknown") != std::string::npos);
    CHECK(ds.groundtruth.size() > 16000);
    CHECK(src.at("imu_noise").find("sensor.yaml") != std::string::npos);
    REQUIRE(ds.manifest.imu);
    CHECK(ds.manifest.imu->noise.accel_noise_density == 0.0028);
    // No camera frame inside a ground-truth gap longer than 0.1 s (room1 has 26 gaps, the longest 1.06 s).
    for (const auto& f : ds.frames) {
      auto it = std::lower_bound(ds.groundtruth.begin(), ds.groundtruth.end(), f.t_ns,
                                 [](const ImuState& g, Timestamp t) { return g.t_ns < t; });
      if (it != ds.groundtruth.begin() && it != ds.groundtruth.end() && it->t_ns != f.t_ns)
        CHECK(it->t_ns - (it - 1)->t_ns <= 100'000'000);
    }
    const app::RunOutput r = app::run_dataset(ds, "sim", app::RunConfig{});
    smoothed.push_back(worst_axis(ds, r.states));
    causal.push_back(worst_axis(ds, r.filter_states));
    WARN("TUM-VI room1, seed " << seed << ": " << ds.frames.size() << " frames, worst-axis position RMSE smoothed "
                               << smoothed.back() << " m, causal " << causal.back() << " m");
  }
  for (std::size_t k = 0; k < smoothed.size(); ++k) {
    CHECK(smoothed[k] <= 0.05);
    CHECK(causal[k] <= 0.10);
  }
}
