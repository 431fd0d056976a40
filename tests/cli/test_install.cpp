// `make install` (cmake --install) gives a roe that works from any folder with only PREFIX/bin on PATH:
// shipped configs by name, the image helpers from libexec, a relocated prefix (issue 26).
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "roe/app/run.hpp"
#include "roe/app/shipped_configs.hpp"
#include "roe/app/sweep.hpp"
#include "roe/core/error.hpp"
#include "support/test_util.hpp"

namespace fs = std::filesystem;

namespace {

using Shell = roe::test::RunResult;
Shell sh(const std::string& cmd) { return roe::test::run_shell(cmd); }

std::string slurp(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::string quoted(const fs::path& p) { return "'" + p.string() + "'"; }

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
  CHECK(fs::exists(prefix / "libexec/roe/roe-refine"));
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
  // refine runs in the helper roe-refine, found in the moved prefix's libexec.
  r = sh(env + "roe -q refine run-paper --out run-refined --no-covariance");
  INFO(r.out);
  CHECK(r.code == 0);
  CHECK(fs::exists(d / "work/run-refined/states.csv"));
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

TEST_CASE("run and sweep read the same bytes for a shipped config", "[cli][install][configs]") {
  using namespace roe::app;
  const auto names = shipped_config_names();
  REQUIRE(names == std::vector<std::string>{"default", "euroc-flight", "paper"});
  for (const std::string& name : names) {
    INFO(name);
    // The compiled bytes are the source file's.
    CHECK(shipped_config_text(name) == slurp(fs::path(ROE_SOURCE_DIR) / "configs" / (name + ".json")));
    // roe run: the name resolves to a path that stands for the shipped config, read from the compiled bytes.
    const fs::path resolved = resolve_run_config(name);
    CHECK(shipped_config_at(resolved) == name);
    const auto run_side = run_config_to_json(run_config_from_file(resolved));
    // roe sweep plan: "configs": [name].
    const nlohmann::json spec = {{"format", "roe-sweep-spec/1"},
                                 {"axes", {{"datasets", {"paper-seq4"}}, {"configs", {name}}}}};
    const SweepPlan plan = plan_sweep(spec, ".", "spec.json");
    REQUIRE(plan.size() == 1);
    CHECK(run_config_to_json(plan.job(0).content.run_config) == run_side);
    // and both equal the shipped text parsed on its own.
    CHECK(run_side == run_config_to_json(run_config_from_json(nlohmann::json::parse(shipped_config_text(name)), name)));
  }
  CHECK(shipped_config_at(fs::path(ROE_SOURCE_DIR) / "configs/sim/paper-seq4.json").empty());
  CHECK_THROWS_WITH(resolve_run_config("papr"), Catch::Contains("shipped: default, euroc-flight, paper"));
}

TEST_CASE("a roe without its share and libexec folders has its configs and answers the helpers' --help",
          "[cli][install]") {
  roe::test::TempDir d;
  // A half-installed prefix: bin/roe alone (a copied binary, or an install interrupted before the rest).
  fs::create_directories(d / "p/bin");
  fs::copy_file(ROE_BINARY, d / "p/bin/roe");
  fs::create_directories(d / "work");
  const std::string roe = "cd " + quoted(d / "work") + " && " + quoted(d / "p/bin/roe") + " ";
  auto r = sh(roe + "run --list-configs");
  CHECK(r.code == 0);
  for (const char* n : {"default", "paper", "euroc-flight"}) CHECK(r.out.find(n) != std::string::npos);
  r = sh(roe + "-q simulate --preset paper-seq4 --duration 4 --out seq");
  REQUIRE(r.code == 0);
  r = sh(roe + "-q run seq --config paper --out run");
  INFO(r.out);
  CHECK(r.code == 0);
  // run.json names where the shipped config belongs in this prefix.
  CHECK(slurp(d / "work/run/run.json").find((d / "p/share/roe/configs/paper.json").lexically_normal().string()) !=
        std::string::npos);
  // The forwarded commands: --help answered by roe itself (exit 0), a real call says how to add the helper.
  for (const std::string cmd : {"infer", "import realsense", "refine"}) {
    INFO(cmd);
    r = sh(roe + cmd + " --help");
    CHECK(r.code == 0);
    CHECK(r.out.find("Usage: roe " + cmd) != std::string::npos);
    CHECK(r.out.find("not installed") != std::string::npos);
  }
  CHECK(sh(roe + "infer --help").out.find("--model") != std::string::npos);
  r = sh(roe + "infer seq --model nowhere");
  CHECK(r.code == 3);
  CHECK(r.out.find("roe-infer, which is not installed") != std::string::npos);
  CHECK(r.out.find("cmake --build BUILD --target roe-infer") != std::string::npos);
  CHECK(r.out.find("internal error") == std::string::npos);

  // An installed copy that differs from the compiled config is refused, not silently used.
  fs::create_directories(d / "p/share/roe/configs");
  std::ofstream(d / "p/share/roe/configs/paper.json") << "{\"description\": \"edited\"}\n";
  r = sh(roe + "-q --force run seq --config paper --out run");
  CHECK(r.code == 2);
  CHECK(r.out.find("differs from the one compiled into this roe") != std::string::npos);
}

TEST_CASE("cmake --install of a build without the helpers installs the rest and names them, without roe refuses",
          "[cli][install]") {
  if (sh("command -v cmake && command -v c++").code != 0) {
    WARN("skipped: cmake or c++ is not on PATH");
    return;
  }
  // A project shaped like roe's install section, with the real install helpers (cmake/install-check.cmake):
  // `main` and two helpers, of which only `main` is built (as `make demo` builds roe alone).
  roe::test::TempDir d;
  fs::create_directories(d / "src/configs");
  std::ofstream(d / "src/main.cpp") << "int main() { return 0; }\n";
  std::ofstream(d / "src/configs/a.json") << "{}\n";
  std::ofstream(d / "src/CMakeLists.txt")
      << "cmake_minimum_required(VERSION 3.16)\nproject(t CXX)\n"
      << "foreach(t main helper-a helper-b)\n  add_executable(${t} main.cpp)\nendforeach()\n"
      << "include(" << (fs::path(ROE_SOURCE_DIR) / "cmake/install-check.cmake").string() << ")\n"
      << "roe_install_check(main helper-a helper-b)\n"
      << "install(TARGETS main RUNTIME DESTINATION bin)\n"
      << "install(TARGETS helper-a helper-b RUNTIME DESTINATION libexec/t OPTIONAL)\n"
      << "install(DIRECTORY ${CMAKE_SOURCE_DIR}/configs/ DESTINATION share/t/configs)\n"
      << "roe_install_report(helper-a \"t import a\" helper-b \"t b\")\n";
  const std::string b = quoted(d / "build");
  auto r = sh("cmake -S " + quoted(d / "src") + " -B " + b + " >/dev/null");
  REQUIRE(r.code == 0);
  // Nothing built: refused before copying anything.
  r = sh("cmake --install " + b + " --prefix " + quoted(d / "p0"));
  CHECK(r.code != 0);
  {
    // CMake wraps its messages at any width (a long temp path moves the breaks): compare with the line
    // breaks and their indentation folded into single spaces.
    std::string flat;
    for (char c : r.out) {
      const bool space = c == '\n' || c == ' ';
      if (!(space && !flat.empty() && flat.back() == ' ')) flat += space ? ' ' : c;
    }
    INFO(flat);
    CHECK(flat.find("is not built; nothing was installed") != std::string::npos);
    CHECK(flat.find("--target main") != std::string::npos);
  }
  CHECK_FALSE(fs::exists(d / "p0"));
  // main alone: installed with the configs; the missing helpers named with their commands; exit 0.
  REQUIRE(sh("cmake --build " + b + " --target main >/dev/null").code == 0);
  r = sh("cmake --install " + b + " --prefix " + quoted(d / "p1"));
  INFO(r.out);
  CHECK(r.code == 0);
  CHECK(fs::exists(d / "p1/bin/main"));
  CHECK(fs::exists(d / "p1/share/t/configs/a.json"));
  CHECK_FALSE(fs::exists(d / "p1/libexec/t/helper-a"));
  CHECK(r.out.find("helper-a (t import a)") != std::string::npos);
  CHECK(r.out.find("helper-b (t b)") != std::string::npos);
  // Everything built: no warning.
  REQUIRE(sh("cmake --build " + b + " >/dev/null").code == 0);
  r = sh("cmake --install " + b + " --prefix " + quoted(d / "p2"));
  CHECK(r.code == 0);
  CHECK(fs::exists(d / "p2/libexec/t/helper-b"));
  CHECK(r.out.find("not built") == std::string::npos);
}
