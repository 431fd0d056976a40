#pragma once
/// @file
/// Marginal covariances of a few parameter blocks of a Ceres problem at its current values, by a Schur
/// complement onto them (docs/refine.md §7): the Gauss–Newton information H = JᵀJ (robust loss applied, as
/// the solve and ceres::Covariance apply it) split into the blocks to eliminate (many, sparse: a batch's
/// nodes) and the blocks kept (few: the calibration), H = [A B; Bᵀ C]; the kept blocks' joint covariance
/// is (C − Bᵀ A⁻¹ B)⁻¹: H is factorised once by a sparse Cholesky with the kept columns last, whose trailing
/// factor block L_kk gives C − Bᵀ A⁻¹ B = L_kk L_kkᵀ. The same numbers as ceres::Covariance's
/// GetCovarianceBlockInTangentSpace (tests/refine/test_marginals.cpp), without its QR of the whole Jacobian.

#include <Eigen/Core>
#include <map>
#include <optional>
#include <vector>

namespace ceres {
class Problem;
}

namespace roe::refine {

/// The kept blocks' joint covariance in their tangent spaces, in the order given.
struct BlockCovariance {
  Eigen::MatrixXd sigma;
  std::map<const double*, std::pair<int, int>> at;  ///< block → (offset, tangent size) in sigma
  /// The tangent-space covariance between blocks a and b (a zero block for a constant block).
  Eigen::MatrixXd block(const double* a, const double* b) const;
};

/// `eliminate`: the blocks marginalised out (a constant block among them is skipped), factorised in the
/// order given (no fill-reducing permutation: pass them in an order with little fill, e.g. a chain's
/// nodes in time order); `keep`: the blocks
/// whose covariance is returned (a constant one gets zero rows). Every non-constant block of the problem
/// must be in one of the two lists. std::nullopt when H is singular: A not positive definite, or the
/// Schur complement's reciprocal condition number below `min_reciprocal_condition` (ceres::Covariance's
/// default rank test, 1e-14).
std::optional<BlockCovariance> marginal_covariance(ceres::Problem& problem, const std::vector<double*>& eliminate,
                                                   const std::vector<double*>& keep, int threads = 1,
                                                   double min_reciprocal_condition = 1e-14);

}  // namespace roe::refine
