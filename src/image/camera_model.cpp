#include "roe/image/camera_model.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>

#include <Eigen/LU>

#include "roe/core/error.hpp"

namespace roe::image {
namespace {

std::string squash(const std::string& s) {
  std::string o;
  for (char c : s)
    if (!std::isspace(static_cast<unsigned char>(c)) && c != '-' && c != '_')
      o.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(c))));
  return o;
}

// The Brown–Conrady polynomial (OpenCV order of terms) applied to (x, y).
Eigen::Vector2d brown(const std::array<double, 5>& c, const Eigen::Vector2d& p) {
  const double x = p.x(), y = p.y();
  const double r2 = x * x + y * y;
  const double f = 1.0 + c[0] * r2 + c[1] * r2 * r2 + c[4] * r2 * r2 * r2;
  return {x * f + 2.0 * c[2] * x * y + c[3] * (r2 + 2.0 * x * x),
          y * f + 2.0 * c[3] * x * y + c[2] * (r2 + 2.0 * y * y)};
}

Eigen::Vector2d modified_brown(const std::array<double, 5>& c, const Eigen::Vector2d& p) {
  const double r2 = p.squaredNorm();
  const double f = 1.0 + c[0] * r2 + c[1] * r2 * r2 + c[4] * r2 * r2 * r2;
  const double x = p.x() * f, y = p.y() * f;
  return {x + 2.0 * c[2] * x * y + c[3] * (r2 + 2.0 * x * x), y + 2.0 * c[3] * x * y + c[2] * (r2 + 2.0 * y * y)};
}

Eigen::Vector2d kb4(const std::array<double, 5>& c, const Eigen::Vector2d& p) {
  const double r = p.norm();
  if (r < 1e-12) return p;
  const double th = std::atan(r);
  const double t2 = th * th;
  const double thd = th * (1.0 + t2 * (c[0] + t2 * (c[1] + t2 * (c[2] + t2 * c[3]))));
  return p * (thd / r);
}

Eigen::Vector2d ftheta(const std::array<double, 5>& c, const Eigen::Vector2d& p) {
  const double r = p.norm();
  if (r < 1e-12 || std::abs(c[0]) < 1e-12) return p;
  const double rd = std::atan(2.0 * r * std::tan(c[0] / 2.0)) / c[0];
  return p * (rd / r);
}

/// Solves g(x) = target for x by Newton's method with a numeric Jacobian, starting at `target`.
template <typename G>
Eigen::Vector2d invert(const G& g, const Eigen::Vector2d& target) {
  Eigen::Vector2d x = target;
  for (int it = 0; it < 30; ++it) {
    const Eigen::Vector2d r = g(x) - target;
    if (r.norm() < 1e-14) break;
    constexpr double h = 1e-7;
    Eigen::Matrix2d J;
    J.col(0) = (g(x + Eigen::Vector2d(h, 0)) - g(x - Eigen::Vector2d(h, 0))) / (2 * h);
    J.col(1) = (g(x + Eigen::Vector2d(0, h)) - g(x - Eigen::Vector2d(0, h))) / (2 * h);
    const double det = J.determinant();
    if (!(std::abs(det) > 1e-12)) break;  // singular (far outside the valid field of view)
    x -= J.inverse() * r;
    if (!x.allFinite()) return target;
  }
  return x;
}

}  // namespace

Distortion parse_distortion(const std::string& name) {
  const std::string s = squash(name);
  if (s == "none" || s.empty()) return Distortion::kNone;
  if (s == "brownconrady" || s == "plumbbob" || s == "radtan" || s == "radialtangential")
    return Distortion::kBrownConrady;
  if (s == "modifiedbrownconrady") return Distortion::kModifiedBrownConrady;
  if (s == "inversebrownconrady") return Distortion::kInverseBrownConrady;
  if (s == "kannalabrandt4" || s == "equidistant" || s == "fisheye") return Distortion::kKannalaBrandt4;
  if (s == "ftheta") return Distortion::kFtheta;
  throw InputError("unknown distortion model \"" + name +
                   "\" (accepted: None, Brown Conrady / plumb_bob / radtan, Modified Brown Conrady, Inverse "
                   "Brown Conrady, Kannala Brandt4 / equidistant, Ftheta)");
}

std::string distortion_name(Distortion d) {
  switch (d) {
    case Distortion::kNone: return "None";
    case Distortion::kBrownConrady: return "Brown Conrady";
    case Distortion::kModifiedBrownConrady: return "Modified Brown Conrady";
    case Distortion::kInverseBrownConrady: return "Inverse Brown Conrady";
    case Distortion::kKannalaBrandt4: return "Kannala Brandt4";
    case Distortion::kFtheta: return "Ftheta";
  }
  return "None";
}

Eigen::Vector2d CameraModel::distort(const Eigen::Vector2d& xy) const {
  switch (model) {
    case Distortion::kNone: return xy;
    case Distortion::kBrownConrady: return brown(coeffs, xy);
    case Distortion::kModifiedBrownConrady: return modified_brown(coeffs, xy);
    case Distortion::kInverseBrownConrady:
      return invert([&](const Eigen::Vector2d& p) { return brown(coeffs, p); }, xy);
    case Distortion::kKannalaBrandt4: return kb4(coeffs, xy);
    case Distortion::kFtheta: return ftheta(coeffs, xy);
  }
  return xy;
}

Eigen::Vector2d CameraModel::undistort(const Eigen::Vector2d& xy_d) const {
  switch (model) {
    case Distortion::kNone: return xy_d;
    case Distortion::kInverseBrownConrady: return brown(coeffs, xy_d);
    case Distortion::kBrownConrady:
      return invert([&](const Eigen::Vector2d& p) { return brown(coeffs, p); }, xy_d);
    case Distortion::kModifiedBrownConrady:
      return invert([&](const Eigen::Vector2d& p) { return modified_brown(coeffs, p); }, xy_d);
    case Distortion::kKannalaBrandt4:
      return invert([&](const Eigen::Vector2d& p) { return kb4(coeffs, p); }, xy_d);
    case Distortion::kFtheta: {
      // Closed form: r = tan(r_d w) / (2 tan(w/2)).
      const double rd = xy_d.norm();
      if (rd < 1e-12 || std::abs(coeffs[0]) < 1e-12) return xy_d;
      const double r = std::tan(rd * coeffs[0]) / (2.0 * std::tan(coeffs[0] / 2.0));
      return xy_d * (r / rd);
    }
  }
  return xy_d;
}

Eigen::Vector2d CameraModel::project(const Eigen::Vector3d& p_C) const {
  const Eigen::Vector2d d = distort(p_C.head<2>() / p_C.z());
  return {fx * d.x() + cx, fy * d.y() + cy};
}

}  // namespace roe::image
