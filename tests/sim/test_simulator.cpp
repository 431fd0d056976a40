// The simulator: IMU consistency with the trajectory (integration), noise statistics, truth-derived
// detections, visibility of the presets' scenes, mocap, determinism, config validation.
#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "roe/core/error.hpp"
#include "roe/math/so3.hpp"
#include "roe/sim/simulator.hpp"

using namespace roe;
using namespace roe::sim;

namespace {
constexpr double kDeg = M_PI / 180.0;
const Eigen::Vector3d g_W(0, 0, 9.81);

SimConfig noise_free(double duration) {
  SimConfig c;
  c.name = "test";
  c.duration_s = duration;
  c.trajectory.azimuth_rad = {0.0, 0.15, {{0.6, 0.04, 0.0}, {0.15, 0.17, 1.0}}};
  c.trajectory.radius_m = {1.2, 0.0, {{0.25, 0.031, 0.5}}};
  c.trajectory.height_m = {0.45, 0.0, {{0.2, 0.05, 1.3}}};
  c.trajectory.target_x_m = {0.0, 0.0, {{0.12, 0.11, 0.0}, {0.04, 0.43, 1.1}}};
  c.trajectory.roll_rad = {0.0, 0.0, {{0.12, 0.07, 0.0}, {0.03, 0.6, 1.0}}};
  c.trajectory.shake_x_m = {0.0, 0.0, {{0.003, 1.3, 0.0}}};
  c.trajectory.shake_z_m = {0.0, 0.0, {{0.003, 1.7, 0.5}}};
  c.imu = {200.0, 0, 0, 0, 0, 0, 0};
  c.detection = {0, 0, 0, 0, 0, "ray", 0, 0, 0.3, 0, 0, 0, false};
  c.visibility.miss_prob = c.visibility.border_miss_prob = 0.0;
  c.mocap.position_sigma_m = c.mocap.rotation_sigma_deg = 0.0;
  c.objects.objects = {{1, false, {}}, {13, false, {}}, {19, false, {}}};
  return c;
}

struct NavState {
  Eigen::Quaterniond q;
  Eigen::Vector3d p, v;
};

// d/dt of (q, p, v) for body rate w and specific force f (paper eq. 3 without biases):
// q̇ = ½ q ⊗ (0, w), ṗ = v, v̇ = R f − g.
struct Deriv {
  Eigen::Vector4d dq;
  Eigen::Vector3d dp, dv;
};
Deriv deriv(const NavState& s, const Eigen::Vector3d& w, const Eigen::Vector3d& f) {
  const Eigen::Quaterniond qd = s.q * Eigen::Quaterniond(0, w.x(), w.y(), w.z());
  return {0.5 * qd.coeffs(), s.v, s.q * f - g_W};
}
NavState step(const NavState& s, const Deriv& d, double h) {
  NavState o;
  o.q.coeffs() = s.q.coeffs() + h * d.dq;
  o.p = s.p + h * d.dp;
  o.v = s.v + h * d.dv;
  return o;
}

// Integrates the IMU samples with classical RK4; the mid-interval input is the mean of the two samples.
// Returns the worst position and rotation errors against the ground truth rows.
std::pair<double, double> integrate(const Dataset& d, double seconds) {
  NavState s{d.groundtruth[0].T_W_I.q, d.groundtruth[0].T_W_I.p, d.groundtruth[0].v_W_I};
  double max_p = 0, max_r = 0;
  for (std::size_t k = 0; k + 1 < d.imu.size(); ++k) {
    const double h = dt_seconds(d.imu[k].t_ns, d.imu[k + 1].t_ns);
    if (dt_seconds(d.imu[0].t_ns, d.imu[k + 1].t_ns) > seconds) break;
    const auto &a = d.imu[k], &b = d.imu[k + 1];
    const Eigen::Vector3d wm = 0.5 * (a.gyro + b.gyro), fm = 0.5 * (a.accel + b.accel);
    const Deriv k1 = deriv(s, a.gyro, a.accel);
    const Deriv k2 = deriv(step(s, k1, h / 2), wm, fm);
    const Deriv k3 = deriv(step(s, k2, h / 2), wm, fm);
    const Deriv k4 = deriv(step(s, k3, h), b.gyro, b.accel);
    s.q.coeffs() += h / 6 * (k1.dq + 2 * k2.dq + 2 * k3.dq + k4.dq);
    s.q.normalize();
    s.p += h / 6 * (k1.dp + 2 * k2.dp + 2 * k3.dp + k4.dp);
    s.v += h / 6 * (k1.dv + 2 * k2.dv + 2 * k3.dv + k4.dv);
    const auto& gt = d.groundtruth[k + 1];
    REQUIRE(gt.t_ns == b.t_ns);
    max_p = std::max(max_p, (s.p - gt.T_W_I.p).norm());
    max_r = std::max(max_r, math::angle_between(s.q, gt.T_W_I.q));
  }
  return {max_p, max_r};
}
}  // namespace

TEST_CASE("Integrating the noise-free IMU reproduces the trajectory", "[sim][imu]") {
  SimConfig c = noise_free(10.0);
  const Dataset d200 = simulate(c, 3);
  const auto [p200, r200] = integrate(d200, 10.0);
  c.imu.rate_hz = 1000.0;
  const Dataset d1000 = simulate(c, 3);
  const auto [p1000, r1000] = integrate(d1000, 10.0);
  INFO("200 Hz: " << p200 << " m, " << r200 / kDeg << " deg; 1000 Hz: " << p1000 << " m, " << r1000 / kDeg);
  // Over 10 s the drift stays sub-millimetre, and it shrinks with the rate (the only error left is
  // the linear interpolation of the inputs inside RK4, O(h²)).
  CHECK(p200 < 1e-3);
  CHECK(r200 < 1e-5);
  CHECK(p1000 < 1e-4);
  CHECK(r1000 < 1e-6);
  CHECK(p1000 < p200 / 10);
  // The first state matches W's definition: IMU at the origin, gravity along +z.
  CHECK(d200.groundtruth[0].T_W_I.p.norm() < 1e-15);
  // At rest the accelerometer would read +g upwards: check the sign convention on the mean.
  Eigen::Vector3d mean_f_W = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < d200.imu.size(); ++k)
    mean_f_W += d200.groundtruth[k].T_W_I.q * d200.imu[k].accel;
  mean_f_W /= static_cast<double>(d200.imu.size());
  CHECK(mean_f_W.z() == Approx(9.81).margin(0.05));
}

TEST_CASE("IMU noise and bias random walks have the configured statistics", "[sim][imu]") {
  SimConfig clean = noise_free(60.0);
  SimConfig noisy = clean;
  noisy.imu.gyro_noise_density = 2.443e-4;
  noisy.imu.accel_noise_density = 1.471e-3;
  noisy.imu.gyro_random_walk = 1e-3;
  noisy.imu.accel_random_walk = 1e-2;
  noisy.imu.gyro_bias_sigma = 0.005;
  noisy.imu.accel_bias_sigma = 0.05;
  const Dataset a = simulate(clean, 5), b = simulate(noisy, 5);  // same seed → same trajectory
  REQUIRE(a.imu.size() == b.imu.size());
  double sg = 0, sa = 0, wg = 0, wa = 0;
  const std::size_t n = a.imu.size();
  for (std::size_t k = 0; k < n; ++k) {
    REQUIRE((a.groundtruth[k].T_W_I.p - b.groundtruth[k].T_W_I.p).norm() < 1e-12);
    const Eigen::Vector3d ng = b.imu[k].gyro - a.imu[k].gyro - b.groundtruth[k].b_g;
    const Eigen::Vector3d na = b.imu[k].accel - a.imu[k].accel - b.groundtruth[k].b_a;
    sg += ng.squaredNorm();
    sa += na.squaredNorm();
    if (k + 1 < n) {
      wg += (b.groundtruth[k + 1].b_g - b.groundtruth[k].b_g).squaredNorm();
      wa += (b.groundtruth[k + 1].b_a - b.groundtruth[k].b_a).squaredNorm();
    }
  }
  const double rate = 200.0, dt = 1.0 / rate;
  CHECK(std::sqrt(sg / (3.0 * n)) == Approx(2.443e-4 * std::sqrt(rate)).epsilon(0.05));
  CHECK(std::sqrt(sa / (3.0 * n)) == Approx(1.471e-3 * std::sqrt(rate)).epsilon(0.05));
  CHECK(std::sqrt(wg / (3.0 * (n - 1))) == Approx(1e-3 * std::sqrt(dt)).epsilon(0.05));
  CHECK(std::sqrt(wa / (3.0 * (n - 1))) == Approx(1e-2 * std::sqrt(dt)).epsilon(0.05));
  // Every sample steps the walk, the first one included (the statistics above would hardly notice one
  // missing step).
  std::size_t still_g = 0, still_a = 0;
  for (std::size_t k = 0; k + 1 < n; ++k) {
    still_g += b.groundtruth[k + 1].b_g == b.groundtruth[k].b_g;
    still_a += b.groundtruth[k + 1].b_a == b.groundtruth[k].b_a;
  }
  CHECK(still_g == 0);
  CHECK(still_a == 0);
  // The noise-free run has zero bias everywhere.
  CHECK(a.groundtruth.back().b_g.norm() == 0.0);
}

TEST_CASE("Noise-free detections equal the truth-derived T_C_O", "[sim][detections]") {
  const SimConfig c = noise_free(20.0);
  const SimRun run = simulate_run(c, 11);
  const Dataset& d = run.dataset;
  REQUIRE(d.manifest.truth);
  const auto& truth = *d.manifest.truth;
  const auto& dets = d.detections.at("sim");
  REQUIRE(dets.size() > 100);
  std::size_t checked = 0;
  std::size_t g = 0;
  for (const auto& det : dets) {
    while (g < d.groundtruth.size() && d.groundtruth[g].t_ns < det.t_ns) ++g;
    if (g == d.groundtruth.size() || d.groundtruth[g].t_ns != det.t_ns) continue;  // frame between IMU stamps
    const Pose T_W_C = d.groundtruth[g].T_W_I * truth.T_I_C;
    const auto it = std::find_if(truth.objects.begin(), truth.objects.end(),
                                 [&](const TruthObject& o) { return o.id == det.object_id; });
    REQUIRE(it != truth.objects.end());
    const Pose T_C_O = T_W_C.inverse() * it->T_W_O;
    const auto diff = math::pose_difference(T_C_O, det.T_C_O);
    REQUIRE(diff.norm() < 1e-9);
    ++checked;
  }
  CHECK(checked > dets.size() / 4);
  // And every frame of the dataset lies on the camera clock at 30 Hz.
  CHECK(d.frames.size() == 601);
  CHECK(d.frames[3].t_ns - d.frames[0].t_ns == 100'000'000);
}

TEST_CASE("Noise-free mocap equals the ground truth through T_B_I", "[sim][mocap]") {
  SimConfig c = noise_free(5.0);
  c.mocap.T_B_I = Pose(math::exp_quat(Eigen::Vector3d(0.1, -0.2, 0.3)), Eigen::Vector3d(0.05, 0.01, -0.02));
  const Dataset d = simulate(c, 2);
  REQUIRE(d.mocap.size() == 601);  // 120 Hz for 5 s
  const Pose T_M_W(Eigen::Quaterniond::Identity(),
                   d.mocap[0].T.act(c.mocap.T_B_I.p) - Eigen::Vector3d::Zero());
  std::size_t g = 0, checked = 0;
  for (const auto& m : d.mocap) {
    while (g < d.groundtruth.size() && d.groundtruth[g].t_ns < m.t_ns) ++g;
    if (g == d.groundtruth.size() || d.groundtruth[g].t_ns != m.t_ns) continue;
    // T_M_B T_B_I = T_M_W T_W_I: rotations agree exactly (W ∥ M), positions up to the constant T_M_W.
    const Pose T_M_I = m.T * c.mocap.T_B_I;
    CHECK(math::angle_between(T_M_I.q, d.groundtruth[g].T_W_I.q) < 1e-9);
    CHECK((T_M_I.p - d.groundtruth[g].T_W_I.p - T_M_W.p).norm() < 1e-9);
    ++checked;
  }
  CHECK(checked == 201);
}

TEST_CASE("Mocap noise has the configured sigma", "[sim][mocap]") {
  SimConfig clean = noise_free(60.0);
  SimConfig noisy = clean;
  noisy.mocap.position_sigma_m = 0.0005;
  noisy.mocap.rotation_sigma_deg = 0.1;
  const Dataset a = simulate(clean, 9), b = simulate(noisy, 9);
  REQUIRE(a.mocap.size() == b.mocap.size());
  double sp = 0, sr = 0;
  for (std::size_t k = 0; k < a.mocap.size(); ++k) {
    sp += (b.mocap[k].T.p - a.mocap[k].T.p).squaredNorm();
    sr += math::log_quat(a.mocap[k].T.q.conjugate() * b.mocap[k].T.q).squaredNorm();
  }
  const double n = 3.0 * a.mocap.size();
  CHECK(std::sqrt(sp / n) == Approx(0.0005).epsilon(0.05));
  CHECK(std::sqrt(sr / n) == Approx(0.1 * kDeg).epsilon(0.05));
}

TEST_CASE("Same seed gives identical data, another seed different data", "[sim][determinism]") {
  SimConfig c;  // all defaults: every noise source on
  c.duration_s = 10.0;
  const Dataset a = simulate(c, 4), b = simulate(c, 4), x = simulate(c, 5);
  REQUIRE(a.imu.size() == b.imu.size());
  for (std::size_t k = 0; k < a.imu.size(); ++k) {
    REQUIRE(a.imu[k].gyro == b.imu[k].gyro);
    REQUIRE(a.imu[k].accel == b.imu[k].accel);
  }
  const auto &da = a.detections.at("sim"), &db = b.detections.at("sim"), &dx = x.detections.at("sim");
  REQUIRE(da.size() == db.size());
  for (std::size_t k = 0; k < da.size(); ++k) {
    REQUIRE(da[k].t_ns == db[k].t_ns);
    REQUIRE(da[k].T_C_O.p == db[k].T_C_O.p);
    REQUIRE(da[k].T_C_O.q.coeffs() == db[k].T_C_O.q.coeffs());
  }
  CHECK((da.size() != dx.size() || da[0].T_C_O.p != dx[0].T_C_O.p));
  CHECK(a.imu[10].accel != x.imu[10].accel);
  CHECK(a.groundtruth[100].T_W_I.q.coeffs() != x.groundtruth[100].T_W_I.q.coeffs());  // trajectory varied
  // Same objects (the layout does not depend on --seed).
  CHECK(a.manifest.truth->objects.size() == x.manifest.truth->objects.size());
}

TEST_CASE("Default scene: speeds, rates, distances and detection coverage", "[sim][scene]") {
  SimConfig c;
  const SimRun run = simulate_run(c, 1);
  const auto& st = run.stats;
  CHECK(st.max_speed_m_s < 1.2);
  CHECK(st.max_rate_deg_s < 90.0);
  CHECK(st.min_distance_m > 0.5);
  CHECK(st.max_distance_m < 2.0);
  CHECK(st.frames_with_detections > st.frames / 2);
  for (const auto& o : c.objects.objects) CHECK(st.detections_per_object.count(o.id) == 1);
  // Labels: outlier and flip rates of the default model over the whole sequence.
  const double n = static_cast<double>(st.detections);
  CHECK(st.outliers / n == Approx(0.05).margin(0.015));
  std::size_t sym = 0, flips = 0;
  const auto& dets = run.dataset.detections.at("sim");
  for (std::size_t k = 0; k < dets.size(); ++k) {
    if (dets[k].object_id != 13) continue;
    ++sym;
    flips += run.labels[k].flipped;
  }
  REQUIRE(sym > 300);
  CHECK(flips / static_cast<double>(sym) == Approx(0.25).margin(0.05));
  // Every detection is in view (depth range and image margin) at its true pose.
  for (const auto& l : run.labels) {
    REQUIRE(l.T_C_O_true.p.z() >= c.visibility.min_depth_m);
    REQUIRE(l.T_C_O_true.p.z() <= c.visibility.max_depth_m);
  }
  // Objects lie inside the ~1 m² placement area.
  for (const auto& o : place_objects(c.objects)) {
    CHECK(std::abs(o.T_W_O.p.x()) <= 0.5);
    CHECK(std::abs(o.T_W_O.p.y()) <= 0.5);
  }
}

TEST_CASE("Object placement: area, height jitter, separation, yaw and lying objects as configured", "[sim]") {
  ObjectsConfig o;
  o.objects.clear();
  for (int id = 1; id <= 12; ++id) o.objects.push_back({id, false, {}});
  o.objects.push_back({99, true, Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(2.0, 3.0, 0.8))});  // given pose
  o.area_center = Eigen::Vector3d(2.0, 3.0, 0.8);
  o.area_size_m = 1.2;
  o.min_separation_m = 0.2;
  o.height_jitter_m = 0.1;
  o.lying_prob = 0.5;
  std::vector<double> yaws;
  int lying = 0, standing = 0;
  double z_min = 1e9, z_max = -1e9;
  for (std::uint64_t seed = 1; seed <= 40; ++seed) {
    o.layout_seed = seed;
    const auto placed = place_objects(o);
    REQUIRE(placed.size() == 13);
    CHECK(placed.back().id == 99);  // the configured order, the given pose kept
    CHECK(placed.back().T_W_O.p == Eigen::Vector3d(2.0, 3.0, 0.8));
    for (std::size_t a = 0; a < placed.size(); ++a) {
      for (std::size_t b = a + 1; b < placed.size(); ++b)
        CHECK((placed[a].T_W_O.p.head<2>() - placed[b].T_W_O.p.head<2>()).norm() >= 0.2);
      if (placed[a].id == 99) continue;
      const Eigen::Vector3d p = placed[a].T_W_O.p;
      CHECK(std::abs(p.x() - 2.0) <= 0.6);
      CHECK(std::abs(p.y() - 3.0) <= 0.6);
      z_min = std::min(z_min, p.z());
      z_max = std::max(z_max, p.z());
      // Standing: the object's z axis is up; lying: it is horizontal (a 90 deg roll after the yaw).
      const Eigen::Matrix3d R = placed[a].T_W_O.R();
      const double up = R.col(2).z();
      if (std::abs(up - 1.0) < 1e-12) {
        ++standing;
        yaws.push_back(std::atan2(R(1, 0), R(0, 0)));
      } else {
        CHECK(std::abs(up) < 1e-12);
        ++lying;
      }
    }
  }
  // Heights in [0.8, 0.9], spread over the range.
  CHECK(z_min >= 0.8);
  CHECK(z_max <= 0.9);
  CHECK(z_max - z_min > 0.08);
  // About half lie; standing yaws cover the circle (mean resultant length near 0).
  CHECK(lying + standing == 480);
  CHECK(lying / 480.0 == Approx(0.5).margin(0.08));
  double cs = 0, sn = 0;
  for (double y : yaws) cs += std::cos(y), sn += std::sin(y);
  CHECK(std::hypot(cs, sn) / yaws.size() < 0.15);
  CHECK(*std::max_element(yaws.begin(), yaws.end()) - *std::min_element(yaws.begin(), yaws.end()) > 5.5);
}

TEST_CASE("Invalid configs are rejected with the key", "[sim][config]") {
  auto expect_key = [](SimConfig c, const std::string& key) {
    try {
      validate(c);
      FAIL("no error for " << key);
    } catch (const ConfigError& e) {
      CHECK(e.context().key == key);
    }
  };
  SimConfig c;
  c.duration_s = 0;
  expect_key(c, "duration_s");
  c = SimConfig{};
  c.detection.outlier_prob = 1.5;
  expect_key(c, "detection.outlier_prob");
  c = SimConfig{};
  c.detection.translation_frame = "world";
  expect_key(c, "detection.translation_frame");
  c = SimConfig{};
  c.objects.objects = {{3, false, {}}, {3, false, {}}};
  expect_key(c, "objects.list[1].id");
  c = SimConfig{};
  c.objects.objects = {{3, false, {}}, {0, false, {}}};
  expect_key(c, "objects.list[1].id");
  c = SimConfig{};
  c.objects.objects.clear();
  expect_key(c, "objects.list");
  c = SimConfig{};
  c.trajectory.radius_m.terms = {{0.1, 0.2, 0.0}, {0.1, -0.5, 0.0}};
  expect_key(c, "trajectory.radius_m.terms[1]");
  c = SimConfig{};
  c.visibility.max_depth_m = 0.2;
  expect_key(c, "visibility.max_depth_m");
  c = SimConfig{};
  c.camera.rate_hz = 500;
  expect_key(c, "camera.rate_hz");
  c = SimConfig{};
  c.camera.intrinsics.width = 0;
  expect_key(c, "camera.intrinsics.width");
  c = SimConfig{};
  c.camera.intrinsics.fx = -1;
  expect_key(c, "camera.intrinsics.fx");
  c = SimConfig{};
  c.mocap.rate_hz = 1e12;  // used to run out of memory (std::bad_alloc, exit 3)
  expect_key(c, "mocap.rate_hz");
  c = SimConfig{};
  c.mocap.rate_hz = 5000;  // a valid rate, but over a day 4.3e8 samples
  c.duration_s = 24 * 3600.0;
  expect_key(c, "mocap.rate_hz");
  c = SimConfig{};
  c.imu.rate_hz = 2000;
  c.duration_s = 24 * 3600.0;  // 1.7e8 IMU samples
  expect_key(c, "imu.rate_hz");
  c = SimConfig{};
  c.duration_s = 0.001;  // not one IMU interval
  expect_key(c, "duration_s");
  c = SimConfig{};
  c.duration_s = 1.0 / c.imu.rate_hz;  // two IMU samples and the first image: fine
  CHECK_NOTHROW(validate(c));
  c = SimConfig{};
  c.start_time_ns = std::numeric_limits<std::int64_t>::max() - 1'000'000'000;  // would overflow
  expect_key(c, "start_time_ns");
  c = SimConfig{};
  c.objects.area_size_m = 0.1;
  c.objects.min_separation_m = 0.5;
  CHECK_THROWS_AS(simulate(c, 1), ConfigError);
}
