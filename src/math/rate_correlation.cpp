// The one correlator of angular-rate magnitudes (math/rate_correlation.hpp).
#include "roe/math/rate_correlation.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>

#include "roe/core/error.hpp"
#include "roe/math/so3.hpp"

namespace roe::math {

namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

double seconds_between(std::int64_t a_ns, std::int64_t b_ns) { return static_cast<double>(b_ns - a_ns) * 1e-9; }

/// `s` averaged into cells of `dt` (cell i holds the samples nearest i·dt); nan where a cell is empty.
std::vector<double> bin_on_grid(const RateSignal& s, double dt) {
  const auto n = static_cast<std::size_t>(s.length_s() / dt) + 1;
  std::vector<double> sum(n, 0.0), count(n, 0.0);
  for (std::size_t k = 0; k < s.t_s.size(); ++k) {
    const auto i = static_cast<std::size_t>(std::floor(s.t_s[k] / dt + 0.5));
    if (i < n) sum[i] += s.value[k], count[i] += 1.0;
  }
  for (std::size_t i = 0; i < n; ++i) sum[i] = count[i] > 0 ? sum[i] / count[i] : kNan;
  return sum;
}

/// `s` read linearly at time t (its own clock); nan outside and across gaps.
double value_at(const RateSignal& s, double t) {
  const auto it = std::lower_bound(s.t_s.begin(), s.t_s.end(), t);
  if (it == s.t_s.begin() || it == s.t_s.end()) return kNan;
  const auto b = static_cast<std::size_t>(it - s.t_s.begin());
  const double ta = s.t_s[b - 1], tb = s.t_s[b];
  if (s.max_gap_s > 0 && tb - ta > s.max_gap_s) return kNan;
  const double u = (t - ta) / (tb - ta);
  return (1.0 - u) * s.value[b - 1] + u * s.value[b];
}

/// Pearson correlation of the pairs (G[i], interpolated at grid time i·dt + gap − o); nan with < 20 pairs.
std::pair<double, std::size_t> correlation_at(const std::vector<double>& G, const RateSignal& m, double dt,
                                              double clock_gap, double o) {
  double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < G.size(); ++i) {
    if (std::isnan(G[i])) continue;
    const double y = value_at(m, clock_gap + static_cast<double>(i) * dt - o);
    if (std::isnan(y)) continue;
    sx += G[i], sy += y, sxx += G[i] * G[i], syy += y * y, sxy += G[i] * y;
    ++n;
  }
  if (n < 20) return {kNan, n};
  const double N = static_cast<double>(n);
  const double cov = sxy - sx * sy / N, vx = sxx - sx * sx / N, vy = syy - sy * sy / N;
  if (vx <= 1e-12 || vy <= 1e-12) return {kNan, n};
  return {cov / std::sqrt(vx * vy), n};
}

}  // namespace

RateCorrelation correlate_rates(const RateSignal& binned, const RateSignal& interpolated, double max_offset_s,
                                double grid_dt_s) {
  if (binned.t_s.size() < 10 || interpolated.t_s.size() < 10 || !(grid_dt_s > 0))
    throw DataError("time-offset estimate needs at least 10 samples of each rate signal");
  const std::vector<double> G = bin_on_grid(binned, grid_dt_s);
  // Search centre: 0 when the clocks overlap, otherwise align the starts.
  const double clock_gap = seconds_between(interpolated.origin_ns, binned.origin_ns);  // binned start − interpolated start
  const bool overlap = clock_gap < interpolated.length_s() && -clock_gap < binned.length_s();
  const double centre = overlap ? 0.0 : clock_gap;
  const auto nlag = static_cast<int>(std::ceil(max_offset_s / grid_dt_s));
  std::vector<double> corr(2 * nlag + 1, kNan);
  std::vector<std::size_t> used(2 * nlag + 1, 0);
  for (int L = -nlag; L <= nlag; ++L)
    std::tie(corr[L + nlag], used[L + nlag]) = correlation_at(G, interpolated, grid_dt_s, clock_gap, centre + L * grid_dt_s);
  int best = -1;
  for (int k = 0; k < static_cast<int>(corr.size()); ++k)
    if (!std::isnan(corr[k]) && (best < 0 || corr[k] > corr[best])) best = k;
  if (best < 0)
    throw DataError(fmt::format("time-offset estimate failed: the two rate signals never overlap with rotation within "
                                "±{} s of the search centre",
                                max_offset_s));
  double delta = 0.0;
  if (best > 0 && best + 1 < static_cast<int>(corr.size()) && !std::isnan(corr[best - 1]) && !std::isnan(corr[best + 1])) {
    const double a = corr[best - 1], b = corr[best], c = corr[best + 1];
    const double den = a - 2 * b + c;
    if (den < 0) delta = std::clamp(0.5 * (a - c) / den, -0.5, 0.5);
  }
  RateCorrelation e;
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

RateSignal pose_rate_signal(const std::vector<std::int64_t>& t_ns, const std::vector<Pose>& poses, double period_s) {
  RateSignal s;
  if (t_ns.empty()) return s;
  const double period = period_s > 0 ? period_s : 0.01;
  s.origin_ns = t_ns.front();
  s.max_gap_s = 3.0 * period;
  for (std::size_t k = 0; k + 1 < t_ns.size(); ++k) {
    const double dt = seconds_between(t_ns[k], t_ns[k + 1]);
    if (!(dt > 0) || dt > 3.0 * period) continue;
    s.t_s.push_back(seconds_between(s.origin_ns, t_ns[k]) + 0.5 * dt);
    s.value.push_back(math::log_quat(poses[k].q.conjugate() * poses[k + 1].q).norm() / dt);
  }
  return s;
}

}  // namespace roe::math
