// Relative pose error: pair selection per unit and mode, the error of known drifts, invariance to
// the alignment, and option checks. evo's own numbers on real data: test_reference_evo.cpp.
#include <catch2/catch.hpp>
#include <cmath>

#include "roe/core/error.hpp"
#include "roe/eval/rpe.hpp"
#include "roe/math/so3.hpp"

using namespace roe;
using namespace roe::eval;
using Pairs = std::vector<std::pair<std::size_t, std::size_t>>;

namespace {

/// Poses along x at the given positions, identity orientation, 1 s apart.
std::vector<Pose> line(const std::vector<double>& x) {
  std::vector<Pose> p;
  for (double v : x) p.emplace_back(Eigen::Quaterniond::Identity(), Eigen::Vector3d(v, 0, 0));
  return p;
}
std::vector<Timestamp> stamps(const std::vector<double>& s) {
  std::vector<Timestamp> t;
  for (double v : s) t.push_back(from_seconds(v));
  return t;
}
RpeOptions opt(double delta, DeltaUnit u, bool all = false, double tol = 0.1) {
  RpeOptions o;
  o.delta = delta;
  o.unit = u;
  o.all_pairs = all;
  o.rel_tol = tol;
  return o;
}

/// A curved 3-D trajectory with turning orientation, n poses at 10 Hz.
std::vector<Pose> wiggle(std::size_t n) {
  std::vector<Pose> p;
  for (std::size_t k = 0; k < n; ++k) {
    const double t = 0.1 * static_cast<double>(k);
    p.emplace_back(math::exp_quat(Eigen::Vector3d(0.1 * std::sin(t), 0.2 * std::cos(0.5 * t), 0.3 * t)),
                   Eigen::Vector3d(std::cos(0.3 * t), std::sin(0.3 * t), 0.1 * t));
  }
  return p;
}

}  // namespace

TEST_CASE("rpe pairs: frames", "[eval][rpe]") {
  const auto p = line({0, 1, 2, 3, 4, 5, 6});
  const auto t = stamps({0, 1, 2, 3, 4, 5, 6});
  CHECK(rpe_index_pairs(p, t, opt(2, DeltaUnit::kFrames)) == Pairs{{0, 2}, {2, 4}, {4, 6}});
  CHECK(rpe_index_pairs(p, t, opt(4, DeltaUnit::kFrames)) == Pairs{{0, 4}});
  CHECK(rpe_index_pairs(p, t, opt(4, DeltaUnit::kFrames, true)) == Pairs{{0, 4}, {1, 5}, {2, 6}});
  CHECK(rpe_index_pairs(p, t, opt(7, DeltaUnit::kFrames)).empty());
}

TEST_CASE("rpe pairs: meters follow evo's walk (first id where the path reaches delta)", "[eval][rpe]") {
  // Path distances 0, 0.5, 1.0, 1.75, 2.75, 3.0, 3.125 (exact in binary).
  const auto p = line({0, 0.5, 1.0, 1.75, 2.75, 3.0, 3.125});
  const auto t = stamps({0, 1, 2, 3, 4, 5, 6});
  // Walked since the last id: 0.5, 1.0 -> id 2; 0.75, 1.75 -> id 4; 0.25, 0.375 (< 1): no more ids.
  CHECK(rpe_index_pairs(p, t, opt(1.0, DeltaUnit::kMeters)) == Pairs{{2, 4}});
  // All pairs: the j > i whose distance from i is closest to 1.0, kept within tol = 0.25:
  //   i=0: 1.0 at j=2; i=1: 0.5 / 1.25 (j=3); i=2: 0.75 (j=3) / 1.75; i=3: 1.0 (j=4);
  //   i=4: 0.25 / 0.375 -> none; i=5: 0.125 -> none.
  CHECK(rpe_index_pairs(p, t, opt(1.0, DeltaUnit::kMeters, true, 0.25)) ==
        Pairs{{0, 2}, {1, 3}, {2, 3}, {3, 4}});
  CHECK(rpe_index_pairs(p, t, opt(1.0, DeltaUnit::kMeters, true, 0.1)) == Pairs{{0, 2}, {3, 4}});
  // Standing still (equal path values): the earliest of the equally close poses.
  const auto q = line({0, 1, 1, 1, 2});
  CHECK(rpe_index_pairs(q, stamps({0, 1, 2, 3, 4}), opt(1.0, DeltaUnit::kMeters, true, 0.0)) ==
        Pairs{{0, 1}, {1, 4}, {2, 4}, {3, 4}});
}

TEST_CASE("rpe pairs: seconds (roe's unit) on the stamps, not on the index", "[eval][rpe]") {
  // Irregular stamps: 0, 0.5, 1.0, 1.25, 2.05, 3.0, 3.2 s.
  const auto p = line({0, 1, 2, 3, 4, 5, 6});
  const auto t = stamps({0, 0.5, 1.0, 1.25, 2.05, 3.0, 3.2});
  // Consecutive: 0, then the first stamp >= 0 + 1 s (1.0, id 2), then >= 2.0 (2.05, id 4), then >= 3.05 (id 6).
  CHECK(rpe_index_pairs(p, t, opt(1.0, DeltaUnit::kSeconds)) == Pairs{{0, 2}, {2, 4}, {4, 6}});
  // All pairs, closest to 1 s within 0.1 s: (0,2) 1.0; i=1: 0.75 -> none; (2,4) 1.05; i=3: 0.8 -> none;
  // (4,5) 0.95 (3.2 is 1.15 away); i=5: 0.2 -> none.
  CHECK(rpe_index_pairs(p, t, opt(1.0, DeltaUnit::kSeconds, true)) == Pairs{{0, 2}, {2, 4}, {4, 5}});
  auto bad = t;
  std::swap(bad[1], bad[2]);
  CHECK_THROWS_AS(rpe_index_pairs(p, bad, opt(1.0, DeltaUnit::kSeconds)), InputError);
}

TEST_CASE("rpe pairs: angles accumulate (consecutive) or compare directly (all pairs)", "[eval][rpe]") {
  // Yaw 0, 4, 8, 12, 8, 20 degrees.
  std::vector<Pose> p;
  for (double y : {0.0, 4.0, 8.0, 12.0, 8.0, 20.0})
    p.emplace_back(math::exp_quat(Eigen::Vector3d(0, 0, y * M_PI / 180.0)), Eigen::Vector3d::Zero());
  const std::vector<Timestamp> t(p.size(), 0);
  // Turned 4, 8 (< 10), 12 -> (0,3); then 4, 16 -> (3,5).
  CHECK(rpe_index_pairs(p, t, opt(10.0, DeltaUnit::kDegrees)) == Pairs{{0, 3}, {3, 5}});
  // Direct angles within 1 deg of 10... none; within 10 % of 12: (0,3) 12, (1,5) 16 no, (2,5) 12, (4,5) 12.
  CHECK(rpe_index_pairs(p, t, opt(12.0, DeltaUnit::kDegrees, true)) == Pairs{{0, 3}, {2, 5}, {4, 5}});
  CHECK(rpe_index_pairs(p, t, opt(12.0 * M_PI / 180.0, DeltaUnit::kRadians, true)) ==
        Pairs{{0, 3}, {2, 5}, {4, 5}});
}

TEST_CASE("rpe: known drifts give known errors", "[eval][rpe]") {
  const auto gt = wiggle(200);
  std::vector<Timestamp> t;
  for (std::size_t k = 0; k < gt.size(); ++k) t.push_back(static_cast<Timestamp>(k) * 100'000'000);

  SECTION("an identical estimate has zero error, also after any rigid transform of its world") {
    const Pose T(math::exp_quat(Eigen::Vector3d(0.3, -1.0, 2.0)), Eigen::Vector3d(5, -3, 1));
    std::vector<Pose> est;
    for (const auto& g : gt) est.push_back(T * g);
    const RpeResult r = compute_rpe(est, gt, t, t, opt(1.0, DeltaUnit::kMeters, true));
    REQUIRE(!r.pairs.empty());
    CHECK(r.trans_m.max < 1e-12);
    CHECK(r.rot_deg.max < 1e-6);
  }
  SECTION("a scaled estimate: |trans(E)| = (s-1)·|Δp| and drift (s-1)·chord/path in %") {
    std::vector<Pose> est = gt;
    for (auto& e : est) e.p *= 1.02;
    const RpeResult r = compute_rpe(est, gt, t, t, opt(10, DeltaUnit::kFrames));
    REQUIRE(r.pairs.size() == 19);
    for (const RpePair& p : r.pairs) {
      const double chord = (gt[p.j].p - gt[p.i].p).norm();
      CHECK(p.trans_m == Approx(0.02 * chord).epsilon(1e-9));
      CHECK(p.rot_deg < 1e-6);
      double path = 0.0;
      for (std::size_t k = p.i + 1; k <= p.j; ++k) path += (gt[k].p - gt[k - 1].p).norm();
      CHECK(p.path_gt_m == Approx(path).epsilon(1e-12));
      CHECK(p.trans_pct == Approx(100.0 * 0.02 * chord / path).epsilon(1e-9));
    }
  }
  SECTION("a constant yaw rate error: the angle of E is the rate times the pair's time") {
    std::vector<Pose> est = gt;
    const auto drift = [](std::size_t k) { return math::exp_quat(Eigen::Vector3d(0, 0, 0.001 * static_cast<double>(k))); };
    // World-frame yaw drift R_k = Rz(0.001 k) R_gt,k: the rotation of P_i⁻¹P_j is R_iᵀ Rz(0.001 (j−i)) R_j,
    // so E's rotation is R_jᵀ Rz(0.001 (j−i)) R_j, of angle 0.001 (j−i).
    for (std::size_t k = 0; k < est.size(); ++k) est[k].q = drift(k) * gt[k].q;
    const RpeResult r = compute_rpe(est, gt, t, t, opt(2.0, DeltaUnit::kSeconds));
    REQUIRE(r.pairs.size() == 9);
    for (const RpePair& p : r.pairs) {
      CHECK(p.j - p.i == 20);
      CHECK(p.rot_deg == Approx(0.001 * 20 * 180.0 / M_PI).epsilon(1e-9));
      // trans(E) = R_Q,relᵀ (t_P − t_Q) with t_P = R_iᵀ Rz(−a_i) d, t_Q = R_iᵀ d, d = p_j − p_i: its
      // length is |(Rz(−a_i) − I) d|.
      const Eigen::Vector3d d = gt[p.j].p - gt[p.i].p;
      CHECK(p.trans_m == Approx((drift(p.i).conjugate() * d - d).norm()).epsilon(1e-9).margin(1e-15));
    }
  }
  SECTION("pairs chosen on the ground truth use its stamps and path") {
    std::vector<Pose> est = gt;
    for (auto& e : est) e.p *= 2.0;  // the estimate walks twice as far
    RpeOptions o = opt(0.5, DeltaUnit::kMeters);
    const RpeResult from_est = compute_rpe(est, gt, t, t, o);
    o.pairs_from = PairsFrom::kGroundTruth;
    const RpeResult from_gt = compute_rpe(est, gt, t, t, o);
    CHECK(from_est.pairs.size() > from_gt.pairs.size() * 3 / 2);
    for (const RpePair& p : from_gt.pairs) CHECK(p.path_gt_m == Approx(0.5).margin(0.06));
  }
  SECTION("a delta longer than the trajectory gives no pairs and zero statistics") {
    const RpeResult r = compute_rpe(gt, gt, t, t, opt(1000.0, DeltaUnit::kMeters));
    CHECK(r.pairs.empty());
    CHECK(r.trans_m.n == 0);
  }
}

TEST_CASE("rpe: options and inputs are checked", "[eval][rpe]") {
  const auto p = line({0, 1, 2});
  const auto t = stamps({0, 1, 2});
  CHECK_THROWS_AS(rpe_index_pairs(p, t, opt(0.0, DeltaUnit::kMeters)), InputError);
  CHECK_THROWS_AS(rpe_index_pairs(p, t, opt(-1.0, DeltaUnit::kSeconds)), InputError);
  CHECK_THROWS_AS(rpe_index_pairs(p, t, opt(NAN, DeltaUnit::kSeconds)), InputError);
  CHECK_THROWS_AS(rpe_index_pairs(p, t, opt(1.5, DeltaUnit::kFrames)), InputError);
  CHECK_THROWS_AS(rpe_index_pairs(p, t, opt(181.0, DeltaUnit::kDegrees)), InputError);
  CHECK_THROWS_AS(rpe_index_pairs(p, t, opt(3.2, DeltaUnit::kRadians)), InputError);
  CHECK_THROWS_AS(rpe_index_pairs(p, t, opt(1.0, DeltaUnit::kMeters, true, -0.1)), InputError);
  CHECK_THROWS_AS(compute_rpe(p, line({0, 1}), t, t, opt(1.0, DeltaUnit::kFrames)), InputError);
  CHECK_THROWS_AS(parse_delta_unit("km"), InputError);
  CHECK_THROWS_AS(parse_pairs_from("both"), InputError);
  for (DeltaUnit u : {DeltaUnit::kFrames, DeltaUnit::kMeters, DeltaUnit::kSeconds, DeltaUnit::kDegrees,
                      DeltaUnit::kRadians})
    CHECK(parse_delta_unit(to_string(u)) == u);
  CHECK(parse_pairs_from("reference") == PairsFrom::kGroundTruth);
}
