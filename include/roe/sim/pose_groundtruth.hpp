#pragma once
/// @file
/// Ground truth that is a pose only (EuRoC vicon0 / TUM-VI mocap0 layout, TUM trajectories) made into the
/// IMU states `roe simulate --from-groundtruth` keeps: the velocity from the poses, the biases unknown
/// (docs/simulator.md §9, "Pose-only ground truth").

#include <vector>

#include "roe/core/types.hpp"

namespace roe::sim {

/// How the velocity is taken from the poses.
struct VelocityFromPosesConfig {
  /// v(t_k) is the slope at t_k of the least-squares quadratic through the positions within ± this time
  /// of t_k (at least 3; else the two neighbours' difference). 0.05 s: 13 samples at 120 Hz (TUM-VI mocap).
  double half_window_s = 0.05;
};

/// IMU states at the poses' stamps (sorted, strictly increasing): T_W_I = the pose, v_W_I from the
/// positions (VelocityFromPosesConfig), b_g = b_a = 0 (unknown). Throws DataError for fewer than 2 poses.
std::vector<ImuState> states_from_poses(const std::vector<StampedPose>& poses,
                                        const VelocityFromPosesConfig& config = {});

}  // namespace roe::sim
