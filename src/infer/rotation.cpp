#include "roe/infer/rotation.hpp"

#include <Eigen/Geometry>
#include <cmath>

#include "roe/math/so3.hpp"

namespace roe::infer {

std::optional<RotationFormat> parse_rotation_format(const std::string& s) {
  if (s == "6d") return RotationFormat::k6d;
  if (s == "quat_wxyz") return RotationFormat::kQuatWxyz;
  if (s == "matrix") return RotationFormat::kMatrix;
  return std::nullopt;
}

int rotation_size(RotationFormat f) {
  switch (f) {
    case RotationFormat::k6d: return 6;
    case RotationFormat::kQuatWxyz: return 4;
    case RotationFormat::kMatrix: return 9;
  }
  return 0;
}

const char* rotation_format_name(RotationFormat f) {
  switch (f) {
    case RotationFormat::k6d: return "6d";
    case RotationFormat::kQuatWxyz: return "quat_wxyz";
    case RotationFormat::kMatrix: return "matrix";
  }
  return "?";
}

std::optional<Eigen::Matrix3d> rotation_from_6d(const double* r) {
  const Eigen::Vector3d a(r[0], r[1], r[2]);
  const Eigen::Vector3d b(r[3], r[4], r[5]);
  if (!a.allFinite() || !b.allFinite()) return std::nullopt;
  const double na = a.norm();
  if (na < 1e-12) return std::nullopt;
  const Eigen::Vector3d x = a / na;
  const Eigen::Vector3d zc = x.cross(b);
  const double nz = zc.norm();
  // b (almost) parallel to a: the second column is undefined.
  if (nz < 1e-9 * std::max(1.0, b.norm())) return std::nullopt;
  const Eigen::Vector3d z = zc / nz;
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R.col(0) = x;
  R.col(1) = y;
  R.col(2) = z;
  return R;
}

std::optional<Eigen::Matrix3d> rotation_from_quat_wxyz(const double* q) {
  Eigen::Quaterniond qq(q[0], q[1], q[2], q[3]);
  if (!qq.coeffs().allFinite() || qq.norm() < 1e-12) return std::nullopt;
  return qq.normalized().toRotationMatrix();
}

std::optional<Eigen::Matrix3d> rotation_from_matrix(const double* m) {
  Eigen::Matrix3d M;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) M(r, c) = m[3 * r + c];
  if (!M.allFinite() || M.norm() < 1e-12) return std::nullopt;
  const Eigen::Matrix3d R = math::orthonormalize(M);
  if (!R.allFinite()) return std::nullopt;
  return R;
}

std::optional<Eigen::Matrix3d> rotation_from_output(RotationFormat f, const double* values) {
  switch (f) {
    case RotationFormat::k6d: return rotation_from_6d(values);
    case RotationFormat::kQuatWxyz: return rotation_from_quat_wxyz(values);
    case RotationFormat::kMatrix: return rotation_from_matrix(values);
  }
  return std::nullopt;
}

}  // namespace roe::infer
