// Monte Carlo: `roe refine` against the Cramér–Rao bound that scripts/crlb.py computes from the simulator's
// own error model, independently of refine's code (issue 48; docs/refine.md §6). One paper-real preset with
// the trajectory held (no seed variation), 20 error draws (the seed varies the IMU noise, the detection
// errors, misses, outliers and bursts; the extrinsics prior drawn from N(truth, prior σ)): refine's RMS
// error of the extrinsics is within 1.3× the bound and its mean NEES inside the χ² interval; the same solve
// with τ held at 0 (white weighting of the correlated detections) fails. The objects relative to the
// anchor are reported and checked without failing (not met yet, see the end of this test). Run alone:
//   ctest -R 'refine/efficiency'   or   build/test_refine '[efficiency]'
#include <catch2/catch.hpp>
#include <cmath>
#include <fstream>
#include <fmt/format.h>

#include <nlohmann/json.hpp>
#include <random>

#include "roe/app/refine.hpp"
#include "roe/app/run.hpp"
#include "roe/app/simulate.hpp"
#include "roe/math/se3.hpp"
#include "roe/math/so3.hpp"
#include "roe/store/dataset.hpp"
#include "support/test_util.hpp"

namespace {

using namespace roe;
namespace fs = std::filesystem;

constexpr int kDraws = 20;
constexpr double kDurationS = 30.0;

/// Squared errors and NEES summed over the draws, per calibration quantity.
struct Tally {
  double sq_p = 0.0, sq_r = 0.0, nees = 0.0;
  int n = 0;
  void add(const Vector6d& e, const refine::Mat6& C) {
    sq_p += e.head<3>().squaredNorm();
    sq_r += e.tail<3>().squaredNorm();
    nees += e.dot(C.ldlt().solve(e));
    ++n;
  }
  double rms_p() const { return std::sqrt(sq_p / n); }
  double rms_r() const { return std::sqrt(sq_r / n); }
};

struct Bound {
  double p = 0.0, r = 0.0;  // RMS position (m), rotation (rad)
};

Bound bound_of(const nlohmann::json& j) {
  return {j.at("rms_position_m").get<double>(), j.at("rms_rotation_deg").get<double>() * M_PI / 180.0};
}

/// χ²_k two-sided 99 % interval of a sum of N NEES of 6 dof (Wilson–Hilferty), as a mean per draw.
std::pair<double, double> mean_nees_interval(int draws) {
  const double k = 6.0 * draws, z = 2.5758;
  const auto q = [&](double s) { return k * std::pow(1.0 - 2.0 / (9.0 * k) + s * z * std::sqrt(2.0 / (9.0 * k)), 3) / draws; };
  return {q(-1.0), q(1.0)};
}

/// What the check says of one estimator: RMS ≤ 1.3 × bound for the extrinsics and every object, mean NEES
/// inside the interval for each.
struct Verdict {
  bool rms_ok = true, nees_ok = true;
  std::string text;
};

Verdict judge(const std::string& name, const Tally& t, const Bound& b) {
  const auto [lo, hi] = mean_nees_interval(t.n);
  Verdict v;
  v.rms_ok = t.rms_p() <= 1.3 * b.p && t.rms_r() <= 1.3 * b.r;
  v.nees_ok = t.nees / t.n >= lo && t.nees / t.n <= hi;
  v.text = name + ": RMS " + std::to_string(t.rms_p() * 1e3) + " mm / " + std::to_string(t.rms_r() * 180 / M_PI) +
           " deg (bound " + std::to_string(b.p * 1e3) + " mm / " + std::to_string(b.r * 180 / M_PI) + " deg), mean NEES " +
           std::to_string(t.nees / t.n) + " in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]\n";
  return v;
}

}  // namespace

TEST_CASE("refine/efficiency: refine is within 1.3x the Cramer-Rao bound and consistent, white weighting is not",
          "[efficiency]") {
  if (std::system("/usr/bin/python3 -c 'import numpy, scipy' 2>/dev/null") != 0) {
    WARN("skipped: /usr/bin/python3 with numpy and scipy is needed for scripts/crlb.py");
    return;
  }
  test::TempDir tmp("roe_refine_eff");
  // The extrinsics prior is drawn from N(truth, prior σ) per draw (the config's 20 mm / 2° per axis), as the
  // bound assumes: an exact prior would make any estimator that stays near it look better than the bound.
  std::mt19937 rng(48);
  std::normal_distribution<double> n01(0.0, 1.0);
  const auto sim_config = [&](int seed) {
    const Eigen::Vector3d dp(0.02 * n01(rng), 0.02 * n01(rng), 0.02 * n01(rng));
    const Eigen::Quaterniond dq = math::exp_quat(Eigen::Vector3d(n01(rng), n01(rng), n01(rng)) * (2.0 * M_PI / 180.0));
    return tmp.write("sim" + std::to_string(seed) + ".json",
                     fmt::format(R"({{"base": "paper-real-seq1", "name": "efficiency",
      "camera": {{"prior_error": {{"p": [{}, {}, {}], "q": [{}, {}, {}, {}]}}}},
      "variation": {{"amplitude_rel": 0, "frequency_rel": 0, "phase_rad": 0, "offset_rel": 0, "azimuth_start_rad": 0}}}})",
                                 dp.x(), dp.y(), dp.z(), dq.x(), dq.y(), dq.z(), dq.w()));
  };
  // The anchor held (the automatic rule picks objects 4 or 15 by the draw): object 15, seen from the start.
  const fs::path run_cfg = tmp.write("run.json", R"({"filter": {"anchor_id": 15}})");
  std::map<std::string, Tally> whitened, white;
  nlohmann::json bound;
  for (int seed = 1; seed <= kDraws; ++seed) {
    const fs::path ds = tmp / ("ds" + std::to_string(seed)), run = tmp / ("run" + std::to_string(seed));
    app::SimulateOptions so;
    so.config_file = sim_config(seed).string();
    so.seed = static_cast<std::uint64_t>(seed);
    so.duration_s = kDurationS;
    app::simulate(so, ds);
    app::RunOptions ro;
    ro.config_file = run_cfg.string();
    app::run(ds, run, ro);
    app::RefineCommandOptions opt;
    const auto res = app::refine_run(run, tmp / ("ref" + std::to_string(seed)), opt);
    opt.refine.tau_s = 0.0;
    const auto resw = app::refine_run(run, tmp / ("refw" + std::to_string(seed)), opt);
    REQUIRE(res.result.report.covariance_ok);
    REQUIRE(resw.result.report.covariance_ok);
    int anchor = -1;
    for (const auto& [id, o] : res.result.objects)
      if (o.anchor) anchor = id;
    REQUIRE(anchor == 15);
    if (seed == 1) {  // the trajectory and objects are the same in every draw: one bound
      const test::RunResult py = test::run_shell("/usr/bin/python3 " + std::string(ROE_SOURCE_DIR) + "/scripts/crlb.py " + ds.string() +
                                                 " --anchor " + std::to_string(anchor) + " --config " + run_cfg.string());
      INFO(py.out);
      REQUIRE(py.code == 0);
      bound = nlohmann::json::parse(py.out);
    }
    const DatasetManifest man = store::read_manifest(ds);
    REQUIRE(man.truth);
    std::map<int, Pose> T_W_O;
    for (const auto& o : man.truth->objects) T_W_O[o.id] = o.T_W_O;
    for (auto* r : {&res.result, &resw.result}) {
      auto& tally = r == &res.result ? whitened : white;
      tally["extrinsics"].add(math::pose_difference(man.truth->T_I_C, r->T_I_C), r->cov_T_I_C);
      for (const auto& [id, o] : r->objects) {
        if (o.anchor) continue;
        const Pose est = r->objects.at(anchor).T_O_W * o.T_O_W.inverse();
        const Pose tru = T_W_O.at(anchor).inverse() * T_W_O.at(id);
        tally["object " + std::to_string(id)].add(math::pose_difference(tru, est), o.cov_relative);
      }
    }
  }
  std::string report;
  bool extrinsics_ok = false, white_ok = true, objects_ok = true;
  for (const auto& [name, t] : whitened) {
    const Bound b = name == "extrinsics" ? bound_of(bound.at("extrinsics"))
                                         : bound_of(bound.at("objects").at(name.substr(7)));
    const Verdict v = judge("refine " + name, t, b), w = judge("tau 0  " + name, white.at(name), b);
    report += v.text + w.text;
    if (name == "extrinsics") extrinsics_ok = v.rms_ok && v.nees_ok;
    else objects_ok = objects_ok && v.rms_ok && v.nees_ok;
    white_ok = white_ok && w.rms_ok && w.nees_ok;
  }
  INFO(report);
  CHECK(extrinsics_ok);
  CHECK_FALSE(white_ok);
  // Not met yet (docs/refine.md §6, issue 48): the objects' rotation relative to the anchor is about 2x its
  // bound with either weighting (8° RMS against 3.9°), its NEES about 10. Recorded, not failing.
  CHECK_NOFAIL(objects_ok);
}
