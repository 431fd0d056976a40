#pragma once
/// @file
/// PoET's rotation outputs → proper rotation matrices R_C_O (x_C = R x_O + t).
///  - "6d" (PoET's default, Zhou et al. CVPR 2019): two 3-vectors a = r[0:3], b = r[3:6] are the
///    first two columns before Gram-Schmidt: x = a/|a|, z = (x × b)/|x × b|, y = z × x, R = [x y z].
///  - "quat_wxyz": a Hamilton quaternion w, x, y, z (PoET's quat/silho_quat models), normalised.
///  - "matrix": 9 values, row-major; projected to the nearest rotation (SVD).
/// Degenerate inputs (zero or parallel vectors, zero quaternion, non-finite values) give nullopt.

#include <Eigen/Core>
#include <optional>
#include <string>

namespace roe::infer {

enum class RotationFormat { k6d, kQuatWxyz, kMatrix };

/// "6d", "quat_wxyz" or "matrix"; nullopt otherwise.
std::optional<RotationFormat> parse_rotation_format(const std::string& s);
/// Values per query: 6, 4 or 9.
int rotation_size(RotationFormat f);
const char* rotation_format_name(RotationFormat f);

std::optional<Eigen::Matrix3d> rotation_from_6d(const double* r);
std::optional<Eigen::Matrix3d> rotation_from_quat_wxyz(const double* q);
std::optional<Eigen::Matrix3d> rotation_from_matrix(const double* m);
std::optional<Eigen::Matrix3d> rotation_from_output(RotationFormat f, const double* values);

}  // namespace roe::infer
