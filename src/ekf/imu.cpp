#include "roe/ekf/imu.hpp"

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

CoreState integrate(const CoreState& x, const Vec3& w0, const Vec3& a0, const Vec3& w1, const Vec3& a1,
                    double dt, CoreTransition* F) {
  const Vec3 w = 0.5 * (w0 + w1) - x.b_g;
  const Vec3 a = 0.5 * (a0 + a1) - x.b_a;
  const Vec3 phi = w * dt;
  const Eigen::Quaterniond q_half = exp_quat(0.5 * phi);
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
    F->F_vbg = Ra_skew_dt * right_jacobian(0.5 * phi) * (0.5 * dt);
    F->F_vba = -R_m * dt;
    F->F_tt = R_half_T * R_half_T;  // Exp(−ω̄dt)
    F->F_tbg = -right_jacobian(phi) * dt;
  }
  return y;
}

}  // namespace roe::ekf
