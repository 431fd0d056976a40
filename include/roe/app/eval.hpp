#pragma once
/// @file
/// `roe eval`: evaluates an estimate against ground truth (DESIGN §4, notes/eval.md §7).
///
///   roe eval RUN_DIR|EST_FILE --gt DATASET|GT_FILE [--align se3|sim3|posyaw|origin|none] [--n-align N]
///            [--max-dt S] [--t-offset S] [--assoc nearest|unique] [--out DIR] [--plot]
///            [--rpe-delta D[,D...] [--rpe-unit m|s|f|deg|rad] [--rpe-all-pairs] [--rpe-pairs-from est|gt]
///             [--rpe-tol FRACTION]]
///   roe eval --summary REPORT_JSON... [--out FILE|DIR/]
///
/// Estimate: a run folder (trajectory.csv, optional reprojection.csv and states.csv written by
/// `roe run`) or a trajectory file (TUM, EuRoC, cnspy CSV, csv-ns; io/trajectory_io.hpp).
/// Ground truth: a dataset folder (state_groundtruth_estimate0 = the IMU pose, or mocap0 with
/// roe.json's mocap T_B_I and time offset: T_M_I = T_M_B · T_B_I at t_mocap + time_offset_s), a plain
/// EuRoC mav0 folder, or a trajectory file. The pipeline is association (eval/associate.hpp) →
/// alignment (eval/align.hpp) → APE metrics (eval/metrics.hpp), and with --rpe-delta the relative pose
/// error (eval/rpe.hpp) of the aligned pairs; for a run folder also the per-object reprojection traces
/// (each raw detection's implied IMU pose, aligned with the same transform).

#include <filesystem>
#include <nlohmann/json.hpp>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "roe/app/figures.hpp"
#include "roe/core/types.hpp"
#include "roe/eval/evaluate.hpp"
#include "roe/io/trajectory_io.hpp"
#include "roe/store/eval_report.hpp"

namespace roe::app {

/// roe eval's default --euler (eval::EulerMetric): also the metric of every sweep job's Euler columns.
inline constexpr const char* kDefaultEulerMetric = "error";

struct EvalOptions {
  std::string est;                  ///< RUN_DIR or EST_FILE
  std::string gt;                   ///< DATASET (or EuRoC mav0 folder) or GT_FILE; empty: run.json's dataset
  std::string est_format = "auto";  ///< --est-format (for a file)
  std::string gt_format = "auto";   ///< --gt-format (for a file)
  std::string gt_source = "auto";   ///< --gt-source for a dataset: auto | groundtruth | mocap
  std::string est_times;            ///< --est-times: a KITTI estimate's times file (else: by index)
  std::string gt_times;             ///< --gt-times: a KITTI ground truth's times file
  std::string align = "se3";        ///< --align
  int n_align = -1;                 ///< --n-align: first N pairs (-1 = all)
  double max_dt_s = 0.01;           ///< --max-dt
  double t_offset_s = 0.0;          ///< --t-offset (added to estimate stamps)
  bool t_offset_auto = false;       ///< --t-offset auto: estimate it (eval/time_offset.hpp)
  double t_offset_max_s = 1.0;      ///< --t-offset-max: ± searched by --t-offset auto
  std::string gt_body_pose;         ///< --gt-body-pose x,y,z,qx,qy,qz,qw or a file holding that line: T_B_I
  bool fit_body_pose = false;       ///< --fit-body-pose: fit T_B_I (eval/body_pose.hpp)
  std::string t_start, t_end;       ///< --t-start / --t-end (seconds, the ground truth's clock); empty: none
  std::string align_window;         ///< --align-window T0:T1 (seconds); empty: every pair
  bool kitti = false;               ///< --kitti: the KITTI devkit's t_rel [%] and r_rel [deg/100 m]
  std::string assoc = "nearest";    ///< --assoc nearest | unique
  std::string out;                  ///< --out DIR; default RUN_DIR/eval for a run folder, none for a file
  bool no_out = false;              ///< --no-out: write nothing (even for a run folder)
  std::string label;                ///< --label (default: label_from_path())
  bool plot = false;                ///< --plot
  FigureOptions figures;            ///< --objects, --plot-mode, --color-by-error, --vector (with --plot)
  bool force = false;               ///< --force
  /// --rpe-delta D[,D...]: relative pose error for each delta (none: no RPE), eval/rpe.hpp.
  std::vector<double> rpe_delta;
  std::string rpe_unit = "m";       ///< --rpe-unit f|m|s|deg|rad
  bool rpe_all_pairs = false;       ///< --rpe-all-pairs
  std::string rpe_pairs_from = "est";  ///< --rpe-pairs-from est|gt
  double rpe_tol = 0.1;             ///< --rpe-tol: all-pairs tolerance relative to the delta
  /// --detections NAME|FILE: calibrate the σ of this detection set of the --gt dataset (or this
  /// detections.csv) against the truth. Empty: the set run.json names, when it has sigmas.
  std::string detections;
  /// --euler error|absolute|absolute-unwrapped: the per-axis Euler figures (eval::EulerMetric).
  std::string euler = kDefaultEulerMetric;
  /// --fit-body-rotation: also report the constant body-frame rotation after the alignment and the
  /// metrics without it (a diagnostic; the headline figures never include it).
  bool fit_body_rotation = false;
  /// --save_results FILE.zip: also write evo's result file of the APE (translation part), which evo_res and
  /// evo_fig read (io/evo_result.hpp); works with --no-out too.
  std::string save_results;
};

/// The settings of an evaluation that a sweep spec's "eval" block carries, in one table: `visit(key,
/// member)` for each, the key as report.json's "options" and sweep specs spell it. Sweep plans fill every
/// default from EvalOptions (so writing a default changes no job id), sweep jobs apply them, and
/// report.json's options echo them. Their values are checked by the parsers run_eval uses
/// (check_sweep_eval_setting).
template <class Options, class Visit>
void for_each_sweep_eval_setting(Options& o, Visit&& visit) {
  visit("align", o.align);
  visit("n_align", o.n_align);
  visit("max_dt_s", o.max_dt_s);
  visit("t_offset_s", o.t_offset_s);
  visit("assoc", o.assoc);
  visit("gt_source", o.gt_source);
  visit("rpe_delta", o.rpe_delta);
  visit("rpe_unit", o.rpe_unit);
}

/// Checks the setting `key` of for_each_sweep_eval_setting with run_eval's own rule; throws InputError.
void check_sweep_eval_setting(const EvalOptions& o, const std::string& key);

/// A sweep's "t_offset_s": seconds, or "auto" for --t-offset auto. The only setting of the table whose JSON
/// is not its member's: read_sweep_t_offset sets t_offset_s or t_offset_auto from it (InputError for anything
/// else), sweep_t_offset_json writes it back. A number stays a number, so the job ids of specs written before
/// "auto" existed do not change.
void read_sweep_t_offset(const nlohmann::json& value, EvalOptions& o);
nlohmann::json sweep_t_offset_json(const EvalOptions& o);

/// One row of a run folder's reprojection.csv: the IMU pose T_W_I implied by one raw detection.
using ReprojectionCsvRow = eval::DetectionPose;

/// reprojection.csv (store::read_reprojection_csv: columns matched by name, any order; nis may be empty,
/// nan or absent). Rows sorted by time (non-decreasing).
std::vector<ReprojectionCsvRow> read_reprojection_csv(const std::filesystem::path& file);

/// Per-pose diagonal covariance from a run folder's states.csv, matched to `t_ns` by stamp (within 1 µs).
/// Reads the columns by the names roe run writes (store::read_states_csv): `timestamp_ns`,
/// `sigma_p_W_I_{x,y,z}` (m) and `sigma_theta_W_I_{x,y,z}` (rad); other columns are ignored, a σ may be
/// nan (no NEES at that pose), a negative σ or decreasing stamps are input errors.
/// Returns an empty vector (and a reason in *why) when the columns are not there.
std::vector<std::optional<eval::PoseCovariance>> read_states_covariance(const std::filesystem::path& file,
                                                                        const std::vector<Timestamp>& t_ns,
                                                                        std::string* why);

/// The estimate / ground truth as loaded, with a description of where they came from.
struct EvalInput {
  io::Trajectory traj;
  std::string kind;         ///< "run", "file", "dataset"
  std::string description;  ///< e.g. "dataset mav0/mocap0 with T_B_I, offset 0 s"
  std::filesystem::path path;
  /// The poses are a dataset's state_groundtruth_estimate0: the world W of its roe.json truth section.
  bool truth_world = false;
  std::string topic;  ///< for a bag: what followed BAG: (TOPIC, or /tf:PARENT.CHILD)
};
EvalInput load_ground_truth(const EvalOptions& o, std::vector<std::string>& warnings);
/// A trajectory straight from a bag topic, `BAG:TOPIC` (ROS 1 or ROS 2, file or rosbag2 folder; a
/// PoseStamped, TransformStamped, PoseWithCovarianceStamped or Odometry topic, or a tf topic as
/// `BAG:/tf:PARENT.CHILD` as evo writes it); nullopt when `spec` is not of that form (an existing
/// path, or no prefix that is a bag by content). InputError for a topic the bag lacks (listing its
/// pose topics) or a damaged bag.
std::optional<EvalInput> load_bag_trajectory(const std::string& spec, std::vector<std::string>& warnings);

/// Detections with σ and the truth that goes with them (roe.json truth.T_I_C, truth.objects, camera
/// time offset), for the σ calibration of `roe eval` (docs/eval.md, "Detection uncertainty calibration").
struct DetectionSigmaSource {
  std::vector<Detection> detections;
  Pose T_I_C;
  double camera_time_offset_s = 0.0;
  std::map<int, Pose> T_W_O;
  std::string description;
};
/// `--detections NAME|FILE` with a dataset as ground truth, else the detection set a run folder's run.json
/// names when it has sigmas; nullopt when there is nothing to calibrate (a warning when the dataset
/// lacks the truth). InputError for an explicit --detections without a dataset, a set or file that is
/// not there, without sigmas, or a dataset without truth.objects. `o.gt` is the resolved ground truth.
std::optional<DetectionSigmaSource> load_detection_sigmas(const EvalOptions& o, bool est_is_run,
                                                          std::vector<std::string>& warnings);

/// The truth in the estimator's own gauge (eval/gauge.hpp) for a run folder evaluated against a
/// dataset's state_groundtruth_estimate0 with roe.json truth.objects: the anchor and its gauge from
/// run.json (config.filter.anchor_gauge, anchor_id, relocks), its estimate and first sight from
/// objects.csv, its true pose from roe.json. nullopt, with the reason in *why, where there is none
/// (a gauge that does not fix W with the anchor, a re-lock, no object truth, ...).
std::optional<eval::GaugeTruth> load_gauge_truth(const std::filesystem::path& run_dir, const EvalInput& gt,
                                                 std::string* why);

struct EvalResult {
  store::EvalReportFile report;  ///< report.json, typed
  std::filesystem::path out;     ///< output folder, empty when nothing was written
  std::string plot_status;       ///< what happened to --plot
  /// report.json's content (store::to_json).
  nlohmann::json report_json() const;
  std::string to_text() const;
};

/// The default label of an estimate: a folder's name, a file's stem, and for a generic file name
/// (data.csv, trajectory.csv, ...) the closest enclosing folder that is not part of a dataset's layout
/// (mav0, state_groundtruth_estimate0, ...): `V1_01_easy/mav0/state_groundtruth_estimate0/data.csv`
/// is `V1_01_easy`. Path arithmetic only.
std::string label_from_path(const std::filesystem::path& path, bool is_dir);
/// The label of an input: label_from_path, and for a bag topic BAGSTEM:TOPIC without the topic's leading
/// '/' (evo_ROS_example:ORB-SLAM, nav2_turtlebot:amcl_pose), so topics of one bag are told apart.
std::string label_of(const EvalInput& in, bool is_dir);

/// Runs the evaluation and writes the output folder (atomically). InputError for bad options/files
/// (every option value is checked, even one that does not apply; --no-out with --out is refused),
/// or when no pair matches (with explain_no_match's diagnosis); DataError when the alignment is
/// degenerate.
EvalResult run_eval(const EvalOptions& options);

struct EvalSummaryOptions {
  std::vector<std::string> reports;  ///< report.json files (or folders containing one)
  /// FILE: writes FILE (without a .csv/.json/.md extension) + .csv, .json and .md; a path ending in '/'
  /// or naming an existing folder: summary.csv/.json/.md inside it; empty = stdout only. An output
  /// that is one of the input reports is refused, even with force.
  std::string out;
  bool force = false;
};

struct EvalSummaryResult {
  nlohmann::json summary;
  std::string markdown;
  std::vector<std::filesystem::path> written;
  std::string to_text() const;
};

/// One row per run and mean and population-std rows (the paper's Tables I–III, which use the
/// population std), as CSV, JSON and Markdown. Each run carries its settings (alignment, n_align,
/// max_dt_s, t_offset_s, assoc); when they differ between runs, `summary["warnings"]` and the
/// Markdown say so (a warning, not an error).
EvalSummaryResult summarize_eval_reports(const EvalSummaryOptions& options);

/// --plot: draws the figure set (app/figures.hpp) of the eval output folder `eval_dir` into
/// eval_dir/plots, with the run folder and dataset of `options` when they are folders. Returns the
/// status line; throws as render_figures does (a plotting failure is an error, nothing is committed).
std::string render_eval_plots(const std::filesystem::path& eval_dir, const EvalOptions& options);

}  // namespace roe::app
