#include "roe/ekf/symmetry.hpp"

#include <Eigen/QR>
#include <cmath>

#include "roe/math/so3.hpp"

namespace roe::ekf {

using math::exp_quat;
using math::skew;

namespace {

/// S(χ) = (Exp(χa), o − Exp(χa) o).
Pose continuous_transform(const ContinuousSymmetry& c, double chi) {
  const Eigen::Quaterniond q = exp_quat(chi * c.axis);
  return Pose(q, c.offset - q * c.offset);
}

/// z turned about the axis so that its rotation is nearest ẑ's: S(χ*) z.
Pose align_about_axis(const Pose& z_hat, const Pose& z, const ContinuousSymmetry& c) {
  const Mat3 M = z.R() * z_hat.R().transpose();
  const Vec3& a = c.axis;
  const double s = (skew(a) * M).trace(), co = M.trace() - a.dot(M * a);
  return continuous_transform(c, std::atan2(s, co)) * z;
}

double rotation_angle(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return 2.0 * std::acos(std::min(1.0, std::abs((a.conjugate() * b).w())));
}

}  // namespace

Pose nearest_equivalent(const Pose& z_hat, const Pose& z, const ObjectSymmetry& sym) {
  const auto candidate = [&](const Pose& zc) { return sym.continuous ? align_about_axis(z_hat, zc, *sym.continuous) : zc; };
  Pose best = candidate(z);
  double best_angle = rotation_angle(z_hat.q, best.q);
  for (const Pose& S : sym.discrete) {
    const Pose c = candidate(S.inverse() * z);
    const double ang = rotation_angle(z_hat.q, c.q);
    if (ang < best_angle) {
      best_angle = ang;
      best = c;
    }
  }
  return best;
}

Vec6 symmetry_direction(ResidualFrame frame, const Pose& z_hat, const ContinuousSymmetry& c) {
  const Mat3 R_C_O = z_hat.R().transpose();
  Vec6 d;
  d.tail<3>() = R_C_O * c.axis;
  if (frame == ResidualFrame::kCamera)
    d.head<3>() = R_C_O * c.offset.cross(c.axis);
  else
    d.head<3>() = c.axis.cross(z_hat.p - c.offset);
  return d;
}

Mat56 symmetry_reduction(const Vec6& d, bool& separable) {
  Mat56 A = Mat56::Zero();
  const Vec3 u = d.tail<3>().normalized();
  separable = d.head<3>().norm() <= 1e-12 * std::max(1.0, d.tail<3>().norm());
  if (separable) {
    // Two orthonormal vectors ⟂ u: the last two columns of the Householder Q of u.
    const Mat3 Q = Eigen::HouseholderQR<Vec3>(u).householderQ();
    A.topLeftCorner<3, 3>().setIdentity();
    A.block<2, 3>(3, 3) = Q.rightCols<2>().transpose();
    return A;
  }
  const Mat6 Q = Eigen::HouseholderQR<Vec6>(d.normalized()).householderQ();
  return Q.rightCols<5>().transpose();
}

}  // namespace roe::ekf
