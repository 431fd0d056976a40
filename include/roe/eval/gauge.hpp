#pragma once
/// @file
/// The truth in an estimator's own gauge (docs/eval.md "Consistency"). An object-relative filter fixes
/// the unobservable directions of its world W by holding parts of the main (anchor) object's
/// object-world pose T_O_W at their first estimate; its covariance is relative to that choice. The
/// true world W_t of a simulation (gravity along z) and the estimator's world W_g differ by a
/// constant T_Wt_Wg that the anchor's estimate and its true pose determine exactly, with no fit to
/// the trajectory: the NEES against T_Wg_Wt · T_Wt_I_true has no alignment error in it, so a
/// consistent filter reads ≈ 3 per 3-dof block. (An alignment fitted on the positions instead has a
/// rotation error of its own that is in no covariance: docs/eval.md.)

#include <string>

#include "roe/core/types.hpp"

namespace roe::eval {

/// The gauges that fix W completely with the anchor (the names of roe run's filter.anchor_gauge).
/// kPose: the anchor's T_O_W held in all 6 dof. kPositionYaw: its position and its rotation about
/// gravity held, W gravity-aligned (roe's default). (The paper's "position" leaves W's yaw to the initial
/// prior: no exact truth in that gauge, and none is made up.)
enum class GaugeKind { kPose, kPositionYaw };
/// "pose", "position_yaw".
std::string to_string(GaugeKind g);

/// T_Wt_Wg: the estimator's world in the true world, from the anchor's estimated T_O_W (its held
/// components) and its true pose T_Wt_O. kPose: T_Wt_O · T_O_W_est. kPositionYaw: the rotation
/// Rz(ψ) about the true world's z axis such that the anchor's true T_O_Wg = T_O_Wt · T_Wt_Wg has no
/// yaw error against the estimate (z component of Log(R̂_O_Wᵀ R_O_Wg) = 0, Newton steps to 1e-13 rad),
/// and the translation that makes its position p_O_Wg equal the estimate's.
Pose estimator_gauge(GaugeKind kind, const Pose& T_O_W_est, const Pose& T_Wt_O_true);

}  // namespace roe::eval
