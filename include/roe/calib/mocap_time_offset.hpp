#pragma once
/// @file
/// The clock offset between a motion-capture track and the IMU, from the shape of their angular rates
/// (`roe import mocap --estimate-offset`, docs/import.md). I/O-free. The camera–IMU offset from
/// detections is calib/time_offset.hpp: another signal (object rotations, not a mocap body's rate).

#include <cstddef>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/math/rate_correlation.hpp"

namespace roe::calib {

/// The mocap clock against the IMU clock (`roe import mocap --estimate-offset`): the correlation peak of math/rate_correlation.hpp,
/// offset_s with t_imu = t_mocap + offset_s.
using MocapOffsetEstimate = math::RateCorrelation;

/// Estimates the clock offset between an IMU and a mocap track by correlating the gyro's
/// angular-rate magnitude with the magnitude of the mocap's body angular rate
/// (|Log(R_k^T R_{k+1})| / dt), both resampled on a common grid of `grid_dt_s` (0 = the mocap's
/// median period, at most 1/200 s). The coarse peak over [-max, max] is refined by a parabola
/// through the three best lags. Result: t_imu = t_mocap + offset. DataError when the overlap is too
/// short or the motion has no rotation.
MocapOffsetEstimate estimate_mocap_time_offset(const std::vector<ImuSample>& imu, const std::vector<StampedPose>& mocap,
                                                double max_offset_s, double grid_dt_s = 0.0);

}  // namespace roe::calib
