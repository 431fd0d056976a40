#pragma once
/// @file
/// The JSON forms of a Pose and of the IMU noise, one definition for every JSON roe reads or writes
/// (roe.json, run.json, simulator configs, the --json summaries of the import commands):
///   Pose      {"p": [x, y, z], "q": [qx, qy, qz, qw]}   (metres; unit Hamilton quaternion, w last)
///   IMU noise {"gyro_noise_density", "gyro_random_walk", "accel_noise_density", "accel_random_walk"}
///             (rad/s/√Hz, rad/s²/√Hz, m/s²/√Hz, m/s³/√Hz; a value < 0 means unknown and is left out)
/// Readers are strict (unknown keys, wrong types, wrong lengths, a non-unit quaternion: ConfigError naming
/// the file and the key path; io::read_json_file adds line and column).

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <string>

#include "roe/core/types.hpp"
#include "roe/io/json.hpp"

namespace roe::io {

/// q normalised, unless it is unit to rounding already: a written quaternion reads back bit-identical
/// (normalising a unit quaternion again can change its last bits).
Eigen::Quaterniond unit_quaternion(const Eigen::Quaterniond& q);

json pose_to_json(const Pose& T);

/// How pose_from_json reads.
struct PoseJsonRead {
  /// Largest accepted |‖q‖ − 1|.
  double quat_tol = 1e-6;
  /// Non-null: "p" and "q" are each optional and default to this pose's (a config overlay); null: both
  /// are required.
  const Pose* base = nullptr;
};

/// `j` at `key_path` of `source` as a Pose (quaternion through unit_quaternion).
Pose pose_from_json(const json& j, const std::string& source, const std::string& key_path,
                    const PoseJsonRead& read = {});

/// The four noise keys of any struct with the members gyro_noise_density, gyro_random_walk,
/// accel_noise_density and accel_random_walk; values < 0 (unknown) are left out.
/// The four noise keys, in the order of imu_noise_values.
inline constexpr const char* kImuNoiseKeys[4] = {"gyro_noise_density", "gyro_random_walk", "accel_noise_density",
                                                 "accel_random_walk"};
/// The members of `n` under kImuNoiseKeys, in that order.
template <typename Noise>
auto imu_noise_values(Noise& n) {
  return std::array<decltype(&n.gyro_noise_density), 4>{&n.gyro_noise_density, &n.gyro_random_walk,
                                                        &n.accel_noise_density, &n.accel_random_walk};
}

template <typename Noise>
json imu_noise_to_json(const Noise& n) {
  json j = json::object();
  const auto values = imu_noise_values(n);
  for (int i = 0; i < 4; ++i)
    if (*values[i] >= 0.0) j[kImuNoiseKeys[i]] = *values[i];
  return j;
}

/// Reads the four noise keys of `o` into `n`: each optional (absent: unchanged), a finite number >= 0
/// when given (0 = a noise-free IMU). Other keys of `o` are the caller's (it calls o.finish()).
template <typename Noise>
void read_imu_noise(JsonObject& o, Noise& n) {
  const auto values = imu_noise_values(n);
  for (int i = 0; i < 4; ++i) {
    const char* key = kImuNoiseKeys[i];
    if (!o.has(key)) continue;
    o.get(key, *values[i]);
    if (!(std::isfinite(*values[i]) && *values[i] >= 0.0))
      throw ConfigError("must be >= 0", {o.source(), 0, 0, o.key_path(key)});
  }
}

}  // namespace roe::io
