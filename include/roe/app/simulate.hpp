#pragma once
/// @file
/// `roe simulate`: builds a simulated dataset folder (DESIGN §3) from a preset or a JSON config, or
/// synthesises detections along a real EuRoC recording (--from-groundtruth).
///
/// Config files are JSON objects whose keys mirror roe::sim::SimConfig (docs/simulator.md lists them);
/// every key is optional (the struct default or the base preset's value is kept) and unknown keys are
/// errors. `"base": "<preset>"` starts from an embedded preset. Presets live in configs/sim/*.json and
/// are compiled into the binary (cmake/extra-sim.cmake), so `roe` finds them wherever it is run.

#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "roe/sim/simulator.hpp"

namespace roe::app {

struct SimulateOptions {
  std::string preset;                ///< --preset NAME (embedded configs/sim/NAME.json)
  std::string config_file;           ///< --config FILE
  std::uint64_t seed = 1;            ///< --seed
  std::optional<double> duration_s;  ///< --duration (overrides the config)
  std::string from_groundtruth;      ///< --from-groundtruth EUROC_MAV0_DIR
  std::optional<int> objects;        ///< --objects N (with --from-groundtruth)
  /// --time-offset S: the true camera–IMU offset (t_imu = t_cam + S; overrides the config's
  /// camera.time_offset_s). roe.json's declared camera.time_offset_s stays the config's (0 for --from-groundtruth).
  std::optional<double> time_offset_s;
  bool force = false;                ///< --force: replace a non-empty output folder
  /// --models-info: describe the symmetric objects' symmetries, the ones the flips use
  /// (sim::simulated_symmetry), in the dataset's models_info.json and point roe.json's objects at it,
  /// so that `roe run` and `roe calib-check` use the same definitions (docs/simulator.md §5).
  bool models_info = false;
};

struct SimulateResult {
  std::filesystem::path out;
  std::string name;
  std::uint64_t seed = 0;
  sim::SimStats stats;
  std::size_t mocap_samples = 0;
  double duration_s = 0.0;
  std::vector<int> object_ids;
  nlohmann::json to_json() const;
  std::string to_text() const;
};

/// Runs the simulation and writes the dataset folder atomically. InputError/ConfigError on bad
/// options or config (with file and key), DataError when the recording cannot be used.
SimulateResult simulate(const SimulateOptions& options, const std::filesystem::path& out);

/// Builds the dataset in memory (what simulate writes), plus the effective config as JSON.
sim::SimRun simulate_dataset(const SimulateOptions& options, nlohmann::json* effective_config = nullptr);

/// Names of the embedded presets, sorted.
std::vector<std::string> list_presets();
/// The JSON text of an embedded preset; InputError listing the names when unknown.
const std::string& preset_text(const std::string& name);
/// One-line description of a preset (its "description" key).
std::string preset_description(const std::string& name);

/// A SimConfig from an embedded preset / a JSON file / JSON text (`source` names it in errors).
sim::SimConfig sim_config_from_preset(const std::string& name);
sim::SimConfig sim_config_from_file(const std::filesystem::path& file);
sim::SimConfig sim_config_from_json(const nlohmann::json& j, const std::string& source);
/// The effective config as JSON (the same keys the loader reads; loading it back gives the same config).
nlohmann::json sim_config_to_json(const sim::SimConfig& config);

}  // namespace roe::app
