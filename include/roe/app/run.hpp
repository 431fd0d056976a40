#pragma once
/// @file
/// `roe run DATASET [--config FILE] [--detections NAME] [--output LEVEL] --out RUN_DIR`: reads a dataset folder, builds
/// the measurement stream (detections grouped per image, shifted into the IMU clock by
/// camera.time_offset_s), runs the multi-object EKF (roe::ekf) and writes RUN_DIR (DESIGN §4):
///   trajectory.csv   t,tx,ty,tz,qx,qy,qz,qw (seconds, 9 decimals): T_W_I
///   trajectory.tum   the same in TUM format
///   states.csv       timestamp_ns, p_W_I, v_W_I, q_W_I, b_g, b_a, p_I_C, q_I_C, then one σ per
///                    error-state component of the core and the extrinsics (sigma_*; rad for angles)
///   objects.csv      timestamp_ns,object_id,anchor, T_O_W (p, q xyzw), six σ, after each image, then
///                    the six σ of T_W_O (where the object is: sigma_p_W_O_*, sigma_theta_W_O_*)
///   reprojection.csv timestamp_ns,object_id, T_W_I implied by the raw detection, status, nis
///   run.json         effective configuration, input hashes, counts, NIS statistics, health, timings,
///                    warnings
/// (at output level "full", the default; "standard" leaves states*.csv's σ empty between images, "minimal"
/// writes trajectory.csv/.tum and run.json only: store::RunConfig::output_level)
///
/// Config file (configs/default.json, configs/paper.json): {"filter": {FilterOptions keys},
/// "output": {"rate": "imu" | "images", "level": "full" | "standard" | "minimal"}, "smoother": ..., "health": {HealthLimits keys}}; every key
/// optional, unknown keys are errors.

#include <array>
#include <filesystem>
#include <map>
#include <optional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "roe/core/dataset.hpp"
#include "roe/ekf/driver.hpp"
#include "roe/ekf/health.hpp"
#include "roe/ekf/options.hpp"
#include "roe/io/output.hpp"
#include "roe/pipeline/run.hpp"
#include "roe/store/dataset.hpp"
#include "roe/store/run_config.hpp"
#include "roe/store/run_files.hpp"
#include "roe/store/run_record.hpp"

namespace roe::app {

/// The run configuration (its struct and JSON mapping: store/run_config.hpp); a config file, shipped ones
/// included (`--config paper`), is read by run_config_from_file.
using RunConfig = store::RunConfig;
using store::recommended_filter_options;
using store::run_config_from_json;
using store::run_config_to_json;
RunConfig run_config_from_file(const std::filesystem::path& file);

/// The rows of states.csv, objects.csv and reprojection.csv (their columns: store/run_files.hpp).
using RecordedState = store::RecordedState;
using ObjectRow = store::ObjectRow;
using ReprojectionRow = store::ReprojectionRow;

/// The run in memory and the function that makes it: the pipeline room (pipeline/run.hpp).
using pipeline::RunOutput;
using pipeline::run_dataset;

struct RunOptions {
  std::string config_file;  ///< empty: built-in defaults (= configs/default.json)
  std::string detections;   ///< --detections NAME; empty: the only set in the dataset
  /// --output full|standard|minimal: the config's "output": {"level"} (store::RunConfig::output_level);
  /// empty: the config's.
  std::string output_level;
  /// --estimator filter|smoother|batch: the config's "estimator" (store::RunConfig::estimator); empty: the config's.
  std::string estimator;
  bool force = false;
};

/// The configuration a run with `options` uses: the config file's (roe's defaults without one), with
/// --output and --estimator over it. cli/cmd_run.cpp reads it before anything is written, to hand a batch
/// run to roe-refine.
RunConfig effective_run_config(const RunOptions& options);

/// roe run's batch estimator ("estimator": "batch", docs/refine.md §8): given the run in memory (the filter's
/// estimate and the smoother's, `rec` its run.json record so far), refines it with the batch MAP of roe refine,
/// writes RUN_DIR's main files (trajectory.csv/.tum, states.csv, objects.csv, reprojection.csv, as the
/// config's output level keeps them) and completes `rec` (final, refine block, timings, warnings). Ceres: it
/// is app::batch_estimate (src/app/refine.cpp), which only roe-refine links and registers here
/// (cli/cmd_refine.cpp); `roe` has none and hands a batch run to roe-refine before it writes anything.
using BatchEstimator = void (*)(const Dataset& dataset, const std::string& detection_set, const RunOutput& run,
                                const io::OutputDir& dir, store::RunRecord& rec);
void set_batch_estimator(BatchEstimator f);
/// Whether this executable has the batch estimator (roe-refine, or a test that registered it).
bool has_batch_estimator();

struct RunResult {
  std::filesystem::path out;
  RunOutput output;
  store::RunRecord record;  ///< run.json
  /// The detection set's meta.json (who produced it; store/dataset.hpp), nullopt when it has none.
  std::optional<store::DetectionSetMeta> detections_meta;
  nlohmann::json to_json() const;
  std::string to_text() const;
};

/// `roe run`: reads DATASET, runs, writes RUN_DIR atomically (OutputDir), the health verdict included
/// (RunResult::output.health; the CLI exits 1 when it is unhealthy). With the batch estimator and none
/// registered (has_batch_estimator), an InputError before anything is read or written.
RunResult run(const std::filesystem::path& dataset, const std::filesystem::path& out,
              const RunOptions& options);

}  // namespace roe::app
