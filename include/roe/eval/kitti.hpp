#pragma once
/// @file
/// The KITTI odometry benchmark's drift figures (the devkit's evaluate_odometry rule), I/O-free: for every
/// 10th pose i as a start and each length L in 100, 200, …, 800 m, the first pose j whose ground-truth path
/// length from the first pose exceeds that of i by more than L; the error pose E = (P_i⁻¹P_j)⁻¹(Q_i⁻¹Q_j)
/// (P estimate, Q ground truth); t_err = |trans(E)| / L, r_err = angle(E) / L (the devkit's
/// acos(max(min((tr R − 1)/2, 1), −1))). t_rel = 100 · mean t_err over every segment (%), r_rel =
/// mean r_err in deg per 100 m. Invariant to an SE(3) alignment of the estimate (a Sim(3) scale changes it).

#include <array>
#include <cstddef>
#include <vector>

#include "roe/core/types.hpp"

namespace roe::eval {

inline constexpr std::array<double, 8> kKittiLengthsM = {100, 200, 300, 400, 500, 600, 700, 800};
inline constexpr std::size_t kKittiStepFrames = 10;

struct KittiLength {
  double length_m = 0.0;
  std::size_t n_segments = 0;
  double t_rel_pct = 0.0, r_rel_deg_per_100m = 0.0;  ///< nan without a segment
};

struct KittiDrift {
  std::size_t n_segments = 0;
  double t_rel_pct = 0.0;           ///< nan without a segment (a path shorter than 100 m)
  double r_rel_deg_per_100m = 0.0;  ///< nan without a segment
  std::vector<KittiLength> per_length;
};

/// The devkit's figures for matched poses est[k] ↔ gt[k] in order (frames). Sizes must agree.
KittiDrift kitti_drift(const std::vector<Pose>& est, const std::vector<Pose>& gt);

}  // namespace roe::eval
