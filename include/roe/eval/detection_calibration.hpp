#pragma once
/// @file
/// Calibration of per-detection uncertainty (the sigma columns of detections.csv) against the ground
/// truth, I/O-free (docs/eval.md, "Detection uncertainty calibration").
///
/// Truth: the true camera → object pose at a detection's stamp, T_C_O = (T_W_I(t_imu) · T_I_C)⁻¹ · T_W_O,
/// with t_imu = t_cam + camera time offset and T_W_I interpolated in the ground truth (true_T_C_O).
/// Error, in the convention the sigma columns and the filter use (ekf/measurement.hpp: t_meas = t + n_t,
/// R_meas = Exp(n_r) R, camera axes): e = [t_meas − t_true ; Log(R_meas R_trueᵀ)] (detection_error).
/// Per detection the normalised errors z_i = e_i / σ_i and NIS = Σ z_i² (6 dof; the columns are per-axis
/// σ, so the covariance is diag(σ²)). For a consistent σ, z_i ~ N(0, 1) and NIS ~ χ²₆.
///
/// Reported per object and for all detections (SigmaCalibration):
///  - the fraction of |z_i| ≤ k for k = 1, 2, 3, pooled over the three translation axes and over the
///    three rotation axes (consistent: χ²₁ CDF(k²) = 68.27 %, 95.45 %, 99.73 %);
///  - NIS: mean (consistent: 6), quantiles at 5/25/50/75/95 % beside χ²₆'s, the fraction above χ²₆'s
///    95 % quantile (a 95 % gate's rejections; consistent: 5 %), and the Kolmogorov–Smirnov distance of
///    the NIS sample from χ²₆ with its asymptotic p-value;
///  - the scale of R that makes them consistent: if the true errors are N(0, s² diag(σ²)), the maximum-
///    likelihood s² = Σ NIS / (6n) (R_scale; sigma_scale = s), with a 95 % interval from χ²_{6n}
///    (independent detections assumed: time-correlated errors make it too narrow); the same per block
///    (translation, rotation: Σ NIS_block / (3n)); and a robust s from the median NIS,
///    √(median NIS / χ²₆ median), which gross outliers barely move.

#include <array>
#include <map>
#include <string>
#include <vector>

#include "roe/core/types.hpp"

namespace roe::eval {

/// T_C_O = (T_W_I · T_I_C)⁻¹ · T_W_O: the one definition of the true detection (the simulator draws its
/// detections around this value).
Pose true_T_C_O(const Pose& T_W_I, const Pose& T_I_C, const Pose& T_W_O);

/// e = [t_meas − t_true ; Log(R_meas R_trueᵀ)], camera axes, m and rad (the sigma columns' convention).
Vector6d detection_error(const Pose& T_C_O_meas, const Pose& T_C_O_true);

/// What the truth of the detections is made of.
struct DetectionTruth {
  std::vector<StampedPose> T_W_I;  ///< ground-truth IMU poses, IMU clock, strictly increasing stamps
  Pose T_I_C;                      ///< camera → IMU (x_I = T_I_C x_C)
  double camera_time_offset_s = 0.0;  ///< t_imu = t_cam + offset
  std::map<int, Pose> T_W_O;          ///< object poses in the ground truth's world, by object id
  /// Ground-truth samples further apart than this are not interpolated across (mocap dropouts).
  Timestamp max_gap_ns = 100'000'000;
};

/// The consistency figures of one group of detections (see the file comment). All zero when n = 0.
struct SigmaCalibration {
  std::size_t n = 0;
  std::array<double, 3> within_t{};  ///< fraction of translation |z| ≤ 1, 2, 3
  std::array<double, 3> within_r{};  ///< fraction of rotation |z| ≤ 1, 2, 3
  double nis_mean = 0.0;
  std::array<double, 5> nis_quantiles{};  ///< at kNisProbabilities
  double frac_above_gate = 0.0;           ///< NIS > χ²₆ 95 % quantile
  double ks_statistic = 0.0;              ///< sup |F_n − F_χ²₆|
  double ks_p_value = 1.0;                ///< asymptotic (Kolmogorov), independent samples assumed
  double sigma_scale = 0.0;               ///< ML s (all six axes); R_scale = s²
  double sigma_scale_lo = 0.0, sigma_scale_hi = 0.0;  ///< 95 % interval of s
  double sigma_scale_t = 0.0, sigma_scale_r = 0.0;    ///< ML s of the translation / rotation block alone
  double sigma_scale_median = 0.0;                     ///< √(median NIS / χ²₆ median)
};

/// Probabilities of SigmaCalibration::nis_quantiles.
inline constexpr std::array<double, 5> kNisProbabilities = {0.05, 0.25, 0.5, 0.75, 0.95};
/// Reference values of a consistent σ: χ²₁ CDF(k²) for k = 1, 2, 3; χ²₆ quantiles at kNisProbabilities;
/// χ²₆'s 95 % quantile (the gate of frac_above_gate).
std::array<double, 3> expected_within();
std::array<double, 5> chi2_6_quantiles();
double nis_gate();

/// One detection's normalised error (for the per-detection output).
struct DetectionResidual {
  Timestamp t_ns = 0;
  int object_id = 0;
  Vector6d error = Vector6d::Zero();  ///< detection_error
  Vector6d sigma = Vector6d::Zero();
  double nis = 0.0;
};

struct ObjectCalibration {
  int object_id = 0;
  SigmaCalibration cal;
};

struct DetectionCalibration {
  std::size_t n_detections = 0;  ///< all detections given
  std::size_t n_without_sigma = 0;
  std::size_t n_without_object_truth = 0;  ///< object id absent from DetectionTruth::T_W_O
  std::size_t n_outside_truth = 0;         ///< stamp outside the ground truth or in a gap
  std::vector<ObjectCalibration> objects;  ///< by object id
  SigmaCalibration all;
  std::vector<DetectionResidual> residuals;  ///< every evaluated detection, in input order
  std::vector<std::string> warnings;
};

/// The figures of a set of (error, σ) pairs.
SigmaCalibration calibrate(const std::vector<DetectionResidual>& residuals);

/// Evaluates every detection with σ against the truth. InputError when none can be evaluated (no σ, no
/// object truth, no overlap in time), saying which.
DetectionCalibration calibrate_detection_sigmas(const std::vector<Detection>& detections, const DetectionTruth& truth);

}  // namespace roe::eval
