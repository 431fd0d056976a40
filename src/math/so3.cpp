#include "roe/math/so3.hpp"

#include <Eigen/SVD>
#include <cmath>

namespace roe::math {
namespace {
// 1 − cos θ without cancellation: 1 − cos θ loses all but ~4 digits just above kSmallAngle
// (cos θ ≈ 1 − 6e-13 at θ = 1.1e-6), which made Jr's first-order term wrong by ~1e-10.
double one_minus_cos(double theta) {
  const double s = std::sin(0.5 * theta);
  return 2.0 * s * s;
}
}  // namespace

Matrix3d skew(const Vector3d& v) {
  Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

Vector3d vee(const Matrix3d& m) {
  return 0.5 * Vector3d(m(2, 1) - m(1, 2), m(0, 2) - m(2, 0), m(1, 0) - m(0, 1));
}

Matrix3d exp_so3(const Vector3d& phi) {
  const double theta = phi.norm();
  const Matrix3d K = skew(phi);
  if (theta < kSmallAngle) {
    return Matrix3d::Identity() + K + 0.5 * K * K;
  }
  const double a = std::sin(theta) / theta;
  const double b = one_minus_cos(theta) / (theta * theta);
  return Matrix3d::Identity() + a * K + b * K * K;
}

Quaterniond exp_quat(const Vector3d& phi) {
  const double theta = phi.norm();
  Quaterniond q;
  if (theta < kSmallAngle) {
    // cos(θ/2) ≈ 1 − θ²/8, sin(θ/2)/θ ≈ 1/2 − θ²/48.
    q.w() = 1.0 - theta * theta / 8.0;
    q.vec() = (0.5 - theta * theta / 48.0) * phi;
  } else {
    q.w() = std::cos(0.5 * theta);
    q.vec() = (std::sin(0.5 * theta) / theta) * phi;
  }
  return q.normalized();
}

Vector3d log_quat(const Quaterniond& q_in) {
  Quaterniond q = q_in.normalized();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  const double n = q.vec().norm();
  if (n < 0.5 * kSmallAngle) {
    // θ = 2 atan2(n, w) ≈ 2 n / w (1 − n²/(3 w²)).
    return (2.0 / q.w()) * (1.0 - n * n / (3.0 * q.w() * q.w())) * q.vec();
  }
  const double theta = 2.0 * std::atan2(n, q.w());
  return (theta / n) * q.vec();
}

Vector3d log_so3(const Matrix3d& R) { return log_quat(Quaterniond(R)); }

Matrix3d right_jacobian(const Vector3d& phi) {
  const double theta = phi.norm();
  const Matrix3d K = skew(phi);
  if (theta < kSmallAngle) {
    return Matrix3d::Identity() - 0.5 * K + (1.0 / 6.0) * K * K;
  }
  const double t2 = theta * theta;
  return Matrix3d::Identity() - (one_minus_cos(theta) / t2) * K +
         ((theta - std::sin(theta)) / (t2 * theta)) * K * K;
}

Matrix3d right_jacobian_inv(const Vector3d& phi) {
  const double theta = phi.norm();
  const Matrix3d K = skew(phi);
  if (theta < kSmallAngle) {
    return Matrix3d::Identity() + 0.5 * K + (1.0 / 12.0) * K * K;
  }
  // 1/θ² − cot(θ/2)/(2θ): finite at θ = π (cot(π/2) = 0), singular only at θ = 2π.
  const double half = 0.5 * theta;
  const double c = 1.0 / (theta * theta) - (std::cos(half) / std::sin(half)) / (2.0 * theta);
  return Matrix3d::Identity() + 0.5 * K + c * K * K;
}

Matrix3d left_jacobian(const Vector3d& phi) { return right_jacobian(-phi); }
Matrix3d left_jacobian_inv(const Vector3d& phi) { return right_jacobian_inv(-phi); }

double angle_between(const Quaterniond& a, const Quaterniond& b) {
  return log_quat(a.conjugate() * b).norm();
}

Vector3d quat_residual(const Quaterniond& q_hat, const Quaterniond& q_meas) {
  const Quaterniond dq = q_hat.normalized().conjugate() * q_meas.normalized();
  return 2.0 * dq.vec() / dq.w();
}

Matrix3d orthonormalize(const Matrix3d& M) {
  Eigen::JacobiSVD<Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Matrix3d S = Matrix3d::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0) S(2, 2) = -1.0;
  return svd.matrixU() * S * svd.matrixV().transpose();
}

Quaterniond canonical(const Quaterniond& q) {
  Quaterniond out = q;
  if (out.w() < 0.0) out.coeffs() = -out.coeffs();
  return out;
}

}  // namespace roe::math
