#include "roe/math/euler.hpp"

#include <algorithm>
#include <cmath>

namespace roe::math {

Vector3d euler_zyx(const Matrix3d& R) {
  // cos(pitch) from the first column (hypot keeps it accurate), pitch by atan2 (asin loses
  // precision near ±90°).
  const double cos_pitch = std::hypot(R(0, 0), R(1, 0));
  const double pitch = std::atan2(-R(2, 0), cos_pitch);
  if (cos_pitch < kGimbalLockCos) {
    // Gimbal lock: only yaw − roll (pitch = +90°) or yaw + roll (pitch = −90°) is defined, and the
    // generic atan2s below would divide rounding noise by cos(pitch). Take roll = 0; then
    // R01 = −sin(yaw), R11 = cos(yaw) for either sign of pitch.
    return {0.0, pitch, std::atan2(-R(0, 1), R(1, 1))};
  }
  const double roll = std::atan2(R(2, 1), R(2, 2));
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  return {roll, pitch, yaw};
}

Matrix3d from_euler_zyx(const Vector3d& rpy) {
  return (Eigen::AngleAxisd(rpy.z(), Vector3d::UnitZ()) * Eigen::AngleAxisd(rpy.y(), Vector3d::UnitY()) *
          Eigen::AngleAxisd(rpy.x(), Vector3d::UnitX()))
      .toRotationMatrix();
}

double wrap_pi(double a) {
  const double two_pi = 2.0 * kPi;
  double w = a - two_pi * std::floor((a + kPi) / two_pi);
  if (w >= kPi) w -= two_pi;  // guard against rounding at the upper edge
  if (w < -kPi) w += two_pi;
  return w;
}

double wrap_180(double a) {
  double w = a - 360.0 * std::floor((a + 180.0) / 360.0);
  if (w >= 180.0) w -= 360.0;
  if (w < -180.0) w += 360.0;
  return w;
}

}  // namespace roe::math
