#pragma once
/// @file
/// The clock offset between a motion-capture track and the IMU, from the shape of their angular rates
/// (`roe import mocap --estimate-offset`, docs/import.md). I/O-free. The camera–IMU offset from
/// detections is calib/time_offset.hpp: another signal (object rotations, not a mocap body's rate).

#include <cstddef>
#include <vector>

#include "roe/core/types.hpp"

namespace roe::calib {

/// The mocap clock against the IMU clock (`roe import mocap --estimate-offset`).
struct MocapOffsetEstimate {
  double offset_s = 0.0;      ///< t_imu = t_mocap + offset_s
  double correlation = 0.0;   ///< normalised cross-correlation at the peak (quality, 1 = perfect)
  double peak_ratio = 0.0;    ///< peak / best value outside ±0.25 s of the peak (>1: distinct)
  std::size_t samples = 0;    ///< overlapping grid samples used at the peak
  double grid_dt_s = 0.0;
  /// The peak is the first or last lag searched: the true offset may lie beyond ±max_offset_s.
  bool peak_at_edge = false;
};

/// Estimates the clock offset between an IMU and a mocap track by correlating the gyro's
/// angular-rate magnitude with the magnitude of the mocap's body angular rate
/// (|Log(R_k^T R_{k+1})| / dt), both resampled on a common grid of `grid_dt_s` (0 = the mocap's
/// median period, at most 1/200 s). The coarse peak over [-max, max] is refined by a parabola
/// through the three best lags. Result: t_imu = t_mocap + offset. DataError when the overlap is too
/// short or the motion has no rotation.
MocapOffsetEstimate estimate_mocap_time_offset(const std::vector<ImuSample>& imu, const std::vector<StampedPose>& mocap,
                                                double max_offset_s, double grid_dt_s = 0.0);

}  // namespace roe::calib
