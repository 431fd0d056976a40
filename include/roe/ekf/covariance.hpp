#pragma once
/// @file
/// The filter's covariance behind one door (issue 41; OpenVINS's StateHelper is the model): the dense n x n P
/// of the error state (filter.hpp's layout) and every change made to it — initialisation, the block-sparse
/// propagation, augmentation with a new object, the anchor's change of variables, the stacked update,
/// symmetrisation — its checks (finite positive diagonal, positive definite) and the covariance part of the
/// smoother's recording. ekf::Filter keeps the policy (which detections, which rows, which update, the gauge,
/// the σ scale, first sight, re-lock) and the maths that decide what to apply (J_x, M, P Hᵀ, S); it reads P
/// through the const accessors below and changes it only through this class.
///
/// Propagation: only the 15 core rows/columns change per IMU sample. The core block is propagated in a
/// fixed-size 15x15 member (authoritative while pending; P's top-left block is stale until the next sync), and
/// the core/rest cross-covariance lazily with the accumulated transition Φ = F_k⋯F_1 (kept transposed, only its
/// non-trivial columns multiplied) the next time the whole P is needed (update, augmentation, recording,
/// full()). docs/filter.md §1–2. No heap allocation per IMU sample. I/O-free.
///
/// The consider covariance (docs/filter.md §18, `consider_correlated_errors`): beside the nominal P that makes
/// the gain, an "actual" covariance P_a of the same state, changed by every door with the same Φ, Q, J_x, B, M,
/// and at each update by the Joseph form of the nominal gain with the white-equivalent noise of detection
/// errors correlated in time (consider_update). P_a never feeds back into the mean, the gain or the gate; it is
/// what the filter reports as σ (the reported_* accessors).

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "roe/ekf/imu.hpp"
#include "roe/ekf/measurement.hpp"  // Mat6, Mat63
#include "roe/ekf/stacked_update.hpp"

namespace roe::ekf {

/// Φᵀ ← Φᵀ Fᵀ for an accumulated core transition Φ = F_k⋯F_1 kept transposed (the filter's lazy cross terms
/// and the smoother recording's segment transition), on Φ's non-trivial columns only (filter/covariance.cpp).
void accumulate_transition(const CoreTransition& F, Mat15& PhiT);

/// A Jacobian of 6 rows that acts on at most 19 error-state columns, kept compact: its column j is the
/// derivative with respect to error-state column idx[j] (the first-sight initialisation's J_x: the IMU's p
/// and θ, the extrinsics, the time offset, the object's Gauss–Markov detection-error state).
struct CompactJacobian6 {
  static constexpr int kMaxCols = 19;
  Eigen::Matrix<double, 6, kMaxCols> J;
  int idx[kMaxCols];
  int nc = 0;
  /// Appends three columns acting on the error-state columns offset … offset + 2.
  void append3(int offset, const Mat63& block);
  /// Appends one column acting on the error-state column `offset`.
  void append1(int offset, const Vec6& column);
  /// The same Jacobian on all n error-state columns (6 x n, zero elsewhere).
  Eigen::MatrixXd dense(int n) const;
};

/// The consider update's noise (docs/filter.md §15 and §18): the stacked m x n measurement Jacobian H, the
/// stacked block-diagonal R, √k per residual row (k the variance inflation of §15, Filter::error_inflation) and
/// the error-state rows of the constant states, whose accumulated noise is D R D instead of R.
struct ConsiderNoise {
  const Eigen::MatrixXd& H;
  const Eigen::MatrixXd& R;
  const Eigen::VectorXd& d;
  const std::vector<Eigen::Index>& rows;
};

/// The consider (sensitivity) update of an actual covariance P_a for a gain K that was not made from it (Gelb,
/// Applied Optimal Estimation, ch. 7): with D = diag(d) and K_s = K's `rows` (the other rows 0),
///   P_a ← (I − K H) P_a (I − K H)ᵀ + K R Kᵀ + K_s (D R D − R) K_sᵀ,
/// the Joseph form, exact for any K, with the core seeing the detection noise R and the constant states the
/// white equivalent D R D of errors correlated in time (§15's noise with the nominal gain), then symmetrised.
/// Formed as P_a − K Y_aᵀ − Y_a Kᵀ + K (H Y_a + R) Kᵀ, Y_a = P_a Hᵀ.
void consider_update(Eigen::MatrixXd& Pa, const Eigen::Ref<const Eigen::MatrixXd>& K, const ConsiderNoise& noise);

class FilterCovariance {
 public:
  /// With `on`, the consider covariance P_a is kept beside P from the next reset() on (docs/filter.md §18).
  void set_consider(bool on) { consider_ = on; }
  bool consider() const { return consider_; }
  /// P ← P0 (n x n, symmetric), nothing pending (initialisation); P_a ← P0 with the consider covariance.
  void reset(Eigen::MatrixXd P0);
  int dim() const { return static_cast<int>(P_.rows()); }

  /// One IMU step: P_cc ← F P_cc Fᵀ + Q on the fixed-size core block, Φ accumulated for the cross terms.
  void propagate(const CoreTransition& F, const ImuNoiseParams& noise, double dt);
  /// The same step on the whole matrix, P ← F P Fᵀ + Q with the dense F (the test-only reference arithmetic,
  /// Filter::set_reference_arithmetic).
  void propagate_dense(const CoreTransition& F, const ImuNoiseParams& noise, double dt);
  /// Adds `var` to the three core variances from `first` on (the re-lock's inflation, process noise added now:
  /// the pending cross-term transition is unaffected).
  void inflate_core(int first, double var);

  /// Augmentation with a new 6-dof state a = f(x, z) (first sight, measurement.hpp): with J_x its Jacobian on
  /// the current error state and Q = J_z R J_zᵀ its measurement noise, P grows to
  /// [P, P J_xᵀ; J_x P, J_x P J_xᵀ + Q] (the new diagonal block symmetrised), n → n + 6.
  void augment(const CompactJacobian6& Jx, const Mat6& Q);
  /// The decay of Gauss–Markov states between detections (docs/filter.md §17): the linear link
  /// y = B u + w with B = diag(b) (b_i = ρ on a decayed state's columns, 1 elsewhere) and w ~ N(0, diag(1 − b²)),
  /// i.e. P ← B P B + diag(1 − b²): the decayed rows and columns scaled by ρ, their diagonal block by ρ² plus
  /// (1 − ρ²) I. `b` has dim() entries in [0, 1]; the core rows must not decay.
  void decay(const Eigen::VectorXd& b);
  /// A linear change of variables of the error state, δx' = M δx (m x n; the anchor's gauge fix, docs/filter.md
  /// §4): P ← M P Mᵀ, symmetrised; n → m.
  void change_variables(const Eigen::MatrixXd& M);

  /// The stacked update (stacked_update.hpp) of P with Y = P Hᵀ (n x m), S and r; δx to `dx`. False, with P
  /// and dx untouched, when S is not positive definite. With the consider covariance, `consider` (required)
  /// gives H and the noise for P_a's consider_update with this update's gain K = P Hᵀ S⁻¹.
  bool update(const Eigen::Ref<const Eigen::MatrixXd>& Y, const Eigen::Ref<const Eigen::MatrixXd>& S,
              const Eigen::Ref<const Eigen::VectorXd>& r, Eigen::VectorXd& dx, const StackedUpdateBuffers& buf,
              const ConsiderNoise* consider = nullptr);
  /// The same with a separate gain for the error-state rows `rows` (stacked_update_constant_gain).
  bool update_constant_gain(const Eigen::Ref<const Eigen::MatrixXd>& Y, const Eigen::Ref<const Eigen::MatrixXd>& S,
                            const Eigen::Ref<const Eigen::MatrixXd>& R, const Eigen::Ref<const Eigen::VectorXd>& d,
                            const Eigen::Ref<const Eigen::VectorXd>& r, const std::vector<Eigen::Index>& rows,
                            Eigen::VectorXd& dx);
  /// The test-only reference update: the textbook Joseph form (I − KH) P (I − KH)ᵀ + K R Kᵀ with
  /// K = P Hᵀ S⁻¹, S = H P Hᵀ + R formed densely from the full H (m x n), then symmetrised. False, with P and
  /// dx untouched, when S is not positive definite.
  bool update_dense(const Eigen::MatrixXd& H, const Eigen::MatrixXd& R, const Eigen::Ref<const Eigen::VectorXd>& r,
                    Eigen::VectorXd& dx, const ConsiderNoise* consider = nullptr);

  /// The guard rails' checks: every diagonal entry finite and positive, and with `positive_definite` P finite
  /// and its Cholesky factorisation successful. Nothing when all hold, else what failed ("covariance diagonal
  /// of b_g[1] is not finite ", "covariance is not positive definite"), for the caller to name time and place.
  std::optional<std::string> check(bool positive_definite);

  /// Diagonal entry i and core entry (i, j) (always current, also between updates).
  double variance(int i) const { return cc_pending_ && i < kCore ? Pcc_(i, i) : P_(i, i); }
  double core(int i, int j) const { return cc_pending_ ? Pcc_(i, j) : P_(i, j); }
  /// The covariance the filter reports as σ: P_a with the consider covariance, else P (same access rules).
  double reported_variance(int i) const {
    return !consider_ ? variance(i) : cc_pending_ && i < kCore ? Pacc_(i, i) : Pa_(i, i);
  }
  double reported_core(int i, int j) const { return !consider_ ? core(i, j) : cc_pending_ ? Pacc_(i, j) : Pa_(i, j); }
  const Eigen::MatrixXd& reported_stored() const { return consider_ ? Pa_ : P_; }
  /// The core block (written back into P first).
  const Eigen::Block<const Eigen::MatrixXd, kCore, kCore> core_block();
  /// P as stored: every block outside the core rows/columns is always current (the objects' covariances).
  const Eigen::MatrixXd& stored() const { return P_; }
  /// The whole covariance brought up to date (core block and cross terms): the update's P Hᵀ, covariance(),
  /// the recording's snapshot of P.
  const Eigen::MatrixXd& full();
  /// P_a brought up to date (the consider covariance; P when it is off).
  const Eigen::MatrixXd& reported_full();

  /// Recording (the smoother's, smoother.hpp): one IMU step's F into the transition Φ of the open propagation
  /// segment (from reset() or the last take_segment() on), called with each propagation while recording.
  void record_step(const CoreTransition& F);
  /// Closes the open segment: its Φ = F_k⋯F_1 and the core block P_cc at its end; the next segment starts.
  void take_segment(Mat15& Phi, Mat15& P_cc);

 private:
  /// Writes the propagated core block back into P (the cross terms may still be pending).
  void sync_core();
  /// P ← ½ (P + Pᵀ) (and P_a).
  void symmetrise();

  Eigen::MatrixXd P_;
  Mat15 Pcc_;
  bool consider_ = false;
  Eigen::MatrixXd Pa_;  // the consider covariance (empty when off); its core block pending in Pacc_ with Pcc_'s
  Mat15 Pacc_;
  bool cc_pending_ = false;
  Mat15 PhiT_ = Mat15::Identity();  // Φᵀ, Φ = F_k⋯F_1 since the last cross-covariance sync
  bool phi_pending_ = false;
  Eigen::MatrixXd tmp_cross_;
  Mat15 rec_PhiT_ = Mat15::Identity();  // Φᵀ of the recording's open propagation segment
};

}  // namespace roe::ekf
