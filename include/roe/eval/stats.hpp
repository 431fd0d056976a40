#pragma once
/// @file
/// Statistics over repeated runs (roe sweep aggregate, docs/sweep.md): the mean with its Student-t
/// confidence interval, paired differences between two configurations run on the same sequences and
/// seeds, and the Wilcoxon signed-rank test. I/O-free; the per-run statistics of one trajectory are
/// eval/metrics.hpp's compute_stats (reused here for mean, median, min, max and the population std).
///
/// Definitions (checked against python3-scipy 1.10 in tests/eval/test_stats.cpp):
///  - std: population standard deviation (ddof 0: numpy's default, evo_res, the paper's tables, roe eval
///    --summary); std_sample: the sample standard deviation (ddof 1), which the CI uses (docs/eval.md).
///  - CI: mean ± t_{(1+c)/2, n−1} · std_sample / √n (scipy.stats.t.interval); undefined (NaN) for n < 2.
///  - Wilcoxon: scipy.stats.wilcoxon(d) with its defaults: zero_method "wilcox" (zero differences
///    dropped), no continuity correction, two-sided, method "auto" = exact null distribution when
///    n ≤ 50 and no difference is zero (the signed-rank sum r+ truncated to an integer when ties give
///    half ranks, as scipy does), otherwise the normal approximation with the tie correction of the
///    variance. Statistic T = min(r+, r−).

#include <cstddef>
#include <string>
#include <vector>

namespace roe::eval {

struct SampleSummary {
  std::size_t n = 0;
  double mean = 0.0, median = 0.0, min = 0.0, max = 0.0;
  double std = 0.0;         ///< population (ddof 0)
  double std_sample = 0.0;  ///< sample (ddof 1); NaN for n < 2
  double ci_low = 0.0, ci_high = 0.0;  ///< confidence interval of the mean (NaN for n < 2)
  double confidence = 0.95;
};

/// Summary of `values`; NaN values are an error of the caller (InternalError). Empty: n = 0, NaN stats.
SampleSummary summarize_sample(const std::vector<double>& values, double confidence = 0.95);

struct WilcoxonResult {
  double statistic = 0.0;  ///< T = min(r+, r−)
  double p_value = 1.0;    ///< two-sided; NaN when every difference is zero or there is none
  std::size_t n_used = 0;  ///< differences ranked (zeros dropped)
  std::string method;      ///< "exact" or "normal"
};

/// Wilcoxon signed-rank test of the differences `d` (H0: symmetric about 0), scipy's defaults.
WilcoxonResult wilcoxon_signed_rank(const std::vector<double>& d);

struct PairedComparison {
  SampleSummary difference;  ///< of b − a, pair by pair
  WilcoxonResult wilcoxon;
};

/// Compares paired samples (same length, same order: pair i is one sequence and seed): b − a.
/// InternalError when the lengths differ.
PairedComparison compare_paired(const std::vector<double>& a, const std::vector<double>& b,
                                double confidence = 0.95);

}  // namespace roe::eval
