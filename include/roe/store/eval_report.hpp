#pragma once
/// @file
/// The files of `roe eval` (docs/eval.md "Output"): report.json as one typed value, EvalReportFile, with
/// one writer and one strict reader over a single field mapping (src/store/eval_report.cpp), and the
/// CSV/TUM files, made from a typed eval::Report (eval/evaluate.hpp). Formatting only: nothing here
/// computes a figure. Every command that reads report.json back (roe eval's text, --summary, roe report,
/// roe sweep run) reads these fields, never the file's keys.

#include <array>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "roe/eval/evaluate.hpp"
#include "roe/io/output.hpp"

namespace roe::store {

/// report.json `inputs.est` / `inputs.gt`: one input as the caller read it.
struct ReportInput {
  std::string path, kind, format, description;
  std::size_t n_poses = 0, duplicate_stamps = 0;
};

/// What report.json says beyond the evaluation itself: the inputs and options as the caller read them.
struct EvalReportContext {
  std::string label;
  std::string est_path, gt_path;
  ReportInput est, gt;
  nlohmann::json options;  ///< the options as given (an echo: shown, never interpreted)
  std::string cov_source;  ///< where the covariances came from (empty: none)
  std::string no_gauge_reason;  ///< why there is no NEES in the estimator's gauge (empty: there is one)
  std::string detections_source;  ///< what the detection σ calibration compared (empty: none)
  std::vector<std::string> warnings;  ///< every warning, in order
};

/// report.json `association`.
struct ReportAssociation {
  double max_dt_s = 0.0, offset_s = 0.0;
  std::string policy;
  std::size_t n_gt = 0, n_est = 0, n_matched = 0, n_overlap_max = 0, n_dropped_unique = 0;
  double max_abs_dt_s = 0.0;
};

/// report.json `alignment`: p' = s R p + t.
struct ReportAlignment {
  std::string type;
  int n_aligned = 0, n_align_requested = -1;
  double scale = 1.0;
  std::array<std::array<double, 3>, 3> R{};  ///< rows
  std::array<double, 3> t{};
  std::array<double, 4> q_xyzw{};
  /// The angle between the ground truth's z and the aligned estimate's (deg); absent in older reports.
  std::optional<double> tilt_deg;
  /// With the tilt warning: the rotation RMSE with --align posyaw (deg).
  std::optional<double> posyaw_rot_rmse_deg;
};

/// report.json `time_offset` (--t-offset auto): the estimate–ground-truth offset, eval/time_offset.hpp.
struct ReportTimeOffset {
  double offset_s = 0.0, sigma_s = 0.0;  ///< t_gt = t_est + offset_s; sigma_s null when not refined
  double search_s = 0.0;                 ///< ± searched around the overlap
  double coarse_offset_s = 0.0, correlation = 0.0, peak_ratio = 0.0;
  bool peak_at_edge = false, refined = false;
  std::size_t n_pairs = 0;
  double ape_rmse_m = 0.0;  ///< the refinement's APE (interpolated ground truth)
};

/// report.json `time_offset_check`: without --t-offset, where the APE minimum lies from the offset used.
struct ReportOffsetCheck {
  double shift_s = 0.0, sigma_s = 0.0;
};

/// report.json `body_pose.fit` (--fit-body-pose): eval::BodyPoseFit.
struct ReportBodyPoseFit {
  std::array<double, 3> sigma_p_m{};
  double sigma_rot_deg = 0.0, rotation_spread_min_deg = 0.0, rotation_spread_max_deg = 0.0;
  int lever_arm_rank = 0;
  std::string verdict;
  std::size_t n_pairs = 0;
};

/// report.json `body_pose`: T_B_I applied to the ground truth (T_W_I = T_W_B·T_B_I), given or fitted.
struct ReportBodyPose {
  std::string source;  ///< "given" (--gt-body-pose) or "fitted" (--fit-body-pose)
  std::array<double, 3> p{};
  std::array<double, 4> q_xyzw{};
  double angle_deg = 0.0;
  Eigen::Vector3d rpy_deg = Eigen::Vector3d::Zero();
  std::optional<ReportBodyPoseFit> fit;  ///< null when given
};

/// report.json `window` (--t-start / --t-end / --align-window): seconds on the ground truth's clock.
struct ReportWindow {
  std::optional<double> t_start_s, t_end_s;
  std::size_t n_cropped = 0;
  std::optional<std::array<double, 2>> align_window_s;
};

/// report.json `per_axis`: the paper's per-axis RMSE and the Euler figures under their metric; for a
/// metric other than `error` also the rotation error's Euler figures and the share of 360° jumps.
struct ReportPerAxis {
  Eigen::Vector3d pos_rmse_m = Eigen::Vector3d::Zero(), pos_mean_m = Eigen::Vector3d::Zero();
  eval::EulerStats rpy_deg;  ///< rpy_rmse_deg, rpy_mean_deg, rpy_std_deg
  std::string euler_metric, euler_definition, wrap;
  eval::EulerStats rotation_error_euler_deg;  ///< only when euler_metric != "error"
  Eigen::Vector3d jump_360_share = Eigen::Vector3d::Zero();  ///< only when euler_metric != "error"
  double jump_360_share_any = 0.0;                           ///< only when euler_metric != "error"
};

/// report.json `cnspy`: cnspy's report values.
struct ReportCnspy {
  double armse_p_m = 0.0, armse_r_deg = 0.0;
  std::optional<double> anees_p, anees_r;
};

/// report.json `consistency.gauge`: the NEES in the estimator's gauge, or why there is none.
struct ReportGauge {
  bool available = false;
  std::string reason;  ///< when not available
  std::string description;  ///< the fields below: when available
  std::size_t n = 0;
  std::optional<double> anees_p, anees_r;
  std::array<double, 3> T_Wt_Wg_p{};
  std::array<double, 4> T_Wt_Wg_q{};  ///< x, y, z, w
};

/// report.json `consistency`: the headline NEES (in the estimator's gauge, else after the alignment).
struct ReportConsistency {
  bool available = false;
  std::string source, frame;
  std::optional<double> anees_p, anees_r;
  ReportGauge gauge;
  std::optional<double> aligned_anees_p, aligned_anees_r;
};

/// The figures of report.json `body_rotation.without` / `.with`.
struct ReportBodyMetrics {
  eval::Stats ape_rot_deg;
  eval::EulerStats rpy_deg;
  std::string euler_metric;
};

/// report.json `body_rotation` (--fit-body-rotation).
struct ReportBodyRotation {
  std::array<double, 4> q_xyzw{};
  double angle_deg = 0.0;
  Eigen::Vector3d rpy_deg = Eigen::Vector3d::Zero();
  ReportBodyMetrics without, with;
};

/// One block of report.json `rpe`; the statistics are null without pairs.
struct ReportRpe {
  double delta = 0.0;
  std::string unit;
  bool all_pairs = false;
  std::string pairs_from;
  double rel_tol = 0.0;
  std::size_t n_pairs = 0;
  std::optional<eval::Stats> trans_m, rot_deg, drift_pct;
};

/// One subset (`all`, `accepted`) of an object of report.json `per_object`: only n when n = 0.
struct ReportFit {
  std::size_t n = 0;
  Eigen::Vector3d pos_rmse_m = Eigen::Vector3d::Zero(), rpy_rmse_deg = Eigen::Vector3d::Zero();
  double ape_trans_rmse_m = 0.0, ape_rot_rmse_deg = 0.0;
};

/// One object of report.json `per_object`.
struct ReportObject {
  int object_id = 0;
  std::size_t n_detections = 0;
  std::map<std::string, std::size_t> counts;  ///< detections per status
  std::size_t n_valid_pose = 0, n_matched = 0;
  ReportFit all, accepted;
};

/// report.json `detection_calibration` (its `expected` block and definition are constants of the writer).
struct ReportDetectionCalibration {
  std::string source;
  std::size_t n_detections = 0, n_evaluated = 0, n_without_sigma = 0, n_without_object_truth = 0,
              n_outside_truth = 0;
  eval::SigmaCalibration all;
  std::vector<eval::ObjectCalibration> per_object;
};

/// The reference values of a consistent detection σ (report.json `detection_calibration.expected`):
/// χ²₁ CDF(k²) within k σ, χ²₆'s mean, quantiles at eval::kNisProbabilities and 95 % gate.
struct ExpectedCalibration {
  std::array<double, 3> within_sigma{};
  double nis_mean = 6.0;
  std::array<double, 5> nis_quantiles{};
  double frac_above_gate = 0.05;
  double gate = 0.0;
  double sigma_scale = 1.0;
};
ExpectedCalibration expected_calibration();

/// report.json `outputs`: the folder written and its files, in order.
struct ReportOutputs {
  std::string dir;
  std::vector<std::string> files;
};

/// report.json `plots` (--plot).
struct ReportPlots {
  bool ok = false;
  std::string status;
};

/// report.json, typed: every field of the file except the fixed texts (definitions, notes, rules) the
/// writer adds. made from an evaluation by make_eval_report_file, written by to_json, read by
/// read_eval_report (strict): read_eval_report(to_json(f)) == f field for field.
struct EvalReportFile {
  std::string title, ref_name, est_name, label, roe_version;  ///< `info`
  ReportInput est, gt;                                         ///< `inputs`
  ReportAssociation association;
  ReportAlignment alignment;
  eval::Stats ape_trans_m, ape_rot_deg;
  std::string euler_metric;
  ReportPerAxis per_axis;
  ReportCnspy cnspy;
  ReportConsistency consistency;
  std::optional<ReportBodyRotation> body_rotation;  ///< null without --fit-body-rotation
  std::optional<ReportTimeOffset> time_offset;      ///< absent without --t-offset auto
  std::optional<ReportOffsetCheck> time_offset_check;  ///< absent where the check did not run
  std::optional<ReportBodyPose> body_pose;          ///< absent without --gt-body-pose / --fit-body-pose
  std::optional<ReportWindow> window;               ///< absent without a crop or alignment window
  std::optional<eval::KittiDrift> kitti;            ///< absent without --kitti
  std::vector<ReportRpe> rpe;
  std::vector<ReportObject> per_object;
  std::optional<ReportDetectionCalibration> detection_calibration;  ///< null without one
  double path_length_est_m = 0.0, path_length_gt_m = 0.0;
  nlohmann::json options = nlohmann::json::object();  ///< the options echo (an object, shown as given)
  std::vector<std::string> warnings;
  std::optional<std::string> evo_results;  ///< --save_results file (absent without)
  std::optional<ReportOutputs> outputs;    ///< absent without an output folder
  std::optional<ReportPlots> plots;        ///< absent without --plot

  /// A roe run folder's evaluation (inputs.est.kind "run"), which has objects to count.
  bool est_is_run() const { return est.kind == "run"; }
};

/// The report of an evaluation (without outputs, plots and evo_results, which the caller adds).
EvalReportFile make_eval_report_file(const eval::Report& r, const EvalReportContext& c);

/// report.json's content: the one writer (io::dump_json(to_json(f), 2) is the file).
nlohmann::json to_json(const EvalReportFile& f);

/// The `per_axis` block alone, as to_json writes it (roe report's --json summary quotes it).
nlohmann::json to_json(const ReportPerAxis& p);

/// The one reader, strict: InputError "not a roe eval report" naming `file` and the key path of a missing
/// or mistyped field (exit 2). A NaN, which JSON writes as null, reads back as NaN.
EvalReportFile read_eval_report(const nlohmann::json& j, const std::string& file);
/// read_eval_report of the file at `path` (InputError for a file that is not JSON).
EvalReportFile read_eval_report_file(const std::filesystem::path& path);

/// The headline numbers of a report, the columns of `roe eval --summary` and of `roe sweep`'s
/// aggregates, in this order: rmse_x_m, rmse_y_m, rmse_z_m, rmse_roll_deg, rmse_pitch_deg, rmse_yaw_deg
/// (per_axis), ate_rmse_m (ape_trans_m.rmse), rot_rmse_deg (ape_rot_deg.rmse). Their names and values
/// are defined here only.
std::vector<std::pair<std::string, double>> headline_metrics(const EvalReportFile& f);
/// The names of headline_metrics, in its order.
const std::vector<std::string>& headline_metric_names();

/// A number of report.json with its key path ("per_axis.pos_rmse_m.x"), for readers that say where a
/// figure comes from (roe report's data-path cells); no value where the report has null.
struct ReportCell {
  std::string path;
  std::optional<double> value;
};
/// per_axis's RMSE: x, y, z, roll, pitch, yaw.
std::vector<ReportCell> per_axis_rmse_cells(const EvalReportFile& f);
/// ape_trans_m's (or with `rotation` ape_rot_deg's) rmse, mean, median, std, min, max.
std::vector<ReportCell> ape_cells(const EvalReportFile& f, bool rotation);
/// The NEES in each frame the report has, labelled: "estimator gauge" (consistency.gauge.anees_p/_r, when
/// available) and "after the alignment" (consistency.aligned.anees_p/_r); `headline` marks consistency.frame.
struct NeesFrame {
  std::string frame;
  bool headline = false;
  std::vector<ReportCell> cells;  ///< position, orientation
};
std::vector<NeesFrame> nees_frames(const EvalReportFile& f);

/// Writes the matched trajectories (CSV and TUM), errors.csv, err_matched_aligned.csv, summary.csv,
/// with RPE rpe.csv and rpe_summary.csv, with detections reprojection_aligned.csv and per_object.csv,
/// with a detection σ calibration detection_sigmas.csv
/// into `dir` (atomically, each). Returns the names written, in order.
std::vector<std::string> write_eval_files(const io::OutputDir& dir, const eval::Report& r,
                                          const EvalReportContext& c);

}  // namespace roe::store
