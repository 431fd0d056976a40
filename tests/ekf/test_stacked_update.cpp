// The stacked update's algebra (stacked_update.hpp) against the textbook Kalman formulas, evaluated
// independently with Eigen's dense inverse: K = P Hᵀ S⁻¹, δx = K r, the Joseph form
// (I − K H) P (I − K H)ᵀ + K R Kᵀ, which for the optimal K equals P − K S Kᵀ.
#include <catch2/catch.hpp>

#include <Eigen/Dense>
#include <random>

#include "roe/ekf/stacked_update.hpp"

using namespace roe::ekf;

namespace {

Eigen::MatrixXd random_spd(int n, std::mt19937& g) {
  std::normal_distribution<double> N(0.0, 1.0);
  Eigen::MatrixXd A(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) A(i, j) = N(g);
  return A * A.transpose() + 0.1 * Eigen::MatrixXd::Identity(n, n);
}

Eigen::MatrixXd random_matrix(int r, int c, std::mt19937& g) {
  std::normal_distribution<double> N(0.0, 1.0);
  Eigen::MatrixXd A(r, c);
  for (int i = 0; i < r; ++i)
    for (int j = 0; j < c; ++j) A(i, j) = N(g);
  return A;
}

}  // namespace

TEST_CASE("stacked_update: K, dx and the Joseph posterior of the textbook formulas", "[ekf][update]") {
  std::mt19937 g(23);
  Eigen::MatrixXd L, W;  // reused across problems of different sizes, as the filter does
  Eigen::VectorXd u;
  for (const auto& [n, m] : {std::pair{21, 6}, std::pair{33, 18}, std::pair{27, 12}, std::pair{45, 24}}) {
    INFO("n = " << n << ", m = " << m);
    const Eigen::MatrixXd P0 = random_spd(n, g);
    const Eigen::MatrixXd H = random_matrix(m, n, g);
    const Eigen::MatrixXd R = random_spd(m, g);
    const Eigen::VectorXd r = random_matrix(m, 1, g);
    const Eigen::MatrixXd Y = P0 * H.transpose();
    Eigen::MatrixXd S = H * P0 * H.transpose() + R;
    S = 0.5 * (S + S.transpose());

    Eigen::MatrixXd P = P0;
    Eigen::VectorXd dx;
    REQUIRE(stacked_update(P, Y, S, r, dx, {L, W, u}));

    const Eigen::MatrixXd K = Y * S.inverse();
    const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(n, n) - K * H;
    const Eigen::MatrixXd joseph = IKH * P0 * IKH.transpose() + K * R * K.transpose();
    const double scale = P0.cwiseAbs().maxCoeff();
    CHECK((dx - K * r).cwiseAbs().maxCoeff() < 1e-9 * (1.0 + (K * r).cwiseAbs().maxCoeff()));
    CHECK((P - joseph).cwiseAbs().maxCoeff() < 1e-9 * scale);
    CHECK((P - (P0 - K * S * K.transpose())).cwiseAbs().maxCoeff() < 1e-9 * scale);
    CHECK(P == P.transpose());  // mirrored, exactly symmetric
    CHECK(Eigen::LLT<Eigen::MatrixXd>(P).info() == Eigen::Success);
  }
}

TEST_CASE("stacked_update: an S that is not positive definite is refused, P untouched", "[ekf][update]") {
  std::mt19937 g(5);
  Eigen::MatrixXd L, W;
  Eigen::VectorXd u;
  const Eigen::MatrixXd P0 = random_spd(15, g);
  const Eigen::MatrixXd Y = random_matrix(15, 6, g);
  Eigen::MatrixXd S = Eigen::MatrixXd::Identity(6, 6);
  S(3, 3) = -1.0;
  Eigen::MatrixXd P = P0;
  Eigen::VectorXd dx = Eigen::VectorXd::Constant(3, 7.0);
  CHECK_FALSE(stacked_update(P, Y, S, Eigen::VectorXd::Ones(6), dx, {L, W, u}));
  CHECK(P == P0);
  CHECK(dx == Eigen::VectorXd::Constant(3, 7.0));
}
