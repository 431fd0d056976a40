// eval::interpolate_pose_at (ground truth at a detection's stamp) against math::interpolate.
#include <catch2/catch.hpp>
#include <random>

#include "math/samples.hpp"
#include "roe/eval/interpolate.hpp"
#include "roe/math/se3.hpp"

using namespace roe::math;
using roe::StampedPose;
using roe::Timestamp;
using roe::eval::interpolate_pose_at;

namespace {

Pose random_pose(std::mt19937& rng) {
  return Pose(exp_quat(roe::test::random_vector(rng)), roe::test::random_vector(rng, 2.0));
}

double pose_dist(const Pose& a, const Pose& b) { return pose_difference(a, b).norm(); }

}  // namespace

TEST_CASE("interpolate_pose_at: samples, between samples, no extrapolation, gaps", "[interpolate]") {
  std::mt19937 rng(24);
  std::vector<StampedPose> seq;
  for (int i = 0; i < 20; ++i)
    seq.push_back({1'000'000'000LL + i * 10'000'000LL + (i > 10 ? 50'000'000LL : 0), random_pose(rng)});
  // Exactly at samples: the sample itself.
  for (const auto& s : seq) {
    auto T = interpolate_pose_at(seq, s.t_ns);
    REQUIRE(T);
    CHECK(T->q.coeffs() == s.T.q.coeffs());
    CHECK(T->p == s.T.p);
  }
  // Between samples: matches math::interpolate with the integer-time alpha.
  for (std::size_t i = 0; i + 1 < seq.size(); ++i) {
    const Timestamp t = seq[i].t_ns + (seq[i + 1].t_ns - seq[i].t_ns) / 4;
    auto T = interpolate_pose_at(seq, t);
    REQUIRE(T);
    CHECK(pose_dist(*T, interpolate(seq[i].T, seq[i + 1].T, 0.25)) < 1e-15);
    // One nanosecond after a sample is close to it.
    auto T1 = interpolate_pose_at(seq, seq[i].t_ns + 1);
    REQUIRE(T1);
    CHECK(pose_dist(*T1, seq[i].T) < 1e-5);
  }
  // No extrapolation.
  CHECK_FALSE(interpolate_pose_at(seq, seq.front().t_ns - 1));
  CHECK_FALSE(interpolate_pose_at(seq, seq.back().t_ns + 1));
  CHECK_FALSE(interpolate_pose_at({}, 0));
  const std::vector<StampedPose> one = {seq[3]};
  CHECK(interpolate_pose_at(one, seq[3].t_ns));
  CHECK_FALSE(interpolate_pose_at(one, seq[3].t_ns + 1));
  // Gap limit: the 60 ms gap between samples 10 and 11 is refused with a 20 ms limit.
  const Timestamp in_gap = seq[10].t_ns + 30'000'000LL;
  CHECK(interpolate_pose_at(seq, in_gap));
  CHECK_FALSE(interpolate_pose_at(seq, in_gap, 20'000'000LL));
  CHECK(interpolate_pose_at(seq, seq[10].t_ns, 20'000'000LL));  // a sample itself is always fine
  CHECK(interpolate_pose_at(seq, seq[3].t_ns + 5, 20'000'000LL));
  // Linear translation at constant velocity is reproduced exactly in time.
  std::vector<StampedPose> lin = {{0, Pose(Quaterniond::Identity(), Vector3d(0, 0, 0))},
                                  {3'000'000'000LL, Pose(Quaterniond::Identity(), Vector3d(3, -6, 9))}};
  auto T = interpolate_pose_at(lin, 1'000'000'000LL);
  REQUIRE(T);
  CHECK((T->p - Vector3d(1, -2, 3)).norm() < 1e-15);
}
