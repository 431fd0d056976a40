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

TEST_CASE("bad usage says 'roe: error:' like every other error, and names the command's help", "[cli]") {
  // stderr merged into out; nothing else is printed.
  auto r = run_roe("eval --max-dt abc x");
  CHECK(r.code == 2);
  CHECK(r.out.rfind("roe: error: ", 0) == 0);
  CHECK(r.out.find("--max-dt") != std::string::npos);
  CHECK(r.out.find("(see roe eval --help)") != std::string::npos);
  r = run_roe("import mocap --format nope a --into b");
  CHECK(r.code == 2);
  CHECK(r.out.rfind("roe: error: --format", 0) == 0);
  CHECK(r.out.find("(see roe import mocap --help)") != std::string::npos);
  r = run_roe("--no-such-flag");
  CHECK(r.out.rfind("roe: error: ", 0) == 0);
  CHECK(r.out.find("(see roe --help)") != std::string::npos);
}
