#pragma once
/// @file
/// Camera–IMU time offset from object detections and the gyro (docs/calib-check.md §3).
///
/// A static object's detected rotation R_C_O(t) and the gyro's integrated rotation must tell the same
/// story once the camera stamps are moved onto the IMU clock: t_imu = t_cam + offset (the convention of
/// roe.json's `camera.time_offset_s` and of Kalibr's `timeshift_cam_imu`). For a candidate offset δ,
/// every detection gives the object's orientation in the frame of the IMU at the start of its window,
///   A_i(δ) = R_I0_I(t_i + δ) · R_I_C · R_C_O(t_i),
/// which is constant over a window for the right δ (R_I0_I from integrating the bias-corrected gyro).
/// The cost of δ is the sum over windows (one per object and `window_s` of its detections) of the
/// squared residual angles of the A_i about a constant rotation plus a linear drift (what a residual
/// gyro bias leaves), truncated at `truncate_deg` so that outliers and flips do not pull. The
/// window's constant starts from a robust point, the detection with the most others within
/// `truncate_deg` at the search's centre (the same one for every δ), so that a flip or an outlier
/// cannot make the mean, its quaternion signs and the inlier set jump as δ moves. An object with a
/// described symmetry (`symmetries`, core/symmetry.hpp) is used through it: each A_i is replaced by its
/// equivalent A_i · S nearest the window's reference (ekf::nearest_equivalent, the filter's choice; the
/// robust start compares through the same map); with a continuous symmetry that turns A_i about the axis
/// to the angle nearest the reference, so the residual has no component about the axis to first order
/// (2 dof instead of 3; the rotation about the axis carries no information). Objects listed in
/// `symmetric_ids` without a described symmetry are left out: their rotation is defined only up to a
/// symmetry the dataset does not describe.
/// The cost is evaluated on a grid over `centre_s` ± `search_s` (centre: the offset the dataset
/// declares), coarse to fine (`coarse_stride`: the full step only where the fits need it); a parabola
/// fitted over ±`fit_halfwidth_s` around its lowest point gives the offset and,
/// from its curvature, the standard error. R_I_C comes from the run (its estimate), because the
/// residual axes depend on it.
///
/// The precision depends on the motion: an offset δ moves each A_i by about |ω|·δ, so it shows only
/// while the camera's rate of turn changes. Detector errors correlated over frames carry fewer
/// independent samples than detections, so `sigma_s` is the largest of three standard errors:
///   - the curvature-based one, inflated by (1 + ρ)/(1 − ρ) in variance for the lag-1 correlation ρ of
///     consecutive residuals (which the per-window fit partly hides: too small alone),
///   - the cluster-robust (sandwich) one, var = G/(G−1) · Σ_w C_w'(δ̂)² / C''(δ̂)² over the G windows,
///     which holds whatever the correlation within a window, as long as windows are independent
///     (noisy when there are few), and
///   - the delete-a-block jackknife: the whole estimate again without each of 10 blocks of windows
///     (contiguous in time), var = (K−1)/K · Σ_b (δ_b − δ̄)². The first two are local to the minimum
///     and miss a minimum that rests on a part of the run (a jagged cost); this one does not. A block
///     without which the cost has no minimum inside the search gives no estimate ("not stable"), and
///     an edge minimum that some block alone makes is marked `edge_stable` = false.
/// docs/calib-check.md §3 compares σ with the spread measured over seeds.

#include <cstddef>
#include <map>
#include <string>
#include <vector>

#include "roe/core/symmetry.hpp"
#include "roe/core/types.hpp"

namespace roe::calib {

struct TimeOffsetOptions {
  double centre_s = 0.0;         ///< search around this offset (the declared one) …
  double search_s = 0.1;         ///< … ± this (seconds)
  double step_s = 0.0005;        ///< grid step (seconds)
  double window_s = 2.0;         ///< detections of one object grouped in windows this long
  std::size_t min_window = 5;    ///< windows with fewer detections are not used
  double truncate_deg = 20.0;    ///< residual angle beyond which a detection costs a constant
  double min_rate_deg_s = 5.0;   ///< RMS gyro rate below which the offset is not observable
  std::size_t min_detections = 50;  ///< fewer usable detections: no estimate
  double fit_halfwidth_s = 0.05; ///< the first parabola fit spans ±this (the second ±3σ of the first)
  /// Coarse to fine: the whole search is evaluated at every coarse_stride-th grid step, the full step only
  /// around the lowest points and inside narrow fits (1: the full grid everywhere, as before 2026-12-02).
  std::size_t coarse_stride = 4;
  /// Threads for the grid (0: every CPU the process may use). The result does not depend on it.
  unsigned threads = 0;
  /// Objects left out unless `symmetries` describes them: a symmetric object's detected rotation is
  /// defined only up to its symmetry (PoET returns either of the equivalent poses).
  std::vector<int> symmetric_ids;
  /// Object id → its symmetry (roe.json `models_info`): such objects are used through it.
  std::map<int, ObjectSymmetry> symmetries;
};

struct TimeOffsetEstimate {
  bool valid = false;
  std::string reason;          ///< why there is no estimate (when !valid)
  double offset_s = 0.0;       ///< t_imu = t_cam + offset_s
  double sigma_s = 0.0;        ///< standard error: the largest of the three below
  double sigma_curvature_s = 0.0;  ///< from the curvature, inflated for the residuals' lag-1 correlation
  double sigma_cluster_s = 0.0;    ///< cluster-robust over windows (0 with fewer than 2 windows)
  double sigma_jackknife_s = 0.0;  ///< delete-a-block jackknife over windows (0 with fewer than 2 windows)
  std::size_t detections = 0;  ///< detections in windows used
  std::size_t symmetric_excluded = 0;  ///< detections of symmetric objects left out
  std::size_t symmetric_used = 0;      ///< detections of objects with a described symmetry, used through it
  std::size_t windows = 0;     ///< windows used
  double rms_rate_deg_s = 0.0; ///< RMS gyro rate over the used detections' times
  double rms_residual_deg = 0.0;  ///< RMS residual angle at the optimum (untruncated inliers)
  double residual_correlation = 0.0;  ///< lag-1 correlation of consecutive residuals (clamped to [0, 0.95])
  /// When the cost is lowest at the edge of the search (valid = false): that edge, and the evidence
  /// for it against the centre, ΔC / (s² (1+ρ)/(1−ρ)), a likelihood-ratio statistic (χ²₁ when the
  /// centre is the true offset).
  bool at_edge = false;
  double edge_offset_s = 0.0;
  double edge_evidence = 0.0;
  /// Whether the cost stays lowest at that edge with any one of the jackknife's blocks of windows left
  /// out (false: the edge rests on a part of the data, and is no evidence).
  bool edge_stable = false;
  std::vector<double> grid_s;  ///< the candidate offsets (the full grid)
  std::vector<double> cost;    ///< the cost per candidate (deg², truncated); NaN where not evaluated
};

/// Estimates the offset from `imu` (sorted, gyro in rad/s), a constant `gyro_bias` (rad/s), the
/// camera-IMU rotation `q_I_C`, and `detections` (T_C_O of static objects, camera clock, any order).
/// Detections whose shifted stamps fall outside the IMU span for some candidate are left out for all.
/// Never throws on data: an unusable input gives valid = false with the reason.
TimeOffsetEstimate estimate_camera_time_offset(const std::vector<ImuSample>& imu, const Eigen::Vector3d& gyro_bias,
                                               const Eigen::Quaterniond& q_I_C,
                                               const std::vector<Detection>& detections,
                                               const TimeOffsetOptions& options = {});

}  // namespace roe::calib
