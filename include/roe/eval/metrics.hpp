#pragma once
/// @file
/// Absolute pose error (APE) metrics of matched, aligned pose pairs (notes/eval.md §1, §5, §7).
///
/// Per pair i (estimate already aligned):
///   translation error  e_p = p_est − p_gt  (evo trans_part; norm = APE translation),
///   rotation error     R_e = R_estᵀ · R_gt (evo's E_i = P_est⁻¹ P_ref, cnspy type5),
///   angle              |Log(R_e)| in degrees (evo rotation_angle_deg),
///   Euler              ZYX of R_e: R_e = Rz(yaw) Ry(pitch) Rx(roll), each wrapped to [-180°, 180°).
/// Statistics use evo's keys and definitions: rmse = √(Σe²/n), mean, median (average of the two
/// middle values for even n), std = population standard deviation (ddof 0), min, max, sse = Σe².
/// ARMSE_p / ARMSE_R are cnspy's report values: the MEAN of the per-pair norms (not an RMSE).

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "roe/core/types.hpp"

namespace roe::eval {

/// How the per-axis Euler figures are formed (roe eval --euler; docs/eval.md "Euler metrics").
/// kError: ZYX Euler of the rotation error R_estᵀR_gt, wrapped to [-180°, 180°) (roe's default, cnspy
/// type5, notes/eval.md §5 convention B): a rotation error.
/// kAbsolute: the difference of the absolute ZYX angles, Euler(R_est) − Euler(R_gt), wrapped to
/// [-180°, 180°) (ov_eval's per-axis figure, convention D): not a rotation error (it mixes frames and
/// breaks down near pitch ±90°).
/// kAbsoluteUnwrapped: the same difference without the wrap, in (−360°, 360°): a 360° jump wherever
/// one absolute angle crosses ±180° and the other does not (the only definition found that reaches the
/// paper's Table I Euler column). Not a rotation error either.
enum class EulerMetric { kError, kAbsolute, kAbsoluteUnwrapped };
/// "error", "absolute", "absolute-unwrapped".
std::string to_string(EulerMetric m);
/// InputError (key euler) for another name.
EulerMetric parse_euler_metric(const std::string& name);
/// One line defining the metric's figure, for reports.
std::string euler_metric_definition(EulerMetric m);

struct Stats {
  double rmse = 0.0, mean = 0.0, median = 0.0, std = 0.0, min = 0.0, max = 0.0, sse = 0.0;
  std::size_t n = 0;
};

/// Statistics of `values` (copied: the median sorts). All zero for an empty input.
Stats compute_stats(std::vector<double> values);

/// The errors of one pair.
struct PoseError {
  Eigen::Vector3d dp = Eigen::Vector3d::Zero();               ///< p_est − p_gt (m)
  Eigen::Quaterniond q_err = Eigen::Quaterniond::Identity();  ///< R_estᵀ R_gt, w ≥ 0
  Eigen::Vector3d rpy_deg = Eigen::Vector3d::Zero();          ///< ZYX Euler of q_err, each in [-180, 180)
  double angle_deg = 0.0;                                     ///< |Log(R_estᵀ R_gt)| (deg)
};

PoseError pose_error(const Pose& est, const Pose& gt);

/// The absolute ZYX angles' difference Euler(R_est) − Euler(R_gt) (deg), each axis in (−360, 360):
/// kAbsoluteUnwrapped's figure; wrap_180 of each axis is kAbsolute's.
Eigen::Vector3d absolute_euler_difference_deg(const Pose& est, const Pose& gt);
/// The per-axis Euler figure of one pair under `m` (deg); `e` is pose_error(est, gt) (kError's figure).
Eigen::Vector3d euler_figure_deg(const Pose& est, const Pose& gt, const PoseError& e, EulerMetric m);

/// Per-axis statistics of Euler figures (deg): rmse = √(Σx²/n), mean, population std. A constant
/// offset shows as rmse ≫ std (rmse² = mean² + std²).
struct EulerStats {
  Eigen::Vector3d rmse = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Vector3d std = Eigen::Vector3d::Zero();
};

/// Position and orientation covariance of an estimate pose. Position: in the estimate's world
/// frame; orientation: of the local (right) error δθ with R_true = R_est · Exp(δθ) (roe's error
/// state), in radians².
struct PoseCovariance {
  Eigen::Matrix3d P_p = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d P_theta = Eigen::Matrix3d::Zero();
};

/// NEES of one pair: position e_pᵀ P_p⁻¹ e_p and orientation δθᵀ P_θ⁻¹ δθ with δθ = Log(R_estᵀ R_gt).
/// NaN when the covariance block is not positive definite.
struct Nees {
  double pos = 0.0;
  double rot = 0.0;
};
Nees pose_nees(const Pose& est, const Pose& gt, const PoseCovariance& cov);

/// Everything roe eval reports for one set of matched, aligned pairs (the per-pair errors are not kept:
/// pose_error() gives them again, bit for bit, where they are written).
struct ApeResult {
  Stats trans_m;                                           ///< of |e_p|
  Stats rot_deg;                                           ///< of the rotation angle
  Eigen::Vector3d pos_rmse_m = Eigen::Vector3d::Zero();    ///< per-axis RMSE of e_p
  EulerMetric euler_metric = EulerMetric::kError;          ///< the metric of rpy_rmse_deg / rpy
  Eigen::Vector3d rpy_rmse_deg = Eigen::Vector3d::Zero();  ///< per-axis RMSE of the euler_metric figures
  EulerStats rpy;                                          ///< rmse (= rpy_rmse_deg), mean, std of them
  EulerStats rpy_error;  ///< the same of kError's figures (= rpy when euler_metric is kError)
  /// Share of the pairs whose absolute-angle difference jumped by 360° (|unwrapped| ≥ 180°), per axis
  /// and on any axis: where kAbsolute and kAbsoluteUnwrapped differ.
  Eigen::Vector3d jump_share = Eigen::Vector3d::Zero();
  double jump_share_any = 0.0;
  Eigen::Vector3d pos_mean_m = Eigen::Vector3d::Zero();    ///< per-axis mean of e_p (≈0 after Umeyama)
  double armse_p_m = 0.0;                                  ///< cnspy ARMSE_p = mean |e_p|
  double armse_r_deg = 0.0;                                ///< cnspy ARMSE_R = mean angle
  /// Per-pair NEES and their means (ANEES) when covariances were given.
  std::vector<Nees> nees;
  std::optional<double> anees_p, anees_r;
};

/// APE of aligned estimate poses against ground truth (same size; InputError otherwise).
/// `cov` (empty, or one per pair, already rotated into the aligned frame) adds NEES. The pairs are
/// evaluated on up to `threads` threads (0: every CPU the process may use); the result is the same,
/// bit for bit, for any thread count (every sum takes the pairs in order).
ApeResult compute_ape(const std::vector<Pose>& est_aligned, const std::vector<Pose>& gt,
                      const std::vector<PoseCovariance>& cov = {}, unsigned threads = 0,
                      EulerMetric euler = EulerMetric::kError);
/// Pairs per parallel task of the per-pair work: large enough that handing out a task costs nothing,
/// small enough to balance the threads.
inline constexpr std::size_t kPairsPerTask = 16384;
/// Pair i of an APE: (aligned estimate pose, ground-truth pose). Called once per pair, from any thread.
using PosePairAt = std::function<std::pair<Pose, Pose>(std::size_t)>;
/// The same over n pairs given by `pair` (no copy of the matched poses needed).
ApeResult compute_ape(std::size_t n, const PosePairAt& pair, const std::vector<PoseCovariance>& cov = {},
                      unsigned threads = 0, EulerMetric euler = EulerMetric::kError);

/// The mean of rotations on SO(3) (Karcher mean: R ← R·Exp(mean_i Log(Rᵀ R_i)) from the normalised
/// quaternion average, until the step is below 1e-12 rad or 100 steps). Identity for n = 0.
Eigen::Quaterniond mean_rotation(std::size_t n, const std::function<Eigen::Quaterniond(std::size_t)>& q_at);

/// Rotates a covariance into the aligned frame: P_p' = s² R P_p Rᵀ; P_θ is local and unchanged.
PoseCovariance align_covariance(const PoseCovariance& c, const Eigen::Matrix3d& R, double s);

}  // namespace roe::eval
