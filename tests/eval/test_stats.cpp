// Sweep statistics against scipy: t quantiles, the mean's t CI, Wilcoxon signed-rank p-values
// (tests/eval/data/stats_reference.json, made by gen_stats_reference.py with python3-scipy).
#include <catch2/catch.hpp>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "roe/core/error.hpp"
#include "roe/eval/stats.hpp"
#include "roe/math/distributions.hpp"

using namespace roe::eval;
using roe::math::student_t_cdf;
using roe::math::student_t_quantile;

namespace {
nlohmann::json reference() {
  std::ifstream in(std::string(ROE_SOURCE_DIR) + "/tests/eval/data/stats_reference.json");
  REQUIRE(in.good());
  return nlohmann::json::parse(in);
}
}  // namespace

TEST_CASE("Student t quantiles match scipy.stats.t.ppf", "[eval][stats]") {
  const auto ref = reference();
  REQUIRE(ref["t_quantiles"].size() >= 50);
  for (const auto& q : ref["t_quantiles"]) {
    const double p = q["p"], dof = q["dof"], t = q["t"];
    INFO("p " << p << " dof " << dof);
    // scipy.stats.t.ppf itself is accurate to ~1e-9 relative (its betainc agrees with ours to 1e-15)
    CHECK(student_t_quantile(p, dof) == Approx(t).epsilon(2e-8));
    CHECK(student_t_cdf(t, dof) == Approx(p).epsilon(2e-8));
  }
  CHECK_THROWS_AS(student_t_quantile(1.0, 3), roe::InternalError);
}

TEST_CASE("mean, std and the t confidence interval match scipy", "[eval][stats]") {
  for (const auto& s : reference()["samples"]) {
    const auto v = s["values"].get<std::vector<double>>();
    const SampleSummary r = summarize_sample(v, s["confidence"].get<double>());
    INFO("n " << v.size());
    CHECK(r.n == v.size());
    CHECK(r.mean == Approx(s["mean"].get<double>()).epsilon(1e-12));
    CHECK(r.std == Approx(s["std"].get<double>()).epsilon(1e-10));  // population (numpy ddof 0)
    CHECK(r.std_sample == Approx(s["std_sample"].get<double>()).epsilon(1e-10));  // ddof 1
    CHECK(r.ci_low == Approx(s["ci_low"].get<double>()).epsilon(1e-8));
    CHECK(r.ci_high == Approx(s["ci_high"].get<double>()).epsilon(1e-8));
  }
  const SampleSummary one = summarize_sample({0.5});
  CHECK(one.mean == 0.5);
  CHECK(one.std == 0.0);  // population std of one value
  CHECK(std::isnan(one.std_sample));
  CHECK(std::isnan(one.ci_low));
  CHECK(summarize_sample({}).n == 0);
}

TEST_CASE("Wilcoxon signed-rank p-values match scipy.stats.wilcoxon's defaults", "[eval][stats]") {
  const auto ref = reference();
  REQUIRE(ref["wilcoxon"].size() == 7);
  for (const auto& w : ref["wilcoxon"]) {
    const auto a = w["a"].get<std::vector<double>>(), b = w["b"].get<std::vector<double>>();
    const PairedComparison c = compare_paired(a, b);
    INFO(w["name"].get<std::string>());
    CHECK(c.wilcoxon.method == w["method"].get<std::string>());
    CHECK(c.wilcoxon.statistic == Approx(w["statistic"].get<double>()));
    CHECK(c.wilcoxon.p_value == Approx(w["p_value"].get<double>()).epsilon(1e-10));
    CHECK(c.difference.n == a.size());
  }
  // Every difference zero: no test (scipy raises), reported as NaN.
  const WilcoxonResult none = wilcoxon_signed_rank({0.0, 0.0, 0.0});
  CHECK(std::isnan(none.p_value));
  CHECK(none.method == "none");
  CHECK_THROWS_AS(compare_paired({1.0}, {1.0, 2.0}), roe::InternalError);
}
