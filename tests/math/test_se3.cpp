#include <catch2/catch.hpp>
#include <cmath>

#include "roe/math/se3.hpp"
#include "samples.hpp"

using namespace roe::math;

namespace {

Pose random_pose(std::mt19937& rng) {
  return Pose(exp_quat(roe::test::random_vector(rng)), roe::test::random_vector(rng, 2.0));
}

// Tangent-space distance (manif style): |pose_difference| over translation (m) and rotation (rad).
double pose_dist(const Pose& a, const Pose& b) { return pose_difference(a, b).norm(); }

}  // namespace

TEST_CASE("se3: compose, inverse and act identities", "[se3]") {
  std::mt19937 rng(21);
  for (int i = 0; i < 200; ++i) {
    const Pose T_A_B = random_pose(rng), T_B_C = random_pose(rng), T_C_D = random_pose(rng);
    const Vector3d x_C = roe::test::random_vector(rng);
    // Associativity and the names: T_A_C = T_A_B * T_B_C maps C into A.
    CHECK(pose_dist((T_A_B * T_B_C) * T_C_D, T_A_B * (T_B_C * T_C_D)) < 1e-12);
    CHECK(((T_A_B * T_B_C).act(x_C) - T_A_B.act(T_B_C.act(x_C))).norm() < 1e-12);
    // x_A = R_A_B x_B + p_A_B.
    CHECK((T_A_B.act(x_C) - (T_A_B.R() * x_C + T_A_B.p)).norm() < 1e-12);
    // Inverses.
    CHECK(pose_dist(T_A_B * T_A_B.inverse(), Pose::identity()) < 1e-12);
    CHECK(pose_dist(T_A_B.inverse() * T_A_B, Pose::identity()) < 1e-12);
    CHECK(pose_dist(T_A_B.inverse().inverse(), T_A_B) < 1e-12);
    CHECK((T_A_B.inverse().act(T_A_B.act(x_C)) - x_C).norm() < 1e-12);
    CHECK(pose_dist((T_A_B * T_B_C).inverse(), T_B_C.inverse() * T_A_B.inverse()) < 1e-12);
    // Homogeneous matrices compose the same way.
    CHECK(((T_A_B * T_B_C).matrix() - T_A_B.matrix() * T_B_C.matrix()).norm() < 1e-12);
    CHECK((T_A_B.inverse().matrix() - T_A_B.matrix().inverse()).norm() < 1e-11);
    // The stored quaternion stays unit through products.
    CHECK(std::abs((T_A_B * T_B_C * T_C_D).q.norm() - 1.0) < 1e-15);
  }
  // Constructors normalise and agree.
  const Pose from_R(Matrix3d(Eigen::AngleAxisd(0.3, Vector3d::UnitY())), Vector3d(1, 2, 3));
  Quaterniond q(2.0, 0.0, 0.0, 0.0);
  CHECK(Pose(q, Vector3d::Zero()).q.w() == 1.0);
  CHECK(pose_dist(from_R, Pose(Quaterniond(Eigen::AngleAxisd(0.3, Vector3d::UnitY())), Vector3d(1, 2, 3))) <
        1e-15);
}

TEST_CASE("se3: pose_difference", "[se3]") {
  std::mt19937 rng(22);
  for (int i = 0; i < 100; ++i) {
    const Pose a = random_pose(rng);
    CHECK(pose_difference(a, a).norm() < 1e-15);
    const Vector3d dp = roe::test::random_vector(rng), dth = roe::test::random_vector(rng, 0.5);
    const Pose b(a.q * exp_quat(dth), a.p + dp);
    const auto d = pose_difference(a, b);
    CHECK((d.head<3>() - dp).norm() < 1e-14);
    if (dth.norm() < kPi) CHECK((d.tail<3>() - dth).norm() < 1e-12);  // local (right) rotation error
    // Swapping the arguments negates both parts: Log(R_b^T R_a) = −Log(R_a^T R_b).
    CHECK((pose_difference(b, a) + d).norm() < 1e-12);
  }
}

TEST_CASE("se3: interpolate endpoints, midpoint and shortest arc", "[se3][interpolate]") {
  std::mt19937 rng(23);
  for (const auto& s : roe::test::rotation_samples(100)) {
    CAPTURE(s.label);
    const Pose a = random_pose(rng);
    const Pose b(a.q * exp_quat(s.phi), a.p + roe::test::random_vector(rng));
    CHECK(pose_dist(interpolate(a, b, 0.0), a) < 1e-15);
    CHECK(pose_dist(interpolate(a, b, 1.0), b) < 1e-12);
    const Pose mid = interpolate(a, b, 0.5);
    CHECK((mid.p - 0.5 * (a.p + b.p)).norm() < 1e-14);
    const double theta = s.phi.norm();
    CHECK(std::abs(angle_between(a.q, mid.q) - 0.5 * theta) < 1e-9);
    CHECK(std::abs(angle_between(mid.q, b.q) - 0.5 * theta) < 1e-9);
    // Same rotation with the other quaternion sign: same interpolation (shortest arc).
    Pose b_neg = b;
    b_neg.q.coeffs() = -b.q.coeffs();
    if (theta < kPi - 1e-6) CHECK(pose_dist(interpolate(a, b_neg, 0.3), interpolate(a, b, 0.3)) < 1e-12);
    // Constant angular rate: the angle at alpha is alpha·θ along the same axis.
    if (theta > 1e-3 && theta < kPi - 1e-3) {
      const Pose q25 = interpolate(a, b, 0.25);
      CHECK((log_quat(a.q.conjugate() * q25.q) - 0.25 * s.phi).norm() < 1e-12);
    }
  }
}
