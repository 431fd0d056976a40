#pragma once
/// @file
/// `roe import realsense|mocap|kalibr` (DESIGN §1, §3; formats in notes/formats.md; user guide in
/// docs/import.md). Each function reads its inputs, writes the dataset folder and returns a summary
/// the CLI prints. Every import records its input files with sha256 in roe.json (`sources`) and
/// refuses to replace existing outputs unless `force`.

#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "roe/calib/mocap_time_offset.hpp"
#include "roe/core/dataset.hpp"
#include "roe/core/types.hpp"
#include "roe/io/kalibr.hpp"
#include "roe/io/mocap_formats.hpp"
#include "roe/io/output.hpp"

namespace roe::app {

namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------
// realsense
// ---------------------------------------------------------------------------------------------

/// Options of `roe import realsense BAG --out DATASET`.
struct ImportRealsenseOptions {
  int crop_width = 640, crop_height = 480;  ///< centred crop of the undistorted colour image
  int out_width = 0, out_height = 0;        ///< 0 = crop size (no resize)
  bool undistort = true;
  int png_compression = 3;
  std::string color_topic;                  ///< "" = find the colour stream automatically
  /// sensor_msgs/Imu topics; "" = found by message type and name (realsense-ros: <ns>/accel/sample,
  /// <ns>/gyro/sample, <ns>/imu, preferring the colour topic's namespace; recorder: Accel_*/Gyro_*
  /// of the Motion Module). imu_topic is a united topic (gyro and accel in every message).
  std::string accel_topic, gyro_topic, imu_topic;
  std::size_t max_frames = 0;               ///< 0 = all
  bool images = true;                       ///< false: IMU and calibration only (no PNGs)
  std::string name;                         ///< dataset name (default: the bag's stem)
  /// A damaged bag (truncated, corrupt chunk) is an InputError unless salvage is set; then what is
  /// intact is imported and the damage is listed in the warnings.
  bool salvage = false;
  bool force = false;
};

struct ImportRealsenseSummary {
  fs::path dataset;
  std::string layout;                       ///< "recorder" or "realsense-ros"
  std::string color_topic, accel_topic, gyro_topic, imu_topic;
  std::size_t frames = 0;                   ///< PNGs written
  std::size_t accel_samples = 0, gyro_samples = 0;
  std::size_t imu_samples = 0;              ///< merged samples in imu0
  std::size_t gyro_outside_accel = 0;       ///< gyro samples dropped: no accel sample on both sides
  /// StreamInfo.fps, else the median interval. On a united IMU topic without separate gyro messages
  /// gyro_rate_hz is the united stream's rate (it carries the gyro stamps) and accel_rate_hz is 0
  /// (unknown) unless the accel topic was recorded too.
  double accel_rate_hz = 0, gyro_rate_hz = 0;
  /// Clock of header.stamp (per-frame metadata of recorder bags, "" if unknown): the colour stream's,
  /// or the IMU's when the bag has no colour stream.
  std::string timestamp_domain;
  std::string imu_timestamp_domain;         ///< clock of the IMU's header.stamp (gyro, else accel), "" if unknown
  std::string source_distortion;            ///< device model name
  std::vector<double> source_coeffs;
  double source_fx = 0, source_fy = 0, source_cx = 0, source_cy = 0;
  int source_width = 0, source_height = 0;
  CameraInfo camera;                        ///< the processed camera as written to roe.json
  std::map<std::string, Pose> extrinsics;   ///< stream → T_stream_ref (tf/0: ref = the group's pin stream)
  bool have_T_I_C = false;                  ///< T_I_C derived from the Color and Accel extrinsics
  std::vector<std::string> warnings;
  nlohmann::json to_json() const;
};

ImportRealsenseSummary import_realsense(const fs::path& bag, const fs::path& dataset,
                                        const ImportRealsenseOptions& options,
                                        const ProgressCallback& progress = {});


// ---------------------------------------------------------------------------------------------
// mocap
// ---------------------------------------------------------------------------------------------

/// Options of `roe import mocap FILE --into DATASET`.
struct ImportMocapOptions {
  std::string format = "auto";  ///< auto | motive | vicon | euroc | tum | csv (cnspy) | rosbag
  std::string body;             ///< rigid body (Motive/Vicon) ; "" = the only one
  std::string topic;            ///< rosbag: the pose topic
  std::string parent;           ///< rosbag tf topics: the parent frame (header.frame_id) of the transform
  std::string child;            ///< rosbag tf topics: the child frame (same as body)
  std::string up = "auto";      ///< world up axis of the file: auto (y for Motive, z otherwise) | y | z
  std::optional<double> time_offset_s;  ///< t_imu = t_mocap + offset (applied to the written stamps)
  bool estimate_offset = false;         ///< estimate the offset against DATASET/mav0/imu0 gyro
  double max_offset_s = 2.0;            ///< search range of the estimate
  std::string mocap_name = "mocap0";    ///< folder under mav0/
  bool salvage = false;                 ///< rosbag: import the intact part of a damaged bag
  bool force = false;
};


struct ImportMocapSummary {
  fs::path dataset;
  fs::path csv;
  std::string format, body, topic, up;
  std::size_t rows = 0;           ///< frames/rows/messages read
  std::size_t poses = 0;          ///< poses written
  std::size_t occluded = 0;       ///< frames skipped because the body was not tracked
  std::size_t duplicates = 0;     ///< poses dropped for a repeated stamp (the first is kept)
  double rate_hz = 0.0;           ///< from the file header when it has one, else median
  double time_offset_s = 0.0;     ///< applied
  std::optional<calib::MocapOffsetEstimate> estimate;
  std::string length_unit, rotation_type;
  bool created_manifest = false;
  std::vector<std::string> warnings;
  nlohmann::json to_json() const;
};

/// Reads any supported mocap/trajectory file (format "auto" detects from the content): T_M_B in the
/// file's world and clock (TUM/EuRoC/cnspy through io/trajectory_io.hpp).
io::MocapData read_mocap(const fs::path& file, const ImportMocapOptions& options);

ImportMocapSummary import_mocap(const fs::path& file, const fs::path& dataset, const ImportMocapOptions& options);


// ---------------------------------------------------------------------------------------------
// kalibr
// ---------------------------------------------------------------------------------------------

struct ImportKalibrOptions {
  std::string camera = "cam0";  ///< which camera of the camchain
  bool force = false;
};

struct ImportKalibrSummary {
  fs::path dataset;
  std::string camera;
  Pose T_cam_imu;                 ///< as in the file (x_C = T_cam_imu x_I)
  Pose T_I_C;                     ///< written prior = inverse(T_cam_imu)
  double timeshift_cam_imu = 0.0; ///< t_imu = t_cam + shift
  std::string camera_model, distortion_model;
  std::vector<double> intrinsics, distortion_coeffs;
  int width = 0, height = 0;
  bool intrinsics_written = false;  ///< false when the processed image size differs (kept the manifest's)
  std::optional<ImuNoise> imu_noise;
  double imu_rate_hz = 0.0;
  bool created_manifest = false;
  std::vector<std::string> warnings;
  nlohmann::json to_json() const;
};

/// The Kalibr readers live in io (roe/io/kalibr.hpp); these names are kept for the app's callers.
using io::KalibrCamchain;
using io::KalibrImu;
using io::read_kalibr_camchain;
using io::read_kalibr_imu;

ImportKalibrSummary import_kalibr(const fs::path& camchain, const std::optional<fs::path>& imu_yaml,
                                  const fs::path& dataset, const ImportKalibrOptions& options);

// ---------------------------------------------------------------------------------------------
// shared
// ---------------------------------------------------------------------------------------------

/// Reads DATASET/roe.json, or — when the folder has none — returns a minimal manifest (schema and
/// name = the folder's name) and sets `created`. The folder must exist (begin_dataset_change).
DatasetManifest open_or_create_manifest(const fs::path& dataset, bool& created);

/// Starts an import's change of DATASET: refuses a path that is a file, creates the folder when
/// absent (removed again by `staged` if the import fails) and takes its lock in `staged`, so that
/// the files staged next and roe.json (staged last) change together and no concurrent import's
/// roe.json slips in between.
void begin_dataset_change(io::StagedFiles& staged, const fs::path& dataset);

}  // namespace roe::app
