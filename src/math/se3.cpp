#include "roe/math/se3.hpp"

namespace roe::math {

Pose interpolate(const Pose& a, const Pose& b, double alpha) {
  // Exp/Log-based slerp: q = a ⊗ Exp(alpha · Log(a⁻¹ ⊗ b)), shortest arc by log_quat's w >= 0.
  const Vector3d delta = log_quat(a.q.conjugate() * b.q);
  return Pose(a.q * exp_quat(alpha * delta), a.p + alpha * (b.p - a.p));
}

Eigen::Matrix<double, 6, 1> pose_difference(const Pose& a, const Pose& b) {
  Eigen::Matrix<double, 6, 1> d;
  d.head<3>() = b.p - a.p;
  d.tail<3>() = log_quat(a.q.conjugate() * b.q);
  return d;
}

}  // namespace roe::math
