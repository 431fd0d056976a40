// roe import poet's uncertainty keys (io/poet_results): PoET's aleatoric log-variances and a 6x6
// covariance, against fixtures written by Python's json module (tests/fixtures/poet_uncertainty/make_fixtures.py)
// with the expected σ computed there.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "roe/core/error.hpp"
#include "roe/io/output.hpp"
#include "roe/io/poet_results.hpp"

namespace fs = std::filesystem;
using namespace roe;

namespace {

const fs::path kDir = fs::path(ROE_SOURCE_DIR) / "tests/fixtures/poet_uncertainty";

nlohmann::json expected() { return nlohmann::json::parse(io::read_file(kDir / "expected.json")); }

const io::PoetRawDetection& find(const io::PoetResults& r, const std::string& id, int index) {
  for (const auto& img : r.images)
    if (img.id == id)
      for (const auto& d : img.detections)
        if (d.index == index) return d;
  FAIL("no detection " << id << "." << index);
  throw 0;
}

}  // namespace

TEST_CASE("PoET aleatoric log-variances and 6x6 covariances become camera-frame sigmas", "[poet_results][uncertainty]") {
  const io::PoetResults r = io::read_poet_results(kDir / "good.json");
  const auto ex = expected()["good"];
  using U = io::PoetRawDetection::Uncertainty;
  for (const auto& [key, id, index, kind] : {std::tuple{"1000.0", "1000", 0, U::kLogVariance},
                                             std::tuple{"1000.1", "1000", 1, U::kLogVariance},
                                             std::tuple{"2000.0", "2000", 0, U::kCovariance}}) {
    INFO(key);
    const auto& d = find(r, id, index);
    CHECK(d.uncertainty == kind);
    REQUIRE(d.sigma.has_value());
    for (int i = 0; i < 6; ++i) CHECK((*d.sigma)[i] == Approx(ex[key][i].get<double>()).epsilon(1e-12));
  }
  // The covariance's correlations are what the per-axis columns drop; the value is Python's.
  CHECK(find(r, "2000", 0).max_abs_correlation == Approx(ex["max_abs_correlation"].get<double>()).epsilon(1e-9));
  CHECK(find(r, "1000", 0).max_abs_correlation == 0.0);
  // No uncertainty keys: no sigma.
  CHECK(ex["2000.1"].is_null());
  CHECK_FALSE(find(r, "2000", 1).sigma.has_value());
  CHECK(find(r, "2000", 1).uncertainty == U::kNone);
  // A non-finite pose is dropped later; its NaN log-variances are not an error and give no sigma.
  const auto& nan = find(r, "3000", 0);
  CHECK_FALSE(nan.finite);
  CHECK_FALSE(nan.sigma.has_value());
}

TEST_CASE("malformed uncertainty values are errors naming the file, key path, line and column", "[poet_results][uncertainty]") {
  const auto bad = expected()["bad"];
  REQUIRE(bad.size() == 10);
  for (const auto& b : bad) {
    const fs::path file = kDir / b["file"].get<std::string>();
    INFO(file.string());
    try {
      (void)io::read_poet_results(file);
      FAIL("no error");
    } catch (const InputError& e) {
      INFO(e.what());
      CHECK(e.context().file == file.string());
      CHECK(e.context().key == b["key"].get<std::string>());
      CHECK(e.context().line == b["line"].get<std::int64_t>());
      CHECK(e.context().column == b["column"].get<std::int64_t>());
      CHECK_THAT(e.bare_message(), Catch::Contains(b["message"].get<std::string>()));
    }
  }
}

TEST_CASE("uncertainty edge cases: float32 asymmetry, a singular but PSD covariance, exact σ of s = 0", "[poet_results][uncertainty]") {
  const std::string head = "{\"5\": {\"0\": {\"t\": [0, 0, 1], \"rot\": [[1,0,0],[0,1,0],[0,0,1]], \"class\": 1, ";
  // float32 printed as float64: off-diagonal pairs differing in the 7th digit are symmetric enough.
  std::string cov = "[";
  for (int i = 0; i < 6; ++i) {
    cov += i ? ",[" : "[";
    for (int j = 0; j < 6; ++j) {
      const double v = i == j ? 0.04 : (i < j ? 0.0100000001 : 0.0100000003);  // ρ = 0.25
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.10g", v);
      cov += (j ? "," : "") + std::string(buf);
    }
    cov += "]";
  }
  cov += "]";
  auto r = io::parse_poet_results(head + "\"cov\": " + cov + "}}}", "x.json");
  REQUIRE(r.images[0].detections[0].sigma);
  CHECK((*r.images[0].detections[0].sigma)[3] == Approx(0.2));
  CHECK(r.images[0].detections[0].max_abs_correlation == Approx(0.25).epsilon(1e-6));
  // Fully correlated (rank 1) is positive semi-definite: accepted.
  std::string one = "[";
  for (int i = 0; i < 6; ++i) one += std::string(i ? "," : "") + "[1,1,1,1,1,1]";
  one += "]";
  r = io::parse_poet_results(head + "\"cov\": " + one + "}}}", "x.json");
  CHECK(r.images[0].detections[0].max_abs_correlation == Approx(1.0));
  // s = 0 → σ = 1 exactly; s = 2 log 0.1 → σ = 0.1.
  r = io::parse_poet_results(head + "\"t_aleatoric\": [0, 0, 0], \"rot_aleatoric\": [" + std::to_string(2 * std::log(0.1)) +
                                 ", 0, 0]}}}",
                             "x.json");
  CHECK((*r.images[0].detections[0].sigma)[0] == 1.0);
  CHECK((*r.images[0].detections[0].sigma)[3] == Approx(0.1).epsilon(1e-6));
  // A string where a number belongs names the element.
  try {
    (void)io::parse_poet_results(head + "\"t_aleatoric\": [0, \"x\", 0], \"rot_aleatoric\": [0, 0, 0]}}}", "x.json");
    FAIL("no error");
  } catch (const InputError& e) {
    CHECK(e.context().key == "5.0.t_aleatoric[1]");
  }
}
