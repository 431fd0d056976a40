#pragma once
/// @file
/// SO(3) utilities: the one place where roe's rotation convention is defined.
///
/// Convention (DESIGN §2, used everywhere in roe):
///  - Quaternions are Hamilton (Eigen::Quaterniond), unit norm: q ⊗ p is the usual Hamilton
///    product and R(q1 ⊗ q2) = R(q1) R(q2). In roe's own files they are stored x, y, z, w.
///  - R_A_B maps coordinates in B into A: x_A = R_A_B x_B.
///  - The error state of a rotation is local (right): R = R̂ · Exp(δθ), q = q̂ ⊗ Exp_q(δθ).
///  - Exp/Log are the exponential and logarithm maps between so(3) vectors (axis · angle, rad) and
///    rotations; Jr/Jl are the right/left Jacobians: Exp(φ + δ) ≈ Exp(φ) Exp(Jr(φ) δ) and
///    Exp(φ + δ) ≈ Exp(Jl(φ) δ) Exp(φ).
/// Small angles (|φ| < kSmallAngle) use Taylor series; Log is computed from the quaternion with
/// the scalar part made non-negative, which stays accurate up to and at θ = π.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace roe::math {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

/// Below this angle (rad), Exp/Log/Jacobians switch to their Taylor expansions.
inline constexpr double kSmallAngle = 1e-6;

/// [v]x: skew(v) * w = v × w.
Matrix3d skew(const Vector3d& v);
/// Inverse of skew for a skew-symmetric matrix (uses the antisymmetric part).
Vector3d vee(const Matrix3d& m);

/// Rotation matrix Exp(φ) (Rodrigues).
Matrix3d exp_so3(const Vector3d& phi);
/// Unit quaternion Exp(φ) = [cos(θ/2), sin(θ/2) φ/θ].
Quaterniond exp_quat(const Vector3d& phi);
/// Log of a rotation matrix; the result has norm in [0, π].
Vector3d log_so3(const Matrix3d& R);
/// Log of a (not necessarily normalised) quaternion; the result has norm in [0, π].
Vector3d log_quat(const Quaterniond& q);

/// Right Jacobian Jr(φ) and its inverse.
Matrix3d right_jacobian(const Vector3d& phi);
Matrix3d right_jacobian_inv(const Vector3d& phi);
/// Left Jacobian Jl(φ) = Jr(−φ) and its inverse.
Matrix3d left_jacobian(const Vector3d& phi);
Matrix3d left_jacobian_inv(const Vector3d& phi);

/// Rotation angle (rad, in [0, π]) between two rotations: |Log(R_a^T R_b)|.
double angle_between(const Quaterniond& a, const Quaterniond& b);

/// The paper's/MaRS's orientation residual: with δq = q_hat⁻¹ ⊗ q_meas, returns 2 δq_v / δq_w
/// (= 2 tan(θ/2) · axis; equals Log(δq) to first order). Sign-invariant in δq.
Vector3d quat_residual(const Quaterniond& q_hat, const Quaterniond& q_meas);

/// Projects a 3x3 matrix to the nearest rotation (SVD), det = +1.
Matrix3d orthonormalize(const Matrix3d& M);

/// Returns q with w >= 0 (the same rotation).
Quaterniond canonical(const Quaterniond& q);

}  // namespace roe::math
