#pragma once
/// @file
/// A RealSense records its accelerometer and gyroscope as two streams at different rates (the recorder and
/// realsense-ros with unite_imu_method none; io/ros/realsense_recording.hpp reads them apart). The filter
/// wants one IMU sample per gyro stamp: the merge is a decision about the data, made here, I/O-free, and
/// tested without a bag.

#include <cstddef>
#include <utility>
#include <vector>

#include "roe/core/types.hpp"

namespace roe::io {

/// Merges separate accel and gyro streams at the gyro stamps: the accelerometer is linearly
/// interpolated between its two neighbouring samples; gyro samples before the first or after the
/// last accel sample are dropped (counted in `dropped`). Both inputs must be time-sorted.
std::vector<ImuSample> merge_accel_gyro(const std::vector<std::pair<Timestamp, Eigen::Vector3d>>& accel,
                                        const std::vector<std::pair<Timestamp, Eigen::Vector3d>>& gyro,
                                        std::size_t* dropped = nullptr);

}  // namespace roe::io
