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
  /// The marginals account for the objects' correlated detection errors (docs/refine.md §2b): the error
  /// model is fitted to the solution's residuals (fit_error_model) and each detection's information is
  /// divided by DetectionErrorModel::variance_factor when the covariance is computed. False: the
  /// marginals of white errors with the filter's σ (the solve itself is the same either way).
  bool correlated_errors = true;
  /// Marginal covariances of the extrinsics and the object-worlds (ceres::Covariance).
  bool covariance = true;
  int threads = 1;
};

/// The model of an object's correlated detection error in the whitened residual u = W e of its detections
/// (docs/refine.md §2b): u(t) = β(t) + w, β a first-order Gauss-Markov process per object (stationary σ
/// s_b per component, time constant τ), w white with σ s_w. All σ in units of the detection's σ (the
/// filter's model times its learned scale), so s_b² + s_w² = 1 when that σ is right.
struct DetectionErrorModel {
  bool correlated = false;   ///< false: white errors (s_b = 0)
  double tau_s = 0.0;
  double sigma_bias = 0.0;   ///< s_b
  double sigma_white = 1.0;  ///< s_w
  /// The variance of a long mean of detections dt_s apart relative to as many independent detections of
  /// unit variance: s_w² + s_b² (1 + φ)/(1 − φ), φ = exp(−dt/τ) (s_w² for a first detection, dt < 0).
  double variance_factor(double dt_s) const;
  /// The fit's data: per lag bin, the mean lag (s), the autocovariance C(lag) and the number of pairs;
  /// lag 0 first (C(0), the variance).
  struct Bin {
    double lag_s = 0.0, cov = 0.0;
    std::size_t pairs = 0;
  };
  std::vector<Bin> autocovariance;
};

/// One object's whitened residuals u_k (6 components) at times t_k (s, increasing): fit_error_model's input.
struct ResidualSeries {
  std::vector<double> t_s;
  std::vector<Vector6d> u;
};

/// Fits DetectionErrorModel to residual series: the autocovariance per component, pooled over objects, in
/// lag bins up to 4.8 s; correlated when C(0.3–0.6 s) exceeds 0.1 C(0); then ln C(lag) = ln s_b² − lag/τ
/// by least squares (weighted by pairs) over the bins from 0.1 s on with C > 0.02 C(0), τ clamped to
/// [0.1, 60] s, s_b² ≤ 0.98 C(0), s_w² = C(0) − s_b² (at least 0.02 C(0)). White: s_w² = C(0).
DetectionErrorModel fit_error_model(const std::vector<ResidualSeries>& series);

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
  double chi2 = 0.0;    ///< whitened squared residual (6 dof; 5 for a continuous symmetry)
  double weight = 1.0;  ///< the robust loss's weight ρ'(s) at the solution
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
  DetectionErrorModel error_model;  ///< fitted to the solution (RefineOptions::correlated_errors)
};

struct RefineResult {
  std::vector<StateSample> nodes;
  Pose T_I_C;
  Mat6 cov_T_I_C = Mat6::Zero();  ///< [δp_I_C; δθ_I_C] (0 when held fixed)
  bool extrinsics_estimated = true;
  std::map<int, RefinedObject> objects;
  std::vector<DetectionFit> detections;  ///< in the order of RefineInput::images
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
