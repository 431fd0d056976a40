// Accuracy, consistency and self-calibration of the filter on simulated sequences (roe::sim):
// noise-free convergence, Monte-Carlo NEES/NIS on the `matched` preset, extrinsics and object-world
// self-calibration.
#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <fmt/format.h>

#include "filter_support.hpp"
#include "roe/math/distributions.hpp"

using namespace roe;
using ekf::Vec3;
using ekf::Vec6;
using roe::test::accuracy;
using roe::test::match;

using roe::test::truth_object;
using roe::test::monte_carlo;
using roe::test::MonteCarlo;

TEST_CASE("noise-free preset: the estimate converges to the truth", "[ekf][sim]") {
  const Dataset d = test::simulate_preset("noise-free", 1, 30.0);
  app::RunConfig cfg = test::plain_config();
  cfg.filter.meas_sigma_p_m = 0.001;
  cfg.filter.meas_sigma_rot_deg = 0.05;
  // The simulated IMU is noise-free; the filter keeps a small process noise.
  cfg.filter.gyro_noise_density = 1e-5;
  cfg.filter.gyro_random_walk = 1e-6;
  cfg.filter.accel_noise_density = 1e-4;
  cfg.filter.accel_random_walk = 1e-5;
  for (ekf::AnchorGauge gauge : {ekf::AnchorGauge::kPositionYaw, ekf::AnchorGauge::kPosition}) {
    cfg.filter.anchor_gauge = gauge;
    const app::RunOutput r = app::run_dataset(d, "sim", cfg);
    INFO("gauge " << ekf::to_string(gauge));
    // After a 5 s convergence window (v starts at 0 while the rig moves; roll/pitch from a moving
    // accelerometer).
    const auto a = accuracy(match(r, d, 5.0));
    INFO("pos rmse " << a.pos_rmse.transpose() << " euler rmse " << a.euler_rmse.transpose());
    CHECK(a.pos_rmse.maxCoeff() < 1e-3);
    CHECK(a.euler_rmse.maxCoeff() < 0.01);
    // Extrinsics converge to the truth.
    const Pose& T_I_C_true = d.manifest.truth->T_I_C;
    const Vec6 e_c = math::pose_difference(T_I_C_true, r.summary.final_T_I_C);
    INFO("extrinsics error " << e_c.transpose());
    CHECK(e_c.head<3>().norm() < 1e-3);
    CHECK(e_c.tail<3>().norm() * math::kDegPerRad < 0.02);
    // Non-anchor object-worlds relative to the anchor: T_Ok_Oa = T_Ok_W T_W_Oa against the truth.
    const Pose T_Oa_W = r.summary.final_T_O_W.at(r.summary.anchor.id);
    const Pose T_W_Oa_true = truth_object(d, r.summary.anchor.id).T_W_O;
    REQUIRE(r.summary.final_T_O_W.size() == d.manifest.truth->objects.size());
    for (const auto& kv : r.summary.final_T_O_W) {
      if (kv.first == r.summary.anchor.id) continue;
      const Pose est = kv.second * T_Oa_W.inverse();
      const Pose tru = truth_object(d, kv.first).T_W_O.inverse() * T_W_Oa_true;
      const Vec6 e = math::pose_difference(tru, est);
      INFO("object " << kv.first << " relative error " << e.transpose());
      CHECK(e.head<3>().norm() < 1e-3);
      CHECK(e.tail<3>().norm() * math::kDegPerRad < 0.02);
    }
  }
}


// Consistency: with the configured noise equal to the simulated noise (the `matched` preset writes
// its per-detection σ), the time-averaged NEES of the IMU pose over N Monte-Carlo runs must lie in the
// two-sided 95 % χ² bounds [χ²_{6N}(0.025)/N, χ²_{6N}(0.975)/N], and the χ² rejection rate must be
// close to 1 − confidence. 20 runs of 20 s (~2 s in total in Release).
TEST_CASE("matched preset Monte-Carlo: NEES inside the 95 % bounds, rejection rate ~ 5 %", "[ekf][sim][mc]") {
  const MonteCarlo mc = monte_carlo("matched", 20, 20.0, 3.0);
  WARN("matched MC: time-averaged NEES " << mc.anees << " (bounds " << mc.lo << ", " << mc.hi
                                         << "), rejection rate " << mc.rejection_rate << " over " << mc.gated
                                         << " gated detections");
  CHECK(mc.anees > mc.lo);
  CHECK(mc.anees < mc.hi);
  CHECK(mc.rejection_rate > 0.03);
  CHECK(mc.rejection_rate < 0.075);
}

// The default's handling of predicted σ (issue 29: online σ scale, split gate, re-lock) on the matched
// preset: consistent when the σ are right. With σ reported at half the true error the scale learned online
// comes out at 2 and the NEES returns to just above its upper bound (7.83 against 7.61, measured
// 2026-12-02; 58.8 without the scale): the object-worlds, which have no process noise, keep the
// overconfidence of the first 15 detections, gated before the scale is learned (docs/filter.md §14).
TEST_CASE("matched Monte-Carlo with predicted σ, online scale, split gate: NEES inside the 95 % bounds",
          "[ekf][sim][mc][sigma]") {
  const auto default_sigma_handling = [](app::RunConfig& c) {
    c.filter.adapt_detection_sigma_scale = true;
    c.filter.gate_mode = ekf::GateMode::kSplit;
    c.filter.relock_after_s = 0.5;
  };
  const auto halve_reported_sigma = [](Dataset& d) {
    for (auto& det : d.detections.at("sim"))
      if (det.sigma) *det.sigma *= 0.5;
  };
  const int N = 20;
  const MonteCarlo right = monte_carlo("matched", N, 20.0, 3.0, "none", default_sigma_handling);
  const MonteCarlo half = monte_carlo("matched", N, 20.0, 3.0, "none", default_sigma_handling, halve_reported_sigma);
  const MonteCarlo half_fixed = monte_carlo("matched", N, 20.0, 3.0, "none", {}, halve_reported_sigma);
  WARN("matched MC, σ right: NEES " << right.anees << ", σ scale " << right.sigma_scale_sum / N << "; σ halved: NEES "
                                    << half.anees << ", scale " << half.sigma_scale_sum / N
                                    << "; σ halved, no online scale: NEES " << half_fixed.anees << " (bounds "
                                    << right.lo << ", " << right.hi << ")");
  CHECK(right.anees > right.lo);
  CHECK(right.anees < right.hi);
  CHECK(right.sigma_scale_sum / N == Approx(1.0).epsilon(0.15));
  CHECK(half.anees > half.lo);
  CHECK(half.anees < 1.1 * half.hi);
  CHECK(half.sigma_scale_sum / N == Approx(2.0).epsilon(0.15));
  CHECK(half_fixed.anees > half_fixed.hi);  // the control: overconfident σ without the scale
}

TEST_CASE("matched-calib Monte-Carlo (fast rotations): NEES and rejection rate", "[ekf][sim][mc]") {
  const MonteCarlo mc = monte_carlo("matched-calib", 20, 20.0, 3.0);
  WARN("matched-calib MC: time-averaged NEES " << mc.anees << " (bounds " << mc.lo << ", " << mc.hi
                                               << "), rejection rate " << mc.rejection_rate << " over "
                                               << mc.gated << " gated detections");
  CHECK(mc.anees > mc.lo);
  CHECK(mc.anees < mc.hi);
  CHECK(mc.rejection_rate > 0.03);
  CHECK(mc.rejection_rate < 0.075);
}

namespace {

// The `matched`-family dataset with T_I_C perturbed by 3 cm / 3° in the prior (the truth unchanged).
Dataset perturbed_extrinsics(const std::string& preset, std::uint64_t seed, double duration) {
  Dataset d = test::simulate_preset(preset, seed, duration);
  const Pose T_I_C_true = d.manifest.truth->T_I_C;
  const Vec3 dp = Vec3(1, -1, 1).normalized() * 0.03;
  const Vec3 dth = Vec3(-1, 1, 1).normalized() * (3.0 * math::kRadPerDeg);
  d.manifest.camera->T_I_C = Pose(T_I_C_true.q * math::exp_quat(dth), T_I_C_true.p + dp);
  return d;
}

app::RunConfig self_calibration_config() {
  app::RunConfig cfg = test::plain_config();
  cfg.filter.use_detection_sigmas = true;
  cfg.filter.extrinsics_sigma_p_m = 0.05;
  cfg.filter.extrinsics_sigma_rot_deg = 5.0;
  return cfg;
}

}  // namespace

// Self-calibration (issue target: extrinsics perturbed by 3 cm / 3° converge to < 5 mm / 0.5°) under a
// calibration motion (`matched-calib`: roll swings ±0.6 rad at 0.5 Hz, pitch/yaw swings ~±10°, as one
// waves a rig for Kalibr), 120 s. Measured: seeds 7/8/9 → 2.0/1.0/2.0 mm and 0.09/0.03/0.11° at 120 s.
TEST_CASE("self-calibration: perturbed extrinsics converge to < 5 mm / 0.5 deg under a calibration motion",
          "[ekf][sim][calib]") {
  const Dataset d = perturbed_extrinsics("matched-calib", 7, 120.0);
  const Pose& T_I_C_true = d.manifest.truth->T_I_C;
  const app::RunOutput r = app::run_dataset(d, "sim", self_calibration_config());
  const Vec6 e = math::pose_difference(T_I_C_true, r.summary.final_T_I_C);
  const double e_p = e.head<3>().norm(), e_r = e.tail<3>().norm() * math::kDegPerRad;
  const auto& last = r.states.back();
  WARN("self-calibration (matched-calib, 120 s): extrinsics error " << e_p * 1000 << " mm, " << e_r
                                                                    << " deg; filter sigma p_I_C "
                                                                    << last.sigma.segment<3>(15).transpose() * 1000
                                                                    << " mm");
  CHECK(e_p < 0.005);
  CHECK(e_r < 0.5);
  // The estimate agrees with its own σ (3σ per axis).
  for (int i = 0; i < 3; ++i) CHECK(std::abs(r.summary.final_T_I_C.p(i) - T_I_C_true.p(i)) < 3.0 * last.sigma(15 + i));
}

// On the paper-like slow orbit alone (`matched`, 0.12 rad/s) a lever-arm error δ looks like an
// accelerometer bias ω²δ (4e-4 m/s² for 3 cm), far below the bias random walk: the lever arm stays
// uncertain. The filter must say so (σ stays above 5 mm) while its estimate stays within 3σ, and the
// rotation still converges.
TEST_CASE("self-calibration on the slow orbit: the lever arm stays uncertain and the filter says so",
          "[ekf][sim][calib]") {
  const Dataset d = perturbed_extrinsics("matched", 7, 60.0);
  const Pose& T_I_C_true = d.manifest.truth->T_I_C;
  const app::RunOutput r = app::run_dataset(d, "sim", self_calibration_config());
  const Vec6 e = math::pose_difference(T_I_C_true, r.summary.final_T_I_C);
  const auto& last = r.states.back();
  WARN("self-calibration (matched, 60 s): extrinsics error "
       << e.head<3>().norm() * 1000 << " mm, " << e.tail<3>().norm() * math::kDegPerRad
       << " deg; filter sigma p_I_C " << last.sigma.segment<3>(15).transpose() * 1000 << " mm");
  CHECK(e.tail<3>().norm() * math::kDegPerRad < 0.5);
  CHECK(last.sigma.segment<3>(15).maxCoeff() > 0.005);
  for (int i = 0; i < 3; ++i)
    CHECK(std::abs(r.summary.final_T_I_C.p(i) - T_I_C_true.p(i)) < 3.0 * last.sigma(15 + i) + 0.002);
}

// Non-anchor object-worlds (issue target: σ < 1 cm / 1° within 10 s of first sight; the paper's Fig. 4,
// with its main object held fixed, ~5 s). Default configuration (extrinsics self-calibrated from the
// 2 cm / 2° prior) with the per-detection σ, `matched`, six seeds of 30 s, every non-anchor object.
// The σ compared is that of the object's pose relative to the anchor, T_A_O (objects.csv sigma_*_A_O_*):
// it does not depend on how W is pinned (roe's default gauge estimates the anchor's tilt against gravity,
// and that common uncertainty enters every T_W_O). Measured: 3.7–7.7 s per object (first object per
// seed 3.7–4.7 s), the same with the extrinsics held at the truth. For T_W_O in the default gauge the
// first object per seed takes 11.3–23.5 s (docs/RESULTS.md §4); that is asserted loosely as a guard.
// Every final estimate must agree with its σ, relative to the anchor and in W.
TEST_CASE("object-worlds: sigma < 1 cm / 1 deg within 10 s of first sight, estimates consistent with sigma",
          "[ekf][sim][calib]") {
  app::RunConfig cfg = test::plain_config();
  cfg.filter.use_detection_sigmas = true;
  const auto below = [](const Vec6& sigma) {
    return sigma.head<3>().maxCoeff() < 0.01 && sigma.tail<3>().maxCoeff() * math::kDegPerRad < 1.0;
  };
  // Σ (err_i / σ_i)² against the χ²₆ 99.9 % quantile (22.46): eighteen objects × six axes of 3σ checks
  // would fail by chance one run in four for a consistent filter.
  const auto nees = [](const Vec6& err, const Vec6& sig) {
    double n = 0.0;
    for (int i = 0; i < 6; ++i) n += (err(i) / sig(i)) * (err(i) / sig(i));
    return n;
  };
  std::vector<double> times_A_O, first_W_O;
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    const Dataset d = test::simulate_preset("matched", seed, 30.0);
    const app::RunOutput r = app::run_dataset(d, "sim", cfg);
    std::map<int, Timestamp> first, reached_A_O, reached_W_O;
    std::map<int, const app::ObjectRow*> last;
    for (const auto& row : r.objects) {
      if (row.anchor) {
        CHECK(row.sigma_A_O.isZero());
        continue;
      }
      last[row.object_id] = &row;
      if (!first.count(row.object_id)) first[row.object_id] = row.t_ns;
      if (below(row.sigma_A_O) && !reached_A_O.count(row.object_id)) reached_A_O[row.object_id] = row.t_ns;
      if (below(row.sigma_W_O) && !reached_W_O.count(row.object_id)) reached_W_O[row.object_id] = row.t_ns;
    }
    REQUIRE(first.size() >= 2);
    const Pose T_A_W_est = r.summary.final_T_O_W.at(r.summary.anchor.id);
    const Pose T_W_A_true = truth_object(d, r.summary.anchor.id).T_W_O;
    double best_W_O = 1e9;
    for (const auto& kv : first) {
      INFO("seed " << seed << " object " << kv.first);
      REQUIRE(reached_A_O.count(kv.first));
      REQUIRE(reached_W_O.count(kv.first));
      const double t = dt_seconds(kv.second, reached_A_O[kv.first]);
      times_A_O.push_back(t);
      CHECK(t <= 10.0);
      best_W_O = std::min(best_W_O, dt_seconds(kv.second, reached_W_O[kv.first]));
      const Pose T_W_O_true = truth_object(d, kv.first).T_W_O;
      const Pose T_O_W_est = r.summary.final_T_O_W.at(kv.first);
      // Relative to the anchor (no gauge needed).
      const Vec6 err_A_O = math::pose_difference(T_W_A_true.inverse() * T_W_O_true, T_A_W_est * T_O_W_est.inverse());
      INFO("error T_A_O " << err_A_O.transpose() << " sigma " << last.at(kv.first)->sigma_A_O.transpose());
      CHECK(nees(err_A_O, last.at(kv.first)->sigma_A_O) < 22.46);
      // In W, against the truth in the filter's gauge (anchor position + yaw).
      const Pose T_Wp_Wt = test::gauge_position_yaw(T_A_W_est, T_W_A_true);
      const Vec6 err_W_O = math::pose_difference(T_Wp_Wt * T_W_O_true, T_O_W_est.inverse());
      INFO("error T_W_O " << err_W_O.transpose() << " sigma " << last.at(kv.first)->sigma_W_O.transpose());
      CHECK(nees(err_W_O, last.at(kv.first)->sigma_W_O) < 22.46);
    }
    first_W_O.push_back(best_W_O);
  }
  std::string list;
  for (double t : times_A_O) list += fmt::format(" {:.1f}", t);
  std::sort(first_W_O.begin(), first_W_O.end());
  WARN("object-worlds: sigma(T_A_O) below 1 cm / 1 deg after [s]:" << list << "; sigma(T_W_O), first object per seed: "
                                                                   << first_W_O.front() << " .. " << first_W_O.back()
                                                                   << " s");
  CHECK(*std::max_element(times_A_O.begin(), times_A_O.end()) <= 10.0);
  CHECK(first_W_O.back() < 25.0);
}
