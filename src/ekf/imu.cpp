#include "roe/ekf/imu.hpp"

#include <cmath>

#include "roe/math/so3.hpp"

namespace roe::ekf {

using math::exp_quat;
using math::exp_so3;
using math::right_jacobian;
using math::skew;

Mat15 CoreTransition::dense() const {
  Mat15 F = Mat15::Identity();
  F.block<3, 3>(kP, kV) = dt * Mat3::Identity();
  F.block<3, 3>(kP, kTheta) = 0.5 * dt * F_vtheta;
  F.block<3, 3>(kP, kBg) = 0.5 * dt * F_vbg;
  F.block<3, 3>(kP, kBa) = 0.5 * dt * F_vba;
  F.block<3, 3>(kV, kTheta) = F_vtheta;
  F.block<3, 3>(kV, kBg) = F_vbg;
  F.block<3, 3>(kV, kBa) = F_vba;
  F.block<3, 3>(kTheta, kTheta) = F_tt;
  F.block<3, 3>(kTheta, kBg) = F_tbg;
  return F;
}

namespace {

/// Jr(φ) = I − (1 − cos θ)/θ² [φ]× + (θ − sin θ)/θ³ [φ]×² (θ = |φ| ≥ kSmallAngle) from given sin θ, 1 − cos
/// θ and the skew matrix K = [φ]× and its square.
Mat3 right_jacobian_from(const Mat3& K, const Mat3& K2, double theta, double sin_t, double one_minus_cos_t) {
  const double t2 = theta * theta;
  return Mat3::Identity() - (one_minus_cos_t / t2) * K + ((theta - sin_t) / (t2 * theta)) * K2;
}

}  // namespace

CoreState integrate(const CoreState& x, const Vec3& w0, const Vec3& a0, const Vec3& w1, const Vec3& a1,
                    double dt, CoreTransition* F) {
  const Vec3 w = 0.5 * (w0 + w1) - x.b_g;
  const Vec3 a = 0.5 * (a0 + a1) - x.b_a;
  const Vec3 phi = w * dt;
  // Exp(φ/2), Jr(φ/2) and Jr(φ) from one sine/cosine pair of θ/4 (double-angle formulas) instead of five
  // trigonometric calls; below the small-angle threshold the Taylor forms of roe::math are used.
  const double theta = phi.norm();
  const bool small = 0.5 * theta < math::kSmallAngle;
  double sin_h = 0.0, omc_h = 0.0, sin_t = 0.0, omc_t = 0.0;  // sin, 1 − cos of θ/2 and θ
  Eigen::Quaterniond q_half;
  if (small) {
    q_half = exp_quat(0.5 * phi);
  } else {
    const double s = std::sin(0.25 * theta), c = std::cos(0.25 * theta);
    q_half.w() = c;
    q_half.vec() = (s / theta) * phi;  // sin(θ/4)/(θ/2) · φ/2
    q_half.normalize();
    sin_h = 2.0 * s * c;
    omc_h = 2.0 * s * s;
    sin_t = 2.0 * sin_h * (1.0 - omc_h);
    omc_t = 2.0 * sin_h * sin_h;
  }
  const Eigen::Quaterniond q_m = x.q_W_I * q_half;
  const Mat3 R_m = q_m.toRotationMatrix();
  const Vec3 acc_W = R_m * a - kGravity_W;

  CoreState y;
  y.q_W_I = (q_m * q_half).normalized();
  y.v_W_I = x.v_W_I + acc_W * dt;
  y.p_W_I = x.p_W_I + x.v_W_I * dt + 0.5 * acc_W * dt * dt;
  y.b_g = x.b_g;
  y.b_a = x.b_a;

  if (F != nullptr) {
    F->dt = dt;
    const Mat3 R_half_T = q_half.toRotationMatrix().transpose();  // Exp(−ω̄dt/2)
    const Mat3 Ra_skew_dt = R_m * skew(a) * dt;                   // R_m [ā]× dt
    // δθ_m = Exp(−ω̄dt/2) δθ − Jr(ω̄dt/2) dt/2 δb_g; δv⁺ = δv − R_m[ā]× dt δθ_m − R_m dt δb_a.
    F->F_vtheta = -Ra_skew_dt * R_half_T;
    Mat3 Jr_half, Jr;
    if (small) {
      Jr_half = right_jacobian(0.5 * phi);
      Jr = right_jacobian(phi);
    } else {
      // [φ]× = 2 [φ/2]× and [φ]×² = 4 [φ/2]×² exactly (power-of-two scaling): one skew square for both.
      const Mat3 K_half = skew(0.5 * phi);
      const Mat3 K2_half = K_half * K_half;
      Jr_half = right_jacobian_from(K_half, K2_half, 0.5 * theta, sin_h, omc_h);
      Jr = right_jacobian_from(2.0 * K_half, 4.0 * K2_half, theta, sin_t, omc_t);
    }
    F->F_vbg = Ra_skew_dt * Jr_half * (0.5 * dt);
    F->F_vba = -R_m * dt;
    F->F_tt = R_half_T * R_half_T;  // Exp(−ω̄dt)
    F->F_tbg = -Jr * dt;
  }
  return y;
}

}  // namespace roe::ekf
