// The failure modes of real PoET (detection_model.hpp 6–8) and the reported σ (9): each against its
// definition, with statistical bounds of at least 6 standard deviations at the fixed seeds (so they
// cannot fail by chance) that still catch a wrong factor.
#include <catch2/catch.hpp>
#include <cmath>

#include "roe/core/error.hpp"
#include "roe/math/so3.hpp"
#include "roe/sim/detection_model.hpp"
#include "detection_support.hpp"

using namespace roe;
using namespace roe::sim;
using roe::sim::test::kCam;

namespace {
constexpr double kDeg = M_PI / 180.0;

DetectionNoiseConfig white_camera_frame() {
  DetectionNoiseConfig d = roe::sim::test::gaussian_only();
  d.translation_frame = "camera";
  d.write_sigmas = true;
  return d;
}

// Pose whose origin projects to pixel (u, v) at depth z, model axes = camera axes.
Pose at_pixel(double u, double v, double z) {
  return Pose(Eigen::Quaterniond::Identity(),
              Eigen::Vector3d((u - kCam.cx) / kCam.fx * z, (v - kCam.cy) / kCam.fy * z, z));
}

// RMS over n detections of (error / reported σ) per axis (translation x, y, z; rotation vector x, y, z).
Vector6d normalised_rms(PoetErrorModel& model, const Pose& truth, int n, Rng& rng, bool bad = false) {
  Vector6d acc = Vector6d::Zero();
  for (int i = 0; i < n; ++i) {
    const Detection d = model.measure(i * 33'333'333LL, 1, truth, FrameCondition{false, bad}, rng);
    REQUIRE(d.sigma);
    Vector6d e;
    e << d.T_C_O.p - truth.p, math::log_quat(truth.q.conjugate() * d.T_C_O.q);
    const Vector6d r = e.cwiseQuotient(*d.sigma);
    acc += r.cwiseProduct(r);
  }
  return (acc / n).cwiseSqrt();
}
}  // namespace

TEST_CASE("Border cut: share of the projected extent beyond the image border", "[sim][noise][failure]") {
  DetectionNoiseConfig cfg = white_camera_frame();
  cfg.object_radius_m = 0.1;
  const PoetErrorModel model(cfg, {}, kCam);
  // At 1 m the extent has a radius of 0.1 · 919.806 px ≈ 92 px.
  const double r_px = 0.1 * kCam.fx;
  CHECK(model.border_cut(at_pixel(320, 240, 1.0)) == 0.0);
  CHECK(model.border_cut(at_pixel(r_px + 1.0, 240, 1.0)) == 0.0);  // just inside: nothing cut
  CHECK(model.border_cut(at_pixel(0.5 * r_px, 240, 1.0)) == Approx(0.25));
  CHECK(model.border_cut(at_pixel(320, 480 - 0.5 * r_px, 1.0)) == Approx(0.25));  // bottom edge
  CHECK(model.border_cut(at_pixel(320, 0.0, 1.0)) == Approx(0.5));
  // Farther away a pixel near the border cuts less (smaller extent): at 2 m the radius is 46 px.
  CHECK(model.border_cut(at_pixel(0.6 * r_px, 240, 2.0)) == 0.0);
  // Without a camera (fx = 0) nothing is cut.
  CHECK(PoetErrorModel(cfg, {}).border_cut(at_pixel(0.0, 240, 1.0)) == 0.0);

  // σ × (1 + gain · c): the reported σ and the drawn errors both follow.
  cfg.border_sigma_gain = 2.0;
  PoetErrorModel gained(cfg, {}, kCam);
  const Pose cut = at_pixel(0.5 * r_px, 240, 1.0);
  const Vector6d s0 = PoetErrorModel(white_camera_frame(), {}, kCam).sigmas(cut);
  CHECK(gained.sigmas(cut)(0) == Approx(1.5 * s0(0)));
  CHECK(gained.sigmas(cut)(5) == Approx(1.5 * s0(5)));
  Rng rng(7);
  const Vector6d rms = normalised_rms(gained, cut, 20000, rng);
  for (int i = 0; i < 6; ++i) CHECK(rms(i) == Approx(1.0).margin(0.04));  // σ̂/σ ± 0.5 % per 1σ
}

TEST_CASE("Border outliers and view-dependent flips move the thresholds of the existing draws",
          "[sim][noise][failure]") {
  DetectionNoiseConfig cfg = white_camera_frame();
  cfg.border_outlier_prob = 0.4;
  cfg.symmetric_flip_prob = 0.1;
  cfg.flip_view_gain = 0.5;
  PoetErrorModel model(cfg, {{16, ycbv_symmetry(16)}}, kCam);
  const double r_px = 0.1 * kCam.fx;
  const Pose cut = at_pixel(0.5 * r_px, 240, 1.0);  // c = 0.25 → outlier probability 0.1
  // End-on (sight along the model z axis: identity rotation, object on the optical axis) → a = 1;
  // side-on (model z ⟂ sight) → a = 0.
  const Pose end_on = at_pixel(kCam.cx, kCam.cy, 1.0);
  const Pose side_on(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX())), end_on.p);
  CHECK(PoetErrorModel::end_on(end_on) == Approx(1.0));
  CHECK(PoetErrorModel::end_on(side_on) == Approx(0.0).margin(1e-12));
  const int n = 20000;
  int outliers = 0, flips_end = 0, flips_side = 0;
  Rng rng(11);
  for (int i = 0; i < n; ++i) {
    DetectionLabel l;
    model.measure(i, 1, cut, false, rng, &l);
    outliers += l.outlier;
    model.measure(i, 16, end_on, false, rng, &l);
    flips_end += l.flipped && !l.outlier;
    model.measure(i, 16, side_on, false, rng, &l);
    flips_side += l.flipped && !l.outlier;
  }
  const double sd = std::sqrt(0.25 / n);  // binomial σ bound
  CHECK(outliers / double(n) == Approx(0.1).margin(6 * sd));
  CHECK(flips_end / double(n) == Approx(0.6).margin(6 * sd));
  CHECK(flips_side / double(n) == Approx(0.1).margin(6 * sd));
}

TEST_CASE("Runs of bad frames: stationary share and mean run length of the two-state chain",
          "[sim][noise][failure]") {
  DetectionNoiseConfig cfg = white_camera_frame();
  cfg.burst_start_prob = 0.02;
  cfg.burst_mean_frames = 10.0;
  PoetErrorModel model(cfg, {}, kCam);
  Rng blur(1), burst(2);
  const int n = 200000;
  int bad = 0, runs = 0;
  bool prev = false;
  for (int i = 0; i < n; ++i) {
    const FrameCondition f = model.frame_condition(0.0, blur, burst);
    bad += f.bad;
    runs += f.bad && !prev;
    prev = f.bad;
  }
  // Stationary share p / (p + 1/L) = 0.02 / 0.12 = 1/6; mean run length L. Runs are ~3000, so the
  // mean length is known to ~2 % (geometric σ/mean ≈ 1/√runs).
  CHECK(bad / double(n) == Approx(1.0 / 6.0).margin(0.02));
  CHECK(bad / double(runs) == Approx(10.0).epsilon(0.1));
  // In a bad frame σ × burst_sigma_scale and the outlier probability is burst_outlier_prob.
  cfg.burst_sigma_scale = 3.0;
  cfg.burst_outlier_prob = 0.5;
  PoetErrorModel scaled(cfg, {}, kCam);
  const Pose truth = at_pixel(300, 200, 1.2);
  CHECK(scaled.sigmas(truth, true)(2) == Approx(3.0 * scaled.sigmas(truth, false)(2)));
  Rng rng(3);
  int outliers = 0;
  for (int i = 0; i < 20000; ++i) {
    DetectionLabel l;
    scaled.measure(i, 1, truth, FrameCondition{false, true}, rng, &l);
    outliers += l.outlier;
    REQUIRE(l.bad_frame);
  }
  CHECK(outliers / 20000.0 == Approx(0.5).margin(6 * std::sqrt(0.25 / 20000)));
}

TEST_CASE("Reported sigma: informative, over- and underconfident by the configured scale",
          "[sim][noise][sigma]") {
  // error / reported σ has RMS 1 / scale on every axis. With 20000 draws the RMS is known to
  // 1/√(2n) = 0.5 % (1σ); the bound of 4 % is 8σ and a wrong scale (e.g. 0.5 ↔ 1) is off by 100 %.
  const Pose truth(math::exp_quat(Eigen::Vector3d(0.1, 0.3, -0.2)), Eigen::Vector3d(0.2, -0.1, 1.3));
  for (double scale : {1.0, 0.5, 2.0}) {
    DetectionNoiseConfig cfg = white_camera_frame();
    cfg.reported_sigma_scale = scale;
    cfg.view_sigma_gain = 0.7;  // per-detection σ that differ from the base σ
    cfg.rotation_sigma_per_depth_deg = 3.0;
    PoetErrorModel model(cfg, {}, kCam);
    Rng rng(17);
    const Vector6d rms = normalised_rms(model, truth, 20000, rng);
    INFO("scale " << scale << ": " << rms.transpose());
    for (int i = 0; i < 6; ++i) CHECK(rms(i) == Approx(1.0 / scale).epsilon(0.04));
  }
  // The same holds in a bad frame (its σ are reported too).
  DetectionNoiseConfig cfg = white_camera_frame();
  cfg.burst_sigma_scale = 4.0;
  PoetErrorModel model(cfg, {}, kCam);
  Rng rng(19);
  const Vector6d rms = normalised_rms(model, truth, 20000, rng, true);
  for (int i = 0; i < 6; ++i) CHECK(rms(i) == Approx(1.0).epsilon(0.04));
}

TEST_CASE("Reported sigma of gross errors: nominal (overconfident failures) or inflated",
          "[sim][noise][sigma]") {
  DetectionNoiseConfig cfg = white_camera_frame();
  cfg.outlier_prob = 0.3;
  const Pose truth = at_pixel(330, 250, 1.0);
  for (const char* mode : {"nominal", "inflated"}) {
    cfg.reported_failure_sigma = mode;
    PoetErrorModel model(cfg, {}, kCam);
    const Vector6d ordinary = model.sigmas(truth);
    Rng rng(23);
    int outliers = 0;
    for (int i = 0; i < 2000; ++i) {
      DetectionLabel l;
      const Detection d = model.measure(i, 1, truth, false, rng, &l);
      REQUIRE(d.sigma);
      if (!l.outlier) {
        REQUIRE(d.sigma->isApprox(ordinary));
        continue;
      }
      ++outliers;
      if (std::string(mode) == "nominal") {
        REQUIRE(d.sigma->isApprox(ordinary));  // a gross error with a small σ
      } else {
        REQUIRE((*d.sigma)(0) == Approx(cfg.failure_sigma_m));
        REQUIRE((*d.sigma)(5) == Approx(cfg.failure_sigma_deg * kDeg));
      }
    }
    CHECK(outliers > 400);
  }
}

TEST_CASE("Detection config validation names the key", "[sim][config]") {
  DetectionNoiseConfig d;
  d.burst_mean_frames = 0.5;
  CHECK_THROWS_WITH(validate(d, "detection"), Catch::Contains("detection.burst_mean_frames"));
  d = DetectionNoiseConfig();
  d.border_outlier_prob = 1.5;
  CHECK_THROWS_WITH(validate(d, "detection"), Catch::Contains("detection.border_outlier_prob"));
  d = DetectionNoiseConfig();
  d.reported_failure_sigma = "huge";
  CHECK_THROWS_AS(validate(d, "detection"), ConfigError);
  d = DetectionNoiseConfig();
  d.reported_sigma_scale = 0.0;  // the sigma columns must be > 0 (docs/dataset-format.md)
  CHECK_THROWS_WITH(validate(d, "detection"), Catch::Contains("detection.reported_sigma_scale"));
  VisibilityConfig v;
  v.max_depth_m = 0.1;
  CHECK_THROWS_WITH(validate(v, "visibility"), Catch::Contains("visibility.max_depth_m"));
}
