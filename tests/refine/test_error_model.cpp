// The detection-error model the batch whitens with (docs/refine.md §2): fit_error_model recovers τ and the
// two σ scales of first-order Gauss-Markov series generated here (the exact discretisation, uneven gaps),
// finds white series white, and its whitened-residual diagnostic sees a white remainder it does not model.
#include <catch2/catch.hpp>
#include <cmath>
#include <random>

#include "roe/refine/refine.hpp"

namespace {

using namespace roe;

/// n samples of y = s ⊙ (x + w_extra): x first-order Gauss-Markov per component (unit variance, τ;
/// exact discretisation over each gap), frames 1/30 s apart with a frame skipped with probability 0.2,
/// scales s_t on the first three components and s_r on the last three, w_extra white with σ s_w.
refine::ErrorSeries gauss_markov(std::mt19937& rng, std::size_t n, double tau, double s_t, double s_r,
                                 double s_w = 0.0) {
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  refine::ErrorSeries s;
  Vector6d x;
  for (int k = 0; k < 6; ++k) x(k) = g(rng);
  double t = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double dt = (u(rng) < 0.2 ? 2.0 : 1.0) / 30.0;
    if (i > 0) {
      t += dt;
      const double rho = tau > 0.0 ? std::exp(-dt / tau) : 0.0;
      for (int k = 0; k < 6; ++k) x(k) = rho * x(k) + std::sqrt(1.0 - rho * rho) * g(rng);
    }
    Vector6d y;
    for (int k = 0; k < 6; ++k) y(k) = (k < 3 ? s_t : s_r) * (x(k) + s_w * g(rng));
    s.t_s.push_back(t);
    s.y.push_back(y);
  }
  return s;
}

}  // namespace

TEST_CASE("refine/error model: the fit recovers tau and the two scales of Gauss-Markov errors") {
  std::mt19937 rng(5);
  for (const double tau : {0.3, 3.0}) {
    std::vector<refine::ErrorSeries> series;
    for (int obj = 0; obj < 4; ++obj) series.push_back(gauss_markov(rng, 1800, tau, 0.7, 0.3));
    const refine::DetectionErrorModel m = refine::fit_error_model(series);
    INFO("tau " << tau << ": fitted tau " << m.tau_s << ", scales " << m.scale_translation << " " << m.scale_rotation
                << ", whitened lag-1 " << m.whitened_lag1);
    CHECK(m.fitted_tau);
    CHECK(m.used == 7200);
    CHECK(m.tau_s == Approx(tau).epsilon(0.1));
    CHECK(m.scale_translation == Approx(0.7).epsilon(0.05));
    CHECK(m.scale_rotation == Approx(0.3).epsilon(0.05));
    CHECK(std::abs(m.whitened_lag1) < 0.03);
    // τ held: only the scales are fitted; held at 0 (white), the whitened residuals are the raw ones,
    // strongly correlated.
    const refine::DetectionErrorModel held = refine::fit_error_model(series, 0.0);
    CHECK_FALSE(held.fitted_tau);
    CHECK(held.tau_s == 0.0);
    CHECK(held.rho(1.0 / 30.0) == 0.0);
    CHECK(held.whitened_lag1 > 0.5);
  }
  // White errors: τ fitted at (or next to) 0, the scales right.
  const refine::DetectionErrorModel w = refine::fit_error_model({gauss_markov(rng, 3000, 0.0, 0.5, 2.0)});
  INFO("white: tau " << w.tau_s);
  CHECK(w.rho(1.0 / 30.0) < 0.05);
  CHECK(w.scale_translation == Approx(0.5).epsilon(0.05));
  CHECK(w.scale_rotation == Approx(2.0).epsilon(0.05));
  // A white remainder the model does not carry shows as a negative lag-1 correlation after whitening.
  const refine::DetectionErrorModel r = refine::fit_error_model({gauss_markov(rng, 3000, 3.0, 1.0, 1.0, 0.5)});
  INFO("with a white remainder: tau " << r.tau_s << ", whitened lag-1 " << r.whitened_lag1);
  CHECK(r.whitened_lag1 < -0.1);
  // Continuous symmetry: two rotation components carry information, the third is zero.
  refine::ErrorSeries c = gauss_markov(rng, 3000, 1.0, 1.0, 0.4);
  for (auto& y : c.y) y(5) = 0.0;
  c.rotation_dof = 2;
  CHECK(refine::fit_error_model({c}).scale_rotation == Approx(0.4).epsilon(0.05));
  // Nothing to fit.
  CHECK(refine::fit_error_model({}).used == 0);
}
