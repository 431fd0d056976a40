// End-to-end checks of the roe executable's global behaviour: help, version, exit codes for bad usage.
#include <sys/wait.h>

#include <array>
#include <catch2/catch.hpp>
#include <cstdio>
#include <string>

namespace {
struct Result {
  int code;
  std::string out;
};
Result run(const std::string& args) {
  const std::string cmd = std::string(ROE_BINARY) + " " + args + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  REQUIRE(p != nullptr);
  std::string out;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) out.append(buf.data(), n);
  const int status = pclose(p);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}
}  // namespace

TEST_CASE("roe --version prints the version and exits 0", "[cli]") {
  const auto r = run("--version");
  CHECK(r.code == 0);
  CHECK(r.out.find("roe 0.") != std::string::npos);
}

TEST_CASE("roe --help lists the commands and exits 0", "[cli]") {
  const auto r = run("--help");
  CHECK(r.code == 0);
  CHECK(r.out.find("--json") != std::string::npos);
}

TEST_CASE("roe without a command or with an unknown one is bad usage (exit 2)", "[cli]") {
  CHECK(run("").code == 2);
  CHECK(run("no-such-command").code == 2);
  CHECK(run("--no-such-flag").code == 2);
}
