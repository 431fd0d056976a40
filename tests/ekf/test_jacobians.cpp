// Numeric-Jacobian tests (central differences, asserting) of every analytic Jacobian the filter uses:
// the discrete transition F against the nominal integrator, every H block (including the anchor's
// structurally zero blocks and the other objects' zero blocks), the first-sight (augmentation)
// Jacobians, the detection-sigma mapping and the gauge generator used for the anchor.
#include <catch2/catch.hpp>
#include <random>

#include "roe/ekf/filter.hpp"
#include "roe/ekf/imu.hpp"
#include "roe/ekf/measurement.hpp"
#include "roe/math/so3.hpp"
#include "support/jacobian.hpp"

using namespace roe;
using namespace roe::ekf;
using math::exp_quat;
using math::log_quat;
using roe::test::check_jacobian;
using roe::test::numeric_jacobian;

namespace {

std::mt19937_64 rng(12345);
double U(double a = -1.0, double b = 1.0) { return std::uniform_real_distribution<double>(a, b)(rng); }
Vec3 U3(double s = 1.0) { return Vec3(U(), U(), U()) * s; }
Eigen::Quaterniond Uq() { return exp_quat(U3(2.0)); }
Pose Upose(double s = 1.0) { return Pose(Uq(), U3(s)); }

CoreState random_core() {
  CoreState x;
  x.p_W_I = U3(2.0);
  x.v_W_I = U3(1.0);
  x.q_W_I = Uq();
  x.b_g = U3(0.02);
  x.b_a = U3(0.2);
  return x;
}

CoreState plus(const CoreState& x, const Eigen::Matrix<double, 15, 1>& d) {
  CoreState y = x;
  y.p_W_I += d.segment<3>(kP);
  y.v_W_I += d.segment<3>(kV);
  y.q_W_I = x.q_W_I * exp_quat(d.segment<3>(kTheta));
  y.b_g += d.segment<3>(kBg);
  y.b_a += d.segment<3>(kBa);
  return y;
}

Eigen::Matrix<double, 15, 1> minus(const CoreState& y, const CoreState& x) {
  Eigen::Matrix<double, 15, 1> d;
  d.segment<3>(kP) = y.p_W_I - x.p_W_I;
  d.segment<3>(kV) = y.v_W_I - x.v_W_I;
  d.segment<3>(kTheta) = log_quat(x.q_W_I.conjugate() * y.q_W_I);
  d.segment<3>(kBg) = y.b_g - x.b_g;
  d.segment<3>(kBa) = y.b_a - x.b_a;
  return d;
}

Vec6 pose_minus(const Pose& a, const Pose& b) {  // a ⊟ b, additive p, right rotation
  Vec6 d;
  d.head<3>() = a.p - b.p;
  d.tail<3>() = log_quat(b.q.conjugate() * a.q);
  return d;
}
Pose pose_plus(const Pose& a, const Vec6& d) { return Pose(a.q * exp_quat(d.tail<3>()), a.p + d.head<3>()); }

}  // namespace

TEST_CASE("discrete F equals finite differences of the nominal integration", "[ekf][jacobian]") {
  for (double dt : {0.0025, 0.005, 0.05}) {
    for (int trial = 0; trial < 5; ++trial) {
      const CoreState x = random_core();
      const Vec3 w0 = U3(2.0), a0 = U3(5.0) + Vec3(0, 0, 9.81), w1 = U3(2.0), a1 = U3(5.0);
      CoreTransition F;
      integrate(x, w0, a0, w1, a1, dt, &F);
      const Mat15 Fa = F.dense();
      const CoreState y0 = integrate(x, w0, a0, w1, a1, dt);
      INFO("dt = " << dt);
      check_jacobian(Fa, [&](const Eigen::VectorXd& d) -> Eigen::VectorXd {
        return minus(integrate(plus(x, d), w0, a0, w1, a1, dt), y0);
      });
      // The block-sparse application equals the dense product.
      Eigen::Matrix<double, 15, 20> X = Eigen::Matrix<double, 15, 20>::Random();
      Eigen::Matrix<double, 15, 20> Y = X;
      F.apply_left(Y);
      CHECK((Y - Fa * X).cwiseAbs().maxCoeff() < 1e-12);
      Eigen::Matrix<double, 20, 15> Xr = Eigen::Matrix<double, 20, 15>::Random(), Yr = Xr, Yt = Xr;
      F.apply_right(Yr);
      CHECK((Yr - Xr * Fa).cwiseAbs().maxCoeff() < 1e-12);
      F.apply_right_transposed(Yt);
      CHECK((Yt - Xr * Fa.transpose()).cwiseAbs().maxCoeff() < 1e-12);
    }
  }
}

TEST_CASE("integration and F below the small-angle threshold (a nearly still gyro)", "[ekf][jacobian]") {
  // ω̄dt below 2·kSmallAngle takes integrate's Taylor branch; finite differences cannot resolve its terms
  // (1e-7 relative), so the branch is checked against closed forms. A constant rate composes exactly:
  // N steps of Exp(ωdt) are Exp(Nωdt).
  const double dt = 0.0025;
  const Vec3 omega(2e-4, -1e-4, 3e-4);  // rad/s: |ω|dt = 9.4e-7 rad per step
  CoreState x = random_core();
  const Eigen::Quaterniond q0 = x.q_W_I;
  const Vec3 w = x.b_g + omega, a = x.b_a + Vec3(0.3, -0.2, 9.81);
  const int n = 4000;
  for (int k = 0; k < n; ++k) x = integrate(x, w, a, w, a, dt);
  const Eigen::Quaterniond q_ref = q0 * exp_quat(omega * (n * dt));
  CHECK(log_quat(q_ref.conjugate() * x.q_W_I).norm() < 1e-10);  // 3.8e-3 rad if a step rotated twice

  // F's blocks against the second-order forms Exp(−φ) ≈ I − K + K²/2, Jr(φ) ≈ I − K/2 + K²/6 (K = [φ]×;
  // the next terms are below 1e-19 here).
  CoreTransition F;
  integrate(x, w, a, w, a, dt, &F);
  const Vec3 phi = omega * dt;
  const auto jr = [](const Vec3& p) {
    const Mat3 K = math::skew(p);
    return Mat3(Mat3::Identity() - 0.5 * K + K * K / 6.0);
  };
  const Mat3 K = math::skew(phi);
  const Mat3 R_half = exp_quat(0.5 * phi).toRotationMatrix();
  const Mat3 R_m = x.q_W_I.toRotationMatrix() * R_half;
  const Vec3 a_b = a - x.b_a;
  const Mat3 F_tt = Mat3::Identity() - K + 0.5 * K * K;
  const Mat3 F_tbg = -jr(phi) * dt;
  const Mat3 F_vbg = R_m * math::skew(a_b) * dt * jr(0.5 * phi) * (0.5 * dt);
  const Mat3 F_vtheta = -R_m * math::skew(a_b) * dt * R_half.transpose();
  const auto rel = [](const Mat3& A, const Mat3& B) { return (A - B).norm() / B.norm(); };
  CHECK(rel(F.F_tt, F_tt) < 1e-13);
  CHECK(rel(F.F_tbg, F_tbg) < 1e-13);
  CHECK(rel(F.F_vbg, F_vbg) < 1e-13);  // 2.4e-7 if Jr were taken at φ instead of φ/2
  CHECK(rel(F.F_vtheta, F_vtheta) < 1e-13);
}

TEST_CASE("object measurement H blocks equal finite differences", "[ekf][jacobian]") {
  for (int trial = 0; trial < 10; ++trial) {
    const CoreState x = random_core();
    const Pose T_I_C = Upose(0.1), T_O_W = Upose(2.0);
    const ObjectPrediction pr = predict_object(x, T_I_C, T_O_W);
    // Columns: δp_W_I, δθ_W_I via the core; δp_I_C, δθ_I_C; δp_O_W, δθ_O_W.
    Eigen::Matrix<double, 6, 12> Ha;
    Ha << pr.H_p_WI, pr.H_theta_WI, pr.H_p_IC, pr.H_theta_IC;
    check_jacobian(Ha, [&](const Eigen::VectorXd& e) -> Eigen::VectorXd {
      Eigen::Matrix<double, 15, 1> d = Eigen::Matrix<double, 15, 1>::Zero();
      d.segment<3>(kP) = e.segment<3>(0);
      d.segment<3>(kTheta) = e.segment<3>(3);
      return pose_minus(predict_object(plus(x, d), pose_plus(T_I_C, e.tail<6>()), T_O_W).T_O_C_hat,
                        pr.T_O_C_hat);
    });
    Eigen::Matrix<double, 6, 6> Hoa;
    Hoa << pr.H_p_OW, pr.H_theta_OW;
    check_jacobian(Hoa, [&](const Eigen::VectorXd& d) -> Eigen::VectorXd {
      return pose_minus(predict_object(x, T_I_C, pose_plus(T_O_W, d)).T_O_C_hat, pr.T_O_C_hat);
    });
    // v and the biases do not enter: their blocks are zero by construction (checked on the full H below).
  }
}

TEST_CASE("the paper residual is the local error to first order and sign-invariant", "[ekf][jacobian]") {
  const Pose zh = Upose();
  const Vec6 d = (Vec6() << 0.01, -0.02, 0.03, 0.001, -0.002, 0.0015).finished();
  const Pose z = pose_plus(zh, d);
  const Vec6 r = object_residual(zh, z);
  CHECK((r - d).cwiseAbs().maxCoeff() < 1e-8);
  Pose zneg = z;
  zneg.q.coeffs() = -zneg.q.coeffs();
  CHECK((object_residual(zh, zneg) - r).norm() < 1e-14);
}

TEST_CASE("first-sight initialisation Jacobians equal finite differences", "[ekf][jacobian]") {
  for (int trial = 0; trial < 10; ++trial) {
    const CoreState x = random_core();
    const Pose T_I_C = Upose(0.1), z = Upose(1.5);
    const ObjectInit in = init_object(x, T_I_C, z);
    // Consistency of the value: T_O_W · T_W_I · T_I_C = z.
    const Pose back = in.T_O_W * Pose(x.q_W_I, x.p_W_I) * T_I_C;
    CHECK(pose_minus(back, z).norm() < 1e-12);
    Eigen::Matrix<double, 6, 18> Ja;
    Ja << in.J_p_WI, in.J_theta_WI, in.J_p_IC, in.J_theta_IC, in.J_z;
    check_jacobian(Ja, [&](const Eigen::VectorXd& e) -> Eigen::VectorXd {
      Eigen::Matrix<double, 15, 1> d = Eigen::Matrix<double, 15, 1>::Zero();
      d.segment<3>(kP) = e.segment<3>(0);
      d.segment<3>(kTheta) = e.segment<3>(3);
      return pose_minus(
          init_object(plus(x, d), pose_plus(T_I_C, e.segment<6>(6)), pose_plus(z, e.segment<6>(12))).T_O_W,
          in.T_O_W);
    });
  }
}

TEST_CASE("the time-offset column is the derivative of the prediction along the IMU motion", "[ekf][jacobian][time_offset]") {
  // ẑ at IMU time t + τ, the rig moved by the IMU integrator (imu.hpp) with a constant ω_m, a_m: its derivative
  // at τ = 0 is H_p v + H_θ ω (measurement.hpp, Li & Mourikis 2014). Central differences over ±ε around x.
  for (int trial = 0; trial < 10; ++trial) {
    const CoreState xm = random_core();
    const Vec3 w = U3(2.0), a = U3(3.0) + Vec3(0, 0, 9.81);
    const double eps = 1e-5;
    const CoreState x = integrate(xm, w, a, w, a, eps);
    const CoreState xp = integrate(x, w, a, w, a, eps);
    const Pose T_I_C = Upose(0.1), T_O_W = Upose(2.0);
    const ObjectPrediction pr = predict_object(x, T_I_C, T_O_W);
    const Vec6 col = time_offset_column(pr.H_p_WI, pr.H_theta_WI, x.v_W_I, w - x.b_g);
    const Vec6 num = (pose_minus(predict_object(xp, T_I_C, T_O_W).T_O_C_hat, pr.T_O_C_hat) -
                      pose_minus(predict_object(xm, T_I_C, T_O_W).T_O_C_hat, pr.T_O_C_hat)) /
                     (2.0 * eps);
    INFO("analytic " << col.transpose() << "\nnumeric  " << num.transpose());
    CHECK((col - num).cwiseAbs().maxCoeff() < 1e-6 * std::max(1.0, col.cwiseAbs().maxCoeff()));
    // shift_in_time is that motion to first order, and the column its derivative (to rounding).
    check_jacobian(col, [&](const Eigen::VectorXd& t) -> Eigen::VectorXd {
      return pose_minus(predict_object(shift_in_time(x, w - x.b_g, t(0)), T_I_C, T_O_W).T_O_C_hat, pr.T_O_C_hat);
    });
    // The first-sight object-world moves with the time offset as J_p v + J_θ ω.
    const Pose z = Upose(1.5);
    const ObjectInit in = init_object(x, T_I_C, z);
    check_jacobian(time_offset_column(in.J_p_WI, in.J_theta_WI, x.v_W_I, w - x.b_g),
                   [&](const Eigen::VectorXd& t) -> Eigen::VectorXd {
                     return pose_minus(init_object(shift_in_time(x, w - x.b_g, t(0)), T_I_C, z).T_O_W, in.T_O_W);
                   });
  }
}

TEST_CASE("per-detection sigmas are mapped through the T_C_O inversion", "[ekf][jacobian]") {
  const Pose T_C_O = Upose(1.0);
  const Vec6 sigma = (Vec6() << 0.01, 0.02, 0.05, 0.03, 0.04, 0.05).finished();
  const Mat6 S = detection_covariance_in_residual_frame(T_C_O, sigma);
  // Numeric Jacobian of z = T_C_O⁻¹ w.r.t. (n_t, n_r) with t + n_t, Exp(n_r) R.
  const Pose z0 = T_C_O.inverse();
  const Mat6 J = numeric_jacobian(6, [&](const Eigen::VectorXd& n) -> Eigen::VectorXd {
    const Pose pert(exp_quat(n.tail<3>()) * T_C_O.q, T_C_O.p + n.head<3>());
    return pose_minus(pert.inverse(), z0);
  });
  const Mat6 Sn = J * sigma.cwiseProduct(sigma).asDiagonal() * J.transpose();
  CHECK((S - Sn).cwiseAbs().maxCoeff() < 1e-9);
  // A full covariance with translation-rotation cross terms (the blocks' signs only show through them).
  Mat6 L = Mat6::Zero();
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c <= r; ++c) L(r, c) = r == c ? 0.02 + 0.01 * r : 0.01 * U();
  const Mat6 C = L * L.transpose();
  const Mat6 Sc = detection_covariance_in_residual_frame(T_C_O, C);
  CHECK((Sc - J * C * J.transpose()).cwiseAbs().maxCoeff() < 1e-9);
}

TEST_CASE("inverse_pose_jacobian equals finite differences of T_O_W -> T_W_O", "[ekf][jacobian]") {
  for (int trial = 0; trial < 20; ++trial) {
    const Pose T_O_W = Upose(2.0);
    const Mat6 J = inverse_pose_jacobian(T_O_W);
    INFO("trial " << trial);
    check_jacobian(J, [&](const Eigen::VectorXd& d) -> Eigen::VectorXd {
      const Pose pert(T_O_W.q * exp_quat(d.tail<3>()), T_O_W.p + d.head<3>());
      return pose_minus(pert.inverse(), T_O_W.inverse());
    });
  }
}

TEST_CASE("relative_pose_jacobian equals finite differences of (T_A_W, T_O_W) -> T_A_W T_O_W^-1",
          "[ekf][jacobian]") {
  for (int trial = 0; trial < 20; ++trial) {
    const Pose T_A_W = Upose(2.0), T_O_W = Upose(2.0);
    const Eigen::Matrix<double, 6, 12> J = relative_pose_jacobian(T_A_W, T_O_W);
    const Pose rel0 = T_A_W * T_O_W.inverse();
    INFO("trial " << trial);
    check_jacobian(J, [&](const Eigen::VectorXd& d) -> Eigen::VectorXd {
      const Pose X(T_A_W.q * exp_quat(d.segment<3>(3)), T_A_W.p + d.segment<3>(0));
      const Pose Y(T_O_W.q * exp_quat(d.segment<3>(9)), T_O_W.p + d.segment<3>(6));
      return pose_minus(X * Y.inverse(), rel0);
    });
  }
}

namespace {

// A filter with objects 1 (anchor), 2 and 3 initialised and a non-trivial state.
Filter make_filter(AnchorGauge gauge, bool extrinsics, ResidualFrame frame = ResidualFrame::kObject,
                   bool time_offset = false, bool error_states = false) {
  FilterOptions opt;
  opt.estimate_time_offset = time_offset;
  if (error_states) {  // Gauss–Markov detection-error states with a ray-aligned, depth-dependent σ
    opt.detection_error_states = true;
    opt.detection_error_correlation_s = 3.0;
    opt.detection_error_correlated_share = 0.8;
    opt.meas_sigma_p_m = 0.02;
    opt.meas_sigma_p_per_depth = 0.02;
    opt.meas_sigma_ray_m = 0.06;
    opt.meas_sigma_ray_per_depth = 0.1;
  }
  opt.residual_frame = frame;
  opt.init_min_detections = 1;  // initialise every object on its first detection
  opt.anchor_id = 1;
  opt.anchor_gauge = gauge;
  opt.estimate_extrinsics = extrinsics;
  ImuNoiseParams noise{1e-3, 1e-4, 1e-2, 1e-3};
  Filter f(opt, noise, Pose(exp_quat(Vec3(0.1, -0.2, 0.05)), Vec3(0.02, 0.01, -0.03)), 0.012);
  f.initialize(0, Vec3::Zero(), Vec3(0, 0, 9.81), Vec3(0.3, -0.2, 9.8));
  f.propagate(10'000'000, Vec3(0.1, 0.2, -0.1), Vec3(0.2, 0.1, 9.7));
  std::vector<Detection> dets;
  for (int id : {1, 2, 3}) {
    Detection d;
    d.t_ns = f.time();
    d.object_id = id;
    d.T_C_O = Upose(1.0);
    d.T_C_O.p.z() += 1.5;
    dets.push_back(d);
  }
  f.update(dets);
  Eigen::VectorXd dx(f.dim());
  for (int i = 0; i < f.dim(); ++i) dx(i) = U(-0.3, 0.3);
  f.boxplus(dx);
  return f;
}

// The error a ⊟ b of two predicted measurements T_O_C in the residual frame: T_O_C (additive p, right
// rotation error) or T_C_O (additive t, left rotation error).
Vec6 prediction_error(ResidualFrame frame, const Pose& a, const Pose& b) {
  if (frame == ResidualFrame::kObject) return pose_minus(a, b);
  const Pose ai = a.inverse(), bi = b.inverse();
  Vec6 d;
  d.head<3>() = ai.p - bi.p;
  d.tail<3>() = log_quat(ai.q * bi.q.conjugate());
  return d;
}

}  // namespace

TEST_CASE("full H of the filter equals finite differences, incl. zero and anchor blocks", "[ekf][jacobian]") {
  for (AnchorGauge gauge : {AnchorGauge::kPose, AnchorGauge::kPosition, AnchorGauge::kPositionYaw}) {
    for (int variant = 0; variant < 3; ++variant) {  // extrinsics and t_d, extrinsics, neither
      const bool extr = variant < 2, td = variant == 0;
      for (ResidualFrame frame : {ResidualFrame::kObject, ResidualFrame::kCamera}) {
        Filter f = make_filter(gauge, extr, frame, td);
        const auto diff = [frame](const Pose& a, const Pose& b) { return prediction_error(frame, a, b); };
        REQUIRE(f.objects().size() == 3);
        CHECK((f.time_offset_offset() >= 0) == td);
        const int anchor_dim = gauge == AnchorGauge::kPose ? 0 : gauge == AnchorGauge::kPosition ? 3 : 2;
        const int expect_dim = 15 + (extr ? 6 : 0) + (td ? 1 : 0) + anchor_dim + 12;
        REQUIRE(f.dim() == expect_dim);
        const ObjectEntry* anchor = f.object(1);
        REQUIRE(anchor != nullptr);
        CHECK(anchor->anchor);
        CHECK(anchor->dim == anchor_dim);
        for (int id : {1, 2, 3}) {
          const Pose z = pose_plus(f.predict(id), (Vec6() << 0.05, -0.02, 0.03, 0.1, -0.05, 0.02).finished());
          Vec6 r;
          Eigen::MatrixXd H;
          f.measurement_jacobian(id, z, r, H);
          const Pose zh0 = f.predict(id);
          INFO("gauge " << to_string(gauge) << " extrinsics " << extr << " time offset " << td << " frame "
                        << to_string(frame) << " object " << id);
          const Eigen::MatrixXd Hn = check_jacobian(H, [&](const Eigen::VectorXd& d) -> Eigen::VectorXd {
            Filter g = f;
            g.boxplus(d);
            // A change δt_d of the time offset: the detection saw the rig δt_d later (measurement.hpp).
            const double tau = g.time_offset_s() - f.time_offset_s();
            const CoreState x = shift_in_time(g.core(), f.body_rate(), tau);
            return diff(predict_object(x, g.T_I_C(), g.object(id)->T_O_W).T_O_C_hat, zh0);
          });
          if (td) CHECK(H.col(f.time_offset_offset()).cwiseAbs().maxCoeff() > 1e-3);
          // Structural zeros: v, biases, every other object's block (incl. the anchor's two tilt
          // columns for a non-anchor detection), and for the anchor its fixed components.
          CHECK(H.middleCols(kV, 3).cwiseAbs().maxCoeff() == 0.0);
          CHECK(H.middleCols(kBg, 6).cwiseAbs().maxCoeff() == 0.0);
          for (const auto& o : f.objects()) {
            if (o.id == id || o.dim == 0) continue;
            CHECK(H.middleCols(o.offset, o.dim).cwiseAbs().maxCoeff() == 0.0);
            CHECK(Hn.middleCols(o.offset, o.dim).cwiseAbs().maxCoeff() < 1e-9);
          }
          // Residual: the paper's, or its camera-frame form (to first order −diff(ẑ, z)).
          if (frame == ResidualFrame::kObject)
            CHECK((r - object_residual(zh0, z)).norm() == 0.0);
          else {
            // First-order agreement: for a perturbation of size δ the difference is O(δ²), so check it
            // on a small one (δ ≈ 1e-4: relative difference ≈ 1e-6) where the bound has a wide margin
            // and does not depend on the random state drawn by earlier tests.
            const Pose z_small =
                pose_plus(zh0, 1e-3 * (Vec6() << 0.05, -0.02, 0.03, 0.1, -0.05, 0.02).finished());
            Vec6 r_small;
            Eigen::MatrixXd H_small;
            f.measurement_jacobian(id, z_small, r_small, H_small);
            CHECK((r_small - diff(z_small, zh0)).norm() < 1e-4 * r_small.norm());
          }
        }
      }
    }
  }
}

TEST_CASE("gauge generator equals finite differences of a change of world frame", "[ekf][jacobian]") {
  for (AnchorGauge gauge : {AnchorGauge::kPosition, AnchorGauge::kPositionYaw}) {
    Filter f = make_filter(gauge, true);
    const Eigen::MatrixXd G = f.gauge_generator();
    REQUIRE(G.cols() == 6);
    const CoreState x = f.core();
    // The error state of the same estimate expressed in the world W' of a change of world frame γ.
    check_jacobian(G, [&](const Eigen::VectorXd& gam) -> Eigen::VectorXd {
      const Pose T_W_Wp(exp_quat(gam.tail<3>()), gam.head<3>());  // x_W = Exp(φ) x_W' + t
      const Pose T_Wp_W = T_W_Wp.inverse();
      Eigen::VectorXd d = Eigen::VectorXd::Zero(f.dim());
      const Pose Ti = T_Wp_W * Pose(x.q_W_I, x.p_W_I);
      d.segment<3>(kP) = Ti.p - x.p_W_I;
      d.segment<3>(kV) = T_Wp_W.q * x.v_W_I - x.v_W_I;
      d.segment<3>(kTheta) = log_quat(x.q_W_I.conjugate() * Ti.q);
      for (const auto& o : f.objects()) {
        if (o.dim == 0) continue;
        const Vec6 e = pose_minus(o.T_O_W * T_W_Wp, o.T_O_W);
        if (o.dim == 6)
          d.segment<6>(o.offset) = e;
        else
          d.segment(o.offset, o.dim) = e.segment(3, o.dim);
      }
      return d;
    });
  }
}

TEST_CASE("the rows a split-gate update uses equal finite differences of their residual part",
          "[ekf][jacobian][split]") {
  // Filter::measurement_rows is the selection Filter::update applies after the split gate: the position
  // rows, the rotation rows or all six, in both residual frames, for the anchor and the other objects.
  for (ResidualFrame frame : {ResidualFrame::kObject, ResidualFrame::kCamera}) {
    for (AnchorGauge gauge : {AnchorGauge::kPosition, AnchorGauge::kPositionYaw}) {
      Filter f = make_filter(gauge, /*extrinsics=*/true, frame);
      for (int id : {1, 2, 3}) {
        const Pose zh0 = f.predict(id);
        const Pose z = pose_plus(zh0, (Vec6() << 0.04, 0.03, -0.02, -0.1, 0.08, 0.05).finished());
        Vec6 r6;
        Eigen::MatrixXd H6;
        f.measurement_jacobian(id, z, r6, H6);
        for (ResidualPart part : {ResidualPart::kPosition, ResidualPart::kRotation, ResidualPart::kBoth}) {
          INFO("frame " << to_string(frame) << " gauge " << to_string(gauge) << " object " << id << " part "
                        << to_string(part));
          Eigen::VectorXd r;
          Eigen::MatrixXd H;
          f.measurement_rows(id, z, part, r, H);
          const int first = part == ResidualPart::kRotation ? 3 : 0;
          const int m = part == ResidualPart::kBoth ? 6 : 3;
          REQUIRE(r.size() == m);
          REQUIRE(H.rows() == m);
          REQUIRE(H.cols() == f.dim());
          const Eigen::VectorXd r6_all = r6;  // dynamic: gcc 12 misreads a 6-vector's dynamic segment (-Warray-bounds)
          CHECK((r - r6_all.segment(first, m)).norm() == 0.0);
          // Numeric Jacobian of the part's rows of the predicted measurement's error.
          check_jacobian(H, [&](const Eigen::VectorXd& d) -> Eigen::VectorXd {
            Filter g = f;
            g.boxplus(d);
            return prediction_error(frame, g.predict(id), zh0).segment(first, m);
          });
        }
      }
    }
  }
}

// The Gauss–Markov detection-error states (docs/filter.md §17): r = z ⊟ ẑ(x) − G ê with G at the detection, so
// the filter's H (every column, the error states' included) is −∂r/∂δx; checked by central differences of the
// residual itself over the whole error state, for every gauge and both residual frames.
TEST_CASE("Gauss-Markov error states: the full H equals finite differences of the residual", "[ekf][jacobian][gauss_markov]") {
  for (AnchorGauge gauge : {AnchorGauge::kPose, AnchorGauge::kPosition, AnchorGauge::kPositionYaw}) {
    for (ResidualFrame frame : {ResidualFrame::kObject, ResidualFrame::kCamera}) {
      // (Without t_d: its column is the derivative along the IMU motion, checked above, not of this residual.)
      Filter f = make_filter(gauge, true, frame, false, /*error_states=*/true);
      const int anchor_dim = gauge == AnchorGauge::kPose ? 0 : gauge == AnchorGauge::kPosition ? 3 : 2;
      REQUIRE(f.dim() == 15 + 6 + anchor_dim + 12 + 18);
      for (const auto& o : f.objects()) {
        REQUIRE(o.err_offset >= 0);
        CHECK(o.err.norm() > 0.1);  // make_filter's random ⊞ moved it: the residual must subtract G ê
        if (o.dim > 0) CHECK(o.offset == o.err_offset + 6);
      }
      for (int id : {1, 2, 3}) {
        // z = ẑ(x̂): z ⊟ ẑ(x̂ ⊞ δ) is then −H δ to first order in either residual frame.
        const Pose z = f.predict(id);
        Vec6 r;
        Eigen::MatrixXd H;
        f.measurement_jacobian(id, z, r, H);
        INFO("gauge " << to_string(gauge) << " frame " << to_string(frame) << " object " << id);
        const Eigen::MatrixXd Hn = check_jacobian(H, [&](const Eigen::VectorXd& d) -> Eigen::VectorXd {
          Filter g = f;
          g.boxplus(d);
          Vec6 rg;
          Eigen::MatrixXd Hg;
          g.measurement_jacobian(id, z, rg, Hg);
          (void)Hg;
          return -rg;
        });
        (void)Hn;
        // The error state's columns: G of the detection, non-zero, and zero for the other objects' error states.
        const ObjectEntry* o = f.object(id);
        CHECK(H.middleCols(o->err_offset, 6).cwiseAbs().maxCoeff() > 1e-3);
        for (const auto& other : f.objects())
          if (other.id != id) CHECK(H.middleCols(other.err_offset, 6).cwiseAbs().maxCoeff() == 0.0);
        // The residual subtracts G ê: with ê = 0 it is the plain residual.
        Filter g = f;
        Eigen::VectorXd zero_err = Eigen::VectorXd::Zero(f.dim());
        zero_err.segment<6>(o->err_offset) = -o->err;
        g.boxplus(zero_err);
        Vec6 r0;
        Eigen::MatrixXd H0;
        g.measurement_jacobian(id, z, r0, H0);
        CHECK((r0 - H.middleCols(o->err_offset, 6) * o->err - r).norm() < 1e-12);
      }
    }
  }
}
