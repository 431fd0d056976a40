// Marginal covariances by a Schur complement onto the kept blocks (docs/refine.md §7).
#include "roe/refine/marginals.hpp"

#include <ceres/crs_matrix.h>
#include <ceres/problem.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>

#include "roe/core/error.hpp"

namespace roe::refine {

Eigen::MatrixXd BlockCovariance::block(const double* a, const double* b) const {
  const auto& [oa, na] = at.at(a);
  const auto& [ob, nb] = at.at(b);
  return sigma.block(oa, ob, na, nb);
}

namespace {

using SpMat = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

/// The free blocks of `blocks` appended to `out`, and the sum of their tangent sizes.
int free_blocks(const ceres::Problem& problem, const std::vector<double*>& blocks, std::vector<double*>& out) {
  int n = 0;
  for (double* b : blocks) {
    if (problem.IsParameterBlockConstant(b)) continue;
    out.push_back(b);
    n += problem.ParameterBlockTangentSize(b);
  }
  return n;
}

/// The lower triangle of H = JᵀJ from J in compressed rows: consecutive rows with the same columns (a
/// residual block's) multiplied as one dense block, their products summed by the triplet assembly.
SpMat information(const ceres::CRSMatrix& J) {
  const auto same_columns = [&J](int r, int s) {
    const int k = J.rows[r + 1] - J.rows[r];
    return J.rows[s + 1] - J.rows[s] == k &&
           std::equal(J.cols.begin() + J.rows[r], J.cols.begin() + J.rows[r] + k, J.cols.begin() + J.rows[s]);
  };
  std::vector<int> starts;  // the first row of each group, then num_rows
  std::size_t count = 0;
  for (int r = 0; r < J.num_rows; ++r) {
    if (r > 0 && same_columns(starts.back(), r)) continue;
    starts.push_back(r);
    const std::size_t k = static_cast<std::size_t>(J.rows[r + 1] - J.rows[r]);
    count += k * (k + 1) / 2;
  }
  starts.push_back(J.num_rows);
  std::vector<Eigen::Triplet<double, int>> trip;
  trip.reserve(count);
  Eigen::MatrixXd Jg, G;
  for (std::size_t g = 0; g + 1 < starts.size(); ++g) {
    const int r0 = starts[g], r1 = starts[g + 1], b = J.rows[r0], k = J.rows[r0 + 1] - b;
    Jg.resize(r1 - r0, k);
    for (int r = r0; r < r1; ++r)
      for (int i = 0; i < k; ++i) Jg(r - r0, i) = J.values[J.rows[r] + i];
    G.noalias() = Jg.transpose() * Jg;
    for (int j = 0; j < k; ++j)  // CRS columns are sorted: i ≥ j is the lower triangle
      for (int i = j; i < k; ++i) trip.emplace_back(J.cols[b + i], J.cols[b + j], G(i, j));
  }
  SpMat H(J.num_cols, J.num_cols);
  H.setFromTriplets(trip.begin(), trip.end());
  return H;
}

/// (C − Bᵀ A⁻¹ B)⁻¹ for H = JᵀJ = [A B; Bᵀ C] (A: the first n columns): H factorised as L Lᵀ with the kept
/// columns last, whose trailing block L_kk satisfies L_kk L_kkᵀ = C − Bᵀ A⁻¹ B. The eliminated columns stay
/// in the caller's order (a batch's nodes in time order: banded, so no fill-reducing permutation is needed).
std::optional<Eigen::MatrixXd> schur_inverse(const ceres::CRSMatrix& J, int n, double min_rcond) {
  const int m = J.num_cols - n;
  const SpMat H = information(J);
  Eigen::SimplicialLLT<SpMat, Eigen::Lower, Eigen::NaturalOrdering<int>> llt(H);
  if (llt.info() != Eigen::Success) return std::nullopt;
  const Eigen::MatrixXd Lkk = Eigen::MatrixXd(llt.matrixL().nestedExpression().bottomRightCorner(m, m));
  Eigen::MatrixXd S = Lkk * Lkk.transpose();
  S = 0.5 * (S + S.transpose()).eval();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(S);
  if (es.info() != Eigen::Success) return std::nullopt;
  const Eigen::VectorXd& l = es.eigenvalues();
  if (m > 0 && !(l(0) > min_rcond * l(m - 1))) return std::nullopt;
  return es.eigenvectors() * l.cwiseInverse().asDiagonal() * es.eigenvectors().transpose();
}

}  // namespace

std::optional<BlockCovariance> marginal_covariance(ceres::Problem& problem, const std::vector<double*>& eliminate,
                                                   const std::vector<double*>& keep, int threads,
                                                   double min_reciprocal_condition) {
  ceres::Problem::EvaluateOptions eo;
  eo.num_threads = threads;
  eo.apply_loss_function = true;
  const int n = free_blocks(problem, eliminate, eo.parameter_blocks);
  const std::size_t n_blocks = eo.parameter_blocks.size();
  const int m = free_blocks(problem, keep, eo.parameter_blocks);
  std::vector<double*> all;
  problem.GetParameterBlocks(&all);
  std::size_t n_free = 0;
  for (double* b : all) n_free += problem.IsParameterBlockConstant(b) ? 0 : 1;
  if (n_free != eo.parameter_blocks.size())
    throw InternalError("marginal_covariance: the free blocks are not split between eliminate and keep");
  BlockCovariance out;
  out.sigma = Eigen::MatrixXd::Zero(m, m);
  int off = 0;
  for (std::size_t i = n_blocks; i < eo.parameter_blocks.size(); ++i) {
    const int k = problem.ParameterBlockTangentSize(eo.parameter_blocks[i]);
    out.at[eo.parameter_blocks[i]] = {off, k};
    off += k;
  }
  ceres::CRSMatrix crs;
  if (!problem.Evaluate(eo, nullptr, nullptr, nullptr, &crs)) return std::nullopt;
  const auto sigma = schur_inverse(crs, n, min_reciprocal_condition);
  if (!sigma) return std::nullopt;
  out.sigma = *sigma;
  // A constant kept block: zero rows and columns appended (its covariance is zero).
  for (double* b : keep) {
    if (!problem.IsParameterBlockConstant(b)) continue;
    const int k = problem.ParameterBlockTangentSize(b);
    out.at[b] = {static_cast<int>(out.sigma.rows()), k};
    out.sigma.conservativeResizeLike(Eigen::MatrixXd::Zero(out.sigma.rows() + k, out.sigma.cols() + k));
  }
  return out;
}

}  // namespace roe::refine
