// χ² quantile/CDF without Boost, against reference values (scipy.stats.chi2.ppf 1.10, 6 significant
// digits; k = 2 against the closed form −2 ln(1 − p)).
#include <catch2/catch.hpp>
#include <cmath>

#include "roe/math/distributions.hpp"

using roe::math::chi2_cdf;
using roe::math::chi2_quantile;
using roe::math::normal_quantile;

TEST_CASE("chi2 quantile matches table values", "[math][chi2]") {
  struct Row {
    double p, k, q;
  };
  const Row rows[] = {
      {0.95, 1, 3.841459},      {0.95, 2, 5.991465},   {0.95, 3, 7.814728},   {0.95, 6, 12.591587},
      {0.99, 6, 16.811894},     {0.997, 6, 19.804652}, {0.05, 6, 1.635383},   {0.025, 120, 91.572642},
      {0.975, 120, 152.211403}, {0.5, 10, 9.341818},   {0.999, 1, 10.827566}, {0.01, 2, 0.0201006717},
  };
  for (const auto& r : rows) {
    INFO("p = " << r.p << " k = " << r.k);
    CHECK(chi2_quantile(r.p, r.k) == Approx(r.q).epsilon(2e-7));
  }
}

TEST_CASE("chi2 cdf inverts the quantile", "[math][chi2]") {
  for (double k : {1.0, 2.0, 6.0, 12.0, 60.0, 600.0, 6000.0})
    for (double p : {1e-6, 0.01, 0.025, 0.5, 0.95, 0.975, 0.999999}) {
      INFO("p = " << p << " k = " << k);
      CHECK(chi2_cdf(chi2_quantile(p, k), k) == Approx(p).epsilon(1e-9));
    }
  // Closed form for k = 2: F(x) = 1 − exp(−x/2).
  for (double x : {0.1, 1.0, 5.0, 20.0})
    CHECK(chi2_cdf(x, 2.0) == Approx(1.0 - std::exp(-0.5 * x)).epsilon(1e-13));
}

TEST_CASE("normal quantile", "[math][chi2]") {
  CHECK(normal_quantile(0.975) == Approx(1.959963985).epsilon(1e-9));
  CHECK(normal_quantile(0.5) == Approx(0.0).margin(1e-12));
  CHECK(normal_quantile(1e-5) == Approx(-4.264890794).epsilon(1e-8));
}

// Both tails to 1e-13 against Python's statistics.NormalDist().inv_cdf (Wichura's AS241, ~1e-16),
// for the same double p: near p = 1 a Halley step on 0.5·erfc(−x/√2) − p would lose ~8 digits.
TEST_CASE("normal quantile: both tails to full precision, odd symmetry", "[math][chi2]") {
  struct Row {
    double p, x;
  };
  const Row rows[] = {
      {0.02, -2.0537489106318225},     {1e-9, -5.9978070150076865},    {1e-100, -21.27345356096532},
      {0.3, -0.5244005127080407},      {0.7, 0.5244005127080407},      {0.98, 2.053748910631822},
      {0.999, 3.090232306167813},      {0.999999, 4.753424308817089},  {0.999999999, 5.997807019601638},
  };
  for (const auto& r : rows) {
    INFO("p = " << r.p);
    CHECK(normal_quantile(r.p) == Approx(r.x).epsilon(1e-13));
  }
  for (double p : {0.6, 0.9, 0.97, 0.99, 0.9999})
    CHECK(normal_quantile(p) == Approx(-normal_quantile(1.0 - p)).epsilon(1e-14));
}
