// Lock-out and re-lock (FilterOptions::relock_after_s, ekf/relock.hpp, docs/filter.md §13), and the
// online scale of predicted σ (adapt_detection_sigma_scale, §14).
//  - LockoutMonitor alone: coherent offsets re-lock (offset and drift recovered), not before after_s;
//    offsets scattered about zero, objects that disagree, or an accepted position do not.
//  - A filter whose position is pushed 1 m off refuses every later (exact) detection for ever with the
//    paper's gate; with relock_after_s it re-locks and returns to the truth.
//  - Detections whose reported σ are half their true errors: the learned scale comes out near 2.
#include <catch2/catch.hpp>
#include <cmath>

#include "roe/ekf/filter.hpp"
#include "roe/ekf/relock.hpp"
#include "roe/math/so3.hpp"
#include "roe/sim/random.hpp"
#include "support/scaled_sigma_detections.hpp"

using namespace roe;
using namespace roe::ekf;
using math::exp_quat;

namespace {

constexpr Timestamp kFrame = 33'333'333;  // 30 Hz

}  // namespace

TEST_CASE("lock-out monitor: coherent offsets re-lock with their offset and drift", "[ekf][relock]") {
  sim::Rng rng(7);
  const Eigen::Vector3d a0(0.5, -0.2, 0.1), drift(0.4, 0.0, -0.2);
  LockoutMonitor m(0.5, 6, 0.3);
  m.accepted(0);
  Timestamp t = 0;
  for (int k = 1; k <= 24; ++k) {  // 0.8 s of two objects refused
    t = k * kFrame;
    for (int id : {3, 4}) m.refused(t, id, a0 + drift * to_seconds(t) + rng.normal3() * 0.05);
    if (t < from_seconds(0.5)) CHECK_FALSE(m.check(t).has_value());  // not before after_s
  }
  const auto r = m.check(t);
  REQUIRE(r.has_value());
  CHECK((r->offset - (a0 + drift * to_seconds(t))).norm() < 0.05);
  CHECK((r->drift_per_s - drift).norm() < 0.15);
  CHECK(r->residual_sigma == Approx(0.05).margin(0.02));
  CHECK(r->objects == 2);
  CHECK(r->since_ns == 0);
  // A position accepted drops the evidence.
  m.accepted(t);
  CHECK_FALSE(m.check(t + kFrame).has_value());
  // Disabled.
  LockoutMonitor off(0.0, 6, 0.3);
  off.refused(0, 1, a0);
  CHECK_FALSE(off.enabled());
  CHECK_FALSE(off.check(from_seconds(10.0)).has_value());
}

TEST_CASE("lock-out monitor: scattered offsets and disagreeing objects do not re-lock", "[ekf][relock]") {
  // Outliers about a right estimate: zero-mean offsets with a large spread, many seeds, checked every frame.
  int fired = 0;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    sim::Rng rng(seed);
    LockoutMonitor m(0.5, 6, 0.3);
    for (int k = 0; k < 60; ++k) {
      const Timestamp t = k * kFrame;
      m.refused(t, 1 + k % 2, rng.normal3() * 0.5);
      fired += m.check(t).has_value();
    }
  }
  CHECK(fired <= 2);  // 1200 checks; the significance test allows about 0.1 % per check
  // Two objects whose offsets are consistent each but disagree with each other (1 m apart).
  LockoutMonitor m(0.5, 6, 0.3);
  for (int k = 0; k < 30; ++k) {
    m.refused(k * kFrame, 1, Eigen::Vector3d(0.5, 0, 0));
    m.refused(k * kFrame, 2, Eigen::Vector3d(-0.5, 0, 0));
  }
  CHECK_FALSE(m.check(29 * kFrame).has_value());
  // One object alone, coherent, is enough (after a visibility gap it is often all there is).
  LockoutMonitor one(0.5, 6, 0.3);
  for (int k = 0; k < 30; ++k) one.refused(k * kFrame, 1, Eigen::Vector3d(0.5, 0.01 * (k % 3), 0));
  CHECK(one.check(29 * kFrame).has_value());
}

namespace {

// A filter at rest with objects 1 (anchor) and 2 initialised from exact detections; the same detections
// stay exact as long as the IMU rests.
struct AtRest {
  Filter f;
  Detection a, b;
  explicit AtRest(const FilterOptions& opt)
      : f(opt, ImuNoiseParams{1e-3, 1e-4, 1e-2, 1e-3}, Pose(exp_quat(Vec3(0.1, -0.05, 0.02)), Vec3(0.02, 0, 0))) {
    f.initialize(0, Vec3::Zero(), kGravity_W, kGravity_W);
    a.object_id = 1;
    a.T_C_O = Pose(exp_quat(Vec3(0.3, -0.2, 0.1)), Vec3(0.2, -0.1, 1.8));
    b.object_id = 2;
    b.T_C_O = Pose(exp_quat(Vec3(-0.4, 0.5, 0.2)), Vec3(-0.3, 0.2, 2.2));
    f.update({a, b});
  }
  // Rest for one frame, then the exact detections.
  FrameResult frame(int k) {
    for (int s = 1; s <= 8; ++s) f.propagate((k - 1) * kFrame + s * kFrame / 8, Vec3::Zero(), kGravity_W);
    return f.update({a, b});
  }
};

FilterOptions rest_options(double relock_after_s) {
  FilterOptions o;
  o.init_min_detections = 1;
  o.anchor_id = 1;
  o.require_anchor = false;
  o.meas_sigma_p_m = 0.02;
  o.meas_sigma_rot_deg = 2.0;
  o.relock_after_s = relock_after_s;
  return o;
}

}  // namespace

TEST_CASE("relock: a filter pushed 1 m off comes back, the paper's gate never does", "[ekf][relock]") {
  for (const double after : {0.0, 0.5}) {
    INFO("relock_after_s " << after);
    AtRest s(rest_options(after));
    const Vec3 p_true = s.f.core().p_W_I;
    // The position (only) jumps 1 m; its covariance stays small: every later detection fails the gate.
    Eigen::VectorXd dx = Eigen::VectorXd::Zero(s.f.dim());
    dx.head<3>() = Vec3(0.6, -0.8, 0.0);
    s.f.boxplus(dx);
    int relocks = 0, refused_frames = 0;
    Timestamp relock_t = -1;
    for (int k = 1; k <= 60; ++k) {
      const FrameResult r = s.frame(k);
      if (r.relock) {
        ++relocks;
        relock_t = r.t_ns;
        CHECK(r.relock->offset.norm() == Approx(1.0).margin(0.1));
        CHECK(r.relock->objects == 2);
      }
      refused_frames += r.n_inliers == 0;
      CHECK(r.position_used == (r.n_inliers > 0));
    }
    if (after == 0.0) {
      CHECK(relocks == 0);
      CHECK(refused_frames >= 50);  // a few pass once the position σ has grown at rest; it stays 1 m off
      CHECK((s.f.core().p_W_I - p_true).norm() > 0.9);
    } else {
      CHECK(relocks == 1);
      CHECK(relock_t >= from_seconds(0.5));
      CHECK(relock_t <= from_seconds(0.7));
      CHECK((s.f.core().p_W_I - p_true).norm() < 0.02);
    }
  }
}

TEST_CASE("adapt_detection_sigma_scale learns the factor of reported σ that are half the true errors",
          "[ekf][relock][sigma]") {
  for (const bool adapt : {false, true}) {
    FilterOptions o = rest_options(0.0);
    o.use_detection_sigmas = true;
    o.adapt_detection_sigma_scale = adapt;
    o.chi2_gate = false;  // the scale alone, without the gate's selection
    AtRest s(o);
    test::ScaledSigmaDetector detect(2.0, 11);  // σ_true = 2 σ_reported
    for (int k = 1; k <= 150; ++k) {
      for (int j = 1; j <= 8; ++j) s.f.propagate((k - 1) * kFrame + j * kFrame / 8, Vec3::Zero(), kGravity_W);
      s.f.update({detect(k * kFrame, 1, s.a.T_C_O), detect(k * kFrame, 2, s.b.T_C_O)});
    }
    INFO("adapt " << adapt);
    if (adapt)
      CHECK(s.f.detection_sigma_scale() == Approx(2.0).epsilon(0.2));
    else
      CHECK(s.f.detection_sigma_scale() == 1.0);
  }
}
