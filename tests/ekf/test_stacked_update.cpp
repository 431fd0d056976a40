// The stacked update's algebra (stacked_update.hpp) against the textbook Kalman formulas, evaluated
// independently with Eigen's dense inverse: K = P Hᵀ S⁻¹, δx = K r, the Joseph form
// (I − K H) P (I − K H)ᵀ + K R Kᵀ, which for the optimal K equals P − K S Kᵀ.
#include <catch2/catch.hpp>

#include <Eigen/Dense>
#include <random>

#include "random_support.hpp"
#include "roe/ekf/stacked_update.hpp"

using namespace roe::ekf;
using roe::ekf::test::random_matrix;
using roe::ekf::test::random_spd;

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

TEST_CASE("stacked_update_constant_gain: the core block optimal for R, the constant block optimal for k R",
          "[ekf][update]") {
  std::mt19937 g(7);
  for (const auto& [n, m] : {std::pair{27, 6}, std::pair{39, 12}, std::pair{45, 18}}) {
    INFO("n = " << n << ", m = " << m);
    const Eigen::MatrixXd P0 = random_spd(n, g);
    const Eigen::MatrixXd H = random_matrix(m, n, g);
    // Block-diagonal R (6 rows per detection), a different k per detection.
    Eigen::MatrixXd R = Eigen::MatrixXd::Zero(m, m);
    Eigen::VectorXd d(m);
    for (int a = 0; a < m / 6; ++a) {
      R.block(6 * a, 6 * a, 6, 6) = random_spd(6, g);
      d.segment(6 * a, 6).setConstant(std::sqrt(1.0 + 40.0 * a));
    }
    const Eigen::VectorXd r = random_matrix(m, 1, g);
    const Eigen::MatrixXd Y = P0 * H.transpose();
    const Eigen::MatrixXd S = H * P0 * H.transpose() + R;
    const Eigen::MatrixXd Rk = d.asDiagonal() * R * d.asDiagonal();
    const Eigen::MatrixXd Sk = H * P0 * H.transpose() + Rk;
    std::vector<Eigen::Index> rows;
    for (int i = 15; i < n; ++i) rows.push_back(i);
    const Eigen::Index c = 15, s = n - 15;

    Eigen::MatrixXd P = P0;
    Eigen::VectorXd dx;
    REQUIRE(stacked_update_constant_gain(P, Y, S, R, d, r, rows, dx));
    // Textbook: K_c = P_c Hᵀ S⁻¹, K_s = P_s Hᵀ S_k⁻¹; the Joseph form of K with R, plus K_s (kR − R) K_sᵀ.
    Eigen::MatrixXd K(n, m);
    K.topRows(c) = Y.topRows(c) * S.inverse();
    K.bottomRows(s) = Y.bottomRows(s) * Sk.inverse();
    const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(n, n) - K * H;
    Eigen::MatrixXd joseph = IKH * P0 * IKH.transpose() + K * R * K.transpose();
    joseph.bottomRightCorner(s, s) += K.bottomRows(s) * (Rk - R) * K.bottomRows(s).transpose();
    const double scale = P0.cwiseAbs().maxCoeff();
    CHECK((dx - K * r).cwiseAbs().maxCoeff() < 1e-9 * (1.0 + (K * r).cwiseAbs().maxCoeff()));
    CHECK((P - joseph).cwiseAbs().maxCoeff() < 1e-9 * scale);
    // Each block is the optimal posterior of its own noise model.
    const Eigen::MatrixXd Pc = P0.topLeftCorner(c, c) - K.topRows(c) * S * K.topRows(c).transpose();
    const Eigen::MatrixXd Ps = P0.bottomRightCorner(s, s) - K.bottomRows(s) * Sk * K.bottomRows(s).transpose();
    CHECK((P.topLeftCorner(c, c) - Pc).cwiseAbs().maxCoeff() < 1e-9 * scale);
    CHECK((P.bottomRightCorner(s, s) - Ps).cwiseAbs().maxCoeff() < 1e-9 * scale);
    CHECK(Eigen::LLT<Eigen::MatrixXd>(P).info() == Eigen::Success);
    // With every k = 1 it is the ordinary update.
    Eigen::MatrixXd P1 = P0, L, W;
    Eigen::VectorXd dx1, dx2, u;
    REQUIRE(stacked_update_constant_gain(P1, Y, S, R, Eigen::VectorXd::Ones(m), r, rows, dx1));
    Eigen::MatrixXd P2 = P0;
    REQUIRE(stacked_update(P2, Y, S, r, dx2, {L, W, u}));
    CHECK((P1 - P2).cwiseAbs().maxCoeff() < 1e-9 * scale);
    CHECK((dx1 - dx2).cwiseAbs().maxCoeff() < 1e-9 * (1.0 + dx2.cwiseAbs().maxCoeff()));
  }
}
