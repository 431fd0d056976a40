#pragma once
// The one numeric-Jacobian check of the tests (manif's JacobianTester in spirit): central differences of a
// function of a perturbation δ of the input, compared with an analytic Jacobian and asserted.
//
// `error(δ)` returns the output's error caused by the perturbation δ, in the output's own tangent space:
// y(x ⊞ δ) ⊟ y(x) for manifold outputs, or simply y(x ⊞ δ) for vector outputs (the constant y(x) cancels in
// the difference). Column i of the numeric Jacobian is (error(+ε eᵢ) − error(−ε eᵢ)) / 2ε: the truncation
// error is O(ε²) and the rounding error O(u/ε), so ε = 1e-6 leaves about 1e-9 of each, far below the
// 1e-7 the checks ask.
#include <catch2/catch.hpp>

#include <Eigen/Core>
#include <utility>

namespace roe::test {

/// Central-difference Jacobian of `error` (a function of an n_in-vector δ returning an Eigen vector).
template <class ErrorFn>
Eigen::MatrixXd numeric_jacobian(int n_in, ErrorFn&& error, double eps = 1e-6) {
  Eigen::MatrixXd J;
  for (int i = 0; i < n_in; ++i) {
    Eigen::VectorXd d = Eigen::VectorXd::Zero(n_in);
    d(i) = eps;
    const Eigen::VectorXd plus = error(d);
    d(i) = -eps;
    const Eigen::VectorXd minus = error(d);
    if (i == 0) J.resize(plus.size(), n_in);
    J.col(i) = (plus - minus) / (2.0 * eps);
  }
  return J;
}

/// Asserts |analytic − numeric|∞ < tolerance (the matrices are printed when it fails) and returns the
/// numeric Jacobian, for checks of its structure.
template <class ErrorFn>
Eigen::MatrixXd check_jacobian(const Eigen::MatrixXd& analytic, ErrorFn&& error, double tolerance = 1e-7,
                               double eps = 1e-6) {
  const Eigen::MatrixXd numeric = numeric_jacobian(static_cast<int>(analytic.cols()),
                                                   std::forward<ErrorFn>(error), eps);
  REQUIRE(numeric.rows() == analytic.rows());
  INFO("analytic\n" << analytic << "\nnumeric\n" << numeric);
  CHECK((analytic - numeric).cwiseAbs().maxCoeff() < tolerance);
  return numeric;
}

}  // namespace roe::test
