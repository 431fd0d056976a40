#pragma once
/// @file
/// `roe calib-check`: checks a run's self-calibration (docs/calib-check.md).
///
///   roe calib-check RUN_DIR [--dataset DATASET | --no-dataset] [--strict] [thresholds]
///
/// Reads RUN_DIR/run.json (config, extrinsics prior, detection counts, inputs), states.csv (the
/// extrinsics trace with σ, the gyro bias) and objects.csv (each object's last row). The dataset —
/// --dataset, or by default the one run.json names when it still exists — adds the truth checks
/// (simulated datasets) and the camera–IMU time offset estimated from the run's detection set and
/// the gyro; its files are compared with the hashes in run.json first. Writes nothing.
/// Exit status (DESIGN §1): 0 when no check failed, 1 when one did (or, with --strict, when one was
/// inconclusive), 2 for unreadable or malformed input.

#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "roe/calib/calib_check.hpp"
#include "roe/calib/time_offset.hpp"

namespace roe::app {

struct CalibCheckOptions {
  std::string dataset;       ///< --dataset; empty = run.json's inputs.dataset_abs when it exists
  bool no_dataset = false;   ///< --no-dataset: only the checks that need the run folder alone
  bool strict = false;       ///< --strict: inconclusive checks fail too
  calib::CalibThresholds thresholds;
  calib::TimeOffsetOptions time_offset;
};

struct CalibCheckResult {
  std::filesystem::path run_dir;
  std::string dataset;          ///< the dataset used ("" when none)
  std::string dataset_from;     ///< "option", "run.json" or "" (none)
  std::string detections;       ///< the run's detection set
  calib::CalibReport report;    ///< "dataset.identity", then the library's checks
  bool strict = false;
  std::vector<std::string> warnings;

  /// 0 pass, 1 a failed check (or, strict, an inconclusive one, or no check that could judge).
  int exit_code() const;
  /// Some calibration check (not dataset.identity, which checks the files) passed, failed or was within its σ:
  /// the run was judged. False when every check was skipped,
  /// inconclusive or unobservable (a `roe run --output minimal` folder has nothing to check): the verdict is
  /// then "NOT JUDGED", never "PASS".
  bool judged() const;
  /// The verdict the JSON calls "passed": no check failed and the run was judged.
  bool passed() const { return exit_code() == 0 && judged(); }
  /// The number of checks per status word (pass, fail, inconclusive, skipped, within-sigma, unobservable: each
  /// present, 0 when none).
  std::map<std::string, int> status_counts() const;
  nlohmann::json to_json() const;
  std::string to_text() const;
};

CalibCheckResult calib_check(const std::filesystem::path& run_dir, const CalibCheckOptions& options);

}  // namespace roe::app
