#include "roe/math/distributions.hpp"

#include <cmath>
#include <limits>
#include <string>

#include "roe/core/error.hpp"

namespace roe::math {
namespace {

// Series P(a, x) = e^{-x} x^a / Γ(a+1) Σ x^n / ((a+1)...(a+n)); converges quickly for x < a + 1.
double gamma_p_series(double a, double x) {
  double term = 1.0 / a;
  double sum = term;
  for (int n = 1; n < 10000; ++n) {
    term *= x / (a + n);
    sum += term;
    if (std::abs(term) < std::abs(sum) * 1e-16) break;
  }
  return sum * std::exp(-x + a * std::log(x) - std::lgamma(a));
}

// Upper tail Q(a, x) by the continued fraction of Γ(a, x) (modified Lentz), for x >= a + 1.
double gamma_q_cf(double a, double x) {
  constexpr double tiny = 1e-300;
  double b = x + 1.0 - a;
  double c = 1.0 / tiny;
  double d = 1.0 / b;
  double h = d;
  for (int i = 1; i < 10000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::abs(d) < tiny) d = tiny;
    c = b + an / c;
    if (std::abs(c) < tiny) c = tiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1.0) < 1e-16) break;
  }
  return std::exp(-x + a * std::log(x) - std::lgamma(a)) * h;
}

/// Continued fraction of the regularised incomplete beta function (modified Lentz), valid for
/// x < (a + 1) / (a + b + 2).
double beta_continued_fraction(double a, double b, double x) {
  constexpr double kTiny = 1e-300;
  constexpr double kEps = 1e-16;
  double c = 1.0;
  double d = 1.0 - (a + b) * x / (a + 1.0);
  if (std::abs(d) < kTiny) d = kTiny;
  d = 1.0 / d;
  double f = d;
  for (int m = 1; m <= 10000; ++m) {
    const double m2 = 2.0 * m;
    // even step
    double num = m * (b - m) * x / ((a + m2 - 1.0) * (a + m2));
    d = 1.0 + num * d;
    c = 1.0 + num / c;
    if (std::abs(d) < kTiny) d = kTiny;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    f *= d * c;
    // odd step
    num = -(a + m) * (a + b + m) * x / ((a + m2) * (a + m2 + 1.0));
    d = 1.0 + num * d;
    c = 1.0 + num / c;
    if (std::abs(d) < kTiny) d = kTiny;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double delta = d * c;
    f *= delta;
    if (std::abs(delta - 1.0) < kEps) break;
  }
  return f;
}

/// Regularised incomplete beta I_x(a, b).
double incomplete_beta(double a, double b, double x) {
  if (x <= 0.0) return 0.0;
  if (x >= 1.0) return 1.0;
  const double log_front =
      std::lgamma(a + b) - std::lgamma(a) - std::lgamma(b) + a * std::log(x) + b * std::log1p(-x);
  const double front = std::exp(log_front);
  if (x < (a + 1.0) / (a + b + 2.0)) return front * beta_continued_fraction(a, b, x) / a;
  return 1.0 - front * beta_continued_fraction(b, a, 1.0 - x) / b;
}

}  // namespace

double gamma_p(double a, double x) {
  ROE_CHECK(a > 0.0 && x >= 0.0, "gamma_p needs a > 0 and x >= 0");
  if (x == 0.0) return 0.0;
  if (x < a + 1.0) return gamma_p_series(a, x);
  return 1.0 - gamma_q_cf(a, x);
}

double chi2_cdf(double x, double k) {
  if (x <= 0.0) return 0.0;
  return gamma_p(0.5 * k, 0.5 * x);
}

double normal_quantile(double p) {
  ROE_CHECK(p > 0.0 && p < 1.0, "normal_quantile needs 0 < p < 1");
  // Φ⁻¹(p) = −Φ⁻¹(1 − p), and 1 − p is exact in double for p ≥ ½: the upper half is computed as the
  // lower one, where the Halley step's Φ(x) − p is formed from a small erfc without cancellation
  // (near p = 1, 0.5·erfc(−x/√2) − p would lose ~8 digits to the subtraction).
  if (p > 0.5) return -normal_quantile(1.0 - p);
  // Acklam's coefficients (rational approximations on the central region and the lower tail).
  static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,  -2.759285104469687e+02,
                             1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                             6.680131188771972e+01, -1.328068155288572e+01};
  static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                             -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                             3.754408661907416e+00};
  const double plow = 0.02425;
  double x;
  if (p < plow) {
    const double q = std::sqrt(-2.0 * std::log(p));
    x = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
  } else {
    const double q = p - 0.5;
    const double r = q * q;
    x = (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
        (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0);
  }
  // One Halley step on Φ(x) − p with Φ from erfc (x ≤ 0 here: erfc of a non-negative argument, no
  // cancellation): brings the relative error to ~1e-15.
  const double e = 0.5 * std::erfc(-x / std::sqrt(2.0)) - p;
  const double u = e * std::sqrt(2.0 * M_PI) * std::exp(0.5 * x * x);
  return x - u / (1.0 + 0.5 * x * u);
}

double chi2_quantile(double p, double k) {
  ROE_CHECK(p > 0.0 && p < 1.0, "chi2_quantile needs 0 < p < 1, got " + std::to_string(p));
  ROE_CHECK(k > 0.0, "chi2_quantile needs k > 0");
  // Wilson–Hilferty start.
  const double z = normal_quantile(p);
  const double h = 2.0 / (9.0 * k);
  double x = k * std::pow(std::max(1.0 - h + z * std::sqrt(h), 0.05), 3.0);
  // Newton on F(x) − p with the χ² density f(x) = x^{k/2−1} e^{−x/2} / (2^{k/2} Γ(k/2)); the iterate
  // is kept positive by halving towards 0 when a step would cross it.
  for (int it = 0; it < 100; ++it) {
    const double F = chi2_cdf(x, k);
    const double logf =
        (0.5 * k - 1.0) * std::log(x) - 0.5 * x - 0.5 * k * std::log(2.0) - std::lgamma(0.5 * k);
    const double f = std::exp(logf);
    if (!(f > 0.0)) break;
    double step = (F - p) / f;
    double xn = x - step;
    if (xn <= 0.0) xn = 0.5 * x;
    const bool done = std::abs(xn - x) <= 1e-14 * x || std::abs(F - p) < 1e-15;
    x = xn;
    if (done) break;
  }
  return x;
}

double student_t_cdf(double t, double dof) {
  ROE_CHECK(dof > 0.0, "degrees of freedom must be positive");
  if (std::isnan(t)) return std::numeric_limits<double>::quiet_NaN();
  if (std::isinf(t)) return t > 0 ? 1.0 : 0.0;
  const double tail = 0.5 * incomplete_beta(0.5 * dof, 0.5, dof / (dof + t * t));
  return t > 0.0 ? 1.0 - tail : tail;
}

double student_t_quantile(double p, double dof) {
  ROE_CHECK(p > 0.0 && p < 1.0, "a quantile needs 0 < p < 1");
  ROE_CHECK(dof > 0.0, "degrees of freedom must be positive");
  if (p == 0.5) return 0.0;
  // The distribution is symmetric: solve for the upper half and mirror.
  const double q = p > 0.5 ? p : 1.0 - p;
  double lo = 0.0, hi = 1.0;
  while (student_t_cdf(hi, dof) < q) hi *= 2.0;
  for (int i = 0; i < 200 && hi - lo > 1e-15 * hi; ++i) {
    const double mid = 0.5 * (lo + hi);
    (student_t_cdf(mid, dof) < q ? lo : hi) = mid;
  }
  const double t = 0.5 * (lo + hi);
  return p > 0.5 ? t : -t;
}

}  // namespace roe::math
