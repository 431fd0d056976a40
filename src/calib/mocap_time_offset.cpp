// The mocap–IMU clock offset by cross-correlating angular-rate magnitudes (calib/mocap_time_offset.hpp).
#include "roe/calib/mocap_time_offset.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include <fmt/format.h>

#include "roe/core/error.hpp"
#include "roe/math/so3.hpp"

namespace roe::calib {

MocapOffsetEstimate estimate_mocap_time_offset(const std::vector<ImuSample>& imu, const std::vector<StampedPose>& mocap,
                                    double max_offset_s, double grid_dt_s) {
  if (imu.size() < 10 || mocap.size() < 10)
    throw DataError("time-offset estimate needs at least 10 IMU samples and 10 mocap poses");
  // Mocap angular-rate magnitude at mid-points of consecutive poses (gaps over 3 periods skipped).
  const double mocap_rate = median_rate_hz(mocap, [](const StampedPose& x) { return x.t_ns; });
  const double period = mocap_rate > 0 ? 1.0 / mocap_rate : 0.01;
  if (grid_dt_s <= 0) grid_dt_s = std::min(period, 0.005);
  std::vector<std::pair<double, double>> mrate;  // (t_mocap s relative, |w|)
  const Timestamp m0 = mocap.front().t_ns;
  for (std::size_t k = 0; k + 1 < mocap.size(); ++k) {
    const double dt = dt_seconds(mocap[k].t_ns, mocap[k + 1].t_ns);
    if (!(dt > 0) || dt > 3.0 * period) continue;
    const double w = math::log_quat(mocap[k].T.q.conjugate() * mocap[k + 1].T.q).norm() / dt;
    mrate.emplace_back(dt_seconds(m0, mocap[k].t_ns) + 0.5 * dt, w);
  }
  // Gyro magnitude binned on the grid (IMU clock, relative to the first IMU sample).
  const Timestamp g0 = imu.front().t_ns;
  const double g_len = dt_seconds(g0, imu.back().t_ns);
  const auto ng = static_cast<std::size_t>(g_len / grid_dt_s) + 1;
  std::vector<double> G(ng, 0.0), Gn(ng, 0.0);
  for (const auto& s : imu) {
    const auto i = static_cast<std::size_t>(std::floor(dt_seconds(g0, s.t_ns) / grid_dt_s + 0.5));
    if (i < ng) {
      G[i] += s.gyro.norm();
      Gn[i] += 1.0;
    }
  }
  for (std::size_t i = 0; i < ng; ++i) G[i] = Gn[i] > 0 ? G[i] / Gn[i] : std::numeric_limits<double>::quiet_NaN();
  // Mocap rate linearly interpolated at mocap-clock time tm (relative to m0); NaN outside/gaps.
  auto m_at = [&](double tm) {
    auto it = std::lower_bound(mrate.begin(), mrate.end(), tm,
                               [](const std::pair<double, double>& a, double t) { return a.first < t; });
    if (it == mrate.begin() || it == mrate.end()) return std::numeric_limits<double>::quiet_NaN();
    const auto& b = *it;
    const auto& a = *(it - 1);
    if (b.first - a.first > 3.0 * period) return std::numeric_limits<double>::quiet_NaN();
    const double u = (tm - a.first) / (b.first - a.first);
    return (1.0 - u) * a.second + u * b.second;
  };
  // Search centre: 0 when the clocks overlap, otherwise align the starts.
  const double clock_gap = dt_seconds(m0, g0);  // t_imu_start − t_mocap_start (s)
  const double m_len = dt_seconds(m0, mocap.back().t_ns);
  const bool overlap = clock_gap < m_len && -clock_gap < g_len;
  const double centre = overlap ? 0.0 : clock_gap;
  const auto nlag = static_cast<int>(std::ceil(max_offset_s / grid_dt_s));
  std::vector<double> corr(2 * nlag + 1, std::numeric_limits<double>::quiet_NaN());
  std::vector<std::size_t> used(2 * nlag + 1, 0);
  // Mocap samples on the grid for offset o: M_o[i] = m(t_imu_i − o) with t_imu_i = g0 + i·dt.
  for (int L = -nlag; L <= nlag; ++L) {
    const double o = centre + L * grid_dt_s;
    double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < ng; ++i) {
      if (std::isnan(G[i])) continue;
      const double tm = clock_gap + static_cast<double>(i) * grid_dt_s - o;  // mocap time rel. m0
      const double m = m_at(tm);
      if (std::isnan(m)) continue;
      sx += G[i];
      sy += m;
      sxx += G[i] * G[i];
      syy += m * m;
      sxy += G[i] * m;
      ++n;
    }
    if (n < 20) continue;
    const double cov = sxy - sx * sy / n, vx = sxx - sx * sx / n, vy = syy - sy * sy / n;
    if (vx <= 1e-12 || vy <= 1e-12) continue;
    corr[L + nlag] = cov / std::sqrt(vx * vy);
    used[L + nlag] = n;
  }
  int best = -1;
  for (int k = 0; k < static_cast<int>(corr.size()); ++k)
    if (!std::isnan(corr[k]) && (best < 0 || corr[k] > corr[best])) best = k;
  if (best < 0)
    throw DataError("time-offset estimate failed: the IMU and mocap signals never overlap with rotation within ±" +
                    fmt::format("{}", max_offset_s) + " s of the search centre");
  double delta = 0.0;
  if (best > 0 && best + 1 < static_cast<int>(corr.size()) && !std::isnan(corr[best - 1]) && !std::isnan(corr[best + 1])) {
    const double a = corr[best - 1], b = corr[best], c = corr[best + 1];
    const double den = a - 2 * b + c;
    if (den < 0) delta = std::clamp(0.5 * (a - c) / den, -0.5, 0.5);
  }
  MocapOffsetEstimate e;
  e.offset_s = centre + (best - nlag + delta) * grid_dt_s;
  e.correlation = corr[best];
  e.samples = used[best];
  e.grid_dt_s = grid_dt_s;
  double second = -1.0;
  const int excl = static_cast<int>(std::ceil(0.25 / grid_dt_s));
  for (int k = 0; k < static_cast<int>(corr.size()); ++k)
    if (std::abs(k - best) > excl && !std::isnan(corr[k])) second = std::max(second, corr[k]);
  e.peak_ratio = second > 0 ? corr[best] / second : std::numeric_limits<double>::infinity();
  e.peak_at_edge = best == 0 || best + 1 == static_cast<int>(corr.size());
  return e;
}

}  // namespace roe::calib
