#pragma once
/// @file
/// The dataset folder of DESIGN §3: roe.json (strict schema) and the EuRoC-style CSV streams.
/// Readers validate strictly (header, column count, numbers, finite values, strictly increasing
/// stamps) and report file:line:column. Writers go through temporary files + rename.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "roe/core/dataset.hpp"
#include "roe/io/json.hpp"

namespace roe::store {

namespace fs = std::filesystem;

/// Which parts of a dataset folder read_dataset loads. Absent optional streams load as empty.
struct DatasetParts {
  bool imu = true;
  bool frames = true;
  bool mocap = true;
  bool groundtruth = true;
  bool detections = true;
  /// Detection sets to load; empty = every folder under detections/.
  std::vector<std::string> detection_names;
};

// Paths inside a dataset folder.
fs::path manifest_path(const fs::path& dataset);     ///< roe.json
fs::path imu_csv_path(const fs::path& dataset);      ///< mav0/imu0/data.csv
fs::path cam_csv_path(const fs::path& dataset);      ///< mav0/cam0/data.csv
fs::path cam_image_dir(const fs::path& dataset);     ///< mav0/cam0/data
fs::path mocap_csv_path(const fs::path& dataset);    ///< mav0/mocap0/data.csv
fs::path groundtruth_csv_path(const fs::path& dataset);  ///< mav0/state_groundtruth_estimate0/data.csv
fs::path detections_dir(const fs::path& dataset, const std::string& name);  ///< detections/<name>

// roe.json
io::json manifest_to_json(const DatasetManifest& m);
/// Validates the schema: unknown keys, wrong types, non-unit quaternions → ConfigError with the key.
DatasetManifest manifest_from_json(const io::json& j, const std::string& source);
DatasetManifest read_manifest(const fs::path& dataset);
void write_manifest(const DatasetManifest& m, const fs::path& file);

/// Reads a whole dataset folder (roe.json must exist).
Dataset read_dataset(const fs::path& dataset, const DatasetParts& parts = {});
/// Writes every non-empty stream and roe.json into `root` (an existing folder, e.g. io::OutputDir::tmp()).
void write_dataset_files(const Dataset& d, const fs::path& root);
/// Writes a new dataset folder atomically (io::OutputDir; refuses a non-empty folder unless force).
void write_dataset(const Dataset& d, const fs::path& dataset, bool force);

// Streams (EuRoC column layouts of DESIGN §3).
std::vector<ImuSample> read_imu_csv(const fs::path& file);
void write_imu_csv(const fs::path& file, const std::vector<ImuSample>& imu);
std::vector<CameraFrame> read_cam_csv(const fs::path& file);
void write_cam_csv(const fs::path& file, const std::vector<CameraFrame>& frames);
/// mocap0: T_M_B poses (EuRoC vicon0 layout, q w first).
std::vector<StampedPose> read_mocap_csv(const fs::path& file);
void write_mocap_csv(const fs::path& file, const std::vector<StampedPose>& poses);
/// state_groundtruth_estimate0: 17 EuRoC columns.
std::vector<ImuState> read_groundtruth_csv(const fs::path& file);
/// Ground truth as `roe simulate --from-groundtruth` reads it, decided by the content: EuRoC's
/// 17-column state_groundtruth_estimate0 (the IMU state), or a pose-only file (io::read_trajectory):
/// the EuRoC vicon0 / TUM-VI mocap0 layout (`#timestamp [ns],p_RS_R_x [m],...,q_RS_w [],...`, 8
/// columns, q w first) or a TUM trajectory (seconds, q x first).
struct GroundTruthFile {
  std::vector<ImuState> states;    ///< the 17-column file's rows; empty for a pose-only file
  std::vector<StampedPose> poses;  ///< a pose-only file's poses (sorted; repeated stamps dropped)
  std::string layout;              ///< "euroc-state", or the trajectory format ("euroc", "tum", ...)
  std::size_t duplicate_stamps = 0;
  bool pose_only() const { return states.empty(); }
};
GroundTruthFile read_groundtruth_file(const fs::path& file);
void write_groundtruth_csv(const fs::path& file, const std::vector<ImuState>& states);
/// detections/<name>/detections.csv (with or without the six sigma columns). Rows are sorted by
/// time; several rows may share a stamp (one per object); a duplicate (stamp, object) is an error.
std::vector<Detection> read_detections_csv(const fs::path& file);
void write_detections_csv(const fs::path& file, const std::vector<Detection>& detections);

/// detections/<name>/meta.json: who produced a detection set, and what its score and σ columns mean. The
/// keys every producer writes are typed; the producer's own record (roe simulate: seed, config; roe import
/// poet: source, options, summary; roe infer: model, config, options, class_map, per_frame, …) is kept as
/// written in `details`. One writer (roe simulate, roe import poet and roe infer write through it) and one
/// strict reader: `producer` (a string) and `frames_processed` (an integer >= 0) are required,
/// `roe_version`, `score`, `sigma` (strings) and `detections` (an integer >= 0) optional; a wrong type is a
/// ConfigError naming the file, the key, its line and column.
struct DetectionSetMeta {
  std::string producer;      ///< "roe simulate <version>", "roe import poet", "roe infer"
  std::string roe_version;   ///< empty: not written (roe simulate names its version in `producer`)
  std::size_t frames_processed = 0;
  std::optional<std::size_t> detections;  ///< the number of detections (roe simulate)
  std::string score;  ///< what detections.csv's score means (empty: not written)
  std::string sigma;  ///< what its σ columns mean (empty: not written)
  io::json details = io::json::object();  ///< the producer's other keys, as written
};
fs::path detection_set_meta_path(const fs::path& dataset, const std::string& name);  ///< detections/<name>/meta.json
io::json detection_set_meta_to_json(const DetectionSetMeta& m);
DetectionSetMeta detection_set_meta_from_json(const io::json& j, const std::string& source);
/// Written atomically (two-space indent, final newline).
void write_detection_set_meta(const fs::path& file, const DetectionSetMeta& m);
/// The meta.json of a set; nullopt when the set has none (a hand-made set, or one written before roe wrote it).
std::optional<DetectionSetMeta> read_detection_set_meta(const fs::path& dataset, const std::string& name);

}  // namespace roe::store
