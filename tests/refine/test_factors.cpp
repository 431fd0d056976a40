// The detection and prior residuals against independent computations (the filter's measurement model,
// math/ on doubles), and the manifolds' ⊞/⊟ (docs/refine.md §5). The Jacobians are Ceres' automatic
// derivatives of these residuals; one test compares them with the filter's analytic H.
#include <ceres/autodiff_cost_function.h>
#include <ceres/autodiff_manifold.h>

#include <catch2/catch.hpp>
#include <array>
#include <random>
#include <tuple>

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

Eigen::Matrix<double, 6, 1> error_of(const Pose& meas, const Scene& s) {
  const Block a = block(s.T_W_I), b = block(s.T_I_C), c = block(s.T_O_W);
  return refine::detection_error<double>(meas.q, meas.p, a.data(), b.data(), c.data());
}

/// The filter's prediction ẑ = T_O_C of the scene's object (ekf::predict_object).
Pose filter_prediction(const Scene& s) {
  ekf::CoreState x;
  x.p_W_I = s.T_W_I.p;
  x.q_W_I = s.T_W_I.q;
  return ekf::predict_object(x, s.T_I_C, s.T_O_W).T_O_C_hat;
}

}  // namespace

TEST_CASE("refine/factors: the detection error is the detector's error, translation in C, rotation in O") {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 50; ++trial) {
    const Scene s = random_scene(rng);
    // The filter's prediction ẑ = T_O_C must be the inverse of the T_C_O composed here.
    const Pose z_hat = filter_prediction(s);
    REQUIRE(math::pose_difference(z_hat.inverse(), s.T_C_O()).norm() < 1e-12);
    // A detection as roe simulate draws it (docs/simulator.md §6): t + n_t, R Exp(n_r).
    std::normal_distribution<double> n(0.0, 0.3);
    const Vector3d n_t(n(rng), n(rng), n(rng)), n_r(n(rng), n(rng), n(rng));
    const Pose T = s.T_C_O();
    const auto e = error_of(Pose(T.q * math::exp_quat(n_r), T.p + n_t), s);
    INFO("trial " << trial);
    CHECK((e.head<3>() - n_t).norm() < 1e-12);
    CHECK((e.tail<3>() - n_r).norm() < 1e-9);
  }
}

TEST_CASE("refine/factors: the whitened detection factor is A e_k minus B e_k-1") {
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0.0, 0.1);
  for (int trial = 0; trial < 20; ++trial) {
    const Scene s = random_scene(rng);
    Scene prev = s;
    prev.T_W_I = random_pose(rng, 2.0);  // the previous detection's node; same extrinsics and object
    const Pose m1(s.T_C_O().q * math::exp_quat(Vector3d(n(rng), n(rng), n(rng))), s.T_C_O().p + Vector3d(n(rng), 0, 0));
    const Pose m0(prev.T_C_O().q, prev.T_C_O().p + Vector3d(0, n(rng), n(rng)));
    const Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Random(), B = Eigen::Matrix<double, 6, 6>::Random();
    const refine::WhitenedDetectionResidual f{m1.q, m0.q, m1.p, m0.p, A, B};
    const Block a = block(s.T_W_I), b = block(s.T_I_C), c = block(s.T_O_W), d = block(prev.T_W_I);
    Eigen::Matrix<double, 6, 1> r;
    REQUIRE(f(a.data(), b.data(), c.data(), d.data(), r.data()));
    CHECK((r - (A * error_of(m1, s) - B * error_of(m0, prev))).norm() < 1e-12);
    const refine::FirstDetectionResidual f1{m1.q, m1.p, A};
    REQUIRE(f1(a.data(), b.data(), c.data(), r.data()));
    CHECK((r - A * error_of(m1, s)).norm() < 1e-12);
  }
}

TEST_CASE("refine/factors: the detection factor's derivatives through the pose manifold equal central differences") {
  std::mt19937 rng(21);
  ceres::AutoDiffManifold<refine::PosePlus, 7, 6> manifold;
  std::normal_distribution<double> n(0.0, 0.1);
  for (int trial = 0; trial < 10; ++trial) {
    const Scene s = random_scene(rng);
    Scene prev = s;
    prev.T_W_I = random_pose(rng, 2.0);
    const Pose m1(s.T_C_O().q * math::exp_quat(Vector3d(n(rng), n(rng), n(rng))), s.T_C_O().p);
    const Pose m0(prev.T_C_O().q, prev.T_C_O().p + Vector3d(n(rng), n(rng), n(rng)));
    const Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Random(), B = Eigen::Matrix<double, 6, 6>::Random();
    const refine::WhitenedDetectionResidual f{m1.q, m0.q, m1.p, m0.p, A, B};
    ceres::AutoDiffCostFunction<refine::WhitenedDetectionResidual, 6, 7, 7, 7, 7> cost(
        new refine::WhitenedDetectionResidual(f));
    std::array<Block, 4> x = {block(s.T_W_I), block(s.T_I_C), block(s.T_O_W), block(prev.T_W_I)};
    const double* params[4] = {x[0].data(), x[1].data(), x[2].data(), x[3].data()};
    Eigen::Matrix<double, 6, 7, Eigen::RowMajor> J[4];
    double* jac[4] = {J[0].data(), J[1].data(), J[2].data(), J[3].data()};
    Eigen::Matrix<double, 6, 1> r;
    REQUIRE(cost.Evaluate(params, r.data(), jac));
    for (int k = 0; k < 4; ++k) {
      Eigen::Matrix<double, 7, 6, Eigen::RowMajor> P;
      REQUIRE(manifold.PlusJacobian(params[k], P.data()));
      const Eigen::Matrix<double, 6, 6> Jt = J[k] * P;
      for (int j = 0; j < 6; ++j) {
        const double h = 1e-6;
        Eigen::Matrix<double, 6, 1> r_plus, r_minus;
        for (const int sign : {1, -1}) {
          std::array<Block, 4> y = x;
          double step[6] = {0, 0, 0, 0, 0, 0};
          step[j] = sign * h;
          REQUIRE(refine::PosePlus{}.Plus(x[k].data(), step, y[k].data()));
          REQUIRE(f(y[0].data(), y[1].data(), y[2].data(), y[3].data(), sign > 0 ? r_plus.data() : r_minus.data()));
        }
        const Eigen::Matrix<double, 6, 1> numeric = (r_plus - r_minus) / (2.0 * h);
        INFO("trial " << trial << " block " << k << " column " << j);
        CHECK((Jt.col(j) - numeric).norm() < 1e-6 * std::max(1.0, numeric.norm()));
      }
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

namespace {

/// Central differences of f over the tangent of block k (PosePlus for 7-blocks, additive otherwise).
template <typename F>
Eigen::MatrixXd numeric_tangent(F f, std::vector<std::vector<double>> x, std::size_t k, int rows) {
  const bool pose = x[k].size() == 7;
  const int dim = pose ? 6 : static_cast<int>(x[k].size());
  Eigen::MatrixXd J(rows, dim);
  const double h = 1e-6;
  for (int j = 0; j < dim; ++j) {
    Eigen::VectorXd r[2];
    for (int s = 0; s < 2; ++s) {
      std::vector<std::vector<double>> y = x;
      std::vector<double> step(static_cast<std::size_t>(dim), 0.0);
      step[static_cast<std::size_t>(j)] = s == 0 ? h : -h;
      if (pose) {
        refine::PosePlus{}.Plus(x[k].data(), step.data(), y[k].data());
      } else {
        for (int i = 0; i < dim; ++i) y[k][static_cast<std::size_t>(i)] += step[static_cast<std::size_t>(i)];
      }
      r[s] = f(y);
    }
    J.col(j) = (r[0] - r[1]) / (2.0 * h);
  }
  return J;
}

std::vector<double> vec(const Block& b) { return {b.begin(), b.end()}; }

}  // namespace

TEST_CASE("refine/factors: the analytic detection Jacobians equal central differences") {
  std::mt19937 rng(31);
  std::normal_distribution<double> n(0.0, 0.3);
  for (int trial = 0; trial < 20; ++trial) {
    const Scene s = random_scene(rng);
    const Pose m(s.T_C_O().q * math::exp_quat(Vector3d(n(rng), n(rng), n(rng))), s.T_C_O().p + Vector3d(n(rng), n(rng), 0));
    const std::vector<std::vector<double>> x = {vec(block(s.T_W_I)), vec(block(s.T_I_C)), vec(block(s.T_O_W))};
    refine::Mat6 J[3];
    const refine::Vec6 e = refine::detection_error_jacobians(m.q, m.p, x[0].data(), x[1].data(), x[2].data(), &J[0],
                                                             &J[1], &J[2]);
    const auto f = [&](const std::vector<std::vector<double>>& y) -> Eigen::VectorXd {
      return refine::detection_error<double>(m.q, m.p, y[0].data(), y[1].data(), y[2].data());
    };
    CHECK((e - f(x)).norm() < 1e-12);
    for (std::size_t k = 0; k < 3; ++k) {
      const Eigen::MatrixXd Jn = numeric_tangent(f, x, k, 6);
      INFO("trial " << trial << " block " << k << "\nanalytic\n" << J[k] << "\nnumeric\n" << Jn);
      CHECK((J[k] - Jn).norm() < 1e-6 * std::max(1.0, Jn.norm()));
    }
    // The ambient Jacobian times the manifold's PlusJacobian gives the tangent one back.
    ceres::AutoDiffManifold<refine::PosePlus, 7, 6> manifold;
    Eigen::Matrix<double, 7, 6, Eigen::RowMajor> P;
    REQUIRE(manifold.PlusJacobian(x[0].data(), P.data()));
    const Eigen::Matrix<double, 6, 6, Eigen::RowMajor> Jt = J[0];
    Eigen::Matrix<double, 6, 7, Eigen::RowMajor> A;
    refine::pose_ambient_jacobian(x[0].data(), Jt.data(), 6, A.data());
    CHECK((A * P - J[0]).norm() < 1e-12);
  }
}

TEST_CASE("refine/factors: the analytic IMU Jacobians equal central differences") {
  std::mt19937 rng(41);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    refine::ImuResidual f;
    f.dR = math::exp_quat(Vector3d(n(rng), n(rng), n(rng)) * 0.3);
    f.dv = Vector3d(n(rng), n(rng), n(rng));
    f.dp = Vector3d(n(rng), n(rng), n(rng));
    f.bg_lin = Vector3d(n(rng), n(rng), n(rng)) * 0.01;
    f.ba_lin = Vector3d(n(rng), n(rng), n(rng)) * 0.1;
    f.gravity = Vector3d(0, 0, 9.81);
    f.dt = 0.05 + 0.1 * std::abs(n(rng));
    f.J_bias = Eigen::Matrix<double, 9, 6>::Random();
    f.W = Eigen::Matrix<double, 9, 9>::Identity();
    const std::vector<std::vector<double>> x = {
        vec(block(random_pose(rng, 1.0))), {n(rng), n(rng), n(rng)}, {0.01 * n(rng), 0.01 * n(rng), 0.01 * n(rng), 0.1 * n(rng), 0.1 * n(rng), 0.1 * n(rng)},
        vec(block(random_pose(rng, 1.0))), {n(rng), n(rng), n(rng)}};
    Eigen::Matrix<double, 9, 6> Jpi, Jb, Jpj;
    Eigen::Matrix<double, 9, 3> Jvi, Jvj;
    const Eigen::Matrix<double, 9, 1> e = refine::imu_error_jacobians(f, x[0].data(), x[1].data(), x[2].data(), x[3].data(),
                                                                     x[4].data(), &Jpi, &Jvi, &Jb, &Jpj, &Jvj);
    const auto fn = [&](const std::vector<std::vector<double>>& y) -> Eigen::VectorXd {
      Eigen::Matrix<double, 9, 1> r;
      f(y[0].data(), y[1].data(), y[2].data(), y[3].data(), y[4].data(), r.data());
      return r;
    };
    CHECK((e - fn(x)).norm() < 1e-9);
    const Eigen::MatrixXd Ja[5] = {Jpi, Jvi, Jb, Jpj, Jvj};
    for (std::size_t k = 0; k < 5; ++k) {
      const Eigen::MatrixXd Jn = numeric_tangent(fn, x, k, 9);
      INFO("trial " << trial << " block " << k << "\nanalytic\n" << Ja[k] << "\nnumeric\n" << Jn);
      CHECK((Ja[k] - Jn).norm() < 1e-6 * std::max(1.0, Jn.norm()));
    }
  }
}

// The detection error at a node's pose carried by the time offset δ (docs/refine.md §2b): the value is the
// templated detection_error at [p + v δ ; q Exp((ω − b_g) δ)] (composed here with Pose and exp_quat), and every
// Jacobian (pose, v, bias, T_I_C, T_O_W, δ) equals central differences of that composition in the block's tangent.
TEST_CASE("refine/factors: the time-shifted detection error and its Jacobians equal central differences") {
  std::mt19937 rng(33);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    const Scene s = random_scene(rng);
    const Pose meas(s.T_C_O().q * math::exp_quat(0.05 * Vector3d(n(rng), n(rng), n(rng))), s.T_C_O().p);
    std::array<double, 7> pose = block(s.T_W_I), extr = block(s.T_I_C), obj = block(s.T_O_W);
    std::array<double, 3> v = {n(rng), n(rng), n(rng)};
    std::array<double, 6> bias = {0.01 * n(rng), 0.01 * n(rng), 0.01 * n(rng), 0.1 * n(rng), 0.1 * n(rng), 0.1 * n(rng)};
    const Vector3d gyro(2.0 * n(rng), 2.0 * n(rng), 2.0 * n(rng));  // up to a few rad/s: φ is not tiny
    double delta = 0.03 * n(rng);
    // The reference: the shifted pose composed with the library's Pose and exp, then the templated error.
    const auto reference = [&]() {
      const Vector3d w = gyro - Vector3d(bias[0], bias[1], bias[2]);
      const Pose T(Eigen::Quaterniond(pose[6], pose[3], pose[4], pose[5]) * math::exp_quat(w * delta),
                   Vector3d(pose[0], pose[1], pose[2]) + Vector3d(v[0], v[1], v[2]) * delta);
      const Block b = block(T);
      return refine::detection_error<double>(meas.q, meas.p, b.data(), extr.data(), obj.data());
    };
    refine::TimeShiftJacobians J;
    const auto e = refine::shifted_detection_error_jacobians(meas.q, meas.p, pose.data(), v.data(), bias.data(), gyro,
                                                             delta, extr.data(), obj.data(), &J);
    INFO("trial " << trial);
    REQUIRE((e - reference()).norm() < 1e-12);
    const double h = 1e-6;
    const auto central = [&](auto&& perturb) {
      perturb(h);
      const auto rp = reference();
      perturb(-2.0 * h);
      const auto rm = reference();
      perturb(h);
      return Eigen::Matrix<double, 6, 1>((rp - rm) / (2.0 * h));
    };
    const auto check = [&](const Eigen::Matrix<double, 6, 1>& analytic, const Eigen::Matrix<double, 6, 1>& numeric,
                           const char* what, int col) {
      INFO(what << " column " << col);
      CHECK((analytic - numeric).norm() < 1e-6 * std::max(1.0, numeric.norm()));
    };
    // Pose blocks: tangent steps through PosePlus (the solve's manifold), undone by the exact inverse step.
    for (auto [blk, Jb, name] : {std::tuple{&pose, &J.pose, "pose"}, std::tuple{&extr, &J.extr, "T_I_C"},
                                 std::tuple{&obj, &J.obj, "T_O_W"}}) {
      for (int j = 0; j < 6; ++j) {
        const std::array<double, 7> base = *blk;
        double step[6] = {0, 0, 0, 0, 0, 0};
        Eigen::Matrix<double, 6, 1> rp = Eigen::Matrix<double, 6, 1>::Zero(), rm = rp;
        for (const int sign : {1, -1}) {
          step[j] = sign * h;
          REQUIRE(refine::PosePlus{}.Plus(base.data(), step, blk->data()));
          (sign > 0 ? rp : rm) = reference();
        }
        *blk = base;
        check(Jb->col(j), (rp - rm) / (2.0 * h), name, j);
      }
    }
    for (int j = 0; j < 3; ++j) check(J.vel.col(j), central([&](double d) { v[j] += d; }), "v", j);
    for (int j = 0; j < 6; ++j) check(J.bias.col(j), central([&](double d) { bias[j] += d; }), "bias", j);
    check(J.delta, central([&](double d) { delta += d; }), "delta", 0);
  }
}
