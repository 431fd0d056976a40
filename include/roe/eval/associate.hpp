#pragma once
/// @file
/// Time-stamp association of an estimate with ground truth (notes/eval.md §1, §4).
///
/// Policy kNearest (default) is evo's rule (evo.core.sync.matching_time_indices): for every stamp of
/// the SHORTER of the two trajectories (on equal length: the estimate), take the nearest stamp of
/// the longer one (on equal distance the earlier one) and accept the pair when |dt| ≤ max_dt. Poses
/// of the longer trajectory may be used more than once. The estimate stamps are shifted by
/// `offset` first (t_est + offset, evo --t_offset). Pairs come in the order of the shorter one.
/// Duplicated ground-truth stamps: only the first pose of each run of equal stamps is ever paired,
/// whichever trajectory is the shorter (evo pairs every pose of a shorter ground truth; a duplicated
/// mocap row is a recording fault, not a second truth). Duplicated estimate stamps are all kept
/// under kNearest (evo).
///
/// Policy kUnique is one-to-one: the kNearest pairs, then every pose of either trajectory is used at
/// most once, and so is every stamp value: among pairs that share a pose or a stamp value, the one
/// with the smallest |dt| is kept (on equal |dt| the first). With duplicated stamps (several poses at
/// one time, e.g. evo's V1_02 test estimate) this keeps the first pose of each duplicate, as cnspy does;
/// kNearest keeps all of them, as evo does.
///
/// All arithmetic is on int64 nanoseconds, so stamps that are equal in the files stay equal.

#include <cstddef>
#include <string>
#include <vector>

#include "roe/core/types.hpp"

namespace roe::eval {

/// kInterpolate (evo #439): evaluate() resamples the ground truth at every estimate stamp (+ offset) by
/// interpolation (eval/interpolate.hpp; not across ground-truth gaps over 3 median periods) and pairs each
/// estimate pose with its own resampled truth; associate() itself treats it as kNearest.
enum class AssocPolicy { kNearest, kUnique, kInterpolate };
/// "nearest", "unique", "interpolate".
std::string to_string(AssocPolicy p);
/// InputError for an unknown name.
AssocPolicy parse_assoc_policy(const std::string& name);

struct AssociationOptions {
  double max_dt_s = 0.01;  ///< accept |t_gt − (t_est + offset)| ≤ max_dt (evo --t_max_diff)
  double offset_s = 0.0;   ///< added to every estimate stamp (evo --t_offset)
  AssocPolicy policy = AssocPolicy::kNearest;
};

struct Association {
  std::vector<std::size_t> est_index;  ///< index into the estimate stamps, one per pair
  std::vector<std::size_t> gt_index;   ///< index into the ground-truth stamps
  std::vector<Timestamp> dt_ns;        ///< t_gt − (t_est + offset), per pair
  std::size_t n_duplicate_est = 0;     ///< estimate stamps equal to their predecessor
  std::size_t n_duplicate_gt = 0;      ///< ground-truth stamps equal to their predecessor
  std::size_t n_dropped_unique = 0;    ///< pairs removed by kUnique
  std::size_t size() const { return est_index.size(); }
};

/// Associates two non-decreasing stamp sequences (InputError when either decreases, naming the
/// index; InputError for a negative or non-finite max_dt). An empty result is returned as is; call
/// explain_no_match() for a message.
Association associate(const std::vector<Timestamp>& t_est, const std::vector<Timestamp>& t_gt,
                      const AssociationOptions& options = {});

/// The time span both trajectories cover and how many poses of each lie in it: the most pairs an
/// association can be expected to find is n_max() (the sparser stream inside the overlap), not the
/// size of the shorter trajectory (a ground truth that covers a longer session than the estimate is
/// not a matching problem). Estimate stamps are shifted by the offset; the span is widened by max_dt
/// on both sides. Empty (begin > end, counts 0) when the ranges do not overlap.
struct Overlap {
  Timestamp begin_ns = 0;  ///< max(first stamps) − max_dt
  Timestamp end_ns = -1;   ///< min(last stamps) + max_dt
  std::size_t n_est = 0;   ///< estimate poses in [begin, end] (shifted stamps)
  std::size_t n_gt = 0;    ///< ground-truth poses in [begin, end]
  std::size_t n_max() const { return n_est < n_gt ? n_est : n_gt; }
};
/// InputError for decreasing stamps or bad options, as associate().
Overlap overlap(const std::vector<Timestamp>& t_est, const std::vector<Timestamp>& t_gt,
                const AssociationOptions& options = {});

/// A message for an association that found no pair: both stamp ranges (in seconds), the closest
/// distance found, and the likely cause: units mixed up (ranges differ by ~1e3/1e6/1e9, e.g. ns read
/// as s; only when the scaled spans are comparable too), relative vs absolute time (one starts within
/// a day of 0, the other at an epoch time: the --t-offset that aligns the starts, and for a ground
/// truth in relative time `roe import mocap --time-offset/--estimate-offset`), or a max_dt
/// smaller than the stamp spacing.
std::string explain_no_match(const std::vector<Timestamp>& t_est, const std::vector<Timestamp>& t_gt,
                             const AssociationOptions& options);

}  // namespace roe::eval
