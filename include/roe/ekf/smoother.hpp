#pragma once
/// @file
/// Fixed-interval Rauch–Tung–Striebel smoother over a recorded run of the filter (docs/filter.md §10).
/// I/O-free. `roe run` uses it when the config says `"smoother": "rts"`: an offline tool sees the whole
/// recording, and the estimate at time t may then use the detections after t as well.
///
/// What the filter records (Filter::set_recording): every IMU propagation step (its end time, the
/// nominal core state and the transition F), and a node at every point where the covariance changes
/// otherwise — after initialisation, before and after every stacked update, and after every object
/// augmentation — with the full nominal state and covariance (a node that ends a propagation segment
/// keeps only the core block of its predicted covariance and the accumulated core transition Φ; the rest
/// follows from the node before it, since propagation changes only the core rows/columns).
///
/// The backward pass is the RTS recursion on the filter's own error state and linearisation (no
/// relinearisation), link by link, with δ = x_s ⊟ x̂ (the inverse of Filter::boxplus):
/// - update: the same variables before and after; the smoothed estimate passes unchanged.
/// - propagation a → b: C = P_a Φᵀ P_b⁻ ⁻¹, δ_a = C δ_b, P_s,a = P_a + C (P_s,b − P_b⁻) Cᵀ (one Cholesky
///   factor of P_b⁻ per segment, not per IMU step). At the IMU steps t_1 … t_m = b inside the segment the
///   smoothed mean follows from the segment's two ends and the recorded transitions alone (O(15²) per step,
///   no covariance): with λ = P_b⁻⁻¹ δ_b and its core part carried backwards, λ(t_m) = λ_c, λ(t_{i−1}) =
///   F_iᵀ λ(t_i), the mean runs forwards from δ_a as the dynamics with the smoothed process noise:
///   δ_s(t_i) = F_i δ_s(t_{i−1}) + Q_i λ(t_i) (equal to A_t λ with A_t = P(t) Φ(b, t)ᵀ, the form used
///   before issue 41, in exact arithmetic; tests/ekf/test_smoother.cpp bounds the round-off). The
///   covariance at a step, P_s(t) = P(t) + A_t P_b⁻⁻¹ (P_s,b − P_b⁻) P_b⁻⁻¹ A_tᵀ on the core rows (P(t), Φ
///   re-propagated from P_a with the recorded F and the same process noise), is the costly part: it is
///   computed only at the steps SmootherOptions::covariance_at asks for. So the IMU-rate trajectory is the
///   exact RTS estimate, not an interpolation.
/// - augmentation y = B u + w (a new object's error is J_x u + J_z n): C = P_u Bᵀ P_y⁻¹. A plain
///   augmentation appends the object, C = [I 0]: the old variables' smoothed estimate is the leading block.
/// - decay of the Gauss–Markov detection-error states y = diag(b) u + w (kDecay): the same link with
///   B = diag(b) and P_y = B P_u B + diag(1 − b²), so the smoother is the RTS smoother of the augmented model.
/// - the anchor's first sight also re-defines W (the gauge, docs/filter.md §4): y holds the old
///   variables in the new W, so the states before it come out of the recursion in the old W. They are
///   moved into the new W by the rigid change of frame T_Wnew_Wold that maps the IMU pose smoothed in the
///   old W at that node onto the same pose smoothed in the new W (the linearised δx' = δx + G γ_s left
///   jumps of millimetres). Their covariance stays that of the old W (the uncertainty of the change of
///   frame is not added); the time before the anchor is initialised is short (init_min_detections images).
///
/// Constant states (extrinsics, object-worlds) come out with the final filtered estimate and covariance
/// at every time, as they must for states without process noise; the test suite checks exactly that.

#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/ekf/imu.hpp"
#include "roe/ekf/state.hpp"

namespace roe::ekf {

struct RecordedStep {
  Timestamp t_ns = 0;
  CoreState x;       ///< nominal core state after the step (the filter's prediction)
  CoreTransition F;  ///< the step's transition
};

struct RecordedNode {
  enum class Kind { kInit, kPropagate, kUpdate, kAugment, kDecay };
  Kind kind = Kind::kInit;
  StateEstimate x;        ///< nominal after the link that made this node
  Eigen::MatrixXd P;      ///< full covariance after the link (empty for kPropagate)
  std::size_t steps = 0;  ///< RecordedStep count when the node was made (kPropagate: its steps end here)
  // kPropagate: the steps [first_step, steps) since the previous node, their product Φ = F_k⋯F_1 and the
  // predicted core block of the covariance.
  std::size_t first_step = 0;
  Mat15 Phi = Mat15::Identity();
  Mat15 P_cc = Mat15::Zero();
  // kAugment: B (dim x previous dim) unless append_only (B = [I; J_x]); `anchor`: the anchor's first
  // sight, which also re-defines W (B = M [I; J_x], filter.cpp).
  bool append_only = true;
  bool anchor = false;
  Eigen::MatrixXd B;
  // kDecay: the decay of Gauss–Markov detection-error states (docs/filter.md §17), the linear link
  // y = diag(b) u + w, w ~ N(0, diag(1 − b²)); P is not stored (it is diag(b) P_u diag(b) + diag(1 − b²) of the
  // node before), and the filter always follows a decay with a node that stores P (an update or augmentation).
  Eigen::VectorXd decay;
};

/// Filled by the filter while it runs (Filter::set_recording). Memory: one dense covariance per update
/// and augmentation, and ~0.6 kB per IMU step.
struct FilterRecording {
  std::vector<RecordedStep> steps;
  std::vector<RecordedNode> nodes;
};

/// The smoothed estimate at one time.
struct SmoothedState {
  Timestamp t_ns = 0;
  CoreState x;
  Pose T_I_C;
  /// σ of [δp, δv, δθ, δb_g, δb_a, δp_I_C, δθ_I_C] (0 for extrinsics held fixed); nan at a step whose
  /// covariance was not asked for (SmootherOptions::covariance_at).
  Eigen::Matrix<double, 21, 1> sigma = Eigen::Matrix<double, 21, 1>::Zero();
  Eigen::Matrix<double, 6, 6> pose_cov = Eigen::Matrix<double, 6, 6>::Zero();  ///< [δp_W_I; δθ_W_I]; nan likewise
};

struct SmootherOptions {
  /// 0 = as many as the process may use (its affinity mask), 1 = the caller's thread only; with more than
  /// one, the IMU steps inside each segment are smoothed on a second thread while the backward pass goes
  /// on (the result is bit-identical for every thread count).
  unsigned threads = 0;
  /// The times (increasing) at which the smoothed covariance (sigma, pose_cov) is wanted; nullptr = at
  /// every IMU step. The mean is smoothed at every step either way; the initial state always has its
  /// covariance. A segment none of whose steps is listed costs O(15²) per step instead of O(15²·30), one
  /// whose only listed step is its last skips M, and P(t) is re-propagated only up to a segment's last listed
  /// step (roe run lists its rows' times with `"output": {"rate": "images"}`, and the first step after each
  /// image with `"output": {"level": "standard"}`).
  const std::vector<Timestamp>* covariance_at = nullptr;
};

struct SmootherResult {
  /// The initial time, then one entry per recorded IMU step (strictly increasing times).
  std::vector<SmoothedState> states;
  /// T_Wnew_Wold: the change of frame applied to the states before the anchor's first sight (identity
  /// without an anchor).
  Pose gauge_shift;
};

/// Runs the backward pass. `noise` must be the filter's IMU noise (the process noise is re-derived from
/// the recorded steps). Throws roe::NumericError when a covariance it must invert is not positive
/// definite.
SmootherResult smooth(const FilterRecording& rec, const ImuNoiseParams& noise, const SmootherOptions& options = {});

}  // namespace roe::ekf
