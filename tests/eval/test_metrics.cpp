// APE statistics (evo definitions), per-axis RMSE, Euler wrap at ±180°, NEES.
#include <catch2/catch.hpp>
#include <algorithm>
#include <random>

#include "roe/core/error.hpp"
#include "roe/eval/metrics.hpp"
#include "roe/math/euler.hpp"
#include "roe/math/so3.hpp"

using namespace roe;
using namespace roe::eval;
using Eigen::Vector3d;

TEST_CASE("compute_stats matches numpy/evo definitions", "[eval][metrics]") {
  const Stats s = compute_stats({3.0, 1.0, 4.0, 1.0, 5.0, 9.0});
  CHECK(s.n == 6);
  CHECK(s.mean == Approx(23.0 / 6.0));
  CHECK(s.median == Approx(3.5));  // mean of the two middle values
  CHECK(s.min == 1.0);
  CHECK(s.max == 9.0);
  CHECK(s.sse == Approx(9 + 1 + 16 + 1 + 25 + 81));
  CHECK(s.rmse == Approx(std::sqrt(133.0 / 6.0)));
  // population std (ddof 0)
  double var = 0;
  for (double x : {3.0, 1.0, 4.0, 1.0, 5.0, 9.0}) var += (x - 23.0 / 6.0) * (x - 23.0 / 6.0);
  CHECK(s.std == Approx(std::sqrt(var / 6.0)));
  CHECK(compute_stats({2.0, 7.0, 1.0}).median == 2.0);
  CHECK(compute_stats({}).n == 0);
}

TEST_CASE("pose_error: rotation error R_est^T R_gt in ZYX, wrapped at ±180", "[eval][metrics]") {
  const Pose gt(Eigen::Quaterniond(math::from_euler_zyx(Vector3d(0.1, -0.2, 0.3))), Vector3d(1, 2, 3));
  SECTION("a pure local yaw error") {
    // R_gt = R_est · Rz(10°)  ⇒  yaw error +10°
    const Pose est(Eigen::Quaterniond(gt.R() * math::from_euler_zyx(Vector3d(0, 0, -10 * math::kRadPerDeg))),
                   Vector3d(1.5, 2, 2));
    const PoseError e = pose_error(est, gt);
    CHECK(e.dp.isApprox(Vector3d(0.5, 0, -1)));
    CHECK(e.rpy_deg.x() == Approx(0).margin(1e-9));
    CHECK(e.rpy_deg.y() == Approx(0).margin(1e-9));
    CHECK(e.rpy_deg.z() == Approx(10.0).epsilon(1e-12));
    CHECK(e.angle_deg == Approx(10.0).epsilon(1e-12));
  }
  SECTION("yaw error of ±179.9° stays near ±180, 180° maps to -180") {
    for (double yaw : {179.9, -179.9, 180.0}) {
      const Pose est(
          Eigen::Quaterniond(gt.R() * math::from_euler_zyx(Vector3d(0, 0, -yaw * math::kRadPerDeg))), gt.p);
      const PoseError e = pose_error(est, gt);
      const double expect = yaw == 180.0 ? -180.0 : yaw;
      CHECK(e.rpy_deg.z() == Approx(expect).epsilon(1e-9));
      CHECK(e.rpy_deg.z() >= -180.0);
      CHECK(e.rpy_deg.z() < 180.0);
      CHECK(e.angle_deg == Approx(std::abs(yaw)).epsilon(1e-9));
    }
  }
  SECTION("roll error near ±180 as well") {
    const Pose est(
        Eigen::Quaterniond(gt.R() * math::from_euler_zyx(Vector3d(-179.5 * math::kRadPerDeg, 0, 0))), gt.p);
    CHECK(pose_error(est, gt).rpy_deg.x() == Approx(179.5).epsilon(1e-9));
  }
}

TEST_CASE("compute_ape: per-axis RMSE, cnspy ARMSE, NEES", "[eval][metrics]") {
  std::vector<Pose> gt, est;
  for (int i = 0; i < 4; ++i) {
    gt.push_back(Pose(Eigen::Quaterniond::Identity(), Vector3d(i, 0, 0)));
    const double s = (i % 2 == 0) ? 1.0 : -1.0;
    est.push_back(Pose(Eigen::Quaterniond(Eigen::AngleAxisd(s * 2 * math::kRadPerDeg, Vector3d::UnitX())),
                       Vector3d(i + s * 0.1, 0.2, 0)));
  }
  const ApeResult r = compute_ape(est, gt);
  CHECK(r.pos_rmse_m.x() == Approx(0.1));
  CHECK(r.pos_rmse_m.y() == Approx(0.2));
  CHECK(r.pos_rmse_m.z() == 0.0);
  CHECK(r.rpy_rmse_deg.x() == Approx(2.0));
  CHECK(r.trans_m.rmse == Approx(std::sqrt(0.05)));
  CHECK(r.armse_p_m == Approx(r.trans_m.mean));
  CHECK(r.rot_deg.max == Approx(2.0));
  CHECK(r.pos_mean_m.x() == Approx(0.0).margin(1e-15));
  CHECK_FALSE(r.anees_p.has_value());

  PoseCovariance c;
  c.P_p = Eigen::Matrix3d::Identity() * 0.01;
  c.P_theta = Eigen::Matrix3d::Identity() * std::pow(2 * math::kRadPerDeg, 2);
  const ApeResult rn = compute_ape(est, gt, std::vector<PoseCovariance>(4, c));
  REQUIRE(rn.anees_p.has_value());
  CHECK(*rn.anees_p == Approx((0.01 + 0.04) / 0.01));
  CHECK(*rn.anees_r == Approx(1.0));
  // Rotated covariance: s² R P Rᵀ
  c.P_p = Vector3d(1, 2, 3).asDiagonal();
  const Eigen::Matrix3d R = math::from_euler_zyx(Vector3d(0, 0, math::kPi / 2));
  const PoseCovariance ca = align_covariance(c, R, 2.0);
  CHECK(ca.P_p(0, 0) == Approx(8.0));
  CHECK(ca.P_p(1, 1) == Approx(4.0));
  CHECK_THROWS_AS(compute_ape(est, {gt[0]}), InputError);
}

// The median of a long, unordered list (the selection must see the whole list), odd and even sizes.
TEST_CASE("compute_stats: median of long shuffled lists", "[eval][metrics]") {
  std::mt19937 rng(7);
  for (int n : {4, 5, 100, 101, 1000}) {
    std::vector<double> v(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) v[static_cast<std::size_t>(i)] = 0.5 * i;
    std::shuffle(v.begin(), v.end(), rng);
    const double expect = n % 2 ? 0.5 * (n / 2) : 0.5 * (0.5 * (n / 2 - 1) + 0.5 * (n / 2));
    INFO("n = " << n);
    CHECK(compute_stats(v).median == expect);
  }
}

// The mean position error is signed (est − gt) per axis, and the rotation NEES uses the local error
// Log(R_estᵀ R_gt), also far from the identity.
TEST_CASE("compute_ape: signed mean position error, rotation NEES away from the identity", "[eval][metrics]") {
  const Eigen::Quaterniond q_gt(math::from_euler_zyx(Vector3d(0.4, -0.7, 2.1)));
  const Vector3d dtheta(0.01, -0.02, 0.015);
  std::vector<Pose> gt{Pose(q_gt, Vector3d(1, 2, 3)), Pose(q_gt, Vector3d(-1, 0, 2))};
  // R_gt = R_est · Exp(δθ)  ⇒  R_est = R_gt · Exp(−δθ)
  const Eigen::Quaterniond q_est = q_gt * math::exp_quat(-dtheta);
  std::vector<Pose> est{Pose(q_est, Vector3d(1.1, 1.8, 3.3)), Pose(q_est, Vector3d(-0.9, -0.4, 2.1))};
  PoseCovariance c;
  c.P_p = Eigen::Matrix3d::Identity();
  c.P_theta = Vector3d(1e-4, 4e-4, 9e-4).asDiagonal();
  const ApeResult r = compute_ape(est, gt, {c, c});
  CHECK(r.pos_mean_m.x() == Approx(0.1));
  CHECK(r.pos_mean_m.y() == Approx(-0.3));
  CHECK(r.pos_mean_m.z() == Approx(0.2));
  const double nees_r = 0.01 * 0.01 / 1e-4 + 0.02 * 0.02 / 4e-4 + 0.015 * 0.015 / 9e-4;
  REQUIRE(r.nees.size() == 2);
  CHECK(r.nees[0].rot == Approx(nees_r).epsilon(1e-9));
  CHECK(*r.anees_r == Approx(nees_r).epsilon(1e-9));
}

// Values far from zero with a small spread (errors of a georeferenced run, stamps in seconds since the
// epoch): the two-pass σ keeps full precision, where Σx² − n·mean² would cancel to nothing.
TEST_CASE("compute_stats: sigma of values far from zero", "[eval][metrics]") {
  std::vector<double> v, d;
  for (int k = 0; k < 1000; ++k) {
    const double u = 0.001 * ((k * 7919) % 1000);  // 0 … 0.999, shuffled
    v.push_back(1.0e8 + u);
    d.push_back(u);
  }
  const Stats far = compute_stats(v), near = compute_stats(d);
  CHECK(far.std == Approx(near.std).epsilon(1e-6));
  CHECK(far.median == Approx(1.0e8 + near.median).epsilon(1e-15));
}

TEST_CASE("compute_ape: the parallel pairs give the sequential loop's figures bit for bit", "[eval][metrics]") {
  // Random pairs far from the origin with errors spread over orders of magnitude, so that any other
  // order of summation would show in the last bits; with covariances (NEES, some not positive definite).
  std::mt19937 rng(7);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const std::size_t n = 40000;  // three parallel tasks of pairs, the last one shorter
  std::vector<Pose> est, gt;
  std::vector<PoseCovariance> cov;
  for (std::size_t i = 0; i < n; ++i) {
    const Pose t(Eigen::Quaterniond(Eigen::Vector4d(g(rng), g(rng), g(rng), g(rng)).normalized()),
                 Vector3d(1e3 + 50 * u(rng), -2e3 + 50 * u(rng), 10 * u(rng)));
    const double scale = std::pow(10.0, 4 * u(rng) - 3);  // errors from 1e-7 to 10
    const Pose d(Eigen::Quaterniond(math::exp_so3(Vector3d(g(rng), g(rng), g(rng)) * 0.3 * scale)),
                 Vector3d(g(rng), g(rng), g(rng)) * scale);
    gt.push_back(t);
    est.push_back(t * d);
    PoseCovariance c;
    const Eigen::Matrix3d A = Eigen::Matrix3d::Random();
    c.P_p = A * A.transpose() + 1e-3 * Eigen::Matrix3d::Identity();
    c.P_theta = (i % 97 == 0) ? Eigen::Matrix3d(-Eigen::Matrix3d::Identity()) : Eigen::Matrix3d(c.P_p * 0.01);
    cov.push_back(c);
  }
  // The reference: one pass in pair order, as compute_ape did it on one thread.
  std::vector<double> tn, an;
  Vector3d sum_dp = Vector3d::Zero(), sq_dp = Vector3d::Zero(), sq_rpy = Vector3d::Zero();
  double sp = 0.0, sr = 0.0;
  std::size_t np = 0, nr = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const PoseError e = pose_error(est[i], gt[i]);
    tn.push_back(e.dp.norm());
    an.push_back(e.angle_deg);
    sum_dp += e.dp;
    sq_dp += e.dp.cwiseAbs2();
    sq_rpy += e.rpy_deg.cwiseAbs2();
    const Nees ne = pose_nees(est[i], gt[i], cov[i]);
    if (std::isfinite(ne.pos)) sp += ne.pos, ++np;
    if (std::isfinite(ne.rot)) sr += ne.rot, ++nr;
  }
  const Stats t_ref = compute_stats(tn), r_ref = compute_stats(an);
  const auto same = [](const Stats& a, const Stats& b) {
    return a.rmse == b.rmse && a.mean == b.mean && a.median == b.median && a.std == b.std && a.min == b.min &&
           a.max == b.max && a.sse == b.sse && a.n == b.n;
  };
  CHECK(nr < n);  // some orientation covariances are not positive definite
  for (const unsigned threads : {1u, 2u, 3u, 8u}) {
    CAPTURE(threads);
    const ApeResult r = compute_ape(est, gt, cov, threads);
    CHECK(same(r.trans_m, t_ref));
    CHECK(same(r.rot_deg, r_ref));
    CHECK(r.pos_mean_m == sum_dp / static_cast<double>(n));
    CHECK(r.pos_rmse_m == (sq_dp / static_cast<double>(n)).cwiseSqrt());
    CHECK(r.rpy_rmse_deg == (sq_rpy / static_cast<double>(n)).cwiseSqrt());
    CHECK(r.armse_p_m == t_ref.mean);
    REQUIRE(r.anees_p.has_value());
    REQUIRE(r.anees_r.has_value());
    CHECK(*r.anees_p == sp / static_cast<double>(np));
    CHECK(*r.anees_r == sr / static_cast<double>(nr));
    REQUIRE(r.nees.size() == n);
    CHECK(r.nees[1234].pos == pose_nees(est[1234], gt[1234], cov[1234]).pos);
  }
  // The pairs given by index (as evaluate() does) are the same pairs.
  const ApeResult by_index = compute_ape(
      n, [&](std::size_t i) { return std::pair<Pose, Pose>(est[i], gt[i]); }, {}, 2);
  CHECK(same(by_index.trans_m, t_ref));
  CHECK(by_index.nees.empty());
}
