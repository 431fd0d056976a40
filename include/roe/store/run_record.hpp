#pragma once
/// @file
/// run.json, typed: what `roe run` (and `roe refine`, whose run.json is its input's with the refined
/// results) records about a run, with one writer and one strict reader. Every command that reads a run
/// folder's run.json (calib-check, refine, eval, report) reads it through read_run_json and uses the
/// fields; none parses it by key.
///
/// The file (docs/dataset-format.md, "run.json"): one JSON object, two-space indented, keys sorted;
///   roe_version, command ("run" | "refine"), config (store/run_config.hpp), inputs, anchor_id, counts,
///   nis, health, relocks, detection_sigmas, init, imu_noise, final, warnings, timing_s, and with
///   command "refine" (or config.estimator "batch") the block refine.
/// Reading is strict: a missing key, a value of the wrong type or an unknown key is a ConfigError (an
/// InputError: exit 2) naming the file, the key path and its line and column. A number the writer could
/// not write (NaN) is null in the file and reads as NaN; optional keys are named below.
/// write → read gives the record back, and write(read(file)) is the file byte for byte.

#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/ekf/driver.hpp"
#include "roe/ekf/health.hpp"
#include "roe/ekf/imu.hpp"
#include "roe/store/run_config.hpp"

namespace roe::store {

/// run.json "inputs": the files the run read.
struct RunInputs {
  std::string dataset;      ///< the dataset folder as given to roe run
  std::string dataset_abs;  ///< the same, absolute (io::provenance_path)
  std::string detections;   ///< the detection set (detections/<name>/)
  /// SHA-256 (hex) of the files read, by their path in the dataset: roe.json, mav0/imu0/data.csv,
  /// detections/<name>/detections.csv.
  std::map<std::string, std::string> sha256;
  std::string config, config_abs;  ///< --config as given and absolute; both empty (keys absent) without
};

/// run.json "counts".
struct RunCounts {
  std::size_t imu_samples = 0, camera_frames = 0, images_with_detections = 0, updates = 0, trajectory_rows = 0;
  ekf::DetectionCounts detections;                 ///< every status, summed over the objects
  std::map<int, ekf::DetectionCounts> per_object;  ///< counts.detections.per_object
};

/// run.json "health": ekf::RunHealth as the file holds it (times in s from the first IMU sample).
struct RunHealthRecord {
  std::vector<std::string> problems;  ///< healthy = empty ("healthy" in the file)
  double duration_s = 0.0;
  std::size_t accepted_updates = 0;
  double supported_fraction = 0.0, longest_dead_reckoning_s = 0.0;
  double longest_dead_reckoning_from_s = 0.0, longest_dead_reckoning_to_s = 0.0;
  double nis_median_ratio = 0.0;
  ekf::HealthLimits limits;
  bool healthy() const { return problems.empty(); }
};

/// One entry of run.json "relocks" (FilterOptions::relock_after_s; times in s from the first IMU sample).
struct RelockRecord {
  double t_s = 0.0, refused_since_s = 0.0;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero(), drift_per_s = Eigen::Vector3d::Zero();
  double residual_sigma = 0.0;
  int detections = 0, objects = 0;
};

/// run.json "init": the extrinsics prior, the init window and where the gyro bias came from.
struct RunInit {
  Pose T_I_C;  ///< the extrinsics prior the filter started from
  int window_samples = 0;
  double window_s = 0.0;
  Eigen::Vector3d accel_mean = Eigen::Vector3d::Zero(), accel_std = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_mean = Eigen::Vector3d::Zero(), gyro_std = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();
  std::string gyro_bias_from = "config";  ///< "rest" or "config"
  std::string gyro_bias_rest_refused;     ///< why not from rest (key absent when empty)
};

/// run.json "detection_sigmas". final_scale is the factor on the detections' σ the filter ended with: the
/// square root of its variance scale, which it keeps within [1/64, 64] (ekf::Filter::learn_sigma_scale), so
/// the reader refuses anything outside [1/8, 8] (0, negative, null, 1e308) before a command uses it.
struct DetectionSigmasRecord {
  bool present = false, used = false;
  double final_scale = 1.0;
};
inline constexpr double kMinDetectionSigmaScale = 1.0 / 8.0, kMaxDetectionSigmaScale = 8.0;

/// One object of run.json "final.objects".
struct FinalObject {
  int id = 0;
  bool anchor = false;
  Pose T_O_W;
};

/// run.json "final.time_offset": the camera–IMU time offset t_d (t_imu = t_cam + t_d) at the end of the run.
/// `estimated` false: the filter held the declared value (σ 0). Absent from files written before issue 49.
struct FinalTimeOffset {
  bool estimated = false;
  double declared_s = 0.0;  ///< roe.json camera.time_offset_s (the prior)
  double value_s = 0.0;
  double sigma_s = 0.0;
};

/// run.json "refine" (in the run.json of roe refine, and of roe run with "estimator": "batch"): the solve's
/// options and report.
struct RefineRecord {
  std::string loss, linear_solver;
  double loss_scale = 0.0;
  int max_iterations = 0;
  bool covariance = false;
  double tau_s_option = -1.0, gross_chi2 = 0.0, imu_noise_scale = 1.0;  ///< options.tau_s (−1: fitted), …
  int fit_rounds = 0;
  struct ErrorModel {  ///< refine::DetectionErrorModel (docs/refine.md §2)
    double tau_s = 0.0, scale_translation = 1.0, scale_rotation = 1.0, whitened_lag1 = 0.0;
    std::size_t used = 0, gross = 0;
    bool fitted_tau = false;
  } error_model;  ///< "detection_error_model"
  std::size_t nodes = 0, imu_factors = 0, detection_factors = 0, detections_weight_below_half = 0,
              parameters = 0, residuals = 0;
  int iterations = 0, solves = 0;
  double initial_cost = 0.0, final_cost = 0.0;
  std::string termination;
  bool covariance_ok = false;
  std::string input_run, input_run_abs, dataset;
  /// Read from the refine block of a roe before issue 48 (white factors, inflated marginals): its options and
  /// error model have no counterpart here (the model's numbers are nan); written back in today's layout.
  bool earlier_layout = false;
};

struct RunRecord {
  std::string roe_version;
  std::string command = "run";  ///< "run" or "refine"
  RunConfig config;
  RunInputs inputs;
  int anchor_id = -1;  ///< −1: no anchor (no usable detection in the IMU span)
  RunCounts counts;
  ekf::NisStats nis;  ///< 6 dof ("dof": 6 in the file); with count 0 only count and gate are written
  RunHealthRecord health;
  std::vector<RelockRecord> relocks;
  DetectionSigmasRecord detection_sigmas;
  RunInit init;
  ekf::ImuNoiseParams imu_noise;  ///< the noise the filter used (after imu_noise_scale)
  /// Where each noise value came from ("config" or "dataset"): gyro_noise_density, gyro_random_walk,
  /// accel_noise_density, accel_random_walk ("imu_noise.from").
  std::array<std::string, 4> imu_noise_from = {"dataset", "dataset", "dataset", "dataset"};
  Pose final_T_I_C;                       ///< "final.T_I_C"
  std::vector<FinalObject> final_objects;  ///< "final.objects", by id
  std::optional<FinalTimeOffset> final_time_offset;  ///< "final.time_offset" (optional when read)
  std::vector<std::string> warnings;
  std::map<std::string, double> timing_s;  ///< wall seconds per stage (read, filter, …, total)
  std::optional<RefineRecord> refine;      ///< present iff command is "refine" or config.estimator "batch"
};

/// The one mapping both ways (the reader is strict, see the file comment; `source` names the file).
nlohmann::json run_record_to_json(const RunRecord& r);
RunRecord run_record_from_json(const nlohmann::json& j, const std::string& source);

/// The text of run.json (two-space indent, final newline); written atomically (io/output.hpp).
std::string format_run_json(const RunRecord& r);
void write_run_json(const std::filesystem::path& file, const RunRecord& r);
/// Reads `file` (errors located by line and column).
RunRecord read_run_json(const std::filesystem::path& file);
/// A run folder's run.json (RUN_DIR/run.json): InputError "not a run folder: run.json is missing" naming
/// the folder when it is not there.
RunRecord read_run_folder_record(const std::filesystem::path& run_dir);

/// The one rule for "which dataset did this run read, and is it still there": inputs.dataset_abs when it
/// is a dataset folder (holds roe.json), else inputs.dataset (as given to roe run, from the current
/// folder) when that is one; nullopt when neither is (moved or deleted). An explicit --dataset/--gt of a
/// command takes precedence over this; the files' identity is checked with inputs.sha256, not here.
std::optional<std::filesystem::path> find_run_dataset(const RunRecord& r);

}  // namespace roe::store
