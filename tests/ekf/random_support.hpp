#pragma once
// Random test matrices of the ekf tests (standard normal entries, filled row by row from the generator).
#include <Eigen/Core>
#include <random>

namespace roe::ekf::test {

inline Eigen::MatrixXd random_matrix(int r, int c, std::mt19937& g) {
  std::normal_distribution<double> N(0.0, 1.0);
  Eigen::MatrixXd A(r, c);
  for (int i = 0; i < r; ++i)
    for (int j = 0; j < c; ++j) A(i, j) = N(g);
  return A;
}

/// A Aᵀ + 0.1 I with A random n x n: symmetric positive definite.
inline Eigen::MatrixXd random_spd(int n, std::mt19937& g) {
  const Eigen::MatrixXd A = random_matrix(n, n, g);
  return A * A.transpose() + 0.1 * Eigen::MatrixXd::Identity(n, n);
}

}  // namespace roe::ekf::test
