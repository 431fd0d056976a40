#pragma once
/// @file
/// Rigid-body poses. A Pose named T_A_B is the pose of frame B in frame A:
/// x_A = R_A_B x_B + p_A_B (DESIGN §2). Composition follows the names: T_A_C = T_A_B * T_B_C.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "roe/math/so3.hpp"

namespace roe::math {

struct Pose {
  Quaterniond q = Quaterniond::Identity();  ///< rotation R_A_B as a unit Hamilton quaternion
  Vector3d p = Vector3d::Zero();            ///< translation p_A_B (metres)

  Pose() = default;
  Pose(const Quaterniond& q_in, const Vector3d& p_in) : q(q_in.normalized()), p(p_in) {}
  Pose(const Matrix3d& R, const Vector3d& p_in) : q(Quaterniond(R).normalized()), p(p_in) {}

  static Pose identity() { return Pose(); }

  Matrix3d R() const { return q.toRotationMatrix(); }
  /// T_B_A from T_A_B.
  Pose inverse() const {
    const Quaterniond qi = q.conjugate();
    return Pose(qi, -(qi * p));
  }
  /// T_A_C = T_A_B * T_B_C.
  Pose operator*(const Pose& o) const { return Pose(q * o.q, p + q * o.p); }
  /// x_A = T_A_B.act(x_B).
  Vector3d act(const Vector3d& x) const { return q * x + p; }
  /// Homogeneous 4x4 matrix.
  Eigen::Matrix4d matrix() const {
    Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
    T.topLeftCorner<3, 3>() = R();
    T.topRightCorner<3, 1>() = p;
    return T;
  }
};

/// Interpolates between a (alpha = 0) and b (alpha = 1): slerp of the rotation along the shortest
/// arc, linear interpolation of the translation. alpha outside [0, 1] extrapolates.
Pose interpolate(const Pose& a, const Pose& b, double alpha);

/// Tangent-space difference used to compare poses in tests and reports:
/// [p_b − p_a ; Log(R_a^T R_b)].
Eigen::Matrix<double, 6, 1> pose_difference(const Pose& a, const Pose& b);

}  // namespace roe::math
