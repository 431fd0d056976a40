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
#include <cstdint>
#include <memory>
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

/// Where a FilterRecording keeps what it has recorded (I/O-free): bytes appended in order, read back by offset.
/// FilterRecording's default keeps them in memory; roe run gives a temporary file beside --out
/// (store::RecordingFile), so that memory does not grow with the recording.
class RecordingSpill {
 public:
  virtual ~RecordingSpill() = default;
  /// Appends `n` bytes; returns the offset of the first.
  virtual std::uint64_t append(const void* data, std::size_t n) = 0;
  /// Reads `n` bytes from `offset` (within what was appended).
  virtual void read(std::uint64_t offset, void* data, std::size_t n) const = 0;
};

/// The recorded IMU steps (FilterRecording::steps): the part of std::vector's interface the filter uses, the
/// steps themselves in the recording's spill in chunks of kChunk (their 63 doubles each, exact), their times in
/// memory (8 bytes a step).
class StepLog {
 public:
  static constexpr std::size_t kChunk = 1024;
  void push_back(const RecordedStep& step);
  std::size_t size() const { return times_.size(); }
  void reserve(std::size_t n) { times_.reserve(n); }
  void clear();
  Timestamp time(std::size_t i) const { return times_[i]; }
  /// Step i, read back.
  RecordedStep operator[](std::size_t i) const;
  /// Steps [first, last), read back into `out`.
  void load(std::size_t first, std::size_t last, std::vector<RecordedStep>& out) const;

 private:
  friend class FilterRecording;
  RecordingSpill* spill_ = nullptr;
  std::vector<Timestamp> times_;
  std::vector<RecordedStep> tail_;     // the steps after the last full chunk
  std::vector<std::uint64_t> chunks_;  // the spill offset of each full chunk
};

/// The recorded nodes (FilterRecording::nodes): the part of std::vector's interface the filter uses. The node
/// in progress (back(): the filter fills it after emplace_back) is held whole; a node is final when the next
/// one is made, and then its matrices (P, Φ and P_cc, B, the decay) go to the spill and its kind, step counts
/// and nominal state stay in memory.
class NodeLog {
 public:
  RecordedNode& emplace_back();
  RecordedNode& back() { return live_; }
  const RecordedNode& back() const { return live_; }
  std::size_t size() const { return heads_.size() + (has_live_ ? 1 : 0); }
  bool empty() const { return size() == 0; }
  void reserve(std::size_t n) { heads_.reserve(n); }
  void clear();
  /// Node j, read back (the matrices from the spill).
  RecordedNode operator[](std::size_t j) const;
  /// Node j's kind and whether it is the anchor's first sight, without reading it back.
  RecordedNode::Kind kind(std::size_t j) const { return j < heads_.size() ? heads_[j].kind : live_.kind; }
  bool anchor(std::size_t j) const { return j < heads_.size() ? heads_[j].anchor : live_.anchor; }

  /// Iteration over the nodes, each read back (`for (const auto& nd : rec.nodes)`).
  class const_iterator {
   public:
    const_iterator(const NodeLog* log, std::size_t j) : log_(log), j_(j) {}
    RecordedNode operator*() const { return (*log_)[j_]; }
    const_iterator& operator++() {
      ++j_;
      return *this;
    }
    bool operator!=(const const_iterator& o) const { return j_ != o.j_; }

   private:
    const NodeLog* log_;
    std::size_t j_;
  };
  const_iterator begin() const { return {this, 0}; }
  const_iterator end() const { return {this, size()}; }

 private:
  friend class FilterRecording;
  struct Head {
    RecordedNode::Kind kind;
    bool append_only, anchor;
    std::size_t steps, first_step;
    StateEstimate x;
    std::uint64_t offset, doubles;  // where its matrices are in the spill, and how many doubles they are
  };
  void spill_live();
  RecordingSpill* spill_ = nullptr;
  std::vector<Head> heads_;
  RecordedNode live_;
  bool has_live_ = false;
};

/// Filled by the filter while it runs (Filter::set_recording). Memory: the nodes' nominal states (~0.3 kB and
/// the objects' entries per update and augmentation) and 8 bytes per IMU step; the rest (~0.5 kB per IMU step
/// and one dense covariance per update and augmentation) in `spill`, by default in memory as well. Movable,
/// not copyable.
class FilterRecording {
 public:
  /// `spill`: where the steps and the nodes' matrices go (outliving the recording); nullptr: in memory.
  explicit FilterRecording(RecordingSpill* spill = nullptr);
  ~FilterRecording();
  FilterRecording(FilterRecording&&) noexcept;
  FilterRecording& operator=(FilterRecording&&) noexcept;
  StepLog steps;
  NodeLog nodes;

 private:
  std::unique_ptr<RecordingSpill> own_;  // the in-memory spill when none is given
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
  /// on, at most 64 segments behind it (the result is bit-identical for every thread count).
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

/// Where the backward pass hands its smoothed states as it produces them (smooth with a sink): the states of
/// each propagation segment (its IMU steps, in time order), the segments from the last to the first, then the
/// initial state alone. Together they are SmootherResult::states, bit for bit. Called from one thread at a
/// time (the smoother's second thread, when it has one); an exception it throws ends the pass and is
/// rethrown by smooth().
class SmoothedStates {
 public:
  virtual ~SmoothedStates() = default;
  virtual void segment(const std::vector<SmoothedState>& states) = 0;
};

/// Runs the backward pass. `noise` must be the filter's IMU noise (the process noise is re-derived from
/// the recorded steps). Throws roe::NumericError when a covariance it must invert is not positive
/// definite.
SmootherResult smooth(const FilterRecording& rec, const ImuNoiseParams& noise, const SmootherOptions& options = {});
/// The same backward pass with every smoothed state handed to `out` as it is produced and none kept, so that
/// its memory does not grow with the recording (roe run writes them into a temporary file, pipeline/run.hpp).
/// Returns SmootherResult::gauge_shift.
Pose smooth(const FilterRecording& rec, const ImuNoiseParams& noise, SmoothedStates& out,
            const SmootherOptions& options = {});

}  // namespace roe::ekf
