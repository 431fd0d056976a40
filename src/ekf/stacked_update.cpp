#include "roe/ekf/stacked_update.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <vector>

namespace roe::ekf {

void add_abt(double* C, Eigen::Index ldc, const double* A, Eigen::Index lda, const double* B, Eigen::Index ldb,
             Eigen::Index M, Eigen::Index N, Eigen::Index K, double alpha, bool lower) {
  using Stride = Eigen::OuterStride<>;
  Eigen::Map<Eigen::MatrixXd, 0, Stride> Cm(C, M, N, Stride(ldc));
  Eigen::Map<const Eigen::MatrixXd, 0, Stride> Am(A, M, K, Stride(lda));
  Eigen::Map<const Eigen::MatrixXd, 0, Stride> Bm(B, N, K, Stride(ldb));
  if (K == 0) return;
  if (lower && M == N)
    Cm.triangularView<Eigen::Lower>() += alpha * Am * Bm.transpose();
  else
    Cm.noalias() += alpha * Am * Bm.transpose();
}

bool stacked_update(Eigen::MatrixXd& P, const Eigen::Ref<const Eigen::MatrixXd>& Y,
                    const Eigen::Ref<const Eigen::MatrixXd>& S, const Eigen::Ref<const Eigen::VectorXd>& r,
                    Eigen::VectorXd& dx, const StackedUpdateBuffers& buf) {
  const Eigen::Index n = P.rows(), m = S.rows();
  if (buf.L.rows() < m || buf.L.cols() < m) buf.L.resize(std::max(m, buf.L.rows()), std::max(m, buf.L.cols()));
  auto L = buf.L.topLeftCorner(m, m);
  L = S;
  Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> llt(L);
  if (llt.info() != Eigen::Success || !(L.diagonal().array() > 0.0).all()) return false;
  if (buf.W.rows() != n || buf.W.cols() < m) {
    const Eigen::Index cols = std::max<Eigen::Index>(m, buf.W.rows() == n ? buf.W.cols() : 0);
    buf.W.resize(n, cols);
  }
  // W = Y L⁻ᵀ (solve X Lᵀ = Y in place), u = L⁻¹ r; then K = W L⁻¹, δx = K r = W u and
  // K S Kᵀ = W Wᵀ.
  auto W = buf.W.leftCols(m);
  W = Y;
  L.triangularView<Eigen::Lower>().transpose().solveInPlace<Eigen::OnTheRight>(W);
  Eigen::VectorXd& u = buf.u;
  u = r;
  L.triangularView<Eigen::Lower>().solveInPlace(u);
  dx.noalias() = W * u;
  // P ← P − W Wᵀ on the lower triangle, mirrored.
  add_abt(P.data(), P.outerStride(), W.data(), buf.W.outerStride(), W.data(), buf.W.outerStride(), n, n, m, -1.0,
          /*lower=*/true);
  P.triangularView<Eigen::StrictlyUpper>() = P.transpose();
  return true;
}

bool stacked_update_constant_gain(Eigen::MatrixXd& P, const Eigen::Ref<const Eigen::MatrixXd>& Y,
                                  const Eigen::Ref<const Eigen::MatrixXd>& S,
                                  const Eigen::Ref<const Eigen::MatrixXd>& R,
                                  const Eigen::Ref<const Eigen::VectorXd>& d,
                                  const Eigen::Ref<const Eigen::VectorXd>& r, const std::vector<Eigen::Index>& rows,
                                  Eigen::VectorXd& dx) {
  const Eigen::MatrixXd DRD = d.asDiagonal() * R * d.asDiagonal();
  const Eigen::MatrixXd Sk = S - R + DRD;
  Eigen::LLT<Eigen::MatrixXd> llt(S), llt_k(Sk);
  if (llt.info() != Eigen::Success || llt_k.info() != Eigen::Success) return false;
  // K = Y S⁻¹ (by the transposed solve, S symmetric), its constant rows Y_s S_k⁻¹.
  Eigen::MatrixXd K = llt.solve(Y.transpose()).transpose();
  K(rows, Eigen::all) = llt_k.solve(Y(rows, Eigen::all).transpose()).transpose();
  dx.noalias() = K * r;
  // (I − K H) P (I − K H)ᵀ + K R Kᵀ = P − K Yᵀ − Y Kᵀ + K S Kᵀ (H P Hᵀ = S − R), then the constant block's
  // K_s (D R D − R) K_sᵀ.
  const Eigen::MatrixXd KY = K * Y.transpose();
  Eigen::MatrixXd Pn = P - KY - KY.transpose();
  Pn.noalias() += K * S * K.transpose();
  const Eigen::MatrixXd Ks = K(rows, Eigen::all);
  Pn(rows, rows) += Ks * (DRD - R) * Ks.transpose();
  P = 0.5 * (Pn + Pn.transpose());
  return true;
}

}  // namespace roe::ekf
