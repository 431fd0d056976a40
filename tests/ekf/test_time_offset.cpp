// The camera–IMU time offset t_d (issue 49): simulated with a true offset (sim::CameraConfig::time_offset_s,
// stamps t_cam = t_imu − t_d), estimated online by the filter (FilterOptions::estimate_time_offset,
// docs/filter.md §16) from a declared prior of 0, checked against the truth and against its own σ (NEES over a
// Monte-Carlo), and the trajectory with the state against the same filter told nothing (offset 0).
#include <catch2/catch.hpp>

#include <cmath>
#include <vector>

#include "filter_support.hpp"
#include "roe/app/simulate.hpp"
#include "roe/math/distributions.hpp"
#include "roe/sim/simulator.hpp"

using namespace roe;

namespace {

Dataset simulate_with_offset(const std::string& preset, std::uint64_t seed, double duration_s, double offset_s) {
  sim::SimConfig c = app::sim_config_from_preset(preset);
  c.duration_s = duration_s;
  c.camera.time_offset_s = offset_s;
  return sim::simulate(c, seed);
}

app::RunConfig offset_config(bool estimate) {
  app::RunConfig cfg = test::plain_config();
  cfg.filter.use_detection_sigmas = true;
  cfg.filter.init_sigma_v_mps = 1.0;
  cfg.filter.estimate_time_offset = estimate;
  cfg.filter.time_offset_sigma_s = 0.03;
  return cfg;
}

}  // namespace

TEST_CASE("simulate: a true camera-IMU offset stamps the frames t_imu - offset and is written to the truth",
          "[ekf][time_offset][sim]") {
  const Dataset a = simulate_with_offset("matched-calib", 3, 5.0, 0.0);
  const Dataset b = simulate_with_offset("matched-calib", 3, 5.0, 0.025);
  REQUIRE(a.frames.size() == b.frames.size());
  for (std::size_t k = 0; k < a.frames.size(); ++k) CHECK(a.frames[k].t_ns - b.frames[k].t_ns == 25'000'000);
  const auto& da = a.detections.at("sim");
  const auto& db = b.detections.at("sim");
  REQUIRE(da.size() == db.size());
  for (std::size_t k = 0; k < da.size(); ++k) {
    CHECK(da[k].t_ns - db[k].t_ns == 25'000'000);
    CHECK((da[k].T_C_O.p - db[k].T_C_O.p).norm() == 0.0);  // the same view, only stamped earlier
  }
  CHECK(b.manifest.truth->camera_time_offset_s == 0.025);
  CHECK(b.manifest.camera->time_offset_s == 0.0);  // the declared prior, not the truth
  CHECK(a.imu.size() == b.imu.size());
}

// Issue 49's done-when: matched-calib (fast rotations) with true offsets −20, 0, +5, +30 ms and a declared 0:
// every estimate within max(1 ms, 3σ) of the truth, and the offset's NEES averaged over the Monte-Carlo inside
// the two-sided 95 % interval of χ²₁ averaged over the runs. With offset 0 the pose is no worse than without
// the state.
TEST_CASE("time offset: matched-calib offsets -20, 0, +5, +30 ms from a declared 0 are recovered, NEES inside chi2_1",
          "[ekf][time_offset][sim][mc]") {
  const std::vector<double> offsets = {-0.020, 0.0, 0.005, 0.030};
  const int seeds = 5;
  double nees_sum = 0.0;
  int n = 0;
  for (double off : offsets) {
    for (int s = 0; s < seeds; ++s) {
      const Dataset d = simulate_with_offset("matched-calib", 100 + s, 20.0, off);
      const app::RunOutput r = app::run_dataset(d, "sim", offset_config(true));
      const double est = r.summary.final_time_offset_s, sigma = r.summary.final_sigma_time_offset_s;
      INFO("true offset " << off * 1e3 << " ms, seed " << 100 + s << ": estimate " << est * 1e3 << " +- "
                          << sigma * 1e3 << " ms");
      CHECK(sigma > 0.0);
      CHECK(std::abs(est - off) <= std::max(0.001, 3.0 * sigma));
      // states.csv carries it at every row with σ, and it starts at the declared prior.
      CHECK(r.states.front().time_offset_s == 0.0);
      CHECK(r.states.back().time_offset_s == est);
      // Images are processed at t_cam + t̂_d, the ones past the IMU's end too: reprojection.csv stays in time order.
      bool ordered = true;
      for (std::size_t k = 1; k < r.reprojection.size(); ++k) ordered &= r.reprojection[k].t_ns >= r.reprojection[k - 1].t_ns;
      CHECK(ordered);
      nees_sum += (est - off) * (est - off) / (sigma * sigma);
      ++n;
    }
  }
  const double anees = nees_sum / n;
  const double lo = math::chi2_quantile(0.025, n) / n, hi = math::chi2_quantile(0.975, n) / n;
  WARN("time offset NEES over " << n << " runs: " << anees << " (95 % bounds " << lo << ", " << hi << ")");
  CHECK(anees > lo);
  CHECK(anees < hi);
}

TEST_CASE("time offset: with no offset the state costs the pose nothing, a 30 ms offset untold costs it",
          "[ekf][time_offset][sim]") {
  // Position RMSE (norm of the per-axis RMSE after an SE(3) alignment) from 3 s on.
  const auto rmse = [](const Dataset& d, bool estimate) {
    const app::RunOutput r = app::run_dataset(d, "sim", offset_config(estimate));
    return test::accuracy(test::match(r, d, 3.0)).pos_rmse.norm();
  };
  double rms_with = 0.0, rms_without = 0.0, rms_untold = 0.0, rms_estimated = 0.0, rms_told = 0.0;
  for (int s = 0; s < 3; ++s) {
    const Dataset d0 = simulate_with_offset("matched-calib", 200 + s, 20.0, 0.0);
    rms_with += rmse(d0, true);
    rms_without += rmse(d0, false);
    Dataset d30 = simulate_with_offset("matched-calib", 200 + s, 20.0, 0.030);
    rms_untold += rmse(d30, false);
    rms_estimated += rmse(d30, true);
    d30.manifest.camera->time_offset_s = 0.030;  // the run told the truth
    rms_told += rmse(d30, false);
  }
  WARN("position RMSE (3 seeds summed): offset 0 with the state " << rms_with << " m, without " << rms_without
                                                                  << "; 30 ms untold " << rms_untold << ", estimated "
                                                                  << rms_estimated << ", told " << rms_told);
  CHECK(rms_with <= 1.05 * rms_without);
  CHECK(rms_estimated < 0.8 * rms_untold);
  // Against a run told the truth: measured 1.34× (0.086 against 0.064 m; per seed 2.0×, 1.1×, 0.98×): the
  // estimate wanders 1–3 ms (inside its σ) for the first 10 s of these 20 s runs (docs/RESULTS.md, issue 49).
  CHECK(rms_estimated <= 1.5 * rms_told);
}
