#pragma once
/// @file
/// Probability distributions for the gates, the consistency tests and the statistics over runs,
/// without Boost (the ground floor: ekf, eval and calib use them; nothing here depends on them).
///
/// χ²: the regularised lower incomplete gamma function P(a, x) (series for x < a + 1, Lentz's
/// continued fraction for the upper tail otherwise) and the quantile by Newton iterations on the CDF
/// started from the Wilson–Hilferty approximation
///   q ≈ k (1 − 2/(9k) + z √(2/(9k)))³,  z = Φ⁻¹(p),
/// refined until |CDF(q) − p| < 1e-12 (relative 1e-14 in q). Accurate to ~1e-10 relative for
/// 1 ≤ k ≤ 10⁴ and 1e-8 ≤ p ≤ 1 − 1e-8 (tested against published table values).

namespace roe::math {

/// Regularised lower incomplete gamma P(a, x) = γ(a, x) / Γ(a), a > 0, x ≥ 0.
double gamma_p(double a, double x);
/// CDF of χ²(k) at x (k > 0 degrees of freedom, need not be an integer).
double chi2_cdf(double x, double k);
/// Inverse of chi2_cdf: the x with P(χ²(k) ≤ x) = p, 0 < p < 1. roe::InternalError otherwise.
double chi2_quantile(double p, double k);
/// Inverse of the standard normal CDF (Acklam's rational approximation + one Halley step).
double normal_quantile(double p);

/// Student's t (the confidence intervals of eval/stats.hpp): CDF through the regularised incomplete
/// beta function I_x(a, b) (modified Lentz continued fraction), quantile by bisection on the CDF to
/// 1e-15 relative. Checked against python3-scipy 1.10 in tests/eval/test_stats.cpp.
/// CDF of Student's t distribution with `dof` > 0 degrees of freedom.
double student_t_cdf(double t, double dof);
/// Quantile of Student's t distribution with `dof` > 0 degrees of freedom, 0 < p < 1.
double student_t_quantile(double p, double dof);

}  // namespace roe::math
