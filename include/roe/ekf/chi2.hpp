#pragma once
/// @file
/// Chi-square distribution functions for the per-object gate and the consistency tests, without
/// Boost: the regularised lower incomplete gamma function P(a, x) (series for x < a + 1, Lentz's
/// continued fraction for the upper tail otherwise) and the quantile by Newton iterations on the CDF
/// started from the Wilson–Hilferty approximation
///   q ≈ k (1 − 2/(9k) + z √(2/(9k)))³,  z = Φ⁻¹(p),
/// refined until |CDF(q) − p| < 1e-12 (relative 1e-14 in q). Accurate to ~1e-10 relative for
/// 1 ≤ k ≤ 10⁴ and 1e-8 ≤ p ≤ 1 − 1e-8 (tested against published table values).

namespace roe::ekf {

/// Regularised lower incomplete gamma P(a, x) = γ(a, x) / Γ(a), a > 0, x ≥ 0.
double gamma_p(double a, double x);
/// CDF of χ²(k) at x (k > 0 degrees of freedom, need not be an integer).
double chi2_cdf(double x, double k);
/// Inverse of chi2_cdf: the x with P(χ²(k) ≤ x) = p, 0 < p < 1. roe::InternalError otherwise.
double chi2_quantile(double p, double k);
/// Inverse of the standard normal CDF (Acklam's rational approximation + one Halley step).
double normal_quantile(double p);

}  // namespace roe::ekf
