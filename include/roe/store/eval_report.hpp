#pragma once
/// @file
/// The files of `roe eval` (docs/eval.md "Output"): report.json's content and the CSV/TUM files, made
/// from a typed eval::Report (eval/evaluate.hpp). Formatting only: nothing here computes a figure.

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "roe/eval/evaluate.hpp"
#include "roe/io/output.hpp"

namespace roe::store {

/// What report.json says beyond the evaluation itself: the inputs and options as the caller read them.
struct EvalReportContext {
  std::string label;
  std::string est_path, gt_path;
  nlohmann::json inputs;   ///< {"est": {...}, "gt": {...}}: path, kind, format, description, counts
  nlohmann::json options;  ///< the options as given
  std::string cov_source;  ///< where the covariances came from (empty: none)
  std::string no_gauge_reason;  ///< why there is no NEES in the estimator's gauge (empty: there is one)
  std::string detections_source;  ///< what the detection σ calibration compared (empty: none)
  std::vector<std::string> warnings;  ///< every warning, in order
};

/// The position and Euler RMSE of report.json's `per_axis` block and of each per-object subset (`all`,
/// `accepted`), read back by the commands that show them (roe eval's text, --summary, roe report): the
/// one reader of the keys eval_report_json writes, beside it (pos_rmse_m {x, y, z}, rpy_rmse_deg {roll,
/// pitch, yaw}).
struct AxisRmse {
  Eigen::Vector3d pos_m = Eigen::Vector3d::Zero();    ///< x, y, z
  Eigen::Vector3d rpy_deg = Eigen::Vector3d::Zero();  ///< roll, pitch, yaw (under the report's Euler metric)
};

/// `block`'s RMSE; InputError "not a roe eval report" naming `file` and the key path (`path` + key) when a
/// number is missing.
AxisRmse read_axis_rmse(const nlohmann::json& block, const std::string& file = "",
                        const std::string& path = "per_axis");

/// report.json's content (without `outputs` and `plots`, which the caller adds).
nlohmann::json eval_report_json(const eval::Report& r, const EvalReportContext& c);

/// Writes the matched trajectories (CSV and TUM), errors.csv, err_matched_aligned.csv, summary.csv,
/// with RPE rpe.csv and rpe_summary.csv, with detections reprojection_aligned.csv and per_object.csv,
/// with a detection σ calibration detection_sigmas.csv
/// into `dir` (atomically, each). Returns the names written, in order.
std::vector<std::string> write_eval_files(const io::OutputDir& dir, const eval::Report& r,
                                          const EvalReportContext& c);

}  // namespace roe::store
