// Statistics over repeated runs: t confidence intervals, paired differences, Wilcoxon signed-rank.
#include "roe/eval/stats.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "roe/core/error.hpp"
#include "roe/eval/metrics.hpp"
#include "roe/math/distributions.hpp"

namespace roe::eval {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double normal_sf(double z) { return 0.5 * std::erfc(z / std::sqrt(2.0)); }

/// Average ranks (1-based) of `v`, ties sharing the mean of their ranks (scipy.stats.rankdata).
/// `tie_sizes` receives the size of every group of equal values larger than one.
std::vector<double> average_ranks(const std::vector<double>& v, std::vector<std::size_t>& tie_sizes) {
  std::vector<std::size_t> order(v.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) { return v[i] < v[j]; });
  std::vector<double> rank(v.size());
  for (std::size_t i = 0; i < order.size();) {
    std::size_t j = i;
    while (j + 1 < order.size() && v[order[j + 1]] == v[order[i]]) ++j;
    const double r = 0.5 * static_cast<double>(i + j) + 1.0;
    for (std::size_t k = i; k <= j; ++k) rank[order[k]] = r;
    if (j > i) tie_sizes.push_back(j - i + 1);
    i = j + 1;
  }
  return rank;
}

/// Number of subsets of {1..n} per rank sum 0..n(n+1)/2 (the exact null distribution of r+ times 2^n).
std::vector<double> signed_rank_counts(std::size_t n) {
  std::vector<double> c(n * (n + 1) / 2 + 1, 0.0);
  c[0] = 1.0;
  for (std::size_t k = 1; k <= n; ++k)
    for (std::size_t s = k * (k + 1) / 2; s >= k; --s) c[s] += c[s - k];
  return c;
}

}  // namespace

SampleSummary summarize_sample(const std::vector<double>& values, double confidence) {
  ROE_CHECK(confidence > 0.0 && confidence < 1.0, "confidence must be in (0, 1)");
  for (double v : values) ROE_CHECK(!std::isnan(v), "a sample value is NaN");
  SampleSummary s;
  s.confidence = confidence;
  s.n = values.size();
  if (values.empty()) {
    s.mean = s.std = s.std_sample = s.median = s.min = s.max = s.ci_low = s.ci_high = kNaN;
    return s;
  }
  const Stats st = compute_stats(values);  // mean, median, min, max, population std (evo's definitions)
  s.mean = st.mean;
  s.median = st.median;
  s.min = st.min;
  s.max = st.max;
  s.std = st.std;
  if (s.n < 2) {
    s.std_sample = s.ci_low = s.ci_high = kNaN;
    return s;
  }
  const double n = static_cast<double>(s.n);
  s.std_sample = st.std * std::sqrt(n / (n - 1.0));
  const double half = math::student_t_quantile(0.5 * (1.0 + confidence), n - 1.0) * s.std_sample / std::sqrt(n);
  s.ci_low = s.mean - half;
  s.ci_high = s.mean + half;
  return s;
}

WilcoxonResult wilcoxon_signed_rank(const std::vector<double>& d_in) {
  for (double v : d_in) ROE_CHECK(!std::isnan(v), "a difference is NaN");
  WilcoxonResult res;
  const std::size_t n_zero = static_cast<std::size_t>(std::count(d_in.begin(), d_in.end(), 0.0));
  if (d_in.empty() || n_zero == d_in.size()) {
    res.statistic = res.p_value = kNaN;
    res.method = "none";
    return res;
  }
  const bool exact = d_in.size() <= 50 && n_zero == 0;
  std::vector<double> d;
  for (double v : d_in)
    if (v != 0.0) d.push_back(v);
  std::vector<double> absd(d.size());
  std::transform(d.begin(), d.end(), absd.begin(), [](double v) { return std::abs(v); });
  std::vector<std::size_t> ties;
  const std::vector<double> r = average_ranks(absd, ties);
  double r_plus = 0.0, r_minus = 0.0;
  for (std::size_t i = 0; i < d.size(); ++i) (d[i] > 0.0 ? r_plus : r_minus) += r[i];
  const double count = static_cast<double>(d.size());
  res.n_used = d.size();
  res.statistic = std::min(r_plus, r_minus);
  if (exact) {
    res.method = "exact";
    const std::vector<double> c = signed_rank_counts(d.size());
    const std::size_t k = static_cast<std::size_t>(r_plus);  // scipy truncates half ranks
    if (k == (c.size() - 1) / 2) {
      res.p_value = 1.0;
      return res;
    }
    const double total = std::ldexp(1.0, static_cast<int>(d.size()));
    double less = 0.0, greater = 0.0;
    for (std::size_t s = 0; s < c.size(); ++s) {
      if (s <= k) less += c[s];
      if (s >= k) greater += c[s];
    }
    res.p_value = std::clamp(2.0 * std::min(less, greater) / total, 0.0, 1.0);
    return res;
  }
  res.method = "normal";
  const double mn = count * (count + 1.0) * 0.25;
  double se = count * (count + 1.0) * (2.0 * count + 1.0);
  for (std::size_t t : ties) {
    const double tt = static_cast<double>(t);
    se -= 0.5 * tt * (tt * tt - 1.0);
  }
  se = std::sqrt(se / 24.0);
  const double z = (res.statistic - mn) / se;
  res.p_value = 2.0 * normal_sf(std::abs(z));
  return res;
}

PairedComparison compare_paired(const std::vector<double>& a, const std::vector<double>& b, double confidence) {
  ROE_CHECK(a.size() == b.size(), "paired samples must have the same length");
  std::vector<double> d(a.size());
  for (std::size_t i = 0; i < a.size(); ++i) d[i] = b[i] - a[i];
  return {summarize_sample(d, confidence), wilcoxon_signed_rank(d)};
}

}  // namespace roe::eval
