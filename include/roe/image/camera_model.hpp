#pragma once
/// @file
/// Pinhole camera with the lens-distortion models librealsense reports (rs2_distortion), and the
/// ROS/Kalibr names that map onto them. No OpenCV here: pure point maths, used by the undistortion
/// maps in image/frame_processor.hpp and by tests.
///
/// Models (x, y = normalised image coordinates, r² = x² + y², coefficients c0..c4):
///  - kNone: identity.
///  - kBrownConrady (librealsense "Brown Conrady", ROS "plumb_bob", Kalibr "radtan"): coefficients
///    k1, k2, p1, p2, k3 DISTORT: f = 1 + k1 r² + k2 r⁴ + k3 r⁶,
///    x_d = x f + 2 p1 x y + p2 (r² + 2x²), y_d = y f + 2 p2 x y + p1 (r² + 2y²)  (OpenCV's model).
///  - kModifiedBrownConrady ("Modified Brown Conrady"): as librealsense's rs2_project_point_to_pixel,
///    the radial factor is applied first and the tangential terms use the scaled coordinates:
///    x' = x f, y' = y f, x_d = x' + 2 p1 x' y' + p2 (r² + 2x'²), y_d = y' + 2 p2 x' y' + p1 (r² + 2y'²).
///  - kInverseBrownConrady ("Inverse Brown Conrady"): the same polynomial as kBrownConrady but the
///    coefficients UNDISTORT (map distorted → undistorted coordinates, rs2_deproject_pixel_to_point);
///    distorting therefore needs the iterative inverse.
///  - kKannalaBrandt4 ("Kannala Brandt4", ROS/Kalibr "equidistant", OpenCV fisheye): θ = atan(r),
///    θ_d = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸), (x_d, y_d) = (θ_d / r) (x, y).
///  - kFtheta ("Ftheta", T265): r_d = atan(2 r tan(w/2)) / w with w = c0, (x_d, y_d) = (r_d / r)(x, y).

#include <array>
#include <string>

#include <Eigen/Core>

namespace roe::image {

enum class Distortion { kNone, kBrownConrady, kModifiedBrownConrady, kInverseBrownConrady, kKannalaBrandt4, kFtheta };

/// Parses a librealsense, ROS or Kalibr distortion model name (case-insensitive; spaces, '-' and '_'
/// ignored). InputError listing the accepted names otherwise.
Distortion parse_distortion(const std::string& name);
/// The librealsense name ("Brown Conrady", "Inverse Brown Conrady", ..., "None").
std::string distortion_name(Distortion d);

struct CameraModel {
  int width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  Distortion model = Distortion::kNone;
  std::array<double, 5> coeffs{};  ///< in librealsense order (k1, k2, p1, p2, k3 for Brown models)

  /// Normalised undistorted (x, y) → normalised distorted coordinates.
  Eigen::Vector2d distort(const Eigen::Vector2d& xy) const;
  /// Normalised distorted → undistorted (closed form or fixed-point/Newton iteration).
  Eigen::Vector2d undistort(const Eigen::Vector2d& xy_d) const;
  /// Pixel of a point in camera coordinates (z > 0).
  Eigen::Vector2d project(const Eigen::Vector3d& p_C) const;
};

}  // namespace roe::image
