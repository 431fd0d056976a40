// The Euler metrics of roe eval --euler (error, absolute, absolute-unwrapped) on a constructed
// trajectory that crosses ±180° (figures computed by hand) and against scipy on random rotations; the
// per-axis mean and std; the body-rotation fit; the truth in the estimator's gauge and its NEES.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "roe/core/error.hpp"
#include "roe/eval/evaluate.hpp"
#include "roe/eval/gauge.hpp"
#include "roe/math/euler.hpp"
#include "roe/math/so3.hpp"

using namespace roe;
using namespace roe::eval;
using Eigen::Vector3d;

namespace {

Pose rpy_pose(double roll_deg, double pitch_deg, double yaw_deg, const Vector3d& p = Vector3d::Zero()) {
  return Pose(Eigen::Quaterniond(math::from_euler_zyx(Vector3d(roll_deg, pitch_deg, yaw_deg) * math::kRadPerDeg)), p);
}

/// Ground-truth yaw crossing +180 → −180 while the estimate (4° ahead) crosses it one sample earlier.
void yaw_crossing(std::vector<Pose>& est, std::vector<Pose>& gt) {
  for (double yaw : {170.0, 175.0, 178.0, -178.0, -172.0}) {
    gt.push_back(rpy_pose(0, 0, yaw));
    est.push_back(rpy_pose(0, 0, yaw + 4.0));  // 174, 179, 182 = −178, −174, −168
  }
}

}  // namespace

TEST_CASE("Euler metrics: hand-computed figures on a yaw crossing ±180 deg", "[eval][metrics][euler]") {
  std::vector<Pose> est, gt;
  yaw_crossing(est, gt);
  // error: R_estᵀR_gt = Rz(−4°) at every pair.
  const ApeResult e = compute_ape(est, gt, {}, 1, EulerMetric::kError);
  CHECK(e.euler_metric == EulerMetric::kError);
  CHECK(e.rpy_rmse_deg.z() == Approx(4.0).epsilon(1e-12));
  CHECK(e.rpy.mean.z() == Approx(-4.0).epsilon(1e-12));
  CHECK(e.rpy.std.z() == Approx(0.0).margin(1e-6));
  CHECK(e.rpy_rmse_deg.x() == Approx(0.0).margin(1e-9));
  // absolute (wrapped): +4° at every pair (estimate minus ground truth).
  const ApeResult a = compute_ape(est, gt, {}, 1, EulerMetric::kAbsolute);
  CHECK(a.rpy_rmse_deg.z() == Approx(4.0).epsilon(1e-12));
  CHECK(a.rpy.mean.z() == Approx(4.0).epsilon(1e-12));
  CHECK(a.rpy.std.z() == Approx(0.0).margin(1e-6));
  // absolute-unwrapped: 4, 4, −356, 4, 4 → rmse √((4·16 + 356²)/5) = √25360, mean −68, std √(25360 − 68²) = 144.
  const ApeResult u = compute_ape(est, gt, {}, 1, EulerMetric::kAbsoluteUnwrapped);
  CHECK(u.rpy_rmse_deg.z() == Approx(std::sqrt(25360.0)).epsilon(1e-12));
  CHECK(u.rpy.mean.z() == Approx(-68.0).epsilon(1e-12));
  CHECK(u.rpy.std.z() == Approx(144.0).epsilon(1e-12));
  CHECK(u.jump_share.z() == Approx(0.2));
  CHECK(u.jump_share.x() == 0.0);
  CHECK(u.jump_share_any == Approx(0.2));
  // The rotation error's figures ride along, the same bits as the error metric's.
  CHECK(u.rpy_error.rmse == e.rpy_rmse_deg);
  CHECK(u.rpy_error.mean == e.rpy.mean);
  CHECK(a.jump_share_any == Approx(0.2));  // the jump is counted for either absolute metric
  // The default is the error metric, bit for bit.
  const ApeResult d = compute_ape(est, gt);
  CHECK(d.rpy_rmse_deg == e.rpy_rmse_deg);
}

TEST_CASE("Euler metrics: a roll crossing ±180 deg (a camera looking down), per pair", "[eval][metrics][euler]") {
  const Pose gt = rpy_pose(178.0, 0, 0), est = rpy_pose(-179.0, 0, 0);  // est roll 181°
  const PoseError pe = pose_error(est, gt);
  // R_estᵀR_gt = Rx(178° − 181°) = Rx(−3°); absolute: wrap(−179 − 178) = wrap(−357) = 3; unwrapped −357.
  CHECK(euler_figure_deg(est, gt, pe, EulerMetric::kError).x() == Approx(-3.0).epsilon(1e-10));
  CHECK(euler_figure_deg(est, gt, pe, EulerMetric::kAbsolute).x() == Approx(3.0).epsilon(1e-10));
  CHECK(euler_figure_deg(est, gt, pe, EulerMetric::kAbsoluteUnwrapped).x() == Approx(-357.0).epsilon(1e-12));
  CHECK(absolute_euler_difference_deg(est, gt).x() == Approx(-357.0).epsilon(1e-12));
}

TEST_CASE("Euler metrics: names, definitions and a constant offset as rmse >> std", "[eval][metrics][euler]") {
  for (EulerMetric m : {EulerMetric::kError, EulerMetric::kAbsolute, EulerMetric::kAbsoluteUnwrapped}) {
    CHECK(parse_euler_metric(to_string(m)) == m);
    CHECK(!euler_metric_definition(m).empty());
  }
  CHECK(to_string(EulerMetric::kAbsoluteUnwrapped) == "absolute-unwrapped");
  try {
    parse_euler_metric("unwrapped");
    FAIL("no error");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).find("error, absolute or absolute-unwrapped") != std::string::npos);
  }
  // A constant 2° roll offset with ±0.5° alternating noise: rmse² = mean² + std², std = 0.5.
  std::vector<Pose> est, gt;
  for (int i = 0; i < 10; ++i) {
    gt.push_back(rpy_pose(10, 20, 30 + i));
    est.push_back(Pose(gt.back().q * Eigen::Quaterniond(Eigen::AngleAxisd(
                                         -(2.0 + (i % 2 ? 0.5 : -0.5)) * math::kRadPerDeg, Vector3d::UnitX())),
                       Vector3d::Zero()));
  }
  const ApeResult r = compute_ape(est, gt);
  CHECK(r.rpy.mean.x() == Approx(2.0).epsilon(1e-9));
  CHECK(r.rpy.std.x() == Approx(0.5).epsilon(1e-6));
  CHECK(r.rpy_rmse_deg.x() == Approx(std::sqrt(4.0 + 0.25)).epsilon(1e-9));
}

// An independent computation: scipy's Rotation.as_euler('ZYX') (intrinsic z-y'-x'' = R = Rz Ry Rx,
// returned as [yaw, pitch, roll]) on random poses, for the three metrics' per-pair figures.
TEST_CASE("Euler metrics: per-pair figures equal scipy's on random rotations", "[eval][metrics][euler][scipy]") {
  if (std::system("/usr/bin/python3 -c 'import scipy.spatial.transform' >/dev/null 2>&1") != 0) {
    WARN("python3 with scipy not available: skipped");
    return;
  }
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  std::vector<Pose> est, gt;
  for (int i = 0; i < 200; ++i) {
    const Eigen::Quaterniond qg(Eigen::Vector4d(n01(rng), n01(rng), n01(rng), n01(rng)).normalized());
    // Half of the estimates near the truth (small errors), half anywhere (large ones).
    const Vector3d d = (i % 2 ? 0.1 : 2.0) * Vector3d(n01(rng), n01(rng), n01(rng));
    gt.push_back(Pose(qg, Vector3d::Zero()));
    est.push_back(Pose(qg * math::exp_quat(d), Vector3d::Zero()));
  }
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "roe_euler_scipy";
  std::filesystem::create_directories(dir);
  {
    std::ofstream f(dir / "pairs.txt");
    f.precision(17);
    for (std::size_t i = 0; i < est.size(); ++i)
      f << est[i].q.x() << " " << est[i].q.y() << " " << est[i].q.z() << " " << est[i].q.w() << " " << gt[i].q.x()
        << " " << gt[i].q.y() << " " << gt[i].q.z() << " " << gt[i].q.w() << "\n";
  }
  const std::string script =
      "import numpy as np\n"
      "from scipy.spatial.transform import Rotation as R\n"
      "d = np.loadtxt('" + (dir / "pairs.txt").string() + "')\n"
      "e, g = R.from_quat(d[:, :4]), R.from_quat(d[:, 4:])\n"
      "err = (e.inv() * g).as_euler('ZYX', degrees=True)[:, ::-1]\n"
      "ae, ag = e.as_euler('ZYX', degrees=True)[:, ::-1], g.as_euler('ZYX', degrees=True)[:, ::-1]\n"
      "un = ae - ag\n"
      "wr = (un + 180.0) % 360.0 - 180.0\n"
      "np.savetxt('" + (dir / "scipy.txt").string() + "', np.hstack([err, wr, un]), fmt='%.17g')\n";
  {
    std::ofstream f(dir / "euler.py");
    f << script;
  }
  REQUIRE(std::system(("/usr/bin/python3 " + (dir / "euler.py").string()).c_str()) == 0);
  std::ifstream in(dir / "scipy.txt");
  const auto angle_close = [](double a, double b) {  // the error metric's ±180 is one angle
    return std::abs(math::wrap_180(a - b)) < 1e-7;
  };
  for (std::size_t i = 0; i < est.size(); ++i) {
    double v[9];
    for (double& x : v) in >> x;
    REQUIRE(in);
    const PoseError pe = pose_error(est[i], gt[i]);
    const Vector3d fe = euler_figure_deg(est[i], gt[i], pe, EulerMetric::kError);
    const Vector3d fa = euler_figure_deg(est[i], gt[i], pe, EulerMetric::kAbsolute);
    const Vector3d fu = euler_figure_deg(est[i], gt[i], pe, EulerMetric::kAbsoluteUnwrapped);
    for (int k = 0; k < 3; ++k) {
      INFO("pair " << i << " axis " << k);
      CHECK(angle_close(fe(k), v[k]));
      CHECK(angle_close(fa(k), v[3 + k]));
      // Unwrapped: scipy's and roe's absolute angles agree up to the ±180 representation, which a
      // difference can only move by 360 on an angle sitting exactly at ±180 (not drawn here).
      CHECK(fu(k) == Approx(v[6 + k]).margin(1e-7));
    }
  }
  std::filesystem::remove_all(dir);
}

TEST_CASE("mean_rotation: the Karcher mean of rotations spread symmetrically about one", "[eval][metrics]") {
  const Eigen::Quaterniond c(math::from_euler_zyx(Vector3d(0.4, -0.3, 2.9)));
  std::vector<Eigen::Quaterniond> qs;
  for (const Vector3d& d : {Vector3d(0.2, 0, 0), Vector3d(-0.2, 0, 0), Vector3d(0, 0.3, 0.1), Vector3d(0, -0.3, -0.1)})
    qs.push_back(c * math::exp_quat(d));
  const Eigen::Quaterniond m = mean_rotation(qs.size(), [&](std::size_t i) { return qs[i]; });
  CHECK(math::log_quat(c.conjugate() * m).norm() < 1e-12);
  CHECK(mean_rotation(0, [&](std::size_t) { return c; }).angularDistance(Eigen::Quaterniond::Identity()) == 0.0);
}

TEST_CASE("evaluate --fit-body-rotation: a 30 deg body-frame offset recovered within 1 deg", "[eval][evaluate][body]") {
  // A trajectory that turns about every axis; the estimate is the ground truth in another world frame,
  // with its body frame rotated by a constant 30° about an oblique axis, and 0.5° noise per axis.
  const Eigen::Quaterniond q_body(Eigen::AngleAxisd(30.0 * math::kRadPerDeg, Vector3d(1, 2, -1).normalized()));
  const Pose T_E_G(Eigen::Quaterniond(math::from_euler_zyx(Vector3d(0.1, 0.2, 1.0))), Vector3d(1, -2, 0.5));
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.5 * math::kRadPerDeg);
  std::vector<Timestamp> t;
  std::vector<Pose> gt, est;
  for (int i = 0; i < 400; ++i) {
    const double s = 0.05 * i;
    t.push_back(100'000'000LL * i);
    gt.push_back(rpy_pose(40 * std::sin(0.7 * s), 30 * std::cos(0.4 * s), 50 * s,
                          Vector3d(2 * std::cos(0.5 * s), 2 * std::sin(0.5 * s), 0.3 * std::sin(s))));
    Pose e = T_E_G * gt.back();
    e.q = e.q * q_body.conjugate() * math::exp_quat(Vector3d(noise(rng), noise(rng), noise(rng)));
    est.push_back(e);
  }
  const std::vector<std::optional<PoseCovariance>> no_cov;
  EvalParams p;
  p.fit_body_rotation = true;
  p.threads = 1;
  const Report r = evaluate({t, est, no_cov, nullptr, "est"}, {t, gt}, p);
  REQUIRE(r.body_rotation);
  const BodyRotationFit& b = *r.body_rotation;
  // R_estᵀR_gt = R_bodyᵀ... with R_est = R_gt R_bodyᵀ: R_estᵀR_gt = R_body, so R_off ≈ q_body.
  CHECK(b.angle_deg == Approx(30.0).margin(1.0));
  CHECK(math::log_quat(q_body.conjugate() * b.q_off).norm() * math::kDegPerRad < 1.0);
  CHECK(b.rpy_deg.isApprox(math::euler_zyx(q_body.toRotationMatrix()) * math::kDegPerRad, 0.05));
  // Without: the offset dominates (rotation RMSE ≈ 30°); with it removed, only the noise (√3·0.5°).
  CHECK(r.ape.rot_deg.rmse == Approx(30.0).margin(1.5));
  CHECK(b.ape.rot_deg.rmse < 1.2);
  CHECK(b.ape.rpy_rmse_deg.maxCoeff() < 0.8);
  CHECK(b.ape.trans_m.rmse == r.ape.trans_m.rmse);  // positions unchanged
  // A diagnostic: the headline figures do not use it, and it is only computed when asked.
  p.fit_body_rotation = false;
  const Report plain = evaluate({t, est, no_cov, nullptr, "est"}, {t, gt}, p);
  CHECK(!plain.body_rotation);
  CHECK(plain.ape.rot_deg.rmse == r.ape.rot_deg.rmse);
}

TEST_CASE("estimator_gauge: the estimator's world from the anchor's held components", "[eval][gauge]") {
  const Pose T_Wt_O(Eigen::Quaterniond(math::from_euler_zyx(Vector3d(0.2, -0.1, 2.0))), Vector3d(3, 1, 0.5));
  SECTION("pose: every component held") {
    const Pose G(Eigen::Quaterniond(math::from_euler_zyx(Vector3d(0.05, 0.02, -1.0))), Vector3d(-1, 2, 0.3));
    const Pose T_O_W_est = T_Wt_O.inverse() * G;  // the anchor's true pose in the estimator's world
    const Pose got = estimator_gauge(GaugeKind::kPose, T_O_W_est, T_Wt_O);
    CHECK(got.p.isApprox(G.p, 1e-12));
    CHECK(got.q.angularDistance(G.q) < 1e-12);
  }
  SECTION("position_yaw: a gravity-aligned world, the anchor's position and yaw held") {
    const Pose G(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Vector3d::UnitZ())), Vector3d(-1, 2, 0.3));
    // The anchor's estimate: exact in position and yaw, off by a tilt (its roll/pitch stay estimated).
    Pose T_O_W_est = T_Wt_O.inverse() * G;
    T_O_W_est.q = T_O_W_est.q * math::exp_quat(Vector3d(0.03, -0.02, 0.0));
    const Pose got = estimator_gauge(GaugeKind::kPositionYaw, T_O_W_est, T_Wt_O);
    CHECK(got.p.isApprox(G.p, 1e-9));
    CHECK(got.q.angularDistance(G.q) < 1e-9);
    // Gravity-aligned: a rotation about z only. The anchor's true T_O_W in that world has the
    // estimate's position and no yaw error against it.
    CHECK(std::abs(got.R()(2, 2) - 1.0) < 1e-12);
    const Pose T_O_Wg = T_Wt_O.inverse() * got;
    CHECK(T_O_Wg.p.isApprox(T_O_W_est.p, 1e-12));
    CHECK(std::abs(math::log_quat(T_O_W_est.q.conjugate() * T_O_Wg.q).z()) < 1e-12);
  }
  CHECK(to_string(GaugeKind::kPositionYaw) == "position_yaw");
}

TEST_CASE("evaluate: NEES in the estimator's gauge reads 3 for errors drawn from the covariance", "[eval][evaluate][gauge]") {
  // The estimate lives in a world G; its errors are drawn from its own covariance. Against the truth
  // mapped into G the NEES averages 3 per block; the alignment-relative NEES, with an alignment
  // rotation error that no covariance holds, does not for the orientation.
  const Pose T_Wt_Wg(Eigen::Quaterniond(Eigen::AngleAxisd(1.2, Vector3d::UnitZ())), Vector3d(4, -1, 0));
  std::mt19937 rng(11);
  std::normal_distribution<double> n01;
  const Vector3d sp(0.02, 0.03, 0.01), sr(0.002, 0.004, 0.003);
  std::vector<Timestamp> t;
  std::vector<Pose> gt, est;
  std::vector<std::optional<PoseCovariance>> cov;
  const int n = 4000;
  for (int i = 0; i < n; ++i) {
    const double s = 0.01 * i;
    t.push_back(10'000'000LL * i);
    gt.push_back(rpy_pose(10 * std::sin(s), 5 * std::cos(0.3 * s), 20 * s, Vector3d(std::cos(s), std::sin(0.5 * s), 0.1 * s)));
    const Pose truth_in_g = T_Wt_Wg.inverse() * gt.back();
    Pose e = truth_in_g;
    e.p -= Vector3d(sp.x() * n01(rng), sp.y() * n01(rng), sp.z() * n01(rng));
    // R_true = R_est Exp(δθ)  ⇒  R_est = R_true Exp(−δθ)
    e.q = e.q * math::exp_quat(-Vector3d(sr.x() * n01(rng), sr.y() * n01(rng), sr.z() * n01(rng)));
    est.push_back(e);
    PoseCovariance c;
    c.P_p = sp.cwiseAbs2().asDiagonal();
    c.P_theta = sr.cwiseAbs2().asDiagonal();
    cov.push_back(c);
  }
  GaugeTruth g;
  g.T_Wt_Wg = T_Wt_Wg;
  g.t_from_ns = t[100];
  EstimateInput ei{t, est, cov, nullptr, "est"};
  ei.gauge = &g;
  EvalParams p;
  p.threads = 1;
  const Report r = evaluate(ei, {t, gt}, p);
  REQUIRE(r.gauge);
  CHECK(r.gauge->n == static_cast<std::size_t>(n - 100));
  // Mean of n χ²₃ draws: 3 ± 3·√(2/(3n)) ≈ 3 ± 0.04 (1σ).
  CHECK(*r.gauge->anees_p == Approx(3.0).margin(0.2));
  CHECK(*r.gauge->anees_r == Approx(3.0).margin(0.2));
  // Without the gauge: no gauge block.
  ei.gauge = nullptr;
  CHECK(!evaluate(ei, {t, gt}, p).gauge);
}
