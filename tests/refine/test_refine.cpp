// roe refine end to end: simulate → run → refine, against the truth and the filter (docs/refine.md §5).
#include <catch2/catch.hpp>
#include <cmath>

#include "roe/app/refine.hpp"
#include "roe/app/run.hpp"
#include "roe/app/simulate.hpp"
#include "roe/store/dataset.hpp"
#include "roe/store/run_files.hpp"
#include "roe/math/se3.hpp"
#include "support/test_util.hpp"

namespace {

using namespace roe;
namespace fs = std::filesystem;
constexpr double kDeg = 180.0 / M_PI;

fs::path simulate(const test::TempDir& tmp, const std::string& preset, double duration_s) {
  app::SimulateOptions so;
  so.preset = preset;
  so.seed = 1;
  so.duration_s = duration_s;
  const fs::path ds = tmp / "ds";
  app::simulate(so, ds);
  return ds;
}

/// Each object's last row of objects.csv.
std::map<int, store::ObjectRow> last_objects(const fs::path& run) {
  std::map<int, store::ObjectRow> m;
  for (const auto& r : store::read_objects_csv(run / "objects.csv")) m[r.object_id] = r;
  return m;
}

int anchor_of(const std::map<int, store::ObjectRow>& m) {
  for (const auto& [id, r] : m)
    if (r.anchor) return id;
  FAIL("no anchor row");
  return -1;
}

}  // namespace

TEST_CASE("refine/app: a noise-free simulation refines to the truth") {
  test::TempDir tmp("roe_refine_nf");
  const fs::path ds = simulate(tmp, "noise-free", 20.0);
  // A noise-free IMU (density 0) would make the IMU residuals singular: give the run a small noise.
  const fs::path cfg = tmp.write("cfg.json", R"({"filter": {"gyro_noise_density": 1e-4, "accel_noise_density": 1e-3,
      "gyro_random_walk": 1e-6, "accel_random_walk": 1e-5}})");
  app::RunOptions ro;
  ro.config_file = cfg.string();
  app::run(ds, tmp / "run", ro);
  // White weighting (τ 0): exact detections pin everything. With τ fitted, exact detections read as an
  // error of unbounded time constant (τ ~ 100 s), which leaves the constants to the differences and the
  // priors: still within 1 mm (measured 0.3 mm).
  app::RefineCommandOptions fitted;
  const auto res_fitted = app::refine_run(tmp / "run", tmp / "ref_fitted", fitted);
  REQUIRE(res_fitted.result.report.usable);
  const Vector6d e_fitted = math::pose_difference(store::read_manifest(ds).truth->T_I_C, res_fitted.result.T_I_C);
  CHECK(e_fitted.head<3>().norm() < 1e-3);
  app::RefineCommandOptions opt;
  opt.refine.tau_s = 0.0;
  const auto res = app::refine_run(tmp / "run", tmp / "ref", opt);
  CHECK(res.result.report.usable);

  const DatasetManifest man = store::read_manifest(ds);
  REQUIRE(man.truth);
  const auto states = store::read_states_csv(tmp / "ref" / "states.csv");
  const Vector6d e_extr = math::pose_difference(man.truth->T_I_C, states.back().T_I_C);
  INFO("extrinsics error " << e_extr.head<3>().norm() * 1e3 << " mm, " << e_extr.tail<3>().norm() * kDeg << " deg");
  CHECK(e_extr.head<3>().norm() < 1e-4);
  CHECK(e_extr.tail<3>().norm() * kDeg < 0.005);

  const auto objs = last_objects(tmp / "ref");
  const int a = anchor_of(objs);
  std::map<int, Pose> truth;
  for (const auto& o : man.truth->objects) truth[o.id] = o.T_W_O;
  int checked = 0;
  for (const auto& [id, row] : objs) {
    if (id == a || !truth.count(id)) continue;
    const Pose est = objs.at(a).T_O_W * row.T_O_W.inverse();  // T_A_O
    const Pose tru = truth.at(a).inverse() * truth.at(id);
    const Vector6d e = math::pose_difference(tru, est);
    INFO("object " << id << ": " << e.head<3>().norm() * 1e3 << " mm, " << e.tail<3>().norm() * kDeg << " deg");
    CHECK(e.head<3>().norm() < 1e-4);
    CHECK(e.tail<3>().norm() * kDeg < 0.005);
    CHECK((row.sigma_A_O.array() > 0).all());
    ++checked;
  }
  CHECK(checked >= 1);
}

TEST_CASE("refine/app: on matched-calib the refinement agrees with the filter within the filter's sigma") {
  test::TempDir tmp("roe_refine_mc");
  const fs::path ds = simulate(tmp, "matched-calib", 60.0);
  app::run(ds, tmp / "run", {});
  const auto res = app::refine_run(tmp / "run", tmp / "ref", {});
  REQUIRE(res.result.report.usable);
  REQUIRE(res.result.report.covariance_ok);

  // The filter's own final extrinsics and σ (states_filter.csv: the causal filter beside the smoother).
  const auto filt = store::read_states_csv(tmp / "run" / "states_filter.csv").back();
  const auto ref = store::read_states_csv(tmp / "ref" / "states.csv").back();
  const Vector6d d = math::pose_difference(filt.T_I_C, ref.T_I_C);
  for (int i = 0; i < 6; ++i) {
    INFO("extrinsics component " << i << ": refined − filter " << d(i) << ", filter σ " << filt.sigma(15 + i)
                                 << ", refined σ " << ref.sigma(15 + i));
    CHECK(std::abs(d(i)) <= 3.0 * filt.sigma(15 + i));
    CHECK(ref.sigma(15 + i) > 0.0);
  }
  const auto fo = last_objects(tmp / "run"), ro = last_objects(tmp / "ref");
  const int a = anchor_of(fo);
  REQUIRE(anchor_of(ro) == a);
  int checked = 0;
  for (const auto& [id, row] : fo) {
    if (id == a || !ro.count(id)) continue;
    const Pose f_AO = fo.at(a).T_O_W * row.T_O_W.inverse();
    const Pose r_AO = ro.at(a).T_O_W * ro.at(id).T_O_W.inverse();
    const Vector6d e = math::pose_difference(f_AO, r_AO);
    for (int i = 0; i < 6; ++i) {
      INFO("object " << id << " component " << i << ": " << e(i) << " vs filter σ " << row.sigma_A_O(i));
      CHECK(std::abs(e(i)) <= 3.0 * row.sigma_A_O(i));
    }
    ++checked;
  }
  CHECK(checked >= 1);
}

TEST_CASE("refine/app: on a paper-real replica the solve whitens the correlated detection errors") {
  // paper-real-seq4 (Gauss-Markov detection errors, τ = 3 s, 5 % outliers and bad-frame runs): the fitted
  // τ is near the simulator's, the whitened residuals are uncorrelated, the gross detections are dropped,
  // and the extrinsics' error from the truth is inside the marginals (no rescaling after the solve).
  test::TempDir tmp("roe_refine_pr");
  app::SimulateOptions so;
  so.preset = "paper-real-seq4";
  so.seed = 1;
  so.duration_s = 40.0;
  app::simulate(so, tmp / "ds");
  app::run(tmp / "ds", tmp / "run", {});
  const auto res = app::refine_run(tmp / "run", tmp / "ref", {});
  REQUIRE(res.result.report.covariance_ok);
  const refine::DetectionErrorModel& m = res.result.report.error_model;
  INFO("fitted tau " << m.tau_s << " s, scales " << m.scale_translation << " / " << m.scale_rotation
                     << ", whitened lag-1 " << m.whitened_lag1 << ", gross " << m.gross << " of " << m.used + m.gross);
  CHECK(m.fitted_tau);
  CHECK(m.tau_s > 1.5);
  CHECK(m.tau_s < 6.0);
  CHECK(std::abs(m.whitened_lag1) < 0.2);
  // 5 % outliers plus the bad-frame runs (2 % start, 5 frames: ~9 % of frames).
  CHECK(m.gross > (m.used + m.gross) / 20);
  CHECK(m.gross < (m.used + m.gross) / 4);
  std::size_t dropped = 0;
  for (const auto& d : res.result.detections) dropped += d.weight == 0.0 ? 1 : 0;
  CHECK(dropped == m.gross);
  // The rotation σ the filter's model gives (20°) is about 3× the replica's 6°: the fitted scale says so.
  CHECK(m.scale_rotation < 0.6);
  const refine::Mat6 C = res.result.cov_T_I_C;
  const DatasetManifest man = store::read_manifest(tmp / "ds");
  REQUIRE(man.truth);
  const Vector6d e = math::pose_difference(man.truth->T_I_C, res.result.T_I_C);
  const double nees = e.dot(C.ldlt().solve(e));
  INFO("extrinsics error " << e.head<3>().norm() * 1e3 << " mm, " << e.tail<3>().norm() * kDeg << " deg, NEES " << nees);
  CHECK(nees < 22.46);  // χ²₆(0.999)
}

TEST_CASE("refine/app: a folder without run.json is an input error") {
  test::TempDir tmp("roe_refine_bad");
  CHECK_THROWS_AS(app::refine_run(tmp.path, tmp / "out", {}), InputError);
}
