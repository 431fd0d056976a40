#pragma once
/// @file
/// The run configuration of `roe run` (configs/*.json, run.json's "config"): the struct, roe's defaults and
/// its one JSON mapping both ways. {"filter": {FilterOptions keys}, "output": {"rate": "imu" | "images",
/// "level": "full" | "standard" | "minimal"},
/// "estimator": "filter" | "smoother" | "batch", "health": {HealthLimits keys}, "description": text}; every
/// key optional,
/// unknown keys are errors (ConfigError naming the source and the key path). Reading a config *file*
/// (shipped configs resolved to the bytes compiled into roe) is app::run_config_from_file.

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "roe/ekf/health.hpp"
#include "roe/ekf/options.hpp"

namespace roe::store {

/// roe's recommended filter settings, the built-in defaults of `roe run` (= configs/default.json): the
/// plain FilterOptions with the changes that made every shipped preset, the sample and the EuRoC V1_02
/// snippet both healthy and more accurate (measured in docs/RESULTS.md §6, the decision in docs/filter.md
/// §12): updates from every initialised object (require_anchor false), a measurement noise larger along the
/// viewing ray than across it and growing with depth, the initial gyro bias from the init window when the
/// IMU rests, and the IMU noise of roe.json scaled by 4.
ekf::FilterOptions recommended_filter_options();

/// What produces the run folder's main files (RunConfig::estimator), by name "filter", "smoother", "batch".
enum class Estimator { kFilter, kSmoother, kBatch };
/// The rows of trajectory.csv/.tum and states.csv (RunConfig::output_rate): "imu", "images".
enum class OutputRate { kImu, kImages };
/// What the run folder holds (RunConfig::output_level): "full", "standard", "minimal".
enum class OutputLevel { kFull, kStandard, kMinimal };

/// The names of each setting's values, in the enum's order: the words of configs, run.json and the CLI.
const std::vector<std::string>& estimators();     ///< filter, smoother, batch
const std::vector<std::string>& output_rates();   ///< imu, images
const std::vector<std::string>& output_levels();  ///< full, standard, minimal (in order of what they keep)
const std::string& to_string(Estimator e);
const std::string& to_string(OutputRate r);
const std::string& to_string(OutputLevel l);
/// The value named `name`; false (out unchanged) for a name not in the list.
bool parse(const std::string& name, Estimator& out);
bool parse(const std::string& name, OutputRate& out);
bool parse(const std::string& name, OutputLevel& out);

struct RunConfig {
  ekf::FilterOptions filter = recommended_filter_options();
  /// Rows of trajectory.csv/.tum and states.csv: "imu" (every IMU sample) or "images" (after each
  /// image update).
  OutputRate output_rate = OutputRate::kImu;
  /// What the run folder holds (docs/filter.md §9, "Output levels"): "full" (every file, σ at every row),
  /// "standard" (the same files; states.csv/states_filter.csv give σ only at the first row after each image,
  /// their σ cells are empty elsewhere), "minimal" (trajectory.csv/.tum and run.json only). Echoed in
  /// run.json only when not "full", so that the config of a default run (and a sweep job's id) is unchanged.
  OutputLevel output_level = OutputLevel::kFull;
  /// What produces the run folder's main files (trajectory.csv/.tum, states.csv, objects.csv; docs/filter.md
  /// §10, docs/refine.md §8): "filter" the causal filter alone (configs/paper.json: the paper's filter);
  /// "smoother" (the default) the fixed-interval RTS smoothed estimate (ekf/smoother.hpp), the filter's own
  /// in trajectory_filter.csv/.tum and states_filter.csv; "batch" the smoother's estimate refined by the
  /// pre-whitened batch MAP of `roe refine` in the same process (Ceres: the helper roe-refine runs it), the
  /// filter's own again in the _filter files. The key replaces "smoother" ("none" | "rts"), which is still
  /// read (configs and run.json files written before, as "filter" and "smoother").
  Estimator estimator = Estimator::kSmoother;
  /// Whether the filter's recording is kept for the RTS smoother (estimator "smoother" or "batch").
  bool smoothed() const { return estimator != Estimator::kFilter; }
  std::string description;  ///< free text (configs/*.json say what they are for)
  /// When a run is judged unhealthy (`roe run` exits 1): "health": {...} in the config.
  ekf::HealthLimits health;
};

/// Strict loader (ConfigError naming `source` and the key; the settings' names are parsed here, once, into
/// their enums: an unknown name is refused naming the key and the allowed names) and its inverse (what run.json echoes):
/// run_config_to_json(run_config_from_json(j)) == j for every j run_config_to_json wrote.
RunConfig run_config_from_json(const nlohmann::json& j, const std::string& source);
/// `every_key`: also the keys echoed only away from their default (output.level), e.g. for the list of a
/// run config's keys (roe sweep's overrides).
nlohmann::json run_config_to_json(const RunConfig& c, bool every_key = false);

/// The "health" block's limits (also run.json's health.limits): its echo and its strict reader (every key
/// optional, unknown keys refused; ConfigError naming `source` and the key under `path`).
nlohmann::json health_limits_to_json(const ekf::HealthLimits& h);
ekf::HealthLimits health_limits_from_json(const nlohmann::json& j, const std::string& source, const std::string& path);

/// Whether a run written with `c` holds `file` (a run folder's file name: "states.csv", "objects.csv",
/// "reprojection.csv", "states_filter.csv", "trajectory_filter.csv", ...; the _filter files also need an
/// estimator beyond the filter). trajectory.csv/.tum and run.json are in every run folder.
bool run_folder_has(const RunConfig& c, const std::string& file);
/// Why a run written with `c` has no `file`, as a reader says it ("the run was written with output level
/// minimal (trajectory and run.json only)"); empty when the level writes the file (its absence is then damage).
std::string run_file_absent_reason(const RunConfig& c, const std::string& file);
/// Whether a run written with `c` records σ at every row of states.csv (level "full", or rate "images").
bool sigma_at_every_row(const RunConfig& c);

}  // namespace roe::store
