#include "roe/ekf/measurement.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>

#include "roe/math/so3.hpp"

namespace roe::ekf {

using math::skew;

CoreState shift_in_time(const CoreState& x, const Vec3& omega_I, double tau_s) {
  CoreState y = x;
  y.p_W_I += tau_s * x.v_W_I;
  y.q_W_I = (x.q_W_I * math::exp_quat(tau_s * omega_I)).normalized();
  return y;
}

Vec6 time_offset_column(const Mat63& d_p_WI, const Mat63& d_theta_WI, const Vec3& v_W_I, const Vec3& omega_I) {
  return d_p_WI * v_W_I + d_theta_WI * omega_I;
}

ObjectPrediction predict_object(const CoreState& x, const Pose& T_I_C, const Pose& T_O_W) {
  const Mat3 R_W_I = x.q_W_I.toRotationMatrix();
  const Mat3 R_O_W = T_O_W.R();
  const Mat3 R_I_C = T_I_C.R();
  const Vec3 p_W_C = x.p_W_I + R_W_I * T_I_C.p;

  ObjectPrediction out;
  out.T_O_C_hat = Pose(T_O_W.q * x.q_W_I * T_I_C.q, T_O_W.p + R_O_W * p_W_C);
  const Mat3 R_O_I = R_O_W * R_W_I;
  out.H_p_WI << R_O_W, Mat3::Zero();
  out.H_theta_WI << -R_O_I * skew(T_I_C.p), R_I_C.transpose();
  out.H_p_IC << R_O_I, Mat3::Zero();
  out.H_theta_IC << Mat3::Zero(), Mat3::Identity();
  out.H_p_OW << Mat3::Identity(), Mat3::Zero();
  out.H_theta_OW << -R_O_W * skew(p_W_C), R_I_C.transpose() * R_W_I.transpose();
  return out;
}

Vec6 object_residual(const Pose& T_O_C_hat, const Pose& T_O_C_meas) {
  Vec6 r;
  r.head<3>() = T_O_C_meas.p - T_O_C_hat.p;
  r.tail<3>() = math::quat_residual(T_O_C_hat.q, T_O_C_meas.q);
  return r;
}

std::string to_string(ResidualPart p) {
  switch (p) {
    case ResidualPart::kNone:
      return "none";
    case ResidualPart::kPosition:
      return "position";
    case ResidualPart::kRotation:
      return "rotation";
    case ResidualPart::kBoth:
      return "both";
  }
  return "unknown";
}

int residual_rows(ResidualPart p, int rows[6], int dim) {
  int m = 0;
  if (p == ResidualPart::kPosition || p == ResidualPart::kBoth)
    for (int i = 0; i < 3; ++i) rows[m++] = i;
  if (p == ResidualPart::kRotation || p == ResidualPart::kBoth)
    for (int i = 3; i < dim; ++i) rows[m++] = i;
  return m;
}

namespace {

/// r_sᵀ S_s⁻¹ r_s of one 3-row part (∞ when r_s is not finite; S_s is positive definite).
double part_nis(const Vec3& r, const Mat3& S) {
  if (!r.allFinite()) return std::numeric_limits<double>::infinity();
  return r.dot(Eigen::LDLT<Mat3>(S).solve(r));
}

}  // namespace

SplitGate split_gate(const Vec6& r, const Mat6& S, double gate_position, double gate_rotation) {
  SplitGate g;
  g.nis_position = part_nis(r.head<3>(), S.topLeftCorner<3, 3>());
  g.nis_rotation = part_nis(r.tail<3>(), S.bottomRightCorner<3, 3>());
  // A non-finite part fails even an infinite gate (no gate: chi2_gate false).
  const bool p = std::isfinite(g.nis_position) && g.nis_position <= gate_position;
  const bool q = std::isfinite(g.nis_rotation) && g.nis_rotation <= gate_rotation;
  g.used = p && q ? ResidualPart::kBoth
                  : p ? ResidualPart::kPosition : q ? ResidualPart::kRotation : ResidualPart::kNone;
  return g;
}

ObjectInit init_object(const CoreState& x, const Pose& T_I_C, const Pose& z) {
  const Mat3 R_W_I = x.q_W_I.toRotationMatrix();
  const Mat3 R_W_C = R_W_I * T_I_C.R();
  const Vec3 p_W_C = x.p_W_I + R_W_I * T_I_C.p;
  ObjectInit out;
  const Eigen::Quaterniond q_O_W = (z.q * (x.q_W_I * T_I_C.q).conjugate()).normalized();
  const Mat3 R_O_W = q_O_W.toRotationMatrix();
  out.T_O_W = Pose(q_O_W, z.p - R_O_W * p_W_C);

  // Rotation rows.
  const Mat3 Jt_theta_WI = -R_W_I;
  const Mat3 Jt_theta_IC = -R_W_C;
  const Mat3 Jt_z = R_W_C;
  // Position rows: δp_O_W = δz_p + A δθ_O_W − R_O_W (δp_W_I + R_W_I δp_I_C − R_W_I [p_I_C]× δθ_W_I).
  const Mat3 A = R_O_W * skew(p_W_C);
  out.J_p_WI << -R_O_W, Mat3::Zero();
  out.J_theta_WI << A * Jt_theta_WI + R_O_W * R_W_I * skew(T_I_C.p), Jt_theta_WI;
  out.J_p_IC << -R_O_W * R_W_I, Mat3::Zero();
  out.J_theta_IC << A * Jt_theta_IC, Jt_theta_IC;
  out.J_z.setZero();
  out.J_z.block<3, 3>(0, 0) = Mat3::Identity();
  out.J_z.block<3, 3>(0, 3) = A * Jt_z;
  out.J_z.block<3, 3>(3, 3) = Jt_z;
  return out;
}

Mat6 detection_error_to_residual_frame(const Pose& T_C_O) {
  const Mat3 R_O_C = T_C_O.R().transpose();
  Mat6 J = Mat6::Zero();
  J.block<3, 3>(0, 0) = -R_O_C;
  J.block<3, 3>(0, 3) = -R_O_C * skew(T_C_O.p);
  J.block<3, 3>(3, 3) = -Mat3::Identity();
  return J;
}

Mat6 detection_covariance_in_residual_frame(const Pose& T_C_O, const Mat6& cov_C) {
  const Mat6 J = detection_error_to_residual_frame(T_C_O);
  return J * cov_C * J.transpose();
}

Mat6 symmetric_sqrt(const Mat6& A) {
  const Eigen::SelfAdjointEigenSolver<Mat6> es(0.5 * (A + A.transpose()));
  const Vec6 s = es.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return es.eigenvectors() * s.asDiagonal() * es.eigenvectors().transpose();
}

Mat6 gauss_markov_error_jacobian(const Mat6& cov_C, const Mat3& R_C_O, double share) {
  Mat6 G = std::sqrt(share) * symmetric_sqrt(cov_C);
  G.rightCols<3>() = (G.rightCols<3>() * R_C_O).eval();
  return G;
}

Mat6 detection_covariance_in_residual_frame(const Pose& T_C_O, const Vec6& sigma_C) {
  return detection_covariance_in_residual_frame(T_C_O, Mat6(sigma_C.cwiseProduct(sigma_C).asDiagonal()));
}

Mat6 inverse_pose_jacobian(const Pose& T_O_W) {
  const Mat3 R_O_W = T_O_W.q.toRotationMatrix();
  const Vec3 p_W_O = -R_O_W.transpose() * T_O_W.p;
  Mat6 J = Mat6::Zero();
  J.block<3, 3>(0, 0) = -R_O_W.transpose();
  J.block<3, 3>(0, 3) = math::skew(p_W_O);
  J.block<3, 3>(3, 3) = -R_O_W;
  return J;
}

Eigen::Matrix<double, 6, 12> relative_pose_jacobian(const Pose& T_A_W, const Pose& T_O_W) {
  const Mat3 R_X = T_A_W.q.toRotationMatrix(), R_Y = T_O_W.q.toRotationMatrix();
  const Vec3 v = R_Y.transpose() * T_O_W.p;
  const Mat3 Jp_th = R_X * skew(v);
  Eigen::Matrix<double, 6, 12> J = Eigen::Matrix<double, 6, 12>::Zero();
  J.block<3, 3>(0, 0) = Mat3::Identity();
  J.block<3, 3>(0, 3) = Jp_th;
  J.block<3, 3>(0, 6) = -R_X * R_Y.transpose();
  J.block<3, 3>(0, 9) = -Jp_th;
  J.block<3, 3>(3, 3) = R_Y;
  J.block<3, 3>(3, 9) = -R_Y;
  return J;
}

}  // namespace roe::ekf
