#pragma once
/// @file
/// Trajectory alignment for evaluation: Umeyama SE(3)/Sim(3), position + yaw, first-pose ("origin")
/// and none. An alignment maps estimate coordinates into the ground-truth world:
///   p' = s · R · p + t,   R'_est = R · R_est   (orientation is rotated, never scaled),
/// which is how evo, rpg_trajectory_evaluation, ov_eval and cnspy apply it (notes/eval.md §3).
///
/// Umeyama (S. Umeyama, "Least-squares estimation of transformation parameters between two point
/// patterns", IEEE TPAMI 13(4), 1991), with x_i the estimate positions and y_i the ground truth:
///   μx, μy = means,  Σxy = (1/n) Σ (y_i − μy)(x_i − μx)^T,  σx² = (1/n) Σ |x_i − μx|²,
///   Σxy = U D V^T (SVD),  S = diag(1, 1, det(U)·det(V) < 0 ? −1 : 1)   (reflection guard),
///   R = U S V^T,  s = tr(D S) / σx² (Sim(3); 1 for SE(3)),  t = μy − s R μx.
/// Only positions enter; orientations take no part (as in every public evaluator).
/// Degenerate input (rank(Σxy) < 2: all points equal, or all on one line) leaves the rotation
/// undetermined; instead of returning an arbitrary rotation (as rpg/cnspy/ov_eval silently do) roe
/// throws DegenerateAlignmentError, as evo does.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "roe/core/error.hpp"
#include "roe/core/types.hpp"

namespace roe::eval {

/// Alignment method (`roe eval --align`).
enum class AlignType {
  kSe3,     ///< Umeyama, rotation + translation (evo -a)
  kSim3,    ///< Umeyama, rotation + translation + scale (evo -as)
  kPosYaw,  ///< rotation about the world z axis (gravity) + translation (rpg/ov_eval "posyaw")
  kOrigin,  ///< first pose of the estimate onto the first ground-truth pose (evo --align_origin)
  kNone,    ///< identity
};

/// "se3", "sim3", "posyaw", "origin", "none".
std::string to_string(AlignType type);
/// Parses the names of to_string; roe::InputError listing the valid names otherwise.
AlignType parse_align_type(const std::string& name);

/// Thrown when the data cannot determine the requested alignment (too few pairs, all positions
/// equal, collinear positions for SE(3)/Sim(3), no horizontal motion for posyaw). The run fails
/// because of the data: exit code 1 in the CLI.
class DegenerateAlignmentError : public DataError {
 public:
  using DataError::DataError;
};

/// The similarity p' = s R p + t (s = 1 except for Sim(3)).
struct Alignment {
  AlignType type = AlignType::kNone;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  double s = 1.0;
  int n_used = 0;  ///< number of pairs the alignment was computed from

  /// s R p + t.
  Eigen::Vector3d apply(const Eigen::Vector3d& p) const { return s * (R * p) + t; }
  /// The aligned pose: position s R p + t, orientation R · R_est (scale does not touch rotation).
  Pose apply(const Pose& T) const;
  /// R as a unit quaternion.
  Eigen::Quaterniond q() const;
};

/// The pose T aligned by `a` as apply_alignment does it: position s R p + t, orientation qa · q
/// re-normalised, with qa = a.q().
Pose aligned_pose(const Alignment& a, const Eigen::Quaterniond& qa, const Pose& T);
/// The alignment's tilt: the angle between the world z axis and R·z (deg), 0 for a rotation about z alone.
double alignment_tilt_deg(const Alignment& a);

/// Applies an alignment to every pose (in place).
void apply_alignment(const Alignment& a, std::vector<Pose>& poses);
void apply_alignment(const Alignment& a, std::vector<StampedPose>& poses);

/// Relative tolerance of the rank test: Σxy is taken as rank-deficient when its second singular
/// value is ≤ kRankTolerance · (largest singular value), or when the largest is exactly 0.
/// (evo counts singular values above machine epsilon in absolute terms; a relative test makes the
/// decision independent of the unit of the positions.)
inline constexpr double kRankTolerance = 1e-12;

/// Umeyama alignment of estimate positions `est` (3×n) onto `gt` (3×n); columns are pairs.
/// n ≥ 3 non-collinear points are needed; otherwise DegenerateAlignmentError.
/// Throws roe::InputError when the sizes differ.
Alignment umeyama_alignment(const Eigen::Ref<const Eigen::Matrix3Xd>& est,
                            const Eigen::Ref<const Eigen::Matrix3Xd>& gt, bool with_scale);

/// Best rotation about z + translation (no scale) mapping `est` onto `gt` in least squares:
/// with C = Σ (x_i − μx)(y_i − μy)^T, yaw = atan2(C01 − C10, C00 + C11) maximises tr(Rz(yaw) C),
/// t = μy − Rz μx. Needs horizontal spread (DegenerateAlignmentError otherwise).
Alignment align_pos_yaw(const Eigen::Ref<const Eigen::Matrix3Xd>& est,
                        const Eigen::Ref<const Eigen::Matrix3Xd>& gt);

/// Single-pose variants. se3: R = R_gt · R_estᵀ, t = p_gt − R p_est (evo --align_origin).
Alignment align_origin(const Pose& est0, const Pose& gt0);
/// posyaw from one pose pair: the yaw that best matches Rz · R_est to R_gt
/// (maximises tr(Rzᵀ R_gt R_estᵀ)), t = p_gt − Rz p_est.
Alignment align_pos_yaw_single(const Pose& est0, const Pose& gt0);

/// The alignment of `type` from matched pose pairs (est[i] ↔ gt[i]), using the first `n_align`
/// pairs (n_align ≤ 0 or ≥ size: all). origin always uses the first pair; posyaw with n_align = 1
/// uses the single-pose variant; se3/sim3 need n_align ≥ 3 (InputError for 1 or 2, which can never
/// determine a rotation, with a hint to use origin). Throws DegenerateAlignmentError as above, and
/// InputError when the vectors differ in size or are empty (except for kNone).
Alignment compute_alignment(AlignType type, const std::vector<Pose>& est, const std::vector<Pose>& gt,
                            int n_align = -1);
/// The same for the pairs est[est_index[k]] ↔ gt[gt_index[k]] (an association's indices), without a
/// copy of the matched poses; their positions are gathered on up to `threads` threads (0: every CPU
/// the process may use). The result is the same as for the copied pairs, bit for bit.
Alignment compute_alignment(AlignType type, const std::vector<Pose>& est, const std::vector<std::size_t>& est_index,
                            const std::vector<Pose>& gt, const std::vector<std::size_t>& gt_index, int n_align = -1,
                            unsigned threads = 0);

}  // namespace roe::eval
