// The analytic Jacobians of the detection and IMU errors (docs/refine.md §7), on doubles: the solve's cost
// functions (refine.cpp) use these; tests/refine/test_factors.cpp checks each against central differences
// of the templated residuals in factors.hpp.
#include "roe/refine/factors.hpp"

#include <Eigen/Geometry>
#include <array>

#include "roe/math/so3.hpp"

namespace roe::refine {

namespace {
using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;
}  // namespace

Vec6 detection_error_jacobians(const Quaterniond& q_meas, const Vector3d& t_meas, const double* pose_WI,
                               const double* pose_IC, const double* pose_OW, Mat6* J_WI, Mat6* J_IC, Mat6* J_OW) {
  const Eigen::Map<const Vector3d> p_WI(pose_WI), p_IC(pose_IC), p_OW(pose_OW);
  const Matrix3d R_WI = Eigen::Map<const Quaterniond>(pose_WI + 3).toRotationMatrix();
  const Matrix3d R_IC = Eigen::Map<const Quaterniond>(pose_IC + 3).toRotationMatrix();
  const Matrix3d R_OW = Eigen::Map<const Quaterniond>(pose_OW + 3).toRotationMatrix();
  const Matrix3d R_OC = R_OW * R_WI * R_IC;
  const Vector3d m = p_WI + R_WI * p_IC;  // the camera's position in W
  const Vector3d p_OC = p_OW + R_OW * m;
  const Vector3d t_hat = -(R_OC.transpose() * p_OC);
  const Matrix3d E = R_OC * q_meas.toRotationMatrix();  // R̂ᵀ R
  Vec6 e;
  e.head<3>() = t_meas - t_hat;
  e.tail<3>() = math::log_so3(E);
  if (!(J_WI || J_IC || J_OW)) return e;
  // e_t = t − t̂: ∂t̂ from R̂ᵀ = R_OCᵀ and p_OC under each block's right perturbation (docs/refine.md §7).
  const Matrix3d Jinv = math::right_jacobian_inv(e.tail<3>());
  const Matrix3d RmT = q_meas.toRotationMatrix().transpose();
  const Matrix3d R_CI = R_IC.transpose(), R_CW = R_CI * R_WI.transpose();
  if (J_WI) {
    J_WI->setZero();
    J_WI->topLeftCorner<3, 3>() = R_CW;
    // the object → IMU vector in I: rotating the IMU about itself moves the object through this lever arm
    J_WI->topRightCorner<3, 3>() = R_CI * math::skew(R_WI.transpose() * (R_OW.transpose() * p_OW + p_WI));
    J_WI->bottomRightCorner<3, 3>() = Jinv * RmT * R_CI;
  }
  if (J_IC) {
    J_IC->setZero();
    J_IC->topLeftCorner<3, 3>() = R_CI;
    J_IC->topRightCorner<3, 3>() = -math::skew(t_hat);
    J_IC->bottomRightCorner<3, 3>() = Jinv * RmT;
  }
  if (J_OW) {
    J_OW->setZero();
    J_OW->topLeftCorner<3, 3>() = R_OC.transpose();
    J_OW->topRightCorner<3, 3>() = R_CW * math::skew(R_OW.transpose() * p_OW);
    J_OW->bottomRightCorner<3, 3>() = Jinv * RmT * R_CW;
  }
  return e;
}

Vec6 shifted_detection_error_jacobians(const Quaterniond& q_meas, const Vector3d& t_meas, const double* pose_WI,
                                       const double* v_WI, const double* bias, const Vector3d& gyro, double delta,
                                       const double* pose_IC, const double* pose_OW, TimeShiftJacobians* J) {
  const Eigen::Map<const Vector3d> v(v_WI), b_g(bias);
  const Vector3d w = gyro - b_g, phi = w * delta;
  const Quaterniond q_shift = Eigen::Map<const Quaterniond>(pose_WI + 3) * Quaterniond(math::exp_so3(phi));
  std::array<double, 7> shifted{};
  Eigen::Map<Vector3d>(shifted.data()) = Eigen::Map<const Vector3d>(pose_WI) + v * delta;
  Eigen::Map<Quaterniond>(shifted.data() + 3) = q_shift.normalized();
  Mat6 J_s;  // in the tangent of the shifted pose
  const Vec6 e = detection_error_jacobians(q_meas, t_meas, shifted.data(), pose_IC, pose_OW, J ? &J_s : nullptr,
                                           J ? &J->extr : nullptr, J ? &J->obj : nullptr);
  if (!J) return e;
  // The shifted pose under the blocks' perturbations (right perturbations, docs/refine.md §2b):
  //   pose: δp' = δp, δθ' = Exp(φ)ᵀ δθ;  v: δp' = δ δv;  b_g: δθ' = −δ J_r(φ) δb_g;  δ: [v ; J_r(φ) ω] = [v ; ω].
  const Matrix3d Jr = math::right_jacobian(phi);
  J->pose = J_s;
  J->pose.rightCols<3>() = J_s.rightCols<3>() * math::exp_so3(phi).transpose();
  J->vel = J_s.leftCols<3>() * delta;
  J->bias.setZero();
  J->bias.leftCols<3>() = -J_s.rightCols<3>() * Jr * delta;
  J->delta = J_s.leftCols<3>() * v + J_s.rightCols<3>() * w;  // J_r(φ) ω = ω: φ = ω δ is parallel to ω
  return e;
}

Eigen::Matrix<double, 9, 1> imu_error_jacobians(const ImuResidual& f, const double* pose_i, const double* v_i_,
                                                const double* b_i, const double* pose_j, const double* v_j_,
                                                Eigen::Matrix<double, 9, 6>* J_pose_i, Eigen::Matrix<double, 9, 3>* J_v_i,
                                                Eigen::Matrix<double, 9, 6>* J_b_i, Eigen::Matrix<double, 9, 6>* J_pose_j,
                                                Eigen::Matrix<double, 9, 3>* J_v_j) {
  const Eigen::Map<const Vector3d> p_i(pose_i), p_j(pose_j), v_i(v_i_), v_j(v_j_);
  const Matrix3d R_i = Eigen::Map<const Quaterniond>(pose_i + 3).toRotationMatrix();
  const Matrix3d R_j = Eigen::Map<const Quaterniond>(pose_j + 3).toRotationMatrix();
  Vec6 db;
  db << Eigen::Map<const Vector3d>(b_i) - f.bg_lin, Eigen::Map<const Vector3d>(b_i + 3) - f.ba_lin;
  const Eigen::Matrix<double, 9, 1> corr = f.J_bias * db;
  const double dt = f.dt;
  const Vector3d a_p = R_i.transpose() * (p_j - p_i - v_i * dt + 0.5 * f.gravity * dt * dt);
  const Vector3d a_v = R_i.transpose() * (v_j - v_i + f.gravity * dt);
  const Vector3d u = corr.segment<3>(6);
  const Matrix3d C = f.dR.toRotationMatrix() * math::exp_so3(u);
  const Matrix3d E = C.transpose() * R_i.transpose() * R_j;
  Eigen::Matrix<double, 9, 1> e;
  e.segment<3>(0) = a_p - (f.dp + corr.segment<3>(0));
  e.segment<3>(3) = a_v - (f.dv + corr.segment<3>(3));
  e.segment<3>(6) = math::log_so3(E);
  const Matrix3d Jinv = math::right_jacobian_inv(e.segment<3>(6));
  const Matrix3d RiT = R_i.transpose();
  if (J_pose_i) {
    J_pose_i->setZero();
    J_pose_i->block<3, 3>(0, 0) = -RiT;
    J_pose_i->block<3, 3>(0, 3) = math::skew(a_p);
    J_pose_i->block<3, 3>(3, 3) = math::skew(a_v);
    J_pose_i->block<3, 3>(6, 3) = -Jinv * R_j.transpose() * R_i;
  }
  if (J_v_i) {
    J_v_i->setZero();
    J_v_i->block<3, 3>(0, 0) = -RiT * dt;
    J_v_i->block<3, 3>(3, 0) = -RiT;
  }
  if (J_b_i) {
    J_b_i->topRows<6>() = -f.J_bias.topRows<6>();
    J_b_i->bottomRows<3>() = -Jinv * E.transpose() * math::right_jacobian(u) * f.J_bias.bottomRows<3>();
  }
  if (J_pose_j) {
    J_pose_j->setZero();
    J_pose_j->block<3, 3>(0, 0) = RiT;
    J_pose_j->block<3, 3>(6, 3) = Jinv;
  }
  if (J_v_j) {
    J_v_j->setZero();
    J_v_j->block<3, 3>(3, 0) = RiT;
  }
  return e;
}

void pose_ambient_jacobian(const double* pose, const double* J_tangent, int rows, double* J_ambient) {
  const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor>> J(J_tangent, rows, 6);
  Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 7, Eigen::RowMajor>> A(J_ambient, rows, 7);
  const double x = pose[3], y = pose[4], z = pose[5], w = pose[6];
  Eigen::Matrix<double, 4, 3> M;  // rows x y z w of ∂(q ⊗ Exp(δθ))/∂δθ
  M << w, -z, y,  //
      z, w, -x,   //
      -y, x, w,   //
      -x, -y, -z;
  M *= 0.5;
  A.leftCols<3>() = J.leftCols<3>();
  A.rightCols<4>() = 4.0 * J.rightCols<3>() * M.transpose();
}

}  // namespace roe::refine
