#include <catch2/catch.hpp>
#include <limits>

#include "roe/core/error.hpp"
#include "roe/core/types.hpp"

using namespace roe;

TEST_CASE("core: ErrorContext::prefix formatting", "[core][error]") {
  CHECK(ErrorContext().prefix().empty());
  CHECK(ErrorContext("a.csv").prefix() == "a.csv: ");
  CHECK(ErrorContext("a.csv", 3).prefix() == "a.csv:3: ");
  CHECK(ErrorContext("a.csv", 3, 4).prefix() == "a.csv:3:4: ");
  CHECK(ErrorContext("a.csv", 3, 4, "x").prefix() == "a.csv:3:4: 'x': ");
  CHECK(ErrorContext("roe.json", 0, 0, "camera.fx").prefix() == "roe.json: 'camera.fx': ");
  CHECK(ErrorContext("", 7).prefix() == "line 7: ");
  CHECK(ErrorContext("", 7, 2).prefix() == "line 7:2: ");
  CHECK(ErrorContext("", 0, 0, "k").prefix() == "'k': ");
  // A column without a line is not shown (it would be ambiguous).
  CHECK(ErrorContext("a.csv", 0, 4).prefix() == "a.csv: ");
}

TEST_CASE("core: errors carry context and the hierarchy maps to exit codes", "[core][error]") {
  const InputError e("bad value", {"f.csv", 2, 5, "tx"});
  CHECK(std::string(e.what()) == "f.csv:2:5: 'tx': bad value");
  CHECK(e.bare_message() == "bad value");
  CHECK(e.context().line == 2);
  CHECK(e.context().column == 5);
  // ConfigError is an InputError (exit 2); NumericError a DataError (exit 1).
  CHECK_THROWS_AS(throw ConfigError("x"), InputError);
  CHECK_THROWS_AS(throw NumericError("x"), DataError);
  CHECK_THROWS_AS(throw DataError("x"), Error);
  CHECK(std::string(Error("plain").what()) == "plain");
  try {
    ROE_CHECK(1 + 1 == 3, "arithmetic");
    FAIL("ROE_CHECK did not throw");
  } catch (const InternalError& ie) {
    CHECK(std::string(ie.what()).find("check failed: 1 + 1 == 3: arithmetic") == 0);
    CHECK(std::string(ie.what()).find("test_error_types.cpp") != std::string::npos);
  }
  CHECK_NOTHROW([] { ROE_CHECK(true, "never"); }());
}

TEST_CASE("core: seconds <-> nanoseconds", "[core][time]") {
  CHECK(to_seconds(1'500'000'000LL) == 1.5);
  CHECK(to_seconds(0) == 0.0);
  CHECK(from_seconds(1.5) == 1'500'000'000LL);
  CHECK(from_seconds(-2.25) == -2'250'000'000LL);
  // Rounded to the nearest nanosecond, halves away from zero (llround).
  CHECK(from_seconds(1.4e-9) == 1);
  CHECK(from_seconds(1.6e-9) == 2);
  CHECK(from_seconds(2.5e-9) == 3);
  CHECK(from_seconds(-2.5e-9) == -3);
  CHECK(from_seconds(0.999999999) == 999'999'999LL);
  CHECK(from_seconds(1e-10) == 0);
  // Stamps below 2^53 ns (~104 days) survive the round trip exactly...
  for (Timestamp t : {Timestamp{1}, Timestamp{123'456'789}, Timestamp{86'400'000'000'001LL},
                      Timestamp{999'999'999'999'999LL}})
    CHECK(from_seconds(to_seconds(t)) == t);
  // ...epoch stamps (~1.4e18 ns) only to the double's resolution (~2^-22 s ≈ 238 ns): keep ns
  // integers internally and use dt_seconds for differences.
  const Timestamp epoch = 1403715523912140000LL;
  CHECK(std::llabs(from_seconds(to_seconds(epoch)) - epoch) <= 256);
  CHECK(dt_seconds(epoch, epoch + 5'000'000) == 0.005);
  CHECK(dt_seconds(epoch + 1, epoch) == -1e-9);
}
