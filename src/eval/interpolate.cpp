#include "roe/eval/interpolate.hpp"

#include "roe/math/se3.hpp"

#include <algorithm>
#include <limits>

namespace roe::eval {

std::optional<Pose> interpolate_pose_at(const std::vector<StampedPose>& poses, Timestamp t_ns,
                                        Timestamp max_gap_ns) {
  if (poses.empty() || t_ns < poses.front().t_ns || t_ns > poses.back().t_ns) return std::nullopt;
  // First sample with stamp >= t.
  const auto it = std::lower_bound(poses.begin(), poses.end(), t_ns,
                                   [](const StampedPose& s, Timestamp t) { return s.t_ns < t; });
  if (it->t_ns == t_ns) return it->T;
  const StampedPose& b = *it;
  const StampedPose& a = *(it - 1);  // exists: t > front().t_ns here
  const Timestamp span = b.t_ns - a.t_ns;
  if (span > max_gap_ns) return std::nullopt;
  const double alpha = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(span);
  return math::interpolate(a.T, b.T, alpha);
}

std::optional<Pose> interpolate_pose_at(const std::vector<StampedPose>& poses, Timestamp t_ns) {
  return interpolate_pose_at(poses, t_ns, std::numeric_limits<Timestamp>::max());
}

}  // namespace roe::eval
