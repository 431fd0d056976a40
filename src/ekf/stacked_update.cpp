#include "roe/ekf/stacked_update.hpp"

#include <Eigen/Cholesky>
#include <algorithm>

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
  if (buf.U.rows() != n || buf.U.cols() < 2 * m) {
    const Eigen::Index cols = std::max<Eigen::Index>(2 * m, buf.U.rows() == n ? buf.U.cols() : 0);
    buf.U.resize(n, cols);
    buf.V.resize(n, cols);
  }
  auto E = buf.U.leftCols(m);
  auto K = buf.V.leftCols(m);
  K = Y;
  // K = Y S⁻¹ = Y L⁻ᵀ L⁻¹: solve X Lᵀ = Y, then K L = X (in place, Eigen's triangular solves).
  L.triangularView<Eigen::Lower>().transpose().solveInPlace<Eigen::OnTheRight>(K);
  L.triangularView<Eigen::Lower>().solveInPlace<Eigen::OnTheRight>(K);
  dx.noalias() = K * r;
  // E = ½ K S − Y (K S as K Sᵀ, S symmetric), then P += [E, K][K, E]ᵀ on the lower triangle, mirrored.
  E.setZero();
  add_abt(E.data(), buf.U.outerStride(), K.data(), buf.V.outerStride(), S.data(), S.outerStride(), n, m, m, 1.0,
          /*lower=*/false);
  E = 0.5 * E - Y;
  buf.U.middleCols(m, m) = K;
  buf.V.middleCols(m, m) = E;
  add_abt(P.data(), P.outerStride(), buf.U.data(), buf.U.outerStride(), buf.V.data(), buf.V.outerStride(), n, n,
          2 * m, 1.0, /*lower=*/true);
  P.triangularView<Eigen::StrictlyUpper>() = P.transpose();
  return true;
}

}  // namespace roe::ekf
