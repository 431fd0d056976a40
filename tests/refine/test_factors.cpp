// The detection and prior residuals against independent computations (the filter's measurement model,
// math/ on doubles), and the manifolds' ⊞/⊟ (docs/refine.md §5). The Jacobians are Ceres' automatic
// derivatives of these residuals; one test compares them with the filter's analytic H.
#include <ceres/autodiff_cost_function.h>
#include <ceres/autodiff_manifold.h>

#include <catch2/catch.hpp>
#include <array>
#include <random>

#include "roe/core/error.hpp"
#include "roe/ekf/measurement.hpp"
#include "roe/math/se3.hpp"
#include "roe/math/so3.hpp"
#include "roe/refine/factors.hpp"

namespace {

using namespace roe;
using Eigen::Vector3d;
using Block = std::array<double, 7>;

Pose random_pose(std::mt19937& rng, double scale) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Pose(math::exp_quat(Vector3d(n(rng), n(rng), n(rng))), scale * Vector3d(n(rng), n(rng), n(rng)));
}
Block block(const Pose& T) { return {T.p.x(), T.p.y(), T.p.z(), T.q.x(), T.q.y(), T.q.z(), T.q.w()}; }

struct Scene {
  Pose T_W_I, T_I_C, T_O_W;
  Pose T_C_O() const { return (T_O_W * T_W_I * T_I_C).inverse(); }
};

Scene random_scene(std::mt19937& rng) { return {random_pose(rng, 2.0), random_pose(rng, 0.05), random_pose(rng, 2.0)}; }

Eigen::Matrix<double, 6, 1> residual_of(const refine::DetectionResidual& f, const Scene& s) {
  const Block a = block(s.T_W_I), b = block(s.T_I_C), c = block(s.T_O_W);
  Eigen::Matrix<double, 6, 1> r;
  f(a.data(), b.data(), c.data(), r.data());
  return r;
}

/// The filter's prediction ẑ = T_O_C of the scene's object (ekf::predict_object).
Pose filter_prediction(const Scene& s) {
  ekf::CoreState x;
  x.p_W_I = s.T_W_I.p;
  x.q_W_I = s.T_W_I.q;
  return ekf::predict_object(x, s.T_I_C, s.T_O_W).T_O_C_hat;
}

}  // namespace

TEST_CASE("refine/factors: the camera-frame detection residual is the detection's error in the camera frame") {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 50; ++trial) {
    const Scene s = random_scene(rng);
    // The filter's prediction ẑ = T_O_C must be the inverse of the T_C_O composed here.
    const Pose z_hat = filter_prediction(s);
    REQUIRE(math::pose_difference(z_hat.inverse(), s.T_C_O()).norm() < 1e-12);
    // A detection t + n_t, Exp(n_r) R (the convention of the σ, measurement.hpp).
    std::normal_distribution<double> n(0.0, 0.3);
    const Vector3d n_t(n(rng), n(rng), n(rng)), n_r(n(rng), n(rng), n(rng));
    const Pose T = s.T_C_O();
    refine::DetectionResidual f;
    f.camera_frame = true;
    f.p_meas = T.p + n_t;
    f.q_meas = math::exp_quat(n_r) * T.q;
    const auto r = residual_of(f, s);
    INFO("trial " << trial);
    CHECK((r.head<3>() - n_t).norm() < 1e-12);
    CHECK((r.tail<3>() - n_r).norm() < 1e-9);
    // Whitening: r = W e.
    f.W = Eigen::Matrix<double, 6, 6>::Identity() * 4.0;
    CHECK((residual_of(f, s) - 4.0 * r).norm() < 1e-9);
  }
}

TEST_CASE("refine/factors: the object-frame detection residual equals the filter's to first order") {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 50; ++trial) {
    const Scene s = random_scene(rng);
    const Pose z_hat = filter_prediction(s);
    std::normal_distribution<double> n(0.0, 1e-3);
    const Pose z(z_hat.q * math::exp_quat(Vector3d(n(rng), n(rng), n(rng))), z_hat.p + Vector3d(n(rng), n(rng), n(rng)));
    refine::DetectionResidual f;
    f.camera_frame = false;
    f.p_meas = z.p;
    f.q_meas = z.q;
    const auto r = residual_of(f, s);
    const auto r_filter = ekf::object_residual(z_hat, z);  // [z_p − ẑ_p ; 2 δq_v/δq_w]
    CHECK((r.head<3>() - r_filter.head<3>()).norm() < 1e-12);
    CHECK((r.tail<3>() - r_filter.tail<3>()).norm() < 1e-8);  // Log vs 2 q_v/q_w: third order
  }
}

TEST_CASE("refine/factors: automatic derivatives through the pose manifold equal the filter's H") {
  // r = z − ẑ in the object frame, so ∂r/∂δx = −H (measurement.hpp) with the same error state.
  std::mt19937 rng(21);
  ceres::AutoDiffManifold<refine::PosePlus, 7, 6> manifold;
  for (int trial = 0; trial < 10; ++trial) {
    const Scene s = random_scene(rng);
    ekf::CoreState x;
    x.p_W_I = s.T_W_I.p;
    x.q_W_I = s.T_W_I.q;
    const ekf::ObjectPrediction pr = ekf::predict_object(x, s.T_I_C, s.T_O_W);
    refine::DetectionResidual f;
    f.camera_frame = false;
    f.p_meas = pr.T_O_C_hat.p;
    f.q_meas = pr.T_O_C_hat.q;
    ceres::AutoDiffCostFunction<refine::DetectionResidual, 6, 7, 7, 7> cost(new refine::DetectionResidual(f));
    Block a = block(s.T_W_I), b = block(s.T_I_C), c = block(s.T_O_W);
    const double* params[3] = {a.data(), b.data(), c.data()};
    Eigen::Matrix<double, 6, 7, Eigen::RowMajor> J[3];
    double* jac[3] = {J[0].data(), J[1].data(), J[2].data()};
    Eigen::Matrix<double, 6, 1> r;
    REQUIRE(cost.Evaluate(params, r.data(), jac));
    const ekf::Mat63 H[3][2] = {{pr.H_p_WI, pr.H_theta_WI}, {pr.H_p_IC, pr.H_theta_IC}, {pr.H_p_OW, pr.H_theta_OW}};
    for (int k = 0; k < 3; ++k) {
      Eigen::Matrix<double, 7, 6, Eigen::RowMajor> P;
      REQUIRE(manifold.PlusJacobian(params[k], P.data()));
      const Eigen::Matrix<double, 6, 6> Jt = J[k] * P;
      INFO("trial " << trial << " block " << k);
      CHECK((Jt.leftCols<3>() + H[k][0]).norm() < 1e-9);
      CHECK((Jt.rightCols<3>() + H[k][1]).norm() < 1e-9);
    }
  }
}

TEST_CASE("refine/factors: pose and anchor manifolds, plus then minus gives the step back") {
  std::mt19937 rng(2);
  refine::PosePlus pose;
  refine::AnchorTiltPlus tilt;
  for (int trial = 0; trial < 20; ++trial) {
    const Block x = block(random_pose(rng, 1.0));
    std::normal_distribution<double> n(0.0, 0.5);
    const double d[6] = {n(rng), n(rng), n(rng), n(rng), n(rng), n(rng)};
    Block y;
    double back[6];
    pose.Plus(x.data(), d, y.data());
    pose.Minus(y.data(), x.data(), back);
    for (int i = 0; i < 6; ++i) CHECK(back[i] == Approx(d[i]).margin(1e-12));
    // R = R̂ Exp(δθ): the rotation step is on the right.
    const Eigen::Quaterniond qx(x[6], x[3], x[4], x[5]), qy(y[6], y[3], y[4], y[5]);
    CHECK(math::angle_between(qy, qx * math::exp_quat(Vector3d(d[3], d[4], d[5]))) < 1e-12);
    pose.Plus(x.data(), d, y.data());
    tilt.Plus(x.data(), d, y.data());
    double back2[2];
    tilt.Minus(y.data(), x.data(), back2);
    CHECK(back2[0] == Approx(d[0]).margin(1e-12));
    CHECK(back2[1] == Approx(d[1]).margin(1e-12));
    for (int i = 0; i < 3; ++i) CHECK(y[i] == x[i]);  // the anchor's position is held
    const Eigen::Quaterniond qt(y[6], y[3], y[4], y[5]);
    CHECK(math::angle_between(qt, qx * math::exp_quat(Vector3d(d[0], d[1], 0.0))) < 1e-12);
  }
}

TEST_CASE("refine/factors: priors and the square root information") {
  std::mt19937 rng(9);
  const Pose p0 = random_pose(rng, 0.1);
  const Vector3d dp(0.01, -0.02, 0.03), dth(0.02, 0.01, -0.03);
  const Pose p1(p0.q * math::exp_quat(dth), p0.p + dp);
  refine::PosePriorResidual f{p0.q, p0.p, Eigen::Matrix<double, 6, 6>::Identity()};
  const Block b = block(p1);
  Eigen::Matrix<double, 6, 1> r;
  f(b.data(), r.data());
  CHECK((r.head<3>() - dp).norm() < 1e-12);
  CHECK((r.tail<3>() - dth).norm() < 1e-12);
  Eigen::Matrix<double, 6, 1> inv_sigma;
  inv_sigma << 1, 2, 3, 4, 5, 6;
  const refine::BiasWalkResidual walk{inv_sigma};
  const double bi[6] = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6}, bj[6] = {0.2, 0.2, 0.1, 0.4, 0.6, 0.0};
  double rw[6];
  walk(bi, bj, rw);
  for (int k = 0; k < 6; ++k) CHECK(rw[k] == Approx((bj[k] - bi[k]) * inv_sigma(k)).margin(1e-15));
  Eigen::MatrixXd A = Eigen::MatrixXd::Random(6, 6);
  const Eigen::MatrixXd cov = A * A.transpose() + Eigen::MatrixXd::Identity(6, 6);
  const Eigen::MatrixXd W = refine::sqrt_information(cov);
  CHECK((W.transpose() * W - cov.inverse()).norm() < 1e-9);
  CHECK_THROWS_AS(refine::sqrt_information(-cov), roe::NumericError);
}
