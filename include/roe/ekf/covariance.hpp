#pragma once
/// @file
/// The filter's covariance behind one door (issue 41): the dense n x n P of the error state (filter.hpp's
/// layout) with its block-sparse propagation. Only the 15 core rows/columns change per IMU sample: the core
/// block is propagated in a fixed-size 15x15 member (authoritative while pending; P's top-left block is
/// stale until the next sync), and the core/rest cross-covariance lazily with the accumulated transition
/// Φ = F_k⋯F_1 (kept transposed, only its non-trivial columns multiplied) the next time the whole P is needed
/// (update, augmentation, recording, covariance()). docs/filter.md §2. No heap allocation per IMU sample.
/// The update, augmentation and the anchor's change of variables operate on full() (ekf::Filter's policy).
/// I/O-free.

#include <Eigen/Core>

#include "roe/ekf/imu.hpp"

namespace roe::ekf {

/// Φᵀ ← Φᵀ Fᵀ for an accumulated core transition Φ = F_k⋯F_1 kept transposed (the filter's lazy cross terms
/// and the smoother recording's segment transition), on Φ's non-trivial columns only (filter/covariance.cpp).
void accumulate_transition(const CoreTransition& F, Mat15& PhiT);

class FilterCovariance {
 public:
  /// P ← 0 (n x n), nothing pending; returns P for the caller to fill (initialisation).
  Eigen::MatrixXd& reset(int n);
  int dim() const { return static_cast<int>(P_.rows()); }

  /// One IMU step: P_cc ← F P_cc Fᵀ + Q on the fixed-size core block, Φ accumulated for the cross terms.
  void propagate(const CoreTransition& F, const ImuNoiseParams& noise, double dt);
  /// The same step on the whole matrix, P ← F P Fᵀ + Q with the dense F (the test-only reference arithmetic,
  /// Filter::set_reference_arithmetic).
  void propagate_dense(const CoreTransition& F, const ImuNoiseParams& noise, double dt);

  /// Diagonal entry i and core entry (i, j) (always current, also between updates).
  double variance(int i) const { return cc_pending_ && i < kCore ? Pcc_(i, i) : P_(i, i); }
  double core(int i, int j) const { return cc_pending_ ? Pcc_(i, j) : P_(i, j); }
  /// The core block (written back into P first).
  const Eigen::Block<const Eigen::MatrixXd, kCore, kCore> core_block();
  /// P as stored: every block outside the core rows/columns is always current (the objects' covariances).
  const Eigen::MatrixXd& stored() const { return P_; }
  /// Writes the propagated core block back into P (the cross terms may still be pending).
  void sync_core();
  /// The whole covariance brought up to date (core block and cross terms), for the update and augmentation.
  Eigen::MatrixXd& full();
  /// Adds `var` to the three core variances from `first` on (the re-lock's inflation, process noise added now:
  /// the pending cross-term transition is unaffected).
  void inflate_core(int first, double var);

 private:
  Eigen::MatrixXd P_;
  Mat15 Pcc_;
  bool cc_pending_ = false;
  Mat15 PhiT_ = Mat15::Identity();  // Φᵀ, Φ = F_k⋯F_1 since the last cross-covariance sync
  bool phi_pending_ = false;
  Eigen::MatrixXd tmp_cross_;
};

}  // namespace roe::ekf
