#pragma once
/// @file
/// The algebra of the filter's stacked update, apart from its policy (which detections enter, the gate,
/// the anchor's masking, symmetric objects: Filter::update). Given the stacked P Hᵀ, S = H P Hᵀ + R and the
/// residual r of m rows:
///   S = L Lᵀ (Cholesky in place, no pivoting: S is symmetric positive definite, failing that is reported),
///   W = Y L⁻ᵀ by one triangular solve from the right (no inverse), so that K = P Hᵀ S⁻¹ = W L⁻¹ and
///   K S Kᵀ = W Wᵀ; δx = K r = W (L⁻¹ r);
///   P ← P − W Wᵀ: the Joseph form (I−KH)P(I−KH)ᵀ + KRKᵀ for this optimal K (both equal P − K S Kᵀ), as a
///   rank-m product on the lower triangle only (n²m/2 multiply-adds), then mirrored (P exactly symmetric).
///   (Until 2026-12-02: the Joseph form exact for the computed K, P + E Kᵀ + K Eᵀ with E = ½ K S − P Hᵀ, two
///   solves and a rank-2m product; the results differ by round-off, docs/benchmarks/ekf.md.)
/// I/O-free; tested against the textbook formulas on random problems (tests/ekf/test_stacked_update.cpp).

#include <Eigen/Core>
#include <vector>

namespace roe::ekf {

/// C += α A Bᵀ on raw column-major storage (C is M x N with leading dimension ldc, A is M x K, B is N x K),
/// so that the update can address sub-blocks by pointer. With `lower` (M = N) only the lower
/// triangle of C is updated (the caller mirrors it). Eigen's products do the arithmetic: a hand-tiled
/// SSE2 kernel measured 12 % faster on the benchmark and was not kept (docs/benchmarks/ekf.md).
void add_abt(double* C, Eigen::Index ldc, const double* A, Eigen::Index lda, const double* B, Eigen::Index ldb,
             Eigen::Index M, Eigen::Index N, Eigen::Index K, double alpha, bool lower);

/// Reusable buffers of stacked_update (sized on first use; no allocation afterwards once they have
/// reached the largest m; the filter also uses W as a gather buffer of its own).
struct StackedUpdateBuffers {
  Eigen::MatrixXd& L;  ///< ≥ m x m: the Cholesky factor
  Eigen::MatrixXd& W;  ///< n x ≥ m: Y L⁻ᵀ
  Eigen::VectorXd& u;  ///< L⁻¹ r
};

/// One stacked update of the n x n covariance P with Y = P Hᵀ (n x m), S (m x m, symmetric) and r (m):
/// writes δx = K r to `dx` and P's Joseph-form posterior to P. Returns false, with P and dx untouched, when
/// S is not positive definite.
bool stacked_update(Eigen::MatrixXd& P, const Eigen::Ref<const Eigen::MatrixXd>& Y,
                    const Eigen::Ref<const Eigen::MatrixXd>& S, const Eigen::Ref<const Eigen::VectorXd>& r,
                    Eigen::VectorXd& dx, const StackedUpdateBuffers& buf);

/// The stacked update with a separate gain for the constant states (extrinsics, object-worlds: the error-state
/// rows listed in `rows`) under detection errors correlated in time (docs/filter.md §15). Detection errors that
/// persist over many images carry fewer independent samples than images; a constant state, which averages
/// every detection it ever sees, must weight them as if their noise were k R (k the variance inflation of a
/// mean of such errors), whereas the core (pose, velocity, biases), which forgets through its process noise,
/// keeps the gain of R. With D = diag(d), d = √k per residual row (R the stacked block-diagonal R):
///   K_c = Y_c S⁻¹ (the other rows),  K_s = Y_s S_k⁻¹, S_k = S − R + D R D (`rows`),  δx = [K_c; K_s] r,
///   P ← (I − K H) P (I − K H)ᵀ + K R Kᵀ + [0 0; 0 K_s (D R D − R) K_sᵀ], K = [K_c; K_s]:
/// the Joseph form of that gain, in which both parts see the same noise of this image (cross block
/// P_cs − K_c H P_·s) and the constant block also carries the part D R D − R (≥ 0) that the errors' persistence
/// adds to what it accumulates, so that its posterior is exactly the optimal one for noise k R
/// (P_ss − K_s S_k K_sᵀ), the core block's the optimal one for R (P_cc − K_c S K_cᵀ), and P stays positive
/// semi-definite. With every d = 1 this is stacked_update
/// (to round-off). Returns false, with P and dx untouched, when S or S_k is not positive definite.
bool stacked_update_constant_gain(Eigen::MatrixXd& P, const Eigen::Ref<const Eigen::MatrixXd>& Y,
                                  const Eigen::Ref<const Eigen::MatrixXd>& S,
                                  const Eigen::Ref<const Eigen::MatrixXd>& R,
                                  const Eigen::Ref<const Eigen::VectorXd>& d,
                                  const Eigen::Ref<const Eigen::VectorXd>& r, const std::vector<Eigen::Index>& rows,
                                  Eigen::VectorXd& dx);

}  // namespace roe::ekf
