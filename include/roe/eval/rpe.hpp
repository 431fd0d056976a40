#pragma once
/// @file
/// Relative pose error (RPE): the drift of an estimate over a distance, a time, a number of poses or a
/// rotation, independent of the global alignment (docs/eval.md §RPE; evo's `evo_rpe`).
///
/// Input: matched pose pairs in association order (estimate P_k, ground truth Q_k, k = 0..n−1; the
/// estimate already aligned, which matters only for a Sim(3) scale). Index pairs (i, j), i < j, are
/// chosen on ONE of the two trajectories (`pairs_from`: the estimate by default, as evo; or the
/// ground truth, evo --pairs_from_reference). Per pair the error pose is
///     E_ij = (Q_i⁻¹ Q_j)⁻¹ (P_i⁻¹ P_j)
/// and the pair reports |trans(E_ij)| (m) and the angle |Log(rot(E_ij))| (deg), evo's translation_part
/// and rotation_angle_deg. Also: the ground truth's path length over the pair, and the translation
/// error in % of it (the KITTI / rpg drift figure), for pairs whose ground-truth path is > 0.
///
/// Pair selection (the same rules as evo v1.36, so that its numbers are reproduced; `tol` = rel_tol·delta):
///   frames,  consecutive: ids 0, δ, 2δ, …; pairs of neighbouring ids.
///   frames,  all pairs:   (i, i+δ) for every i.
///   meters,  consecutive: walk the path from the first pose, take an id each time the distance walked
///                         since the last id (or the start) reaches δ; pairs of neighbouring ids (so
///                         the first pair starts at the first id, not at pose 0).
///   meters,  all pairs:   for every i, the first j > i whose path distance from i is closest to δ,
///                         kept when it is within tol of δ.
///   degrees/radians, consecutive: accumulate the angles between neighbouring poses from a start id;
///                         when the sum reaches δ, emit (start, current) and start again there.
///   degrees/radians, all pairs:   every (i, j > i) whose direct angle |Log(R_iᵀ R_j)| is within tol of δ.
///   seconds (roe; evo has no time unit), on the chosen trajectory's stamps:
///                         consecutive: ids 0, then each first pose at least δ after the previous id;
///                         all pairs: for every i, the first j > i whose time from i is closest to δ,
///                         kept when within tol of δ.

#include <cstddef>
#include <string>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/eval/metrics.hpp"

namespace roe::eval {

enum class DeltaUnit { kFrames, kMeters, kSeconds, kDegrees, kRadians };
/// "f", "m", "s", "deg", "rad".
std::string to_string(DeltaUnit u);
/// Accepts f|frames, m|meters|metres, s|seconds, deg|degrees, rad|radians; InputError otherwise.
DeltaUnit parse_delta_unit(const std::string& name);

enum class PairsFrom { kEstimate, kGroundTruth };
/// "est", "gt".
std::string to_string(PairsFrom p);
/// Accepts est|estimate, gt|groundtruth|reference; InputError otherwise.
PairsFrom parse_pairs_from(const std::string& name);

struct RpeOptions {
  double delta = 1.0;                      ///< > 0; an integer for frames; ≤ 180° (π rad) for angles
  DeltaUnit unit = DeltaUnit::kFrames;
  bool all_pairs = false;                  ///< all pairs instead of consecutive ones
  PairsFrom pairs_from = PairsFrom::kEstimate;
  double rel_tol = 0.1;                    ///< all-pairs tolerance, relative to delta (evo's rel_delta_tol)
};

/// Throws InputError naming the problem when `o` is not usable (delta ≤ 0 or not finite, a fractional
/// number of frames, an angle beyond 180° / π, a negative or non-finite tolerance).
void check_rpe_options(const RpeOptions& o);

/// The index pairs (i, j) that the rules above select on `poses` (with their `t_ns`, used for
/// seconds). Empty when none qualifies (e.g. δ longer than the trajectory).
std::vector<std::pair<std::size_t, std::size_t>> rpe_index_pairs(const std::vector<Pose>& poses,
                                                                 const std::vector<Timestamp>& t_ns,
                                                                 const RpeOptions& o);

struct RpePair {
  std::size_t i = 0, j = 0;     ///< indices into the matched pairs
  Eigen::Vector3d dp = Eigen::Vector3d::Zero();  ///< trans(E_ij) (m), in the frame of Q_j
  double trans_m = 0.0;         ///< |trans(E_ij)|
  double rot_deg = 0.0;         ///< |Log(rot(E_ij))|
  double path_gt_m = 0.0;       ///< ground-truth path length from i to j
  double trans_pct = 0.0;       ///< 100 · trans_m / path_gt_m (NaN when path_gt_m is 0)
};

struct RpeResult {
  RpeOptions options;
  std::vector<RpePair> pairs;
  Stats trans_m;    ///< of |trans(E)|
  Stats rot_deg;    ///< of the angle of E
  Stats trans_pct;  ///< of the drift in %, over pairs with a ground-truth path > 0
};

/// RPE of matched pairs (`est` aligned, `gt`, `t_est`/`t_gt` their stamps; all the same size,
/// InputError otherwise). An empty `pairs` (with zero stats) when no index pair qualifies.
RpeResult compute_rpe(const std::vector<Pose>& est, const std::vector<Pose>& gt,
                      const std::vector<Timestamp>& t_est, const std::vector<Timestamp>& t_gt,
                      const RpeOptions& o);

}  // namespace roe::eval
