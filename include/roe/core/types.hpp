#pragma once
/// @file
/// Plain data types shared by every area. Time is int64 nanoseconds (DESIGN §2); seconds as double
/// appear only in interoperable trajectory files and in dt arithmetic.

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "roe/math/se3.hpp"

namespace roe {

using math::Pose;
using Vector6d = Eigen::Matrix<double, 6, 1>;

/// A time stamp in integer nanoseconds.
using Timestamp = std::int64_t;

inline constexpr Timestamp kNsPerSecond = 1'000'000'000;

/// Seconds (double) of a nanosecond stamp.
inline double to_seconds(Timestamp t_ns) { return static_cast<double>(t_ns) * 1e-9; }
/// Nanosecond stamp of seconds, rounded to the nearest nanosecond.
inline Timestamp from_seconds(double t_s) { return static_cast<Timestamp>(std::llround(t_s * 1e9)); }
/// dt in seconds between two stamps (b − a), computed in integers first to keep precision.
inline double dt_seconds(Timestamp a, Timestamp b) { return static_cast<double>(b - a) * 1e-9; }

/// Sample rate [Hz] of a stream from the median interval between consecutive stamps (the element at
/// n/2 of the sorted intervals), so that gaps, dropped samples and jittered stamps do not move it;
/// 0 for fewer than two stamps or a median interval that is not positive (unsorted stamps).
double median_rate_hz(const std::vector<Timestamp>& stamps);
/// The same for any sequence of samples, `stamp(sample)` giving each one's Timestamp.
template <class Samples, class StampOf>
double median_rate_hz(const Samples& samples, StampOf stamp) {
  std::vector<Timestamp> t;
  t.reserve(samples.size());
  for (const auto& s : samples) t.push_back(stamp(s));
  return median_rate_hz(t);
}

/// One IMU sample in the IMU frame I: angular rate (rad/s) and specific force (m/s²).
struct ImuSample {
  Timestamp t_ns = 0;
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();
};

/// A pose with a time stamp; the frame names are given by the container (e.g. T_W_I).
struct StampedPose {
  Timestamp t_ns = 0;
  Pose T;
};

/// The full IMU state as in EuRoC's state_groundtruth_estimate0 (17 columns).
struct ImuState {
  Timestamp t_ns = 0;
  Pose T_W_I;
  Eigen::Vector3d v_W_I = Eigen::Vector3d::Zero();
  Eigen::Vector3d b_g = Eigen::Vector3d::Zero();
  Eigen::Vector3d b_a = Eigen::Vector3d::Zero();
};

/// A camera frame (processed image) of mav0/cam0/data.csv.
struct CameraFrame {
  Timestamp t_ns = 0;
  std::string filename;  ///< relative to mav0/cam0/data/, may be empty when no image exists
};

/// One object pose measurement T_C_O of detections.csv (DESIGN §3).
struct Detection {
  Timestamp t_ns = 0;
  int object_id = 0;
  Pose T_C_O;  ///< x_C = R x_O + t, metres
  double score = std::numeric_limits<double>::quiet_NaN();  ///< NaN when the producer has none
  /// Optional per-detection standard deviations in the camera frame: tx, ty, tz (m), rx, ry, rz (rad).
  std::optional<Vector6d> sigma;
};

}  // namespace roe

#include <functional>
namespace roe {
/// Progress reporting from long library operations (io, infer): (done, total). The CLI draws a bar.
using ProgressCallback = std::function<void(std::size_t done, std::size_t total)>;
}  // namespace roe
