#pragma once
/// @file
/// Pose interpolation at a timestamp within a time-sorted sequence (ground truth, mocap, estimates).

#include <optional>
#include <vector>

#include "roe/core/types.hpp"

namespace roe::eval {

/// The pose of `poses` (sorted by strictly increasing t_ns) at time `t_ns`: a stamp equal to a
/// sample returns that sample's pose exactly; a stamp between two samples interpolates them with
/// math::interpolate (slerp along the shortest arc + linear translation) at
/// alpha = (t − t_a) / (t_b − t_a), computed in integer nanoseconds before the division.
/// Returns std::nullopt outside [front().t_ns, back().t_ns] (no extrapolation) and for an empty
/// sequence. O(log n) (binary search).
std::optional<Pose> interpolate_pose_at(const std::vector<StampedPose>& poses, Timestamp t_ns);

/// As above, but also refuses (nullopt) when the two bracketing samples are more than `max_gap_ns`
/// apart, so gaps in a recording (mocap dropouts) are not bridged by a long slerp.
std::optional<Pose> interpolate_pose_at(const std::vector<StampedPose>& poses, Timestamp t_ns,
                                        Timestamp max_gap_ns);

}  // namespace roe::eval
