// `make install` (cmake --install) gives a roe that works from any folder with only PREFIX/bin on PATH:
// shipped configs by name, the image helpers from libexec, a relocated prefix (issue 26).
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "support/test_util.hpp"

namespace fs = std::filesystem;

namespace {

using Shell = roe::test::RunResult;
Shell sh(const std::string& cmd) { return roe::test::run_shell(cmd); }

std::string slurp(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

TEST_CASE("an installed roe runs the main path from an empty folder with only its bin on PATH",
          "[cli][install]") {
  if (sh("command -v cmake").code != 0) {
    WARN("skipped: cmake is not on PATH");
    return;
  }
  roe::test::TempDir d;
  const fs::path build = fs::path(ROE_BINARY).parent_path();
  const fs::path prefix = d / "prefix";
  auto r = sh("cmake --install '" + build.string() + "' --prefix '" + prefix.string() + "'");
  INFO(r.out);
  REQUIRE(r.code == 0);
  CHECK(fs::exists(prefix / "bin/roe"));
  CHECK(fs::exists(prefix / "libexec/roe/roe-infer"));
  CHECK(fs::exists(prefix / "share/roe/configs/paper.json"));

  // Relocated, as a user moving the folder would: nothing may refer to the build tree or the old prefix.
  const fs::path moved = d / "elsewhere";
  fs::rename(prefix, moved);
  fs::create_directories(d / "work");
  const std::string env = "cd '" + (d / "work").string() + "' && env -i HOME='" + d.path.string() +
                          "' PATH='" + (moved / "bin").string() + ":/usr/bin:/bin' ";
  r = sh(env + "roe -q simulate --preset paper-seq4 --duration 8 --out seq");
  INFO(r.out);
  REQUIRE(r.code == 0);
  r = sh(env + "roe -q run seq --config paper --out run-paper");
  INFO(r.out);
  CHECK(r.code == 0);
  // run.json names the shipped file the name resolved to, inside the moved prefix.
  const std::string run_json = slurp(d / "work/run-paper/run.json");
  CHECK(run_json.find((moved / "share/roe/configs/paper.json").string()) != std::string::npos);
  r = sh(env + "roe -q eval run-paper --gt seq --out eval");
  CHECK(r.code == 0);
  CHECK(fs::exists(d / "work/eval/report.json"));
  r = sh(env + "roe run --list-configs");
  CHECK(r.code == 0);
  CHECK(r.out.find("euroc-flight") != std::string::npos);
  CHECK(r.out.find("default") != std::string::npos);
  r = sh(env + "roe infer --help");
  CHECK(r.code == 0);
  CHECK(r.out.find("--model") != std::string::npos);
  // A name that is neither a file nor a shipped config names both possibilities.
  r = sh(env + "roe run seq --config papr --out x");
  CHECK(r.code == 2);
  CHECK(r.out.find("'papr' is neither a file nor a shipped config (shipped: default, euroc-flight, paper)") !=
        std::string::npos);
}

TEST_CASE("a --config path that exists wins over the shipped name", "[cli][install]") {
  roe::test::TempDir d;
  const std::string ds = (d / "ds").string();
  REQUIRE(roe::test::run_roe("-q simulate --preset paper-seq4 --duration 3 --out " + ds).code == 0);
  // A folder named `paper` in the current folder: taken as the path, so it is an error (not a JSON file).
  fs::create_directories(d / "paper");
  const auto r = sh("cd '" + d.path.string() + "' && '" + std::string(ROE_BINARY) + "' run ds --config paper --out r");
  CHECK(r.code == 2);
  CHECK(r.out.find("share/roe") == std::string::npos);
}
