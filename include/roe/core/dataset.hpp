#pragma once
/// @file
/// In-memory form of the dataset folder of DESIGN §3 (`roe.json` + the EuRoC-style streams).
/// store/dataset.hpp reads and writes it; sim produces it; the run pipeline (pipeline/run.hpp) consumes it;
/// io/kalibr.hpp reads a Kalibr calibration into its camera and IMU records. No I/O here.

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "roe/core/symmetry.hpp"
#include "roe/core/types.hpp"

namespace roe {

/// Schema id written into and required from roe.json.
inline constexpr const char* kDatasetSchema = "roe-dataset/1";

/// One input a dataset was made from (an import, a simulation config, ...).
struct SourceRecord {
  std::string kind;    ///< e.g. "simulate", "realsense", "mocap", "kalibr", "poet"
  std::string path;    ///< as given by the user (may be empty for generated data)
  std::string sha256;  ///< hex digest of the file's bytes, empty when not a file
  std::map<std::string, std::string> options;  ///< the options used, as strings
};

/// IMU noise (continuous-time, Kalibr/EuRoC convention).
/// Continuous-time IMU noise. Negative = unknown (the key is absent from roe.json); 0 = a noise-free
/// IMU (e.g. the simulator's noise-free preset).
struct ImuNoise {
  double gyro_noise_density = -1.0;   ///< rad/s/√Hz
  double gyro_random_walk = -1.0;     ///< rad/s²/√Hz
  double accel_noise_density = -1.0;  ///< m/s²/√Hz
  double accel_random_walk = -1.0;    ///< m/s³/√Hz
  bool known() const {
    return gyro_noise_density >= 0 && gyro_random_walk >= 0 && accel_noise_density >= 0 && accel_random_walk >= 0;
  }
};

struct ImuInfo {
  double rate_hz = 0.0;
  ImuNoise noise;
};

/// The processed camera (undistorted, cropped) and its prior extrinsics.
struct CameraInfo {
  int width = 0;
  int height = 0;
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;
  std::string distortion_model = "none";  ///< of the processed image; "none" after undistortion
  std::vector<double> distortion;         ///< coefficients of distortion_model
  Pose T_I_C;                             ///< prior camera → IMU extrinsics (x_I = T_I_C x_C)
  double time_offset_s = 0.0;             ///< t_imu = t_cam + time_offset_s
};

struct MocapInfo {
  std::string body;            ///< rigid-body name
  Pose T_B_I;                  ///< IMU in the mocap body frame (x_B = T_B_I x_I)
  double time_offset_s = 0.0;  ///< t_imu = t_mocap + time_offset_s
};

struct ObjectInfo {
  int id = 0;             ///< the id used in detections.csv (YCB-V class id for PoET)
  std::string name;
  bool symmetric = false;
  /// A BOP models_info.json (path as written in roe.json, relative to its folder) and the object's id in
  /// it (−1: the same as `id`); `symmetry` is what the reader found there (empty without a file).
  std::string models_info;
  int models_info_id = -1;
  ObjectSymmetry symmetry;
};

struct TruthObject {
  int id = 0;
  Pose T_W_O;  ///< object pose in the world of state_groundtruth_estimate0
};

/// Simulation truth (absent for real recordings).
struct Truth {
  Pose T_I_C;
  /// The true camera–IMU time offset (s; t_imu = t_cam + offset): a detection stamped t_cam saw the rig at
  /// t_cam + offset. roe.json's camera.time_offset_s is the declared prior, which may differ.
  double camera_time_offset_s = 0.0;
  std::vector<TruthObject> objects;
  std::optional<ImuNoise> imu_noise;
  /// The detection-error model's parameters, by name (booleans as 0/1), as simulated.
  std::map<std::string, double> detection_noise;
};

/// roe.json.
struct DatasetManifest {
  std::string schema = kDatasetSchema;
  std::string name;
  std::vector<SourceRecord> sources;
  std::optional<ImuInfo> imu;
  std::optional<CameraInfo> camera;
  std::optional<MocapInfo> mocap;
  std::vector<ObjectInfo> objects;
  std::optional<Truth> truth;
};

/// The whole dataset in memory. Streams are time-sorted.
struct Dataset {
  DatasetManifest manifest;
  std::vector<ImuSample> imu;              ///< mav0/imu0
  std::vector<CameraFrame> frames;         ///< mav0/cam0/data.csv
  std::vector<StampedPose> mocap;          ///< mav0/mocap0: T_M_B
  std::vector<ImuState> groundtruth;       ///< mav0/state_groundtruth_estimate0
  std::map<std::string, std::vector<Detection>> detections;  ///< detections/<name>/
};

}  // namespace roe
