#pragma once
/// @file
/// ZYX Euler angles, used in reports only (DESIGN §2): R = Rz(yaw) Ry(pitch) Rx(roll).

#include "roe/math/so3.hpp"

namespace roe::math {

/// Below this |cos(pitch)| euler_zyx treats the rotation as gimbal-locked (roll := 0). Chosen near
/// √ε so that both the generic and the locked formulas reproduce R to about 1e-8.
inline constexpr double kGimbalLockCos = 1e-8;

/// (roll, pitch, yaw) in radians of R = Rz(yaw) Ry(pitch) Rx(roll):
/// roll = atan2(R21, R22), pitch = atan2(−R20, hypot(R00, R10)), yaw = atan2(R10, R00);
/// at gimbal lock (|cos pitch| < kGimbalLockCos) roll = 0 and yaw = atan2(−R01, R11).
/// roll and yaw are in [-π, π], pitch in [-π/2, π/2].
Vector3d euler_zyx(const Matrix3d& R);
/// The rotation of (roll, pitch, yaw) radians.
Matrix3d from_euler_zyx(const Vector3d& rpy);
/// Wraps an angle (rad) into [-π, π).
double wrap_pi(double angle);
/// Wraps an angle (deg) into [-180, 180).
double wrap_180(double angle_deg);

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kTwoPi = 2.0 * kPi;  // exact: the double nearest 2π
inline constexpr double kDegPerRad = 180.0 / kPi;
inline constexpr double kRadPerDeg = kPi / 180.0;

}  // namespace roe::math
