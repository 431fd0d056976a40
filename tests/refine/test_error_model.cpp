// The correlated detection-error model of the batch (docs/refine.md §2b): fit_error_model recovers a
// Gauss-Markov + white process generated here, and variance_factor is the variance of a long mean of such
// errors measured by Monte Carlo.
#include <catch2/catch.hpp>
#include <cmath>
#include <random>

#include "roe/refine/refine.hpp"

namespace {

using namespace roe;

/// n samples dt apart of u = β + w per component: β first-order Gauss-Markov (stationary σ s_b, time
/// constant τ; exact discretisation), w white (σ s_w).
refine::ResidualSeries gauss_markov(std::mt19937& rng, std::size_t n, double dt, double tau, double s_b, double s_w) {
  std::normal_distribution<double> g(0.0, 1.0);
  const double phi = tau > 0.0 ? std::exp(-dt / tau) : 0.0;
  refine::ResidualSeries s;
  Vector6d beta;
  for (int k = 0; k < 6; ++k) beta(k) = s_b * g(rng);
  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0)
      for (int k = 0; k < 6; ++k) beta(k) = phi * beta(k) + s_b * std::sqrt(1.0 - phi * phi) * g(rng);
    Vector6d u;
    for (int k = 0; k < 6; ++k) u(k) = beta(k) + s_w * g(rng);
    s.t_s.push_back(static_cast<double>(i) * dt);
    s.u.push_back(u);
  }
  return s;
}

}  // namespace

TEST_CASE("refine/error model: the fit recovers tau and the two sigmas of a Gauss-Markov plus white error") {
  std::mt19937 rng(5);
  for (const double tau : {1.0, 3.0}) {
    std::vector<refine::ResidualSeries> series;
    for (int obj = 0; obj < 4; ++obj) series.push_back(gauss_markov(rng, 1800, 1.0 / 30.0, tau, 0.8, 0.4));
    const refine::DetectionErrorModel m = refine::fit_error_model(series);
    INFO("tau " << tau << ": fitted tau " << m.tau_s << " s_b " << m.sigma_bias << " s_w " << m.sigma_white);
    REQUIRE(m.correlated);
    CHECK(m.tau_s == Approx(tau).epsilon(0.3));
    CHECK(m.sigma_bias == Approx(0.8).epsilon(0.15));
    // The split of the variance between s_b and s_w is the weakest part of the fit (an extrapolation to
    // lag 0); what the marginals use is the variance factor, dominated by s_b² (1 + φ)/(1 − φ).
    refine::DetectionErrorModel truth;
    truth.correlated = true;
    truth.tau_s = tau;
    truth.sigma_bias = 0.8;
    truth.sigma_white = 0.4;
    CHECK(m.sigma_white < 0.6);
    CHECK(m.variance_factor(1.0 / 30.0) == Approx(truth.variance_factor(1.0 / 30.0)).epsilon(0.3));
    REQUIRE(m.autocovariance.size() >= 2);
    CHECK(m.autocovariance.front().lag_s == 0.0);
    CHECK(m.autocovariance.front().cov == Approx(0.8 * 0.8 + 0.4 * 0.4).epsilon(0.15));
  }
  // White errors: not correlated, s_w² = the variance.
  std::vector<refine::ResidualSeries> white = {gauss_markov(rng, 1800, 1.0 / 30.0, 0.0, 0.0, 0.7)};
  const refine::DetectionErrorModel w = refine::fit_error_model(white);
  CHECK_FALSE(w.correlated);
  CHECK(w.sigma_white == Approx(0.7).epsilon(0.05));
  CHECK(w.variance_factor(1.0 / 30.0) == Approx(0.49).epsilon(0.1));
  // Nothing to fit: white of unit σ.
  CHECK_FALSE(refine::fit_error_model({}).correlated);
}

TEST_CASE("refine/error model: variance_factor is the variance of a long mean of the errors (Monte Carlo)") {
  refine::DetectionErrorModel m;
  m.correlated = true;
  m.tau_s = 2.0;
  m.sigma_bias = 0.8;
  m.sigma_white = 0.4;
  const double dt = 0.1;
  const std::size_t n = 3000, trials = 1500;  // 300 s = 150 τ per mean
  std::mt19937 rng(9);
  double sum2 = 0.0;
  for (std::size_t t = 0; t < trials; ++t) {
    const refine::ResidualSeries s = gauss_markov(rng, n, dt, m.tau_s, m.sigma_bias, m.sigma_white);
    Vector6d mean = Vector6d::Zero();
    for (const auto& u : s.u) mean += u;
    mean /= static_cast<double>(n);
    sum2 += mean.squaredNorm() / 6.0;
  }
  const double var_of_mean = sum2 / static_cast<double>(trials);
  INFO("Monte Carlo n·var(mean) " << var_of_mean * n << ", variance_factor " << m.variance_factor(dt));
  CHECK(var_of_mean * static_cast<double>(n) == Approx(m.variance_factor(dt)).epsilon(0.08));
  // A first detection (no predecessor) and white errors: the variance alone.
  CHECK(m.variance_factor(-1.0) == Approx(0.8));
  m.correlated = false;
  CHECK(m.variance_factor(dt) == Approx(0.8));
}
