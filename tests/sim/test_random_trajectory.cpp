// roe::sim::Rng distributions and the analytic trajectory derivatives.
#include <catch2/catch.hpp>
#include <cmath>
#include <tuple>

#include "roe/math/so3.hpp"
#include "roe/sim/random.hpp"
#include "roe/sim/simulator.hpp"
#include "roe/sim/trajectory.hpp"

using namespace roe;
using namespace roe::sim;

TEST_CASE("Rng streams are deterministic and independent", "[sim][random]") {
  Rng a = Rng::stream(7, "imu"), b = Rng::stream(7, "imu"), c = Rng::stream(7, "mocap"),
      d = Rng::stream(8, "imu");
  bool differs_c = false, differs_d = false;
  for (int i = 0; i < 100; ++i) {
    const double x = a.normal();
    REQUIRE(x == b.normal());
    differs_c |= x != c.normal();
    differs_d |= x != d.normal();
  }
  CHECK(differs_c);
  CHECK(differs_d);
}

TEST_CASE("Rng distributions have the right moments", "[sim][random]") {
  Rng rng(42);
  const int n = 200000;
  double s = 0, s2 = 0, u = 0, u2 = 0;
  for (int i = 0; i < n; ++i) {
    const double x = rng.normal();
    s += x;
    s2 += x * x;
    const double y = rng.uniform();
    REQUIRE(y >= 0.0);
    REQUIRE(y < 1.0);
    u += y;
    u2 += y * y;
  }
  CHECK(std::abs(s / n) < 0.01);
  CHECK(std::abs(s2 / n - 1.0) < 0.01);
  CHECK(std::abs(u / n - 0.5) < 0.005);
  CHECK(std::abs(u2 / n - 1.0 / 3.0) < 0.005);

  // Uniform rotations: E[trace R] = 0 and E[R] = 0 for the Haar measure.
  Eigen::Matrix3d mean = Eigen::Matrix3d::Zero();
  const int m = 50000;
  for (int i = 0; i < m; ++i) mean += rng.rotation().toRotationMatrix();
  mean /= m;
  CHECK(mean.cwiseAbs().maxCoeff() < 0.02);

  // Points in the ball: radius ≤ r and E[|x|] = 3r/4.
  double rs = 0;
  for (int i = 0; i < m; ++i) {
    const double r = rng.in_ball(0.3).norm();
    REQUIRE(r <= 0.3);
    rs += r;
  }
  CHECK(std::abs(rs / m - 0.225) < 0.003);

  // uniform_int covers its range evenly.
  std::vector<int> counts(7, 0);
  for (int i = 0; i < 70000; ++i) ++counts[rng.uniform_int(7)];
  for (int c : counts) CHECK(std::abs(c - 10000) < 400);
}

namespace {
TrajectoryConfig test_trajectory() {
  TrajectoryConfig t;
  t.azimuth_rad = {0.3, 0.2, {{0.6, 0.05, 0.1}, {0.2, 0.3, 1.0}}};
  t.radius_m = {1.1, 0.0, {{0.3, 0.04, 0.2}, {0.05, 0.25, 0.5}}};
  t.height_m = {0.5, 0.0, {{0.2, 0.06, 0.4}}};
  t.target_x_m = {0.0, 0.0, {{0.1, 0.2, 0.3}}};
  t.target_y_m = {0.05, 0.0, {{0.1, 0.15, 0.9}}};
  t.target_z_m = {-0.02, 0.0, {{0.05, 0.13, 0.7}}};
  t.roll_rad = {0.0, 0.0, {{0.2, 0.1, 0.0}, {0.05, 0.7, 1.0}}};
  t.shake_x_m = {0.0, 0.0, {{0.003, 1.3, 0.0}}};
  t.shake_y_m = {0.0, 0.0, {{0.003, 1.1, 1.0}}};
  t.shake_z_m = {0.0, 0.0, {{0.003, 1.7, 2.0}}};
  return t;
}
}  // namespace

TEST_CASE("Trajectory derivatives match central differences", "[sim][trajectory]") {
  const InspectionTrajectory traj(test_trajectory());
  const Pose T_C_I = CameraConfig{}.T_I_C.inverse();
  const double h = 1e-4;
  for (double t : {0.0, 1.7, 12.3, 33.3, 59.0}) {
    for (int which = 0; which < 2; ++which) {
      auto eval = [&](double s) { return which == 0 ? traj.camera(s) : traj.attached(s, T_C_I); };
      const Kinematics k = eval(t), kp = eval(t + h), km = eval(t - h);
      const Eigen::Vector3d v_num = (kp.T_M_X.p - km.T_M_X.p) / (2 * h);
      const Eigen::Vector3d a_num = (kp.v_M - km.v_M) / (2 * h);
      // Body rate: R(t+h) = R(t-h) Exp(2h ω) to second order.
      const Eigen::Vector3d w_num = math::log_so3(km.T_M_X.R().transpose() * kp.T_M_X.R()) / (2 * h);
      const Eigen::Vector3d al_num = (kp.omega_X - km.omega_X) / (2 * h);
      INFO("t = " << t << " frame " << which);
      CHECK((k.v_M - v_num).norm() < 1e-6);
      CHECK((k.a_M - a_num).norm() < 1e-6);
      CHECK((k.omega_X - w_num).norm() < 1e-6);
      CHECK((k.alpha_X - al_num).norm() < 1e-5);
      // The optical axis points at the look-at point (the centre plus the target offset).
      if (which == 0) {
        const auto& c = traj.config();
        const Eigen::Vector3d target = c.center + Eigen::Vector3d(evaluate_signal(c.target_x_m, t)(0),
                                                                  evaluate_signal(c.target_y_m, t)(0),
                                                                  evaluate_signal(c.target_z_m, t)(0));
        const Eigen::Vector3d z_M = k.T_M_X.R().col(2);
        CHECK((z_M - (target - k.T_M_X.p).normalized()).norm() < 1e-12);
      }
    }
  }
}

TEST_CASE("Signals evaluate to the sum of sinusoids", "[sim][trajectory]") {
  const SmoothSignal s{0.5, 0.1, {{2.0, 0.25, 0.3}}};
  const double t = 1.3, w = 2 * M_PI * 0.25;
  const Eigen::Vector3d e = evaluate_signal(s, t);
  CHECK(e(0) == Approx(0.5 + 0.13 + 2.0 * std::sin(w * t + 0.3)).margin(1e-12));
  CHECK(e(1) == Approx(0.1 + 2.0 * w * std::cos(w * t + 0.3)).margin(1e-12));
  CHECK(e(2) == Approx(-2.0 * w * w * std::sin(w * t + 0.3)).margin(1e-12));
}

TEST_CASE("Seed variation changes the trajectory a little and deterministically", "[sim][trajectory]") {
  const TrajectoryConfig nominal = test_trajectory();
  const VariationConfig v;
  const TrajectoryConfig a = vary_trajectory(nominal, v, 1), b = vary_trajectory(nominal, v, 1),
                         c = vary_trajectory(nominal, v, 2);
  CHECK(a.radius_m.terms[0].amplitude == b.radius_m.terms[0].amplitude);
  CHECK(a.radius_m.terms[0].amplitude != c.radius_m.terms[0].amplitude);
  for (const auto* s : {&a, &c}) {
    CHECK(std::abs(s->radius_m.terms[0].amplitude / 0.3 - 1.0) <= v.amplitude_rel);
    CHECK(std::abs(s->radius_m.offset / 1.1 - 1.0) <= v.offset_rel);
    CHECK(std::abs(s->roll_rad.terms[1].phase_rad - 1.0) <= v.phase_rad);
  }
  // Over many seeds each factor fills its whole range: amplitude x U(1 - a, 1 + a), frequency
  // x U(1 - f, 1 + f), phase + U(-phi, phi), start azimuth + U(-a0, a0),
  // height x U(1 - o, 1 + o).
  const Sinusoid& n = nominal.radius_m.terms[0];
  double amp_lo = 9, amp_hi = -9, f_lo = 9, f_hi = -9, ph_lo = 9, ph_hi = -9, az_lo = 9, az_hi = -9, h_lo = 9, h_hi = -9;
  for (std::uint64_t seed = 1; seed <= 300; ++seed) {
    const TrajectoryConfig varied = vary_trajectory(nominal, v, seed);
    const Sinusoid& x = varied.radius_m.terms[0];
    az_lo = std::min(az_lo, varied.azimuth_rad.offset - nominal.azimuth_rad.offset);
    az_hi = std::max(az_hi, varied.azimuth_rad.offset - nominal.azimuth_rad.offset);
    h_lo = std::min(h_lo, varied.height_m.offset / nominal.height_m.offset - 1.0);
    h_hi = std::max(h_hi, varied.height_m.offset / nominal.height_m.offset - 1.0);
    amp_lo = std::min(amp_lo, x.amplitude / n.amplitude - 1.0);
    amp_hi = std::max(amp_hi, x.amplitude / n.amplitude - 1.0);
    f_lo = std::min(f_lo, x.frequency_hz / n.frequency_hz - 1.0);
    f_hi = std::max(f_hi, x.frequency_hz / n.frequency_hz - 1.0);
    ph_lo = std::min(ph_lo, x.phase_rad - n.phase_rad);
    ph_hi = std::max(ph_hi, x.phase_rad - n.phase_rad);
  }
  for (auto [lo, hi, range] : {std::tuple{amp_lo, amp_hi, v.amplitude_rel}, std::tuple{f_lo, f_hi, v.frequency_rel},
                               std::tuple{ph_lo, ph_hi, v.phase_rad}, std::tuple{az_lo, az_hi, v.azimuth_start_rad},
                               std::tuple{h_lo, h_hi, v.offset_rel}}) {
    CHECK(lo >= -range);
    CHECK(hi <= range);
    CHECK(lo < -0.9 * range);
    CHECK(hi > 0.9 * range);
  }
}
