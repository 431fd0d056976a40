#pragma once
/// @file
/// `roe refine RUN_DIR --out RUN_DIR2 [--dataset DATASET] [--loss huber|cauchy|none] [--loss-scale K]`:
/// the offline batch MAP of a run (refine/refine.hpp, docs/refine.md). Reads RUN_DIR (run.json, states.csv,
/// objects.csv, reprojection.csv) and the dataset the run read (its IMU and detection files are compared
/// with the run's hashes first), refines, and writes RUN_DIR2 with the files of `roe run` (DESIGN §4) so
/// that eval, calib-check and report read it unchanged:
///   states.csv       the refined IMU states at the run's state times (each propagated from the last node
///                    with the IMU), the refined T_I_C; σ of the extrinsics = their marginal (Ceres); σ of
///                    the IMU states = the run's (refine computes the marginals of the calibration only)
///   objects.csv      one row per object at the last node: T_O_W with its marginal σ (and of T_W_O, T_A_O)
///   reprojection.csv the run's rows, T_W_I implied by each raw detection with the refined calibration,
///                    the run's status, `nis` = the refined whitened squared residual of the detections used
///   trajectory.csv / .tum, run.json (the run's, with "command": "refine", the refined "final" and a
///                    "refine" section: inputs, options, solver report, timings)

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "roe/core/dataset.hpp"
#include "roe/io/output.hpp"
#include "roe/pipeline/run.hpp"
#include "roe/refine/refine.hpp"
#include "roe/store/run_record.hpp"

namespace roe::app {

struct RefineCommandOptions {
  std::string dataset;  ///< empty: the dataset run.json names (store::find_run_dataset)
  refine::RefineOptions refine;
  bool force = false;
};

struct RefineCommandResult {
  std::filesystem::path out;
  refine::RefineResult result;
  store::RunRecord record;  ///< run.json
  std::vector<std::string> warnings;
  nlohmann::json to_json() const;
  std::string to_text() const;
};

/// roe run's batch estimator (app::BatchEstimator, app/run.hpp): the same solve and files as refine_run, on the
/// run in memory, into RUN_DIR.
void batch_estimate(const Dataset& dataset, const std::string& detection_set, const pipeline::RunOutput& run,
                    const io::OutputDir& dir, store::RunRecord& rec);

RefineCommandResult refine_run(const std::filesystem::path& run_dir, const std::filesystem::path& out,
                               const RefineCommandOptions& options);

}  // namespace roe::app
