// The covariance owner's doors (ekf::FilterCovariance, covariance.hpp) against dense formulas written here:
// augmentation [P, P J_xᵀ; J_x P, J_x P J_xᵀ + Q], the change of variables M P Mᵀ, the stacked update and the
// smoother's segment recording, each after IMU steps whose cross terms are still pending (so a door that
// forgot to bring P up to date fails), and the checks' findings.
#include <catch2/catch.hpp>

#include <Eigen/Dense>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "random_support.hpp"
#include "roe/core/error.hpp"
#include "roe/ekf/covariance.hpp"

using namespace roe::ekf;
using roe::ekf::test::random_matrix;
using roe::ekf::test::random_spd;

namespace {

ImuNoiseParams noise() {
  ImuNoiseParams q;
  q.gyro_noise_density = 2e-3;
  q.gyro_random_walk = 3e-5;
  q.accel_noise_density = 2e-2;
  q.accel_random_walk = 4e-4;
  return q;
}

/// k IMU steps of a rotating, accelerating IMU (transitions with every non-trivial block non-zero).
std::vector<CoreTransition> transitions(int k, std::mt19937& g) {
  std::normal_distribution<double> N(0.0, 1.0);
  std::vector<CoreTransition> Fs(k);
  CoreState x;
  x.b_g = Vec3(0.01, -0.02, 0.005);
  x.b_a = Vec3(0.05, 0.02, -0.03);
  for (auto& F : Fs) {
    const Vec3 w(0.5 + 0.1 * N(g), -0.3 + 0.1 * N(g), 0.8 + 0.1 * N(g));
    const Vec3 a(0.4 + N(g), -0.2 + N(g), 9.81 + N(g));
    x = integrate(x, w, a, w, a, 0.0025, &F);
  }
  return Fs;
}

/// The dense reference of those steps: P ← F P Fᵀ + Q on the whole matrix, symmetrised.
Eigen::MatrixXd propagate_dense(Eigen::MatrixXd P, const std::vector<CoreTransition>& Fs) {
  const int n = static_cast<int>(P.rows());
  for (const auto& F : Fs) {
    Eigen::MatrixXd Fn = Eigen::MatrixXd::Identity(n, n);
    Fn.topLeftCorner<kCore, kCore>() = F.dense();
    P = Fn * P * Fn.transpose();
    auto Pcc = P.topLeftCorner<kCore, kCore>();
    add_process_noise(noise(), F.dt, Pcc);
    P = (0.5 * (P + P.transpose())).eval();
  }
  return P;
}

double rel_diff(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B) {
  return (A - B).cwiseAbs().maxCoeff() / B.cwiseAbs().maxCoeff();
}

}  // namespace

TEST_CASE("FilterCovariance: augment, then change_variables, equal the dense M P_aug M^T", "[ekf][covariance]") {
  std::mt19937 g(41);
  const int n = 21;  // core + extrinsics
  const Eigen::MatrixXd P0 = random_spd(n, g);
  const auto Fs = transitions(13, g);
  // J_x on p, θ and the extrinsics' p, θ (the first sight's columns), dense here and compact for the owner.
  const int cols[4] = {kP, kTheta, kCore, kCore + 3};
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(6, n);
  CompactJacobian6 Jx;
  for (int c : cols) {
    const Mat63 blk = random_matrix(6, 3, g);
    J.middleCols<3>(c) = blk;
    Jx.append3(c, blk);
  }
  CHECK(Jx.dense(n) == J);
  const Mat6 Q = random_spd(6, g);

  FilterCovariance cov;
  cov.reset(P0);
  for (const auto& F : Fs) cov.propagate(F, noise(), F.dt);  // cross terms pending
  cov.augment(Jx, Q);
  REQUIRE(cov.dim() == n + 6);
  const Eigen::MatrixXd P = propagate_dense(P0, Fs);
  Eigen::MatrixXd P_aug(n + 6, n + 6);
  P_aug << P, P * J.transpose(), J * P, J * P * J.transpose() + Q;
  CHECK(rel_diff(cov.full(), P_aug) < 1e-12);
  CHECK(cov.full() == cov.full().transpose());

  // A change of variables that keeps 2 of the 6 new components (the anchor's position_yaw gauge's shape).
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n + 2, n + 6);
  M.topLeftCorner(n, n).setIdentity();
  M.topRightCorner(n, 6) = random_matrix(n, 6, g);
  M(n, n + 3) = M(n + 1, n + 4) = 1.0;
  cov.change_variables(M);
  REQUIRE(cov.dim() == n + 2);
  CHECK(rel_diff(cov.full(), M * P_aug * M.transpose()) < 1e-12);
  CHECK(cov.full() == cov.full().transpose());
  CHECK(!cov.check(true));
  // A change of variables or an augmentation that does not fit the state is refused, P untouched.
  const Eigen::MatrixXd kept = cov.full();
  CHECK_THROWS_AS(cov.change_variables(M), roe::InternalError);  // M is (n + 2) x (n + 6)
  CompactJacobian6 outside;
  outside.append3(n + 2, random_matrix(6, 3, g));
  CHECK_THROWS_AS(cov.augment(outside, Q), roe::InternalError);
  CHECK(cov.full() == kept);

  // Propagation after the change: the new rows are constants (only the core block and its cross terms move).
  const auto Fs2 = transitions(7, g);
  const Eigen::MatrixXd P1 = cov.full();
  for (const auto& F : Fs2) cov.propagate(F, noise(), F.dt);
  CHECK(rel_diff(cov.full(), propagate_dense(P1, Fs2)) < 1e-12);
}

TEST_CASE("FilterCovariance: the stacked update acts on the up-to-date P", "[ekf][covariance][update]") {
  std::mt19937 g(7);
  const int n = 27, m = 12;
  const Eigen::MatrixXd P0 = random_spd(n, g);
  const auto Fs = transitions(9, g);
  FilterCovariance cov;
  cov.reset(P0);
  for (const auto& F : Fs) cov.propagate(F, noise(), F.dt);
  const Eigen::MatrixXd P = propagate_dense(P0, Fs);
  const Eigen::MatrixXd H = random_matrix(m, n, g), R = random_spd(m, g);
  const Eigen::VectorXd r = random_matrix(m, 1, g);
  // Y and S from the reference P: the door must bring its own P up to date before it applies the update.
  const Eigen::MatrixXd Y = P * H.transpose();
  Eigen::MatrixXd S = H * P * H.transpose() + R;
  S = (0.5 * (S + S.transpose())).eval();
  Eigen::MatrixXd L, W;
  Eigen::VectorXd u, dx, dx_dense;
  REQUIRE(cov.update(Y, S, r, dx, {L, W, u}));
  const Eigen::MatrixXd K = Y * S.inverse();
  const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(n, n) - K * H;
  const Eigen::MatrixXd joseph = IKH * P * IKH.transpose() + K * R * K.transpose();
  CHECK(rel_diff(cov.full(), joseph) < 1e-9);
  CHECK((dx - K * r).cwiseAbs().maxCoeff() < 1e-9 * (1.0 + (K * r).cwiseAbs().maxCoeff()));

  FilterCovariance ref;
  ref.reset(P0);
  for (const auto& F : Fs) ref.propagate_dense(F, noise(), F.dt);
  REQUIRE(ref.update_dense(H, R, r, dx_dense));
  CHECK(rel_diff(ref.full(), joseph) < 1e-9);
  CHECK(ref.full() == ref.full().transpose());
  CHECK((dx_dense - K * r).cwiseAbs().maxCoeff() < 1e-9 * (1.0 + (K * r).cwiseAbs().maxCoeff()));

  // A non-positive-definite S leaves P and δx untouched.
  const Eigen::MatrixXd before = cov.full();
  dx.setConstant(3.0);
  CHECK_FALSE(cov.update(Y, -S, r, dx, {L, W, u}));
  CHECK(cov.full() == before);
  CHECK((dx.array() == 3.0).all());
}

TEST_CASE("FilterCovariance: the recording's segments are Phi = F_k...F_1 and the core block at their end",
          "[ekf][covariance][smoother]") {
  std::mt19937 g(3);
  const int n = 21;
  const Eigen::MatrixXd P0 = random_spd(n, g);
  const auto Fs = transitions(11, g);
  FilterCovariance cov;
  cov.reset(P0);
  Mat15 Phi_ref = Mat15::Identity();
  for (int k = 0; k < 6; ++k) {
    cov.propagate(Fs[k], noise(), Fs[k].dt);
    cov.record_step(Fs[k]);
    Phi_ref = (Fs[k].dense() * Phi_ref).eval();
  }
  Mat15 Phi, P_cc;
  cov.take_segment(Phi, P_cc);
  const std::vector<CoreTransition> first(Fs.begin(), Fs.begin() + 6);
  CHECK(rel_diff(Phi, Phi_ref) < 1e-13);
  CHECK(rel_diff(P_cc, propagate_dense(P0, first).topLeftCorner<kCore, kCore>()) < 1e-12);
  // The next segment starts at the identity.
  Phi_ref.setIdentity();
  for (int k = 6; k < 11; ++k) {
    cov.propagate(Fs[k], noise(), Fs[k].dt);
    cov.record_step(Fs[k]);
    Phi_ref = (Fs[k].dense() * Phi_ref).eval();
  }
  cov.take_segment(Phi, P_cc);
  CHECK(rel_diff(Phi, Phi_ref) < 1e-13);
  CHECK(rel_diff(P_cc, propagate_dense(P0, Fs).topLeftCorner<kCore, kCore>()) < 1e-12);
  // A propagation without record_step leaves the segment's Φ alone; reset() starts a new segment.
  cov.propagate(Fs[0], noise(), Fs[0].dt);
  cov.take_segment(Phi, P_cc);
  CHECK(Phi == Mat15::Identity());
  cov.record_step(Fs[1]);
  cov.reset(P0);
  cov.take_segment(Phi, P_cc);
  CHECK(Phi == Mat15::Identity());
  CHECK(P_cc == P0.topLeftCorner<kCore, kCore>());
}

TEST_CASE("FilterCovariance: the checks name what failed", "[ekf][covariance]") {
  std::mt19937 g(5);
  const int n = 21;
  const Eigen::MatrixXd P0 = random_spd(n, g);
  FilterCovariance cov;
  cov.reset(P0);
  CHECK(!cov.check(true));

  Eigen::MatrixXd bad = P0;
  bad(kBg + 1, kBg + 1) = -1e-3;
  cov.reset(bad);
  CHECK(cov.check(false).value_or("(nothing)") == "covariance diagonal of b_g[1] is not positive ");

  bad = P0;
  bad(17, 17) = std::numeric_limits<double>::quiet_NaN();
  cov.reset(bad);
  CHECK(cov.check(false).value_or("(nothing)") == "covariance diagonal of error-state index 17 is not finite ");

  // Positive diagonal, off-diagonal problems: only the full check sees them.
  bad = P0;
  bad(3, 19) = bad(19, 3) = std::numeric_limits<double>::infinity();
  cov.reset(bad);
  CHECK(!cov.check(false));
  CHECK(cov.check(true).value_or("(nothing)") == "covariance is not finite");

  bad = Eigen::MatrixXd::Identity(n, n);
  bad(0, 1) = bad(1, 0) = 2.0;  // [[1, 2], [2, 1]] has eigenvalue −1
  cov.reset(bad);
  CHECK(!cov.check(false));
  CHECK(cov.check(true).value_or("(nothing)") == "covariance is not positive definite");

  // The diagonal check sees the core block propagated since the last sync (pending, not yet in P).
  cov.reset(P0);
  CoreTransition F = transitions(1, g)[0];
  ImuNoiseParams q = noise();
  q.accel_noise_density = std::numeric_limits<double>::quiet_NaN();
  cov.propagate(F, q, F.dt);
  CHECK(cov.check(false).value_or("(nothing)") == "covariance diagonal of p_W_I[0] is not finite ");
}

// The decay of Gauss–Markov detection-error states (docs/filter.md §17): the linear link y = B u + w with
// B = diag(b), w ~ N(0, diag(1 − b²)), applied after IMU steps whose cross terms are pending.
TEST_CASE("FilterCovariance: decay equals the dense B P B^T + diag(1 - b^2)", "[ekf][covariance][gauss_markov]") {
  std::mt19937 g(49);
  const int n = kCore + 6 + 18;  // core, extrinsics, an object's error state and object-world, another error state
  const Eigen::MatrixXd P0 = random_spd(n, g);
  const auto Fs = transitions(9, g);
  FilterCovariance cov;
  cov.reset(P0);
  for (const auto& F : Fs) cov.propagate(F, noise(), F.dt);
  Eigen::VectorXd b = Eigen::VectorXd::Ones(n);
  b.segment<6>(kCore + 6).setConstant(0.93);  // ρ = exp(−Δt/τ)
  b.segment<6>(kCore + 18).setConstant(0.0);  // a long gap: the state forgets everything
  cov.decay(b);
  const Eigen::MatrixXd P = propagate_dense(P0, Fs);
  Eigen::MatrixXd expected = b.asDiagonal() * P * b.asDiagonal();
  expected.diagonal().array() += 1.0 - b.array().square();
  CHECK(rel_diff(cov.full(), expected) < 1e-12);
  CHECK(cov.full() == cov.full().transpose());
  CHECK(!cov.check(true));
  // The core may not decay, and no b outside [0, 1].
  Eigen::VectorXd bad = b;
  bad(kP) = 0.5;
  CHECK_THROWS_AS(cov.decay(bad), roe::InternalError);
  bad = b;
  bad(kCore + 6) = 1.5;
  CHECK_THROWS_AS(cov.decay(bad), roe::InternalError);
}

// The consider covariance (docs/filter.md §18): P_a beside P through every door, the same Φ, Q, J_x, M, B, and
// at an update the Joseph form of P's gain with the white-equivalent noise of correlated detection errors.
namespace {

/// The consider update written densely: (I − K H) P_a (I − K H)ᵀ + N, N the noise of K n with n's covariance R
/// as the core sees it and D R D on the constant rows: N = K R Kᵀ with its constant block replaced by
/// K_s D R D K_sᵀ (the cross block K_c R K_sᵀ).
Eigen::MatrixXd consider_dense(const Eigen::MatrixXd& Pa, const Eigen::MatrixXd& K, const Eigen::MatrixXd& H,
                               const Eigen::MatrixXd& R, const Eigen::VectorXd& d, int first_constant) {
  const int n = static_cast<int>(Pa.rows()), c = n - first_constant;
  const Eigen::MatrixXd A = Eigen::MatrixXd::Identity(n, n) - K * H;
  Eigen::MatrixXd N = K * R * K.transpose();
  const Eigen::MatrixXd Ks = K.bottomRows(c);
  N.bottomRightCorner(c, c) = Ks * d.asDiagonal() * R * d.asDiagonal() * Ks.transpose();
  return A * Pa * A.transpose() + N;
}

/// A block-diagonal R of 6 x 6 detection blocks and √k constant per block.
void detection_noise(int blocks, std::mt19937& g, Eigen::MatrixXd& R, Eigen::VectorXd& d) {
  R = Eigen::MatrixXd::Zero(6 * blocks, 6 * blocks);
  d.resize(6 * blocks);
  for (int b = 0; b < blocks; ++b) {
    R.block<6, 6>(6 * b, 6 * b) = random_spd(6, g);
    d.segment<6>(6 * b).setConstant(std::sqrt(1.0 + 60.0 * b));  // k = 1 (a first detection), 61, 121
  }
}

}  // namespace

TEST_CASE("consider_update equals the dense Joseph form with the white-equivalent noise", "[ekf][covariance][consider]") {
  std::mt19937 g(181);
  const int n = 33, m = 18;
  const Eigen::MatrixXd Pa = random_spd(n, g), K = 0.1 * random_matrix(n, m, g), H = random_matrix(m, n, g);
  Eigen::MatrixXd R;
  Eigen::VectorXd d;
  detection_noise(3, g, R, d);
  std::vector<Eigen::Index> rows;
  for (int i = kCore; i < n; ++i) rows.push_back(i);
  Eigen::MatrixXd P = Pa;
  consider_update(P, K, ConsiderNoise{H, R, d, rows});
  const Eigen::MatrixXd expected = consider_dense(Pa, K, H, R, d, kCore);
  CHECK(rel_diff(P, expected) < 1e-12);
  CHECK(P == P.transpose());
  // Without constant rows, or with every k = 1, it is the plain Joseph form of that gain.
  const Eigen::MatrixXd A = Eigen::MatrixXd::Identity(n, n) - K * H;
  const Eigen::MatrixXd joseph = A * Pa * A.transpose() + K * R * K.transpose();
  P = Pa;
  consider_update(P, K, ConsiderNoise{H, R, d, {}});
  CHECK(rel_diff(P, joseph) < 1e-12);
  P = Pa;
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(m);
  consider_update(P, K, ConsiderNoise{H, R, ones, rows});
  CHECK(rel_diff(P, joseph) < 1e-12);
  // The persistence only adds: P_a with k > 1 minus the white Joseph form is positive semi-definite.
  P = Pa;
  consider_update(P, K, ConsiderNoise{H, R, d, rows});
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(P - joseph);
  CHECK(es.eigenvalues().minCoeff() > -1e-9 * es.eigenvalues().maxCoeff());
  CHECK(es.eigenvalues().maxCoeff() > 1e-3);
  // Sizes that do not fit are refused.
  Eigen::MatrixXd small = Pa.topLeftCorner(n - 1, n - 1);
  CHECK_THROWS_AS(consider_update(small, K, ConsiderNoise{H, R, d, rows}), roe::InternalError);
}

TEST_CASE("FilterCovariance: the consider covariance follows every door, P is the same bytes as without it",
          "[ekf][covariance][consider]") {
  std::mt19937 g(53);
  const int n = 21;  // core + extrinsics
  const Eigen::MatrixXd P0 = random_spd(n, g);
  const auto Fs = transitions(11, g), Fs2 = transitions(5, g);
  CompactJacobian6 Jx;
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(6, n);
  for (int c : {kP, kTheta, kCore, kCore + 3}) {
    const Mat63 blk = random_matrix(6, 3, g);
    J.middleCols<3>(c) = blk;
    Jx.append3(c, blk);
  }
  const Mat6 Q = random_spd(6, g);
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n + 2, n + 6);
  M.topLeftCorner(n, n).setIdentity();
  M.topRightCorner(n, 6) = random_matrix(n, 6, g);
  M(n, n + 3) = M(n + 1, n + 4) = 1.0;
  const int n2 = n + 2, m = 12;
  const Eigen::MatrixXd H = random_matrix(m, n2, g);
  Eigen::MatrixXd R;
  Eigen::VectorXd d;
  detection_noise(2, g, R, d);
  const Eigen::VectorXd r = random_matrix(m, 1, g);
  std::vector<Eigen::Index> rows;
  for (int i = kCore; i < n2; ++i) rows.push_back(i);
  const ConsiderNoise cn{H, R, d, rows};

  // The same sequence of doors on a covariance with and without P_a: propagation (cross terms pending),
  // augmentation, a change of variables, an update, the re-lock's inflation, more propagation.
  FilterCovariance with, without;
  with.set_consider(true);
  for (FilterCovariance* c : {&with, &without}) c->reset(P0);
  CHECK(with.reported_full() == P0);
  for (const auto& F : Fs)
    for (FilterCovariance* c : {&with, &without}) c->propagate(F, noise(), F.dt);
  CHECK(with.reported_variance(kV + 1) == with.variance(kV + 1));  // P_a = P until the first update
  for (FilterCovariance* c : {&with, &without}) {
    c->augment(Jx, Q);
    c->change_variables(M);
  }
  const Eigen::MatrixXd Pu = with.full();  // P = P_a before the update
  const Eigen::MatrixXd Y = Pu * H.transpose();
  Eigen::MatrixXd S = H * Pu * H.transpose() + R;
  S = (0.5 * (S + S.transpose())).eval();
  Eigen::MatrixXd L1, W1, L2, W2;
  Eigen::VectorXd u1, u2, dx1, dx2;
  CHECK_THROWS_AS(with.update(Y, S, r, dx1, {L1, W1, u1}), roe::InternalError);  // P_a needs its noise
  REQUIRE(with.update(Y, S, r, dx1, {L1, W1, u1}, &cn));
  REQUIRE(without.update(Y, S, r, dx2, {L2, W2, u2}));
  CHECK(dx1 == dx2);
  CHECK(with.full() == without.full());
  const Eigen::MatrixXd K = Y * S.inverse();
  Eigen::MatrixXd Pa = consider_dense(Pu, K, H, R, d, kCore);
  CHECK(rel_diff(with.reported_full(), Pa) < 1e-9);
  CHECK(with.reported_variance(kCore + 2) > 1.5 * with.variance(kCore + 2));  // the extrinsics' σ grew
  // After the update P_a ≠ P: every later door must act on both.
  for (FilterCovariance* c : {&with, &without}) c->inflate_core(kV, 0.25);
  Pa.block<3, 3>(kV, kV).diagonal().array() += 0.25;
  for (const auto& F : Fs2)
    for (FilterCovariance* c : {&with, &without}) c->propagate(F, noise(), F.dt);
  Pa = propagate_dense(Pa, Fs2);
  CHECK(std::abs(with.reported_core(kTheta, kP + 2) - Pa(kTheta, kP + 2)) < 1e-9 * Pa.cwiseAbs().maxCoeff());
  CHECK(rel_diff(with.reported_full(), Pa) < 1e-9);
  CHECK(with.full() == without.full());
  CHECK(without.reported_full() == without.full());  // off: the reported covariance is P
  Eigen::VectorXd b = Eigen::VectorXd::Ones(n2);
  b.tail<2>().setConstant(0.5);
  for (FilterCovariance* c : {&with, &without}) c->decay(b);
  Pa = (b.asDiagonal() * Pa * b.asDiagonal()).eval();
  Pa.diagonal().array() += 1.0 - b.array().square();
  CHECK(rel_diff(with.reported_full(), Pa) < 1e-9);
  CHECK(with.full() == without.full());
  CHECK(!with.check(true));

  // The dense reference doors (the filter's reference arithmetic) give the same P_a.
  FilterCovariance ref;
  ref.set_consider(true);
  ref.reset(P0);
  for (const auto& F : Fs) ref.propagate_dense(F, noise(), F.dt);
  ref.augment(Jx, Q);
  ref.change_variables(M);
  Eigen::VectorXd dx3;
  REQUIRE(ref.update_dense(H, R, r, dx3, &cn));
  CHECK(rel_diff(ref.reported_full(), consider_dense(Pu, K, H, R, d, kCore)) < 1e-9);
}
