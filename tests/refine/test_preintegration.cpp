// Preintegration and the IMU residual against the filter's integrator (docs/refine.md §5).
#include <catch2/catch.hpp>
#include <random>

#include "roe/ekf/imu.hpp"
#include "roe/math/so3.hpp"
#include "roe/refine/factors.hpp"
#include "roe/refine/preintegration.hpp"
#include "support/jacobian.hpp"

namespace {

using namespace roe;
using Eigen::Vector3d;

/// 200 Hz samples of a smooth, non-trivial motion (sums of sines), with a stamp jitter.
std::vector<ImuSample> make_imu(double duration_s) {
  std::vector<ImuSample> imu;
  Timestamp t = 1'000'000'000;
  for (int k = 0; to_seconds(t) < 1.0 + duration_s; ++k) {
    const double s = to_seconds(t);
    ImuSample m;
    m.t_ns = t;
    m.gyro = Vector3d(0.8 * std::sin(1.3 * s), 0.5 * std::cos(0.7 * s + 0.2), 0.3 * std::sin(2.1 * s + 1.0));
    m.accel = Vector3d(1.5 * std::sin(0.9 * s), 0.7 * std::cos(1.7 * s), 9.81 + 0.8 * std::sin(1.1 * s));
    imu.push_back(m);
    t += 5'000'000 + (k % 3) * 100'000;
  }
  return imu;
}

/// The filter's propagation written out here sample by sample (the interpolation rule of ekf::run_filter).
ekf::CoreState integrate_direct(const std::vector<ImuSample>& imu, ekf::CoreState x, Timestamp t0, Timestamp t1) {
  auto at = [&](Timestamp t) {
    std::size_t k = 0;
    while (imu[k + 1].t_ns < t) ++k;
    const double a = static_cast<double>(t - imu[k].t_ns) / static_cast<double>(imu[k + 1].t_ns - imu[k].t_ns);
    return ImuSample{t, imu[k].gyro + a * (imu[k + 1].gyro - imu[k].gyro), imu[k].accel + a * (imu[k + 1].accel - imu[k].accel)};
  };
  ImuSample prev = at(t0);
  for (const auto& s : imu) {
    if (s.t_ns <= t0 || s.t_ns >= t1) continue;
    x = ekf::integrate(x, prev.gyro, prev.accel, s.gyro, s.accel, dt_seconds(prev.t_ns, s.t_ns));
    prev = s;
  }
  const ImuSample end = at(t1);
  return ekf::integrate(x, prev.gyro, prev.accel, end.gyro, end.accel, dt_seconds(prev.t_ns, end.t_ns));
}

ekf::CoreState random_state(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  ekf::CoreState x;
  x.p_W_I = Vector3d(n(rng), n(rng), n(rng));
  x.v_W_I = Vector3d(n(rng), n(rng), n(rng));
  x.q_W_I = math::exp_quat(Vector3d(n(rng), n(rng), n(rng)));
  x.b_g = 0.01 * Vector3d(n(rng), n(rng), n(rng));
  x.b_a = 0.1 * Vector3d(n(rng), n(rng), n(rng));
  return x;
}

Eigen::Matrix<double, 9, 1> imu_residual(const refine::Preintegration& pre, const ekf::CoreState& a,
                                         const ekf::CoreState& b) {
  refine::ImuResidual f{pre.dR, pre.dv, pre.dp, pre.bg_lin, pre.ba_lin, ekf::kGravity_W, pre.dt, pre.J_bias,
                        refine::Mat9::Identity()};
  const double pa[7] = {a.p_W_I.x(), a.p_W_I.y(), a.p_W_I.z(), a.q_W_I.x(), a.q_W_I.y(), a.q_W_I.z(), a.q_W_I.w()};
  const double pb[7] = {b.p_W_I.x(), b.p_W_I.y(), b.p_W_I.z(), b.q_W_I.x(), b.q_W_I.y(), b.q_W_I.z(), b.q_W_I.w()};
  const double ba_[6] = {a.b_g.x(), a.b_g.y(), a.b_g.z(), a.b_a.x(), a.b_a.y(), a.b_a.z()};
  Eigen::Matrix<double, 9, 1> r;
  f(pa, a.v_W_I.data(), ba_, pb, b.v_W_I.data(), r.data());
  return r;
}

}  // namespace

TEST_CASE("refine/preintegration: the IMU residual vanishes on states the filter's integrator propagates") {
  const auto imu = make_imu(2.0);
  std::mt19937 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const ekf::CoreState xi = random_state(rng);
    const Timestamp ti = imu[3].t_ns + 1'234'567 * trial, tj = ti + 33'333'333 + 2'000'000 * trial;
    const ekf::CoreState xj = integrate_direct(imu, xi, ti, tj);
    std::size_t hint = 0;
    const auto pre = refine::preintegrate(imu, ti, tj, xi.b_g, xi.b_a, {0.01, 0.001, 0.1, 0.01}, hint);
    const auto r = imu_residual(pre, xi, xj);
    INFO("trial " << trial << " residual " << r.transpose());
    CHECK(r.norm() < 1e-9);
    // A wrong end state shows: 1 mm in p_j moves e_p by R_iᵀ · 1 mm.
    ekf::CoreState moved = xj;
    moved.p_W_I.x() += 1e-3;
    CHECK(imu_residual(pre, xi, moved).head<3>().norm() == Approx(1e-3).epsilon(1e-6));
  }
}

TEST_CASE("refine/preintegration: propagate equals the filter's integrator") {
  const auto imu = make_imu(2.0);
  std::mt19937 rng(3);
  const ekf::CoreState x = random_state(rng);
  const Timestamp ti = imu[10].t_ns + 777, tj = imu[200].t_ns - 999;
  std::size_t hint = 0;
  const ekf::CoreState a = refine::propagate(imu, x, ti, tj, hint);
  const ekf::CoreState b = integrate_direct(imu, x, ti, tj);
  CHECK((a.p_W_I - b.p_W_I).norm() < 1e-12);
  CHECK((a.v_W_I - b.v_W_I).norm() < 1e-12);
  CHECK(math::angle_between(a.q_W_I, b.q_W_I) < 1e-12);
}

TEST_CASE("refine/preintegration: bias Jacobians match central differences of the preintegration") {
  const auto imu = make_imu(1.0);
  const Vector3d bg(0.01, -0.02, 0.005), ba(0.05, 0.1, -0.08);
  const Timestamp ti = imu[2].t_ns + 500'000, tj = ti + 100'000'000;
  std::size_t hint = 0;
  const ekf::ImuNoiseParams noise{0.01, 0.001, 0.1, 0.01};
  const auto pre = refine::preintegrate(imu, ti, tj, bg, ba, noise, hint);
  // error(δ): the preintegration at the biases (b_g, b_a) + δ against the one at (b_g, b_a), in its tangent
  // space [Δp; Δv; Log(ΔRᵀ ΔR')].
  const auto error = [&](const Eigen::VectorXd& d) {
    std::size_t h = 0;
    const auto q = refine::preintegrate(imu, ti, tj, bg + d.head<3>(), ba + d.tail<3>(), noise, h);
    Eigen::Matrix<double, 9, 1> e;
    e << q.dp - pre.dp, q.dv - pre.dv, math::log_quat(pre.dR.conjugate() * q.dR);
    return Eigen::VectorXd(e);
  };
  const Eigen::MatrixXd num = test::check_jacobian(pre.J_bias, error, 1e-6);
  for (int c = 0; c < 6; ++c) {
    INFO("bias component " << c);
    CHECK(num.col(c).norm() > 1e-4);  // every bias moves the preintegration
  }
  // The covariance is symmetric positive definite and grows with the interval.
  const Eigen::LLT<refine::Mat9> llt(pre.cov);
  CHECK(llt.info() == Eigen::Success);
  hint = 0;
  const auto longer = refine::preintegrate(imu, ti, tj + 100'000'000, bg, ba, noise, hint);
  CHECK(longer.cov.trace() > pre.cov.trace());
}
