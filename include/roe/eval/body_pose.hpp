#pragma once
/// @file
/// The pose of the estimate's body (the IMU, I) in the ground truth's body (a mocap marker body, B):
/// T_W_I = T_W_B · T_B_I. Given (`roe eval --gt-body-pose`) it is applied to every ground-truth pose;
/// fitted (`--fit-body-pose`, a hand–eye calibration against the evaluated pairs) it is estimated
/// jointly with the alignment, I/O-free. Only rotation of the body makes a lever arm observable: a lever
/// arm along an axis the body never turns about is a constant offset that the alignment's translation
/// absorbs.

#include <cstddef>
#include <string>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/eval/align.hpp"

namespace roe::eval {

/// Below this rotation spread (degrees, about an axis perpendicular to a lever-arm direction) that
/// direction of the lever arm is unobservable: it is set to 0 and the verdict says so.
inline constexpr double kMinBodyRotationSpreadDeg = 2.0;

struct BodyPoseFit {
  Pose T_B_I;                                           ///< the fitted body pose (ground truth body → estimate body)
  Eigen::Vector3d sigma_p_m = Eigen::Vector3d::Zero();  ///< 1σ of T_B_I.p per axis of B (0 where unobservable)
  double sigma_rot_deg = 0.0;                           ///< 1σ of the rotation (per axis, isotropic)
  /// The ground truth body's rotation spread, smallest and largest over directions (deg): the square root
  /// of the eigenvalues of I − R̄ᵀR̄, R̄ the mean rotation matrix of the ground-truth poses.
  double rotation_spread_min_deg = 0.0, rotation_spread_max_deg = 0.0;
  int lever_arm_rank = 0;  ///< observable directions of the lever arm (3: all)
  /// "observable", "partly unobservable: ...", or "unobservable: ..." (the lever arm is then 0).
  std::string verdict;
  int iterations = 0;
  std::size_t n_pairs = 0;
};

/// Fits T_B_I from matched pairs est[est_index[k]] (T_W'_I) ↔ gt[gt_index[k]] (T_W_B), alternating the
/// alignment of `type` (se3, sim3 or posyaw; InputError for others: the fit needs a fitted world) on
/// positions (p_gt + R_gt t_BI) with the least-squares lever arm jointly with the alignment's translation
/// given its rotation, and the rotation R_BI = mean on SO(3) of R_gtᵀ·R·R_est. σ from the residuals, with
/// their autocorrelation (effective_sample_fraction). DataError for fewer than 10 pairs.
BodyPoseFit fit_body_pose(const std::vector<Pose>& est, const std::vector<std::size_t>& est_index,
                          const std::vector<Pose>& gt, const std::vector<std::size_t>& gt_index, AlignType type,
                          int n_align = -1);

/// "x,y,z,qx,qy,qz,qw" (metres; the quaternion is normalised, |‖q‖ − 1| ≤ 0.05) as a pose; InputError at
/// key path `key` otherwise.
Pose parse_pose_text(const std::string& text, const std::string& key);

}  // namespace roe::eval
