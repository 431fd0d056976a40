#pragma once
/// @file
/// Symmetric objects in the measurement model (core/symmetry.hpp for the definitions). I/O-free.
///
/// Equivalent measurements: a detection T_C_O of a symmetric object is as good as T_C_O · S for every
/// S ∈ {I} ∪ discrete (and, with a continuous symmetry, T_C_O · S(ψ) for every ψ). In the filter's
/// measurement z = T_O_C that is z' = S⁻¹ z (S(ψ)⁻¹ = S(−ψ)).
///
/// Discrete: the residual uses the equivalent measurement nearest the prediction ẑ, nearest by the
/// rotation angle |Log(R̂_O_Cᵀ R'_O_C)| (ties: the first in the file's order, identity first).
///
/// Continuous (axis a, offset o): every candidate is first turned about the axis to the angle χ* that
/// brings its rotation nearest ẑ's, z' = S(χ*) z with
///   χ* = atan2(tr([a]× M), tr M − aᵀ M a),   M = R_O_C R̂_O_Cᵀ
/// (tr(R̂ᵀ Exp(χa) R) = cos χ (tr M − aᵀMa) + sin χ tr([a]×M) + aᵀMa). The rotation about the axis is then
/// unobservable: to first order the equivalent measurements move the residual along
///   camera frame (t, left error of R_C_O):    d = [R_C_O (o × a) ; R_C_O a]
///   object frame (p_O_C, right error of R_O_C): d = [a × (p_O_C − o) ; R_C_O a]
/// (evaluated at the prediction). The residual, H and R are reduced by a 5x6 A with A d = 0 and
/// orthonormal rows: r' = A r, H' = A H, R' = A R Aᵀ (5 dof; the update and the NIS do not depend on which
/// such A, they are invariant under A ← G A for an invertible G). When d has no position part (camera
/// frame with the offset on the axis through the model origin, the BOP case o = 0), A = [I₃ 0; 0 B] with
/// B (2x3) orthonormal ⟂ R_C_O a: the position rows stay as they are and the rotation residual is projected
/// onto the plane ⟂ the axis (2 rows), so the split gate tests 3 + 2 dof. Otherwise (object frame, or an
/// offset off that axis) the position and rotation rows mix and the split gate tests the 5 rows jointly.

#include <Eigen/Core>

#include "roe/core/symmetry.hpp"
#include "roe/ekf/measurement.hpp"
#include "roe/ekf/options.hpp"

namespace roe::ekf {

using Mat56 = Eigen::Matrix<double, 5, 6>;

/// The symmetry-equivalent z' of the measurement z = T_O_C nearest the prediction (above).
Pose nearest_equivalent(const Pose& T_O_C_hat, const Pose& T_O_C_meas, const ObjectSymmetry& sym);

/// d = ∂r/∂ψ of the residual under the continuous symmetry, at the prediction (above; 6-vector in the
/// residual frame's [position; rotation]).
Vec6 symmetry_direction(ResidualFrame frame, const Pose& T_O_C_hat, const ContinuousSymmetry& c);

/// A (5x6, orthonormal rows, A d = 0); the block form [I₃ 0; 0 B] when d's position part vanishes
/// (`separable` true), else the orthonormal complement of d in R⁶ (`separable` false).
Mat56 symmetry_reduction(const Vec6& d, bool& separable);

}  // namespace roe::ekf
