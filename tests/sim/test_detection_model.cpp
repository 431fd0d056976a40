// The PoET-like error model and the visibility rules: empirical statistics against the configured
// parameters (σ within 10 %, rates within a few binomial standard deviations).
#include <catch2/catch.hpp>
#include <cmath>

#include "roe/math/so3.hpp"
#include "roe/sim/detection_model.hpp"
#include "roe/sim/simulator.hpp"
#include "detection_support.hpp"

using namespace roe;
using namespace roe::sim;
using roe::sim::test::gaussian_only;
using roe::sim::test::kCam;

namespace {
constexpr double kDeg = M_PI / 180.0;

// Errors of one detection in the ray frame (u1, u2 lateral, r along) and the rotation error vector.
struct Err {
  Eigen::Vector3d t_ray;
  Eigen::Vector3d rot;
};
Err error_of(const Pose& truth, const Detection& d) {
  const Eigen::Vector3d r = truth.p.normalized();
  Eigen::Vector3d u1 = Eigen::Vector3d::UnitY().cross(r).normalized();
  const Eigen::Vector3d u2 = r.cross(u1);
  const Eigen::Vector3d e = d.T_C_O.p - truth.p;
  return {Eigen::Vector3d(e.dot(u1), e.dot(u2), e.dot(r)), math::log_quat(truth.q.conjugate() * d.T_C_O.q)};
}
}  // namespace

TEST_CASE("Gaussian errors: per-component sigma within 10 % of the configured values", "[sim][noise]") {
  const DetectionNoiseConfig cfg = gaussian_only();
  PoetErrorModel model(cfg, {});
  Rng rng(123);
  // An off-axis object, so the ray frame differs from the camera axes.
  const Pose truth(math::exp_quat(Eigen::Vector3d(0.3, -1.0, 0.5)), Eigen::Vector3d(0.3, -0.2, 1.6));
  const double z = truth.p.z();
  const double s_lat = 0.01 + 0.01 * z, s_ray = 0.03 + 0.05 * z, s_rot = 6.0 * kDeg;
  const int n = 40000;
  Eigen::Vector3d st = Eigen::Vector3d::Zero(), sr = Eigen::Vector3d::Zero(), mt = Eigen::Vector3d::Zero();
  for (int i = 0; i < n; ++i) {
    const Err e = error_of(truth, model.measure(1000 + i * 33'333'333LL, 1, truth, false, rng));
    st += e.t_ray.cwiseProduct(e.t_ray);
    sr += e.rot.cwiseProduct(e.rot);
    mt += e.t_ray;
  }
  st = (st / n).cwiseSqrt();
  sr = (sr / n).cwiseSqrt();
  CHECK(st(0) == Approx(s_lat).epsilon(0.1));
  CHECK(st(1) == Approx(s_lat).epsilon(0.1));
  CHECK(st(2) == Approx(s_ray).epsilon(0.1));
  for (int i = 0; i < 3; ++i) CHECK(sr(i) == Approx(s_rot).epsilon(0.1));
  CHECK((mt / n).norm() < 0.002);  // unbiased
  // The tighter (statistical) check: 40000 samples estimate σ to about ±0.35 %.
  CHECK(st(2) == Approx(s_ray).epsilon(0.02));
  CHECK(sr(0) == Approx(s_rot).epsilon(0.02));
}

TEST_CASE("Camera-frame errors and the written sigmas", "[sim][noise]") {
  DetectionNoiseConfig cfg = gaussian_only();
  cfg.translation_frame = "camera";
  cfg.write_sigmas = true;
  PoetErrorModel model(cfg, {});
  Rng rng(5);
  const Pose truth(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.4, 0.3, 1.0));
  const int n = 40000;
  Eigen::Vector3d s = Eigen::Vector3d::Zero();
  Detection last;
  for (int i = 0; i < n; ++i) {
    last = model.measure(i * 33'333'333LL, 1, truth, false, rng);
    const Eigen::Vector3d e = last.T_C_O.p - truth.p;
    s += e.cwiseProduct(e);
  }
  s = (s / n).cwiseSqrt();
  REQUIRE(last.sigma);
  CHECK((*last.sigma)(0) == Approx(0.02));
  CHECK((*last.sigma)(2) == Approx(0.08));
  CHECK((*last.sigma)(3) == Approx(6.0 * kDeg));
  for (int i = 0; i < 3; ++i) CHECK(s(i) == Approx((*last.sigma)(i)).epsilon(0.05));
}

TEST_CASE("Gauss-Markov correlation: marginal sigma kept, lag-1 correlation exp(-dt/tau)", "[sim][noise]") {
  DetectionNoiseConfig cfg = gaussian_only();
  cfg.correlation_time_s = 0.3;
  PoetErrorModel model(cfg, {});
  Rng rng(77);
  const Pose truth(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.0, 0.0, 1.0));
  const double s_ray = 0.08;
  const int n = 200000;
  const long long dt_ns = 33'333'333;
  double s2 = 0, lag = 0, prev = 0;
  for (int i = 0; i < n; ++i) {
    const double e = model.measure(i * dt_ns, 1, truth, false, rng).T_C_O.p.z() - 1.0;
    s2 += e * e;
    if (i > 0) lag += e * prev;
    prev = e;
  }
  const double sigma = std::sqrt(s2 / n);
  const double rho = (lag / (n - 1)) / (s2 / n);
  CHECK(sigma == Approx(s_ray).epsilon(0.1));
  CHECK(rho == Approx(std::exp(-dt_ns * 1e-9 / 0.3)).margin(0.02));
  // White noise (τ = 0) has no lag-1 correlation.
  PoetErrorModel white(gaussian_only(), {});
  double w2 = 0, wl = 0, wp = 0;
  for (int i = 0; i < n / 4; ++i) {
    const double e = white.measure(i * dt_ns, 1, truth, false, rng).T_C_O.p.z() - 1.0;
    w2 += e * e;
    if (i > 0) wl += e * wp;
    wp = e;
  }
  CHECK(std::abs(wl / w2) < 0.02);
}

TEST_CASE("Outliers, symmetric flips and blur happen at the configured rates", "[sim][noise]") {
  DetectionNoiseConfig cfg;      // defaults: 5 % outliers, 25 % flips, blur > 120 °/s or 2 % of frames
  cfg.rotation_sigma_deg = 0.0;  // so a flip is recognisable exactly
  PoetErrorModel model(cfg, {{13, ycbv_symmetry(13)}, {16, ycbv_symmetry(16)}});
  Rng rng(99);
  const Pose truth(math::exp_quat(Eigen::Vector3d(0.2, 0.4, -0.1)), Eigen::Vector3d(0.1, 0.05, 1.2));
  const int n = 40000;
  int outliers = 0, flips16 = 0, flips13 = 0, far = 0, flips1 = 0, flips13_negative = 0;
  double flip_cos = 0.0, flip_sin = 0.0;
  for (int i = 0; i < n; ++i) {
    const Timestamp t = i * 33'333'333LL;
    for (int id : {1, 13, 16}) {
      DetectionLabel label;
      const Detection d = model.measure(t, id, truth, false, rng, &label);
      if (id == 1) {
        outliers += label.outlier;
        flips1 += label.flipped;
        // Outliers: translation within 0.3 m of the truth (plus nothing else), random rotation.
        if (label.outlier) {
          REQUIRE((d.T_C_O.p - truth.p).norm() <= 0.3 + 1e-12);
          far += math::angle_between(d.T_C_O.q, truth.q) > 30 * kDeg;
        }
      }
      if (id == 16 && !label.outlier) {
        const Eigen::Quaterniond flipped =
            truth.q * Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()));
        const bool is_flip = math::angle_between(d.T_C_O.q, flipped) < 1e-9;
        REQUIRE(is_flip == label.flipped);
        flips16 += is_flip;
      }
      if (id == 13 && !label.outlier) {
        // Continuous symmetry: the error is a rotation about the model z axis only, by an angle uniform
        // on the circle.
        const Eigen::Vector3d e = math::log_quat(truth.q.conjugate() * d.T_C_O.q);
        REQUIRE(e.head<2>().norm() < 1e-9);
        flips13 += label.flipped;
        if (label.flipped) {
          flip_cos += std::cos(e.z());
          flip_sin += std::sin(e.z());
          flips13_negative += e.z() < 0.0;  // angles in (π, 2π) come back from log as negative
        }
      }
    }
  }
  const double p_out = outliers / double(n);
  CHECK(p_out == Approx(0.05).margin(4 * std::sqrt(0.05 * 0.95 / n)));
  CHECK(far > 0.8 * outliers);  // a uniform rotation is mostly far from the truth
  CHECK(flips1 == 0);           // non-symmetric objects never flip
  const double n_in = n * 0.95;
  CHECK(flips16 / n_in == Approx(0.25).margin(0.015));
  CHECK(flips13 / n_in == Approx(0.25).margin(0.015));
  // Uniform on the circle: mean cos and sin 0 (σ of each 1/√(2·flips) ≈ 0.007), half the angles past π.
  CHECK(flip_cos / flips13 == Approx(0.0).margin(0.03));
  CHECK(flip_sin / flips13 == Approx(0.0).margin(0.03));
  CHECK(flips13_negative / double(flips13) == Approx(0.5).margin(0.03));

  // Blur: always above the rate threshold, 2 % of frames below it; blurred detections are corrupted.
  int blurred = 0;
  for (int i = 0; i < n; ++i) {
    REQUIRE(model.frame_blurred(121 * kDeg, rng));
    blurred += model.frame_blurred(119 * kDeg, rng);
  }
  CHECK(blurred / double(n) == Approx(0.02).margin(4 * std::sqrt(0.02 * 0.98 / n)));
  int corrupted = 0;
  for (int i = 0; i < 1000; ++i) {
    DetectionLabel label;
    const Detection d = model.measure(n * 33'333'333LL + i * 33'333'333LL, 1, truth, true, rng, &label);
    REQUIRE(label.blurred);
    corrupted += math::angle_between(d.T_C_O.q, truth.q) > 30 * kDeg;
  }
  CHECK(corrupted > 800);
}

TEST_CASE("Visibility: depth range, image margin and border-weighted misses", "[sim][visibility]") {
  const VisibilityConfig vis;  // margin 10 px, 0.3–2.5 m, 2 % + 30 % at the border over 60 px
  auto at = [](double x, double y, double z) {
    return Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(x, y, z));
  };
  CHECK(object_in_view(at(0, 0, 1.0), kCam, vis));
  CHECK_FALSE(object_in_view(at(0, 0, -1.0), kCam, vis));  // behind
  CHECK_FALSE(object_in_view(at(0, 0, 0.29), kCam, vis));
  CHECK(object_in_view(at(0, 0, 0.31), kCam, vis));
  CHECK(object_in_view(at(0, 0, 2.49), kCam, vis));
  CHECK_FALSE(object_in_view(at(0, 0, 2.51), kCam, vis));
  // Horizontal margin: u = fx x / z + cx must lie in [10, 630].
  const double z = 1.0;
  const double x_in = (629.0 - kCam.cx) / kCam.fx * z, x_out = (631.0 - kCam.cx) / kCam.fx * z;
  CHECK(object_in_view(at(x_in, 0, z), kCam, vis));
  CHECK_FALSE(object_in_view(at(x_out, 0, z), kCam, vis));
  const double y_in = (11.0 - kCam.cy) / kCam.fy * z, y_out = (9.0 - kCam.cy) / kCam.fy * z;
  CHECK(object_in_view(at(0, y_in, z), kCam, vis));
  CHECK_FALSE(object_in_view(at(0, y_out, z), kCam, vis));
  // Miss probability: the base rate in the middle, base + border at the margin, linear in between.
  CHECK(miss_probability(at(0, 0, 1.0), kCam, vis) == Approx(0.02));
  CHECK(miss_probability(at(x_in, 0, z), kCam, vis) == Approx(0.02 + 0.3 * (1.0 - 1.0 / 60.0)).margin(1e-3));
  const double x_half = (600.0 - kCam.cx) / kCam.fx * z;  // 30 px into the 60 px band
  CHECK(miss_probability(at(x_half, 0, z), kCam, vis) == Approx(0.02 + 0.15).margin(1e-3));
  CHECK(miss_probability(at(0, 0, 3.0), kCam, vis) == 0.0);
  // Empirical miss rates.
  Rng rng(3);
  const int n = 40000;
  int miss_centre = 0, miss_border = 0;
  for (int i = 0; i < n; ++i) {
    miss_centre += !object_visible(at(0, 0, 1.0), kCam, vis, rng);
    miss_border += !object_visible(at(x_half, 0, z), kCam, vis, rng);
  }
  CHECK(miss_centre / double(n) == Approx(0.02).margin(0.004));
  CHECK(miss_border / double(n) == Approx(0.17).margin(0.01));
}

// The same rules at each of the four image edges (left, right, top, bottom): in view 1 px inside the
// margin, out 1 px outside it, and the border-band miss probability halfway (30 px) into the band.
TEST_CASE("Visibility: the margin and the border band at every image edge", "[sim][visibility]") {
  const VisibilityConfig vis;  // margin 10 px, band 60 px, 2 % + 30 %
  const double z = 1.5;
  const auto at_pixel = [&](double u, double v) {
    return Pose(Eigen::Quaterniond::Identity(),
                Eigen::Vector3d((u - kCam.cx) / kCam.fx * z, (v - kCam.cy) / kCam.fy * z, z));
  };
  const double uc = 0.5 * kCam.width, vc = 0.5 * kCam.height;
  struct Edge {
    const char* name;
    double du, dv;  // pixel offset per px of distance *into* the image from the edge line
    double u0, v0;  // a point on the edge line
  };
  const Edge edges[] = {{"left", 1, 0, 0, vc},
                        {"right", -1, 0, static_cast<double>(kCam.width), vc},
                        {"top", 0, 1, uc, 0},
                        {"bottom", 0, -1, uc, static_cast<double>(kCam.height)}};
  for (const Edge& e : edges) {
    INFO(e.name << " edge");
    const auto inside = [&](double px) { return at_pixel(e.u0 + e.du * px, e.v0 + e.dv * px); };
    CHECK(object_in_view(inside(11.0), kCam, vis));
    CHECK_FALSE(object_in_view(inside(9.0), kCam, vis));
    CHECK(miss_probability(inside(10.0 + 30.0), kCam, vis) == Approx(0.02 + 0.15).margin(1e-9));
    CHECK(miss_probability(inside(10.0 + 60.0), kCam, vis) == Approx(0.02).margin(1e-9));
    CHECK(miss_probability(inside(10.0 + 15.0), kCam, vis) == Approx(0.02 + 0.3 * 0.75).margin(1e-9));
  }
}

TEST_CASE("YCB-V names and symmetries", "[sim]") {
  CHECK(ycbv_name(1) == "002_master_chef_can");
  CHECK(ycbv_name(13) == "024_bowl");
  CHECK(ycbv_name(21) == "061_foam_brick");
  CHECK(ycbv_name(42) == "obj_42");
  for (int id = 1; id <= 21; ++id) {
    const bool sym = id == 13 || id == 16 || id == 19 || id == 20 || id == 21;
    CHECK(!ycbv_symmetry(id).empty() == sym);
  }
}
