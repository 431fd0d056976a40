// IMU preintegration with the filter's integrator (docs/refine.md §2).
#include "roe/refine/preintegration.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "roe/core/error.hpp"

namespace roe::refine {

ImuSample imu_at(const std::vector<ImuSample>& imu, Timestamp t_ns, std::size_t& hint) {
  if (imu.empty() || t_ns < imu.front().t_ns || t_ns > imu.back().t_ns)
    throw InputError(fmt::format("time {} ns outside the IMU stream", t_ns), {"mav0/imu0/data.csv"});
  if (hint >= imu.size() || imu[hint].t_ns > t_ns) hint = 0;
  while (hint + 1 < imu.size() && imu[hint + 1].t_ns <= t_ns) ++hint;
  const ImuSample& a = imu[hint];
  if (a.t_ns == t_ns || hint + 1 == imu.size()) return {t_ns, a.gyro, a.accel};
  const ImuSample& b = imu[hint + 1];
  const double alpha = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  return {t_ns, a.gyro + alpha * (b.gyro - a.gyro), a.accel + alpha * (b.accel - a.accel)};
}

void for_each_interval(const std::vector<ImuSample>& imu, Timestamp t_i, Timestamp t_j, std::size_t& hint,
                       const std::function<void(const ImuSample& a, const ImuSample& b)>& fn) {
  ROE_CHECK(t_i < t_j, "for_each_interval: t_i < t_j");
  ImuSample a = imu_at(imu, t_i, hint);
  const std::size_t first = hint + 1;  // the first sample after t_i
  const ImuSample end = imu_at(imu, t_j, hint);
  for (std::size_t s = first; s < imu.size() && imu[s].t_ns < t_j; ++s) {
    fn(a, imu[s]);
    a = imu[s];
  }
  fn(a, end);
}

Preintegration preintegrate(const std::vector<ImuSample>& imu, Timestamp t_i, Timestamp t_j, const Vec3& bg,
                            const Vec3& ba, const ekf::ImuNoiseParams& noise, std::size_t& hint) {
  Preintegration pre;
  pre.t_i = t_i;
  pre.t_j = t_j;
  pre.dt = dt_seconds(t_i, t_j);
  pre.bg_lin = bg;
  pre.ba_lin = ba;
  ekf::ImuNoiseParams white = noise;  // the random walks are the separate bias residual
  white.gyro_random_walk = 0.0;
  white.accel_random_walk = 0.0;
  ekf::CoreState x;
  x.b_g = bg;
  x.b_a = ba;
  ekf::Mat15 P = ekf::Mat15::Zero();
  Eigen::Matrix<double, 15, 6> Phi_b = Eigen::Matrix<double, 15, 6>::Zero();  // Φ's bias columns
  Phi_b.bottomRows<6>().setIdentity();
  for_each_interval(imu, t_i, t_j, hint, [&](const ImuSample& a, const ImuSample& b) {
    const double dt = dt_seconds(a.t_ns, b.t_ns);
    if (dt <= 0.0) return;
    ekf::CoreTransition F;
    x = ekf::integrate(x, a.gyro, a.accel, b.gyro, b.accel, dt, &F);
    F.apply_left(Phi_b);
    F.apply_left(P);
    F.apply_right_transposed(P);
    ekf::add_process_noise(white, dt, P);
  });
  // Back from the integrated state (started at the origin, at rest) to the preintegrated quantities.
  pre.dR = x.q_W_I;
  pre.dv = x.v_W_I + ekf::kGravity_W * pre.dt;
  pre.dp = x.p_W_I + 0.5 * ekf::kGravity_W * pre.dt * pre.dt;
  pre.J_bias = Phi_b.topRows<9>();
  pre.cov = P.topLeftCorner<9, 9>();
  // [δp, δv, δθ] is the core's order (kP, kV, kTheta).
  return pre;
}

ekf::CoreState propagate(const std::vector<ImuSample>& imu, const ekf::CoreState& x0, Timestamp t_i, Timestamp t_j,
                         std::size_t& hint) {
  ekf::CoreState x = x0;
  if (t_j == t_i) return x;
  for_each_interval(imu, t_i, t_j, hint, [&](const ImuSample& a, const ImuSample& b) {
    const double dt = dt_seconds(a.t_ns, b.t_ns);
    if (dt > 0.0) x = ekf::integrate(x, a.gyro, a.accel, b.gyro, b.accel, dt);
  });
  return x;
}

}  // namespace roe::refine
