#pragma once
/// @file
/// One evaluation of an estimate against ground truth, I/O-free (notes/eval.md §7): association
/// (associate.hpp) → alignment (align.hpp) → APE (metrics.hpp), the relative pose error (rpe.hpp) of
/// the aligned pairs for each requested delta, and the per-object traces of a run's raw detections.
/// The result is a typed Report (as OpenVINS's ov_eval ResultTrajectory); io/eval_report.hpp turns
/// it into report.json and the CSV files, app/eval.cpp reads the inputs and calls evaluate() once.

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "roe/core/types.hpp"
#include <memory>

#include "roe/eval/align.hpp"
#include "roe/eval/associate.hpp"
#include "roe/eval/body_pose.hpp"
#include "roe/eval/detection_calibration.hpp"
#include "roe/eval/gauge.hpp"
#include "roe/eval/kitti.hpp"
#include "roe/eval/metrics.hpp"
#include "roe/eval/rpe.hpp"
#include "roe/eval/time_offset.hpp"

namespace roe::eval {

/// How to evaluate. check_params() validates it.
struct EvalParams {
  AlignType align = AlignType::kSe3;
  int n_align = -1;  ///< align on the first N matched pairs (-1 = all)
  AssociationOptions assoc;
  std::vector<RpeOptions> rpe;  ///< one relative-pose-error block per delta (none: no RPE)
  EulerMetric euler = EulerMetric::kError;  ///< the per-axis Euler figures (metrics.hpp)
  /// Also fit a constant body-frame rotation after the alignment and report the metrics with it
  /// (a diagnostic: the headline figures never include it).
  bool fit_body_rotation = false;
  /// --t-offset auto: estimate the estimate–ground-truth offset (time_offset.hpp) within ±auto_offset_max_s
  /// and associate with it instead of assoc.offset_s.
  bool auto_offset = false;
  double auto_offset_max_s = 1.0;
  /// Without auto_offset: check whether the pairs look time-shifted (check_trajectory_offset) and warn.
  bool check_offset = true;
  /// --gt-body-pose: T_B_I, the estimate's body in the ground truth's (T_W_I = T_W_B·T_B_I), applied to
  /// every ground-truth pose.
  std::optional<Pose> gt_body_pose;
  /// --fit-body-pose: fit T_B_I (body_pose.hpp) on the pairs and evaluate with it.
  bool fit_body_pose = false;
  /// --t-start / --t-end: only pairs whose ground-truth stamp lies in [t_start, t_end] (ns).
  std::optional<Timestamp> t_start_ns, t_end_ns;
  /// --align-window T0:T1: the alignment from the pairs whose ground-truth stamp lies in [T0, T1] only.
  std::optional<std::pair<Timestamp, Timestamp>> align_window_ns;
  /// --kitti: the KITTI odometry drift figures (kitti.hpp) of the aligned pairs.
  bool kitti = false;
  /// Threads for the per-pair work (0: every CPU the process may use). The report does not depend on it.
  unsigned threads = 0;
};

/// Above this tilt of the alignment (the angle between the ground truth's z and the aligned estimate's
/// z), an SE(3)/Sim(3) alignment gets a warning naming --align posyaw.
inline constexpr double kTiltWarningDeg = 1.0;

/// InputError (key path = the option's CLI name) for a bad max_dt, n_align, RPE block or a delta
/// listed twice, a crop or alignment window that is empty, --fit-body-pose with --gt-body-pose or with
/// an alignment it cannot fit. Returns the warnings the parameters alone imply (n_align ignored by origin/none).
std::vector<std::string> check_params(const EvalParams& p);

/// The IMU pose T_W_I one raw detection implies (a run folder's reprojection.csv). A detection
/// that gave no pose has a non-finite position; it still counts in the status counts.
struct DetectionPose {
  Timestamp t_ns = 0;
  int object_id = 0;
  Pose T_W_I;
  std::string status;  ///< accepted, initialized, rejected, ...
  double nis = 0.0;
  std::string used;  ///< the part that updated the filter: none, position, rotation, both (empty: older files)
};

/// Detections with σ to calibrate against the ground truth (detection_calibration.hpp): the ground
/// truth's poses are T_W_I; T_I_C, the camera time offset and the object poses complete the truth.
struct DetectionSigmaInput {
  const std::vector<Detection>& detections;
  Pose T_I_C;
  double camera_time_offset_s = 0.0;  ///< t_imu = t_cam + offset
  std::map<int, Pose> T_W_O;          ///< in the ground truth's world
};

/// The truth in the estimator's own gauge (gauge.hpp): the estimator's world in the ground truth's,
/// valid from t_from_ns (the anchor's first sight: the rows before it are in an earlier world).
struct GaugeTruth {
  Pose T_Wt_Wg;
  Timestamp t_from_ns = 0;
  std::string description;  ///< how it was found (for the report)
};
/// The estimate: stamps and poses (non-decreasing stamps), optionally a covariance per pose and
/// the run's raw detections. The vectors are referenced, not copied: they must outlive the call, and
/// the stamps and poses also the Report made from them (it indexes the matched pairs in them).
struct EstimateInput {
  const std::vector<Timestamp>& t_ns;
  const std::vector<Pose>& poses;
  /// Empty (no NEES) or one per pose; a pose without one disables NEES with a warning.
  const std::vector<std::optional<PoseCovariance>>& cov;
  const std::vector<DetectionPose>* detections = nullptr;  ///< null: no per-object traces
  std::string source;  ///< names the estimate in errors (a path), never opened
  const DetectionSigmaInput* detection_sigmas = nullptr;  ///< null: no σ calibration
  /// null: no NEES in the estimator's gauge (then only the alignment-relative NEES, which its
  /// rotation error inflates).
  const GaugeTruth* gauge = nullptr;
};

/// NEES of the unaligned estimate against the truth in the estimator's gauge, with the estimate's own
/// covariance (no alignment in it): pose_nees(est, T_Wg_Wt · gt, cov) over the matched pairs from
/// t_from_ns on. A consistent filter reads ≈ 3 for each block.
struct GaugeConsistency {
  GaugeTruth truth;
  std::size_t n = 0;  ///< pairs used
  std::optional<double> anees_p, anees_r;
};

/// The constant rotation between the estimated and the true body frames after the alignment,
/// R_off = mean on SO(3) of R_estᵀ R_gt (metrics.hpp mean_rotation), and the APE with the estimate's
/// orientations replaced by R_est·R_off (positions unchanged).
struct BodyRotationFit {
  Eigen::Quaterniond q_off = Eigen::Quaterniond::Identity();
  double angle_deg = 0.0;                                ///< |Log(R_off)|
  Eigen::Vector3d rpy_deg = Eigen::Vector3d::Zero();     ///< ZYX Euler of R_off
  ApeResult ape;                                         ///< with the offset removed
};
/// The ground truth (referenced as EstimateInput's vectors are).
struct GroundTruthInput {
  const std::vector<Timestamp>& t_ns;
  const std::vector<Pose>& poses;
};

/// APE of one object's detection trace (all its matched detections, or the accepted ones).
struct ObjectFit {
  std::size_t n = 0;  ///< matched detections used; the figures below are 0 when n = 0
  Eigen::Vector3d pos_rmse_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d rpy_rmse_deg = Eigen::Vector3d::Zero();
  double ape_trans_rmse_m = 0.0;
  double ape_rot_rmse_deg = 0.0;
};

/// One object's trace: its detections' implied IMU poses (aligned with the trajectory's alignment)
/// against the ground truth, with the same association options.
struct ObjectReport {
  int object_id = 0;
  std::size_t n_detections = 0;
  std::map<std::string, std::size_t> counts;  ///< detections per status
  std::size_t n_valid_pose = 0;
  std::size_t n_matched = 0;
  ObjectFit all;       ///< every matched detection, outliers included
  ObjectFit accepted;  ///< only those the filter accepted (status accepted or initialized)
};

/// Everything one evaluation computes.
struct Report {
  EvalParams params;
  std::size_t n_est = 0, n_gt = 0;
  Association association;
  Overlap overlap;
  double max_abs_dt_s = 0.0;
  Alignment alignment;
  Eigen::Quaterniond alignment_q = Eigen::Quaterniond::Identity();  ///< alignment.q()
  /// The inputs the matched pairs index (set by evaluate()): the report refers to them instead of
  /// copying the matched poses, so they must outlive it.
  const std::vector<Timestamp>* est_t_ns = nullptr;
  const std::vector<Pose>* est_poses = nullptr;
  const std::vector<Timestamp>* gt_t_ns = nullptr;
  const std::vector<Pose>* gt_poses = nullptr;
  /// The matched estimate covariances rotated into the aligned frame (empty: no NEES).
  std::vector<PoseCovariance> cov;
  ApeResult ape;
  std::vector<RpeResult> rpe;  ///< one per params.rpe entry
  bool has_detections = false;
  std::vector<ObjectReport> objects;              ///< by object id
  std::vector<DetectionPose> detections_aligned;  ///< every detection, grouped by object id
  double path_length_est_m = 0.0, path_length_gt_m = 0.0;
  /// The detections' σ against the ground truth (EstimateInput::detection_sigmas), independent of the
  /// alignment: T_C_O is relative.
  std::optional<DetectionCalibration> detection_calibration;
  std::optional<GaugeConsistency> gauge;       ///< EstimateInput::gauge given and covariances present
  std::optional<BodyRotationFit> body_rotation;  ///< EvalParams::fit_body_rotation
  std::optional<TrajectoryOffset> time_offset;   ///< EvalParams::auto_offset (params.assoc.offset_s holds its value)
  std::optional<OffsetCheck> offset_check;       ///< the check without auto_offset (when it could run)
  std::optional<BodyPoseFit> body_pose;          ///< EvalParams::fit_body_pose
  /// The alignment's tilt: the angle between the ground truth's z axis and the aligned estimate's (deg).
  double tilt_deg = 0.0;
  /// The tilt-free alternative when the tilt warning fired: rotation RMSE with --align posyaw (deg).
  std::optional<double> posyaw_rot_rmse_deg;
  std::size_t n_cropped = 0;  ///< pairs left out by t_start / t_end
  std::optional<KittiDrift> kitti;  ///< EvalParams::kitti
  /// The ground truth the pairs index when evaluate() made it (body pose applied, or resampled at the
  /// estimate's stamps with --assoc interpolate); gt_t_ns / gt_poses point into these then.
  std::shared_ptr<const std::vector<Timestamp>> owned_gt_t_ns;
  std::shared_ptr<const std::vector<Pose>> owned_gt_poses;
  std::vector<std::string> warnings;  ///< what the data implies (duplicates, few matches, ...)

  /// The matched pairs, in association order: pair k is the estimate's pose association.est_index[k]
  /// and the ground truth's pose association.gt_index[k].
  std::size_t n_pairs() const { return association.size(); }
  Timestamp t_est(std::size_t k) const { return (*est_t_ns)[association.est_index[k]]; }
  Timestamp t_gt(std::size_t k) const { return (*gt_t_ns)[association.gt_index[k]]; }
  /// The estimate pose of pair k in the ground truth's frame (aligned_pose() with the alignment).
  Pose est_aligned(std::size_t k) const { return aligned_pose(alignment, alignment_q, (*est_poses)[association.est_index[k]]); }
  const Pose& gt(std::size_t k) const { return (*gt_poses)[association.gt_index[k]]; }
  /// Pair k's errors, as the APE statistics saw them.
  PoseError error(std::size_t k) const { return pose_error(est_aligned(k), gt(k)); }

  /// The alignment type to report: the one requested when nothing was aligned.
  AlignType align_type() const { return alignment.type == AlignType::kNone ? params.align : alignment.type; }
};

/// Evaluates `est` against `gt`. InputError (at est.source) when no pair matches, with
/// explain_no_match()'s diagnosis; DataError when the alignment is degenerate.
Report evaluate(const EstimateInput& est, const GroundTruthInput& gt, const EvalParams& params);

}  // namespace roe::eval
