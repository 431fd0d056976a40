#pragma once
/// @file
/// Lock-out detection (docs/filter.md §13). A χ² gate protects the filter from wrong detections, but once
/// the estimate itself has drifted (a visibility gap, an overconfident covariance) it refuses the right
/// ones as well and never recovers: the paper's failure mode, and what made roe's default lose 1–45 m on
/// two paper-real runs. The sign that the estimate, not the detector, is wrong: the rejected detections of
/// several objects (or many of one) agree on where the camera is. This monitor collects the offset of each
/// refused detection's implied camera position from the estimate, formed from the detected translation
/// alone (a flipped or noisy detected rotation does not move it),
///   e_i = p_W_O − R̂_W_C t_C_O,i − p̂_W_C,
/// since a position last passed the gate, and says the estimate is lost when
///   - the part has been refused for at least `after_s` (FilterOptions::relock_after_s),
///   - at least `min_detections` offsets were collected,
///   - the offsets follow one line e(t) = a + b (t − t_now) (a least-squares fit; a lost estimate drifts),
///     every object's mean residual from that line within `agree` (the objects agree with each other),
///   - and the current offset a is significant: |a| > 4 se(a), se the standard error of the line at t_now
/// Random outliers scatter around zero: they do not re-lock. One object suffices: after a visibility gap
/// the one object in view is often all there is. The rotation is not monitored: the gyro keeps it, and a
/// rotation offset formed from detected rotations is dominated by their flips (measured: re-locking it
/// from them broke paper-real-seq4, docs/filter.md §13). The filter then inflates the part's covariance by what was observed
/// (Relock), so that the next detections pass the gate and pull the estimate back.
///
/// I/O-free and independent of the filter's state layout.

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "roe/core/types.hpp"

namespace roe::ekf {

/// What the monitor observed when it declared the part lost.
struct Relock {
  Timestamp since_ns = 0;             ///< when the part last passed the gate (or the run started)
  Eigen::Vector3d offset;             ///< a: the estimate's offset now (implied − estimate)
  Eigen::Vector3d drift_per_s;        ///< b: how the offset changed per second over the window
  double residual_sigma = 0.0;        ///< σ of the offsets about the fitted line (per axis, RMS)
  int detections = 0;                 ///< offsets used
  int objects = 0;                    ///< distinct objects among them
};

class LockoutMonitor {
 public:
  /// after_s ≤ 0 disables the monitor (check() never fires). agree: how far (m or rad) an object's mean
  /// residual may lie from the common line.
  LockoutMonitor(double after_s, int min_detections, double agree);
  /// A position passed the gate at t (for any detection): the evidence so far is dropped.
  void accepted(Timestamp t);
  /// A detection of `object_id` whose position was refused at t, with its offset e (see above).
  void refused(Timestamp t, int object_id, const Eigen::Vector3d& offset);
  /// Whether the evidence up to `now` says the position estimate is lost. Does not reset: the caller
  /// calls accepted(now) after acting on it.
  std::optional<Relock> check(Timestamp now) const;
  bool enabled() const { return after_ns_ > 0; }

 private:
  struct Sample {
    Timestamp t;
    int object_id;
    Eigen::Vector3d e;
  };
  Timestamp after_ns_ = 0;
  int min_detections_ = 0;
  double agree_ = 0.0;
  Timestamp since_ns_ = 0;
  bool started_ = false;
  std::vector<Sample> samples_;
};

}  // namespace roe::ekf
