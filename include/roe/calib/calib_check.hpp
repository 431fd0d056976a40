#pragma once
/// @file
/// `roe calib-check`'s checks of a run's self-calibration (docs/calib-check.md): are the camera-IMU
/// extrinsics and the object poses observed, settled, consistent with their prior, and — when the
/// dataset knows the truth — accurate; and do the camera stamps agree with the gyro.
///
/// Typed data in, typed verdicts out (no I/O). Each check ends as
///   pass          measured within its limit,
///   fail          measured beyond its limit (the command exits 1),
///   inconclusive  the data cannot decide (e.g. a time offset estimated less precisely than its limit,
///                 a run too short, a dataset that is not there); `--strict` fails on it,
///   skipped       not applicable (extrinsics held fixed, no truth, --no-dataset); never a failure,
///   unobservable  a σ check (extrinsics.sigma, objects.sigma) beyond its limit: the data did not determine the
///                 quantity that well (a slow orbit's lever arm, an object seen briefly). Not calibrated, not
///                 wrong: nothing in the data contradicts the estimate (exit 0; `--strict` fails on it);
///   within-sigma  an error check (extrinsics.settled, truth.*) measured beyond its limit but within what
///                 the filter's own σ explains: not a failure (exit 0), but not a pass either: the
///                 estimate is too uncertain to tell (the σ checks say how uncertain); `--strict` fails
///                 on it, as on inconclusive.
/// The error checks (extrinsics.settled, truth.*) fail only when an error exceeds both the absolute
/// limit and what the filter's own σ explains (a test at `confidence`: χ² for truth.*, a bound on the
/// largest per-axis excursion over the window for .settled): a consistent filter that
/// is still imprecise is caught by the σ checks, not twice.

#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "roe/calib/time_offset.hpp"
#include "roe/core/types.hpp"

namespace roe::calib {

enum class CheckStatus { kPass, kFail, kInconclusive, kSkipped, kWithinSigma, kUnobservable };
/// "pass", "fail", "inconclusive", "skipped", "within-sigma", "unobservable".
const char* to_string(CheckStatus s);

struct CheckResult {
  std::string name;     ///< stable id for scripts, e.g. "extrinsics.sigma"
  CheckStatus status = CheckStatus::kSkipped;
  std::string message;  ///< one line: what was measured, against which limit, or why it was not checked
  /// Measured figures and the limits used, by name (metres, degrees, seconds, or unitless).
  std::vector<std::pair<std::string, double>> values;
};

struct CalibReport {
  std::vector<CheckResult> checks;
  bool failed() const;         ///< any check failed
  bool undecided() const;      ///< any check inconclusive
  bool within_sigma() const;   ///< any check beyond its limit but within its σ
  bool unobservable() const;   ///< any σ check beyond its limit (not calibrated, not contradicted)
};

/// The extrinsics at one time with their standard deviations [p x y z (m), θ x y z (rad)].
struct ExtrinsicsSample {
  Timestamp t_ns = 0;
  Pose T_I_C;
  Vector6d sigma = Vector6d::Zero();
};

/// One object of the run: its final pose T_O_W (absent when it never entered the state) and its
/// standard deviations relative to the anchor [p x y z (m), θ x y z (rad)].
struct ObjectEstimate {
  int id = 0;
  bool anchor = false;
  std::optional<Pose> T_O_W;
  Vector6d sigma_A_O = Vector6d::Zero();
  std::size_t detections = 0;  ///< detections of the object in the run's detection set
};

struct CalibInput {
  bool extrinsics_estimated = true;
  std::optional<int> anchor_id;              ///< the run's anchor object (none: run.json anchor_id null)
  Pose prior_T_I_C;                          ///< the filter's initial extrinsics
  Vector6d prior_sigma = Vector6d::Zero();   ///< their standard deviations (m, rad)
  std::vector<ExtrinsicsSample> extrinsics;  ///< the run's trace, sorted by time (not empty)
  std::vector<ObjectEstimate> objects;
  std::optional<Pose> true_T_I_C;            ///< from the dataset's truth (simulation)
  std::map<int, Pose> true_T_W_O;            ///< from the dataset's truth (simulation)
  /// Object id → its symmetry (roe.json `models_info`): truth.objects compares such an object with the
  /// equivalent of its true pose nearest the estimate (ekf::nearest_equivalent).
  std::map<int, ObjectSymmetry> symmetries;
  /// Objects the dataset marks symmetric (roe.json `symmetric`), described by a models_info or not: a
  /// symmetric anchor makes every pose relative to it defined only up to its symmetry (truth.objects).
  std::vector<int> symmetric_ids;
  /// The offset estimated from the raw camera stamps (estimate_camera_time_offset); absent = not run.
  std::optional<TimeOffsetEstimate> time_offset;
  /// The run's own estimate of the offset, when its filter had the time-offset state (run.json
  /// final.time_offset, FilterOptions::estimate_time_offset): camera.time_offset's verdict then comes from it,
  /// and the detection–gyro correlation above is the independent check of that estimate.
  struct OnlineTimeOffset {
    double value_s = 0.0;
    double sigma_s = 0.0;
  };
  std::optional<OnlineTimeOffset> online_time_offset;
  std::string time_offset_absent_reason;     ///< why it was not run (shown when absent)
  /// Empty when the dataset was read; else why not, for the truth checks ("--no-dataset", …).
  std::string dataset_absent_reason;
  double declared_time_offset_s = 0.0;       ///< the dataset's camera.time_offset_s (applied by roe run)
  /// Empty when the run's estimate (the extrinsics trace, the objects) was read; else why the run folder
  /// has none (a run written with output level minimal): every check is then inconclusive, with this reason,
  /// and `extrinsics` may be empty.
  std::string estimate_absent_reason;
  /// Set when the estimate is a batch solution of the whole recording (`roe refine`, `roe run` with the batch
  /// estimator): Ceres' termination (run.json refine.termination). Its extrinsics have no history to settle
  /// and its σ are the batch's marginals: extrinsics.settled then asks whether the solve converged
  /// (docs/calib-check.md §5).
  std::optional<std::string> batch_termination;
};

/// Limits (defaults and their reasons: docs/calib-check.md §2).
struct CalibThresholds {
  double max_sigma_p_m = 0.01;         ///< extrinsics.sigma: largest axis σ of p_I_C
  double max_sigma_rot_deg = 1.0;      ///< extrinsics.sigma: largest axis σ of θ_I_C
  double settle_fraction = 0.2;        ///< extrinsics.settled: the last fraction of the run …
  double settle_min_s = 2.0;           ///< … but at least this long
  double max_drift_p_m = 0.005;        ///< extrinsics.settled: largest distance from the final p_I_C
  double max_drift_rot_deg = 0.5;      ///< extrinsics.settled: largest angle from the final q_I_C
  double confidence = 0.99;            ///< of the tests (extrinsics.prior, .settled, truth.*) and the time offset
  double max_object_sigma_p_m = 0.02;  ///< objects.sigma: largest axis σ relative to the anchor
  double max_object_sigma_rot_deg = 2.0;
  double max_err_p_m = 0.01;           ///< truth.extrinsics: |p_I_C − truth|
  double max_err_rot_deg = 1.0;        ///< truth.extrinsics: angle(q_I_C, truth)
  double max_object_err_p_m = 0.05;    ///< truth.objects: anchor-relative position error
  double max_object_err_rot_deg = 5.0; ///< truth.objects: anchor-relative rotation error
  double max_time_offset_s = 0.01;     ///< camera.time_offset: |estimated − declared|
};

/// Runs every check in a fixed order: extrinsics.sigma, extrinsics.settled, extrinsics.prior,
/// objects.sigma, truth.extrinsics, truth.objects, camera.time_offset (dataset.identity is the
/// app's, as it reads files).
/// roe::InputError for thresholds that are not positive or an empty extrinsics trace.
CalibReport check_calibration(const CalibInput& in, const CalibThresholds& th = {});

}  // namespace roe::calib
