// End-to-end checks of the roe executable's global behaviour: help, version, exit codes for bad usage.
#include <catch2/catch.hpp>
#include <string>

#include "support/test_util.hpp"

using roe::test::run_roe;

TEST_CASE("roe --version prints the version and exits 0", "[cli]") {
  const auto r = run_roe("--version");
  CHECK(r.code == 0);
  CHECK(r.out.find("roe 0.") != std::string::npos);
}

TEST_CASE("roe --help lists the commands and exits 0", "[cli]") {
  const auto r = run_roe("--help");
  CHECK(r.code == 0);
  CHECK(r.out.find("--json") != std::string::npos);
}

TEST_CASE("roe without a command or with an unknown one is bad usage (exit 2)", "[cli]") {
  CHECK(run_roe("").code == 2);
  CHECK(run_roe("no-such-command").code == 2);
  CHECK(run_roe("--no-such-flag").code == 2);
}
