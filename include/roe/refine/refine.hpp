#pragma once
/// @file
/// The offline batch refinement of a run (docs/refine.md): a robust MAP over the whole recording with
/// Ceres Solver, initialised from the run's (smoothed) estimate. I/O-free: typed data in, typed data out.
///
/// Unknowns: per node (every image with a used detection, plus the first and last time of the run's
/// trajectory) T_W_I, v_W_I, b_g, b_a; the extrinsics T_I_C (held at their prior when the run did not
/// estimate them); one T_O_W per object, the anchor's position and yaw held as the filter holds them.
/// Residuals (factors.hpp): IMU preintegration + bias random walk between consecutive nodes; one per
/// detection with a robust loss on its whitened residual; the extrinsics prior; the first node's bias
/// prior (the filter's initial bias and σ).

#include <Eigen/Core>
#include <map>
#include <string>
#include <vector>

#include "roe/core/symmetry.hpp"
#include "roe/core/types.hpp"
#include "roe/ekf/images.hpp"
#include "roe/ekf/imu.hpp"
#include "roe/ekf/options.hpp"

namespace roe::refine {

using Mat6 = Eigen::Matrix<double, 6, 6>;

enum class Loss { kNone, kHuber, kCauchy };
/// "none", "huber", "cauchy".
std::string to_string(Loss l);
/// roe::ConfigError for another name.
Loss parse_loss(const std::string& name);

struct RefineOptions {
  Loss loss = Loss::kCauchy;
  /// Scale of the loss in units of the detection's σ (the whitened 6-dof residual's norm): quadratic up to
  /// about there. Default √χ²₆(0.95) = 3.55, the filter's gate.
  double loss_scale = 3.5485;
  int max_iterations = 50;
  /// "sparse_normal_cholesky" or "sparse_schur" (Ceres' linear solvers).
  std::string linear_solver = "sparse_normal_cholesky";
  /// The time constant τ of the detections' Gauss-Markov error (docs/refine.md §2): < 0 fitted to the
  /// residuals (default), 0 white (independent detections: every factor is the standardised error), > 0 held.
  double tau_s = -1.0;
  /// How many times the error model (τ, the σ scales, the gross detections) is fitted before a solve: at
  /// the initial estimate, then at each solution (solve → fit → solve). At least 1.
  int fit_rounds = 2;
  /// The IMU noise of the IMU and bias factors, as a multiple of the nominal noise (the run's
  /// RefineInput::noise divided by the run's filter.imu_noise_scale: that scale keeps the causal filter's
  /// χ² gate from refusing correct detections after fast motion, a single-linearisation problem the
  /// iterated batch does not have; docs/refine.md §2).
  double imu_noise_scale = 1.0;
  /// A detection is gross (dropped, its object's chain bridged over it) when its standardised squared
  /// error ‖y‖² (6 dof, the fitted scales) exceeds this: χ²₆(0.9999) by default.
  double gross_chi2 = 27.86;
  /// Marginal covariances of the extrinsics and the object-worlds (ceres::Covariance).
  bool covariance = true;
  int threads = 1;
};

/// The model of the detections' errors the solve whitens with (docs/refine.md §2): per object, the
/// standardised error y = S e (e = detection_error: translation in the camera frame, rotation in the
/// object frame; S: the translation on the viewing ray and across it, each component over the σ model's
/// σ times the block's scale) is a first-order Gauss-Markov process with unit variance per component and
/// time constant τ: y_k = ρ y_{k−1} + √(1 − ρ²) w_k, ρ = exp(−Δt/τ), Δt since the object's previous
/// used detection.
struct DetectionErrorModel {
  double tau_s = 0.0;          ///< 0: white
  double scale_translation = 1.0;  ///< the σ model's translation σ are multiplied by this
  double scale_rotation = 1.0;     ///< the σ model's rotation σ are multiplied by this
  /// Diagnostics of the fit: the lag-1 correlation of the whitened residuals pooled over objects and
  /// components (near 0 when the model fits; clearly negative when a white remainder is there).
  double whitened_lag1 = 0.0;
  std::size_t used = 0, gross = 0;  ///< detections in the chains, detections dropped as gross
  bool fitted_tau = false;          ///< τ was fitted (RefineOptions::tau_s < 0)
  /// ρ of two detections dt_s apart (0 when white).
  double rho(double dt_s) const;
};

/// One object's standardised errors y_k = S_k e_k (unit scales) at times t_k (s, increasing), with the
/// number of rotation components that carry information (3, or 2 for a continuous symmetry).
struct ErrorSeries {
  std::vector<double> t_s;
  std::vector<Vector6d> y;
  int rotation_dof = 3;
};

/// Maximum likelihood fit of DetectionErrorModel to error series: for a given τ the scales have the
/// closed form s² = mean of the whitened squared residuals of their block, and τ minimises the profile
/// negative log-likelihood ½ [N_t ln s_t² + N_r ln s_r² + Σ_k dof_k ln(1 − ρ_k²)] over 0 and a log grid
/// of [0.01, 100] s refined by golden section. tau_fixed ≥ 0: τ held there, only the scales fitted.
DetectionErrorModel fit_error_model(const std::vector<ErrorSeries>& series, double tau_fixed = -1.0);

/// Leave-one-out outliers of a series under the model: d_k² = the squared standardised distance of y_k
/// (over the scales) from its conditional mean given its neighbours y_{k−1}, y_{k+1}, in units of the
/// conditional σ (√((1 − ρ₁²)(1 − ρ₂²)/(1 − ρ₁²ρ₂²)) of the unit AR(1)); flagged where d_k² > chi2 and
/// d_k² is at least its neighbours' (an outlier also disturbs its neighbours' d, less). Much sharper than
/// ‖y‖² when ρ is near 1: an outlier is far from where its neighbours say the slow error is.
std::vector<bool> isolated_outliers(const ErrorSeries& s, const DetectionErrorModel& m, double chi2);

/// An IMU state with its time (a node, or the run's estimate that initialises one).
struct StateSample {
  Timestamp t_ns = 0;
  ekf::CoreState x;
};

struct RefineInput {
  std::vector<ImuSample> imu;
  ekf::ImuNoiseParams noise;      ///< what the run's filter used (after imu_noise_scale)
  ekf::FilterOptions filter;      ///< the run's: detection σ model, extrinsics prior σ, gauge, bias σ
  double detection_sigma_scale = 1.0;  ///< the run's final learned scale of per-detection σ
  std::map<int, ObjectSymmetry> symmetries;
  /// The detections to use, grouped per image in the IMU clock (the run's accepted and gated ones).
  std::vector<ekf::ImageDetections> images;
  /// The run's estimate (time-sorted, e.g. states.csv), interpolated to initialise the nodes; its first
  /// and last times are the first and last node.
  std::vector<StateSample> initial;
  Pose prior_T_I_C;               ///< the extrinsics prior (the run's init.T_I_C)
  Pose initial_T_I_C;             ///< where the solve starts
  std::map<int, Pose> initial_T_O_W;  ///< objects without an entry are left out with their detections
  int anchor_id = -1;
  Eigen::Vector3d prior_b_g = Eigen::Vector3d::Zero();  ///< the filter's initial biases (the first node's prior)
  Eigen::Vector3d prior_b_a = Eigen::Vector3d::Zero();
  /// The camera–IMU time offset t_d (t_imu = t_cam + t_d; docs/refine.md §2b). `images` are in the IMU clock
  /// with the declared offset (roe.json camera.time_offset_s). With estimate_time_offset the batch estimates
  /// t_d, starting from initial_time_offset_s (the run's estimate), with the prior N(declared,
  /// filter.time_offset_sigma_s²) — the filter's own prior, so the detections are not counted twice.
  double declared_time_offset_s = 0.0;
  bool estimate_time_offset = false;
  double initial_time_offset_s = 0.0;
};

struct RefinedObject {
  Pose T_O_W;
  bool anchor = false;
  Mat6 cov = Mat6::Zero();            ///< [δp_O_W; δθ_O_W] (rows/columns of held components 0)
  Mat6 cov_relative = Mat6::Zero();   ///< T_A_O relative to the anchor (0 for the anchor)
};

/// One detection after the solve.
struct DetectionFit {
  Timestamp t_ns = 0;
  int object_id = 0;
  double chi2 = 0.0;    ///< squared whitened residual ‖r‖² of its factor (a gross one: its ‖y‖²)
  double weight = 1.0;  ///< the robust loss's weight ρ'(s) at the solution (0: dropped as gross)
};

struct SolveReport {
  int iterations = 0;
  double initial_cost = 0.0, final_cost = 0.0;
  std::string termination;  ///< Ceres' termination type and message
  bool usable = false;      ///< Ceres' IsSolutionUsable()
  double solve_s = 0.0, covariance_s = 0.0;
  /// Ceres' own split of solve_s: residual and Jacobian evaluation, linear solves.
  double residual_s = 0.0, jacobian_s = 0.0, linear_solver_s = 0.0;
  bool covariance_ok = false;
  std::size_t nodes = 0, imu_factors = 0, detection_factors = 0, parameters = 0, residuals = 0;
  DetectionErrorModel error_model;  ///< the last fit, the one the final solve whitened with
  int solves = 0;                   ///< Ceres solves (one per fit round)
};

struct RefineResult {
  std::vector<StateSample> nodes;
  Pose T_I_C;
  Mat6 cov_T_I_C = Mat6::Zero();  ///< [δp_I_C; δθ_I_C] (0 when held fixed)
  bool extrinsics_estimated = true;
  std::map<int, RefinedObject> objects;
  std::vector<DetectionFit> detections;  ///< in the order of RefineInput::images
  /// t_d (s) and its marginal σ (0: held at the declared offset, RefineInput::estimate_time_offset false).
  bool time_offset_estimated = false;
  double time_offset_s = 0.0, sigma_time_offset_s = 0.0;
  SolveReport report;
};

/// Builds and solves the problem. InputError for an empty IMU stream, fewer than two state samples,
/// images outside their span, or no object-world to start from; NumericError when Ceres fails.
RefineResult refine(const RefineInput& in, const RefineOptions& options);

/// The refined IMU states at the given times (sorted, within the nodes' span): each propagated with the
/// IMU from the last node at or before it (ekf::integrate, preintegration.hpp).
std::vector<StateSample> states_at(const RefineResult& r, const std::vector<ImuSample>& imu,
                                   const std::vector<Timestamp>& times);

}  // namespace roe::refine
