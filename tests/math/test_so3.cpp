// Property tests of SO(3) (DESIGN §2 conventions) over the sample set of samples.hpp.
#include <catch2/catch.hpp>
#include <Eigen/Eigenvalues>
#include <cmath>

#include "roe/math/so3.hpp"
#include "samples.hpp"

using namespace roe::math;
using roe::test::rotation_samples;

namespace {

constexpr double kFdStep = 1e-6;         // central-difference step (rad)
constexpr double kFdTol = 1e-7;          // Jacobian tolerance vs central differences
constexpr double kRoundTripTol = 1e-12;  // rad (relative below 1e-3 rad), Log∘Exp

// Numeric Jacobian of f: R^3 → R^3 at 0 by central differences.
template <typename F>
Matrix3d numeric_jacobian(F&& f) {
  Matrix3d J;
  for (int i = 0; i < 3; ++i) {
    const Vector3d e = kFdStep * Vector3d::Unit(i);
    J.col(i) = (f(e) - f(-e)) / (2.0 * kFdStep);
  }
  return J;
}

// Distance between rotation matrices as the angle of R_a^T R_b.
double rot_dist(const Matrix3d& a, const Matrix3d& b) { return log_so3(a.transpose() * b).norm(); }

}  // namespace

TEST_CASE("so3: skew and vee", "[so3]") {
  std::mt19937 rng(1);
  for (int i = 0; i < 20; ++i) {
    const Vector3d v = roe::test::random_vector(rng), w = roe::test::random_vector(rng);
    CHECK((skew(v) * w - v.cross(w)).norm() < 1e-14);
    CHECK((vee(skew(v)) - v).norm() == 0.0);
    CHECK((skew(v) + skew(v).transpose()).norm() == 0.0);
  }
}

TEST_CASE("so3: Exp is a rotation and agrees with exp_quat and Eigen's AngleAxis", "[so3]") {
  for (const auto& s : rotation_samples()) {
    CAPTURE(s.label);
    const Matrix3d R = exp_so3(s.phi);
    CHECK((R.transpose() * R - Matrix3d::Identity()).norm() < 1e-14);
    CHECK(std::abs(R.determinant() - 1.0) < 1e-14);
    CHECK((exp_quat(s.phi).toRotationMatrix() - R).norm() < 1e-14);
    CHECK(std::abs(exp_quat(s.phi).norm() - 1.0) < 1e-15);
    const double theta = s.phi.norm();
    if (theta > 0.0) {
      const Matrix3d R_ref = Eigen::AngleAxisd(theta, s.phi / theta).toRotationMatrix();
      CHECK((R_ref - R).norm() < 1e-14);
    } else {
      CHECK(R == Matrix3d::Identity());
    }
  }
}

TEST_CASE("so3: Log∘Exp and Exp∘Log round trips", "[so3]") {
  double worst = 0.0;
  for (const auto& s : rotation_samples()) {
    CAPTURE(s.label);
    const double theta = s.phi.norm();
    const Vector3d from_R = log_so3(exp_so3(s.phi));
    const Vector3d from_q = log_quat(exp_quat(s.phi));
    CHECK(from_R.norm() <= kPi + 1e-15);
    if (theta < kPi) {
      // Unique logarithm: recovered to 1e-12 absolute, and relative to the angle for tiny ones.
      const double tol = theta > 1e-3 ? kRoundTripTol : kRoundTripTol * theta;
      CHECK((from_R - s.phi).norm() <= tol);
      CHECK((from_q - s.phi).norm() <= tol);
      worst = std::max(worst, (from_R - s.phi).norm());
    } else {
      // θ = π: Log(R) is ±φ (R is the same rotation), both of norm π.
      CHECK(std::abs(from_R.norm() - kPi) < 1e-12);
      CHECK(std::min((from_R - s.phi).norm(), (from_R + s.phi).norm()) < 1e-9);
      CHECK(std::min((from_q - s.phi).norm(), (from_q + s.phi).norm()) < 1e-12);
    }
    // Exp∘Log: back to the same rotation.
    const Matrix3d R = exp_so3(s.phi);
    CHECK(rot_dist(exp_so3(log_so3(R)), R) < 1e-12);
    // Log of a quaternion ignores its sign and its norm.
    const Quaterniond q = exp_quat(s.phi);
    Quaterniond q_scaled;
    q_scaled.coeffs() = -2.5 * q.coeffs();
    CHECK((log_quat(q_scaled) - log_quat(q)).norm() < 1e-12);
  }
  // Printed with -s to document the accuracy reached.
  INFO("worst Log(Exp(phi)) error below pi: " << worst);
  CHECK(worst <= kRoundTripTol);
}

TEST_CASE("so3: right/left Jacobians against central differences", "[so3][jacobian]") {
  for (const auto& s : rotation_samples()) {
    CAPTURE(s.label);
    const Vector3d phi = s.phi;
    const Matrix3d R0 = exp_so3(phi);
    // Jr: Exp(φ + δ) = Exp(φ) Exp(Jr δ) + O(δ²)  ⇒  Jr = ∂ Log(Exp(φ)ᵀ Exp(φ + δ)) / ∂δ.
    const Matrix3d Jr_num =
        numeric_jacobian([&](const Vector3d& d) { return log_so3(R0.transpose() * exp_so3(phi + d)); });
    CHECK((Jr_num - right_jacobian(phi)).norm() < kFdTol);
    // Jl: Exp(φ + δ) = Exp(Jl δ) Exp(φ) + O(δ²).
    const Matrix3d Jl_num =
        numeric_jacobian([&](const Vector3d& d) { return log_so3(exp_so3(phi + d) * R0.transpose()); });
    CHECK((Jl_num - left_jacobian(phi)).norm() < kFdTol);
    CHECK((left_jacobian(phi) - right_jacobian(phi).transpose()).norm() < 1e-14);

    // Inverses: Jr⁻¹ = ∂ Log(Exp(φ) Exp(δ)) / ∂δ. Only where Log is smooth (away from its cut at π).
    if (phi.norm() < kPi - 1e-3) {
      const Matrix3d Jri_num = numeric_jacobian([&](const Vector3d& d) { return log_so3(R0 * exp_so3(d)); });
      CHECK((Jri_num - right_jacobian_inv(phi)).norm() < kFdTol);
      const Matrix3d Jli_num = numeric_jacobian([&](const Vector3d& d) { return log_so3(exp_so3(d) * R0); });
      CHECK((Jli_num - left_jacobian_inv(phi)).norm() < kFdTol);
    }
    // Jr Jr⁻¹ = I everywhere, including θ = π.
    CHECK((right_jacobian(phi) * right_jacobian_inv(phi) - Matrix3d::Identity()).norm() < 1e-12);
    CHECK((left_jacobian(phi) * left_jacobian_inv(phi) - Matrix3d::Identity()).norm() < 1e-12);
  }
}

TEST_CASE("so3: first-order identities Exp(φ+δ) ≈ Exp(φ)Exp(Jr δ) ≈ Exp(Jl δ)Exp(φ)", "[so3][jacobian]") {
  std::mt19937 rng(99);
  for (const auto& s : rotation_samples()) {
    CAPTURE(s.label);
    for (double scale : {1e-4, 1e-5}) {
      const Vector3d d = roe::test::random_vector(rng, scale);
      const Matrix3d exact = exp_so3(s.phi + d);
      const double err_r = rot_dist(exp_so3(s.phi) * exp_so3(right_jacobian(s.phi) * d), exact);
      const double err_l = rot_dist(exp_so3(left_jacobian(s.phi) * d) * exp_so3(s.phi), exact);
      // Second order in |δ| (the constant is below 1 for |φ| <= π).
      CHECK(err_r < d.squaredNorm() + 1e-14);
      CHECK(err_l < d.squaredNorm() + 1e-14);
      // While ignoring Jr leaves a first-order error wherever Jr ≠ I.
      if (s.phi.norm() > 0.5 && scale == 1e-4) {
        CHECK(rot_dist(exp_so3(s.phi) * exp_so3(d), exact) > 10 * err_r);
      }
    }
  }
}

TEST_CASE("so3: quat_residual is Log for small angles and sign-invariant", "[so3]") {
  std::mt19937 rng(5);
  for (int i = 0; i < 100; ++i) {
    const Quaterniond q_hat = exp_quat(roe::test::random_vector(rng));
    for (double scale : {1e-3, 1e-5, 1e-9}) {
      const Vector3d d = roe::test::random_vector(rng, scale);
      const Quaterniond q_meas = q_hat * exp_quat(d);
      const Vector3d r = quat_residual(q_hat, q_meas);
      // 2 tan(θ/2) − θ = θ³/12 + O(θ⁵).
      CHECK((r - d).norm() < std::pow(d.norm(), 3) / 6.0 + 1e-15);
      Quaterniond neg;
      neg.coeffs() = -q_meas.coeffs();
      CHECK((quat_residual(q_hat, neg) - r).norm() < 1e-15);
      CHECK((quat_residual(q_hat, q_meas) - log_quat(q_hat.conjugate() * q_meas)).norm() <
            std::pow(d.norm(), 3) / 6.0 + 1e-15);
    }
  }
  // Exact form for a finite angle: 2 tan(θ/2) along the axis.
  const Vector3d axis = Vector3d(1, -2, 0.5).normalized();
  const Vector3d r = quat_residual(Quaterniond::Identity(), exp_quat(1.0 * axis));
  CHECK((r - 2.0 * std::tan(0.5) * axis).norm() < 1e-14);
}

TEST_CASE("so3: angle_between, canonical, orthonormalize", "[so3]") {
  std::mt19937 rng(3);
  for (int i = 0; i < 50; ++i) {
    const Quaterniond a = exp_quat(roe::test::random_vector(rng));
    const Vector3d d = roe::test::random_vector(rng, 0.5);
    const Quaterniond b = a * exp_quat(d);
    if (d.norm() < kPi) CHECK(std::abs(angle_between(a, b) - d.norm()) < 1e-12);
    Quaterniond neg;
    neg.coeffs() = -a.coeffs();
    const Quaterniond c = canonical(neg);
    CHECK(c.w() >= 0.0);
    CHECK((c.toRotationMatrix() - a.toRotationMatrix()).norm() < 1e-14);
    CHECK(angle_between(a, neg) < 1e-7);
    // A perturbed rotation projects back near the original, with det +1.
    std::normal_distribution<double> n(0.0, 1e-3);
    Matrix3d M = a.toRotationMatrix();
    for (int k = 0; k < 9; ++k) M.data()[k] += n(rng);
    const Matrix3d R = orthonormalize(M);
    CHECK((R.transpose() * R - Matrix3d::Identity()).norm() < 1e-12);
    CHECK(std::abs(R.determinant() - 1.0) < 1e-12);
    CHECK(rot_dist(R, a.toRotationMatrix()) < 1e-2);
  }
  // A reflection is mapped to a proper rotation.
  CHECK(orthonormalize(Vector3d(1, 1, -1).asDiagonal()).determinant() > 0.0);
  // Far from a rotation (det > 0): the result is M's polar factor, the R with M = R P, P symmetric positive
  // definite (the rotation closest to M in the Frobenius norm).
  for (int i = 0; i < 20; ++i) {
    const Matrix3d Ra = exp_so3(roe::test::random_vector(rng)), Rb = exp_so3(roe::test::random_vector(rng));
    const Matrix3d M = Ra * Vector3d(1.3, 0.8, 0.5).asDiagonal() * Rb;
    const Matrix3d R = orthonormalize(M);
    const Matrix3d P = R.transpose() * M;
    CHECK((R.transpose() * R - Matrix3d::Identity()).norm() < 1e-12);
    CHECK((P - P.transpose()).norm() < 1e-12);
    CHECK(Eigen::SelfAdjointEigenSolver<Matrix3d>(0.5 * (P + P.transpose())).eigenvalues().minCoeff() > 0.0);
    CHECK(rot_dist(R, Ra * Rb) < 1e-12);  // M = (Ra Rb)(Rbᵀ D Rb)
  }
}
