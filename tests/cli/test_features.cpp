// The optional libraries (cmake/features.cmake, issue 38): `roe --version` says which this roe has, and a
// roe without them still offers their commands but refuses them with the package and the CMake option.
// ROE_BINARY_WITHOUT_OPTIONAL is roe's CLI compiled as a build without OpenCV, Ceres and LibTorch
// (cmake/extra-features.cmake); ROE_BUILT_* are what this build's configure step found.
#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>
#include <string>

#include "support/test_util.hpp"

namespace {

roe::test::RunResult without(const std::string& args, bool merge_stderr = true) {
  return roe::test::run_shell(std::string(ROE_BINARY_WITHOUT_OPTIONAL) + " " + args +
                              (merge_stderr ? "" : " 2>/dev/null"));
}

bool has(const std::string& text, const std::string& what) { return text.find(what) != std::string::npos; }

/// The line of `library` in `roe --version`'s listing, or "".
std::string line_of(const std::string& version, const std::string& library) {
  const auto at = version.find("\n  " + library + " ");
  if (at == std::string::npos) return "";
  return version.substr(at + 1, version.find('\n', at + 1) - at - 1);
}

}  // namespace

TEST_CASE("roe --version lists the optional libraries this build has", "[cli][features]") {
  const auto r = roe::test::run_roe("--version");
  REQUIRE(r.code == 0);
  CHECK(r.out.rfind("roe 0.", 0) == 0);
  const struct {
    const char* library;
    bool built;
    const char* commands;
  } expected[] = {{"OpenCV", ROE_BUILT_OPENCV != 0, "roe import realsense, roe infer"},
                  {"Ceres Solver", ROE_BUILT_CERES != 0, "roe refine"},
                  {"LibTorch", ROE_BUILT_TORCH != 0, "roe infer (the PoET pose head)"}};
  const auto json = nlohmann::json::parse(roe::test::run_roe("--json --version", false).out);
  for (const auto& e : expected) {
    INFO(e.library);
    const std::string line = line_of(r.out, e.library);
    REQUIRE(!line.empty());
    CHECK(has(line, e.built ? " yes " : " no "));
    CHECK(has(line, e.commands));
  }
  CHECK(json["features"] == nlohmann::json({{"opencv", ROE_BUILT_OPENCV != 0},
                                            {"ceres", ROE_BUILT_CERES != 0},
                                            {"torch", ROE_BUILT_TORCH != 0}}));
}

TEST_CASE("a roe without OpenCV, Ceres and LibTorch says so in --version", "[cli][features]") {
  const auto r = without("--version");
  REQUIRE(r.code == 0);
  CHECK(has(line_of(r.out, "OpenCV"), "no   roe import realsense, roe infer (needs libopencv-dev, -DROE_WITH_OPENCV=ON)"));
  CHECK(has(line_of(r.out, "Ceres Solver"), "no   roe refine (needs libceres-dev, -DROE_WITH_CERES=ON)"));
  CHECK(has(line_of(r.out, "LibTorch"), "no   roe infer (the PoET pose head) (needs libtorch-dev"));
  const auto json = nlohmann::json::parse(without("--json --version", false).out);
  CHECK(json["features"] == nlohmann::json({{"opencv", false}, {"ceres", false}, {"torch", false}}));
}

TEST_CASE("a roe without Ceres offers roe refine and refuses it with exit 2, naming libceres-dev",
          "[cli][features]") {
  roe::test::TempDir d;
  const auto help = without("refine --help");
  CHECK(help.code == 0);
  CHECK(has(help.out, "--loss"));
  // Refused before anything is read or written: the run folder does not even exist.
  const auto r = without("refine '" + (d / "no-such-run").string() + "' --out '" + (d / "out").string() + "'");
  CHECK(r.code == 2);
  CHECK(has(r.out, "roe: error: roe refine needs Ceres Solver, and this roe was built without it."));
  CHECK(has(r.out, "Install libceres-dev"));
  CHECK(has(r.out, "-DROE_WITH_CERES=ON"));
  CHECK(!std::filesystem::exists(d / "out"));
  const auto j = without("--json refine '" + (d / "x").string() + "' --out '" + (d / "out").string() + "'", false);
  CHECK(j.code == 2);
  const auto doc = nlohmann::json::parse(j.out);
  CHECK(doc["exit_code"] == 2);
  CHECK(has(doc["error"]["message"].get<std::string>(), "libceres-dev"));
}

TEST_CASE("a roe without Ceres refuses roe run's batch estimator with exit 2 and runs its default", "[cli][features]") {
  roe::test::TempDir d;
  // Refused from the effective config, before the dataset is read or the run folder made.
  auto r = without("run '" + (d / "no-such-ds").string() + "' --estimator batch --out '" + (d / "out").string() + "'");
  CHECK(r.code == 2);
  CHECK(has(r.out, "roe: error: roe run --estimator batch needs Ceres Solver, and this roe was built without it."));
  CHECK(has(r.out, "Install libceres-dev"));
  CHECK(!std::filesystem::exists(d / "out"));
  const std::string cfg = d.write("batch.json", R"({"estimator": "batch"})").string();
  r = without("run '" + (d / "no-such-ds").string() + "' --config '" + cfg + "' --out '" + (d / "out").string() + "'");
  CHECK(r.code == 2);
  CHECK(has(r.out, "(" + cfg + ") needs Ceres Solver"));
  // --estimator over the config: the smoother needs nothing optional, and roe's default is the smoother.
  REQUIRE(without("-q simulate --preset matched --seed 1 --duration 3 --out '" + (d / "ds").string() + "'").code == 0);
  r = without("-q run '" + (d / "ds").string() + "' --config '" + cfg + "' --estimator smoother --out '" +
              (d / "run").string() + "'");
  CHECK(r.code == 0);
  CHECK(std::filesystem::exists(d / "run" / "states_filter.csv"));
  CHECK(without("-q run '" + (d / "ds").string() + "' --out '" + (d / "run2").string() + "'").code == 0);
}

TEST_CASE("a roe without OpenCV refuses import realsense and infer with exit 2, naming libopencv-dev",
          "[cli][features]") {
  roe::test::TempDir d;
  for (const std::string cmd : {"import realsense", "infer"}) {
    INFO(cmd);
    const std::string args = cmd == "infer" ? "infer '" + (d / "ds").string() + "' --model '" + (d / "m").string() + "'"
                                            : "import realsense '" + (d / "a.bag").string() + "' --out '" +
                                                  (d / "ds").string() + "'";
    const auto r = without(args);
    CHECK(r.code == 2);
    CHECK(has(r.out, "roe: error: roe " + cmd + " needs OpenCV, and this roe was built without it."));
    CHECK(has(r.out, "Install libopencv-dev"));
    CHECK(has(r.out, "-DROE_WITH_OPENCV=ON"));
    CHECK(!has(r.out, "helper"));  // not the advice of an installation that lacks its helpers
    const auto help = without(cmd + " --help");
    CHECK(help.code == 0);
    CHECK(has(help.out, "Usage: roe " + cmd));
    CHECK(has(help.out, "libopencv-dev"));
  }
  CHECK(!std::filesystem::exists(d / "ds"));
  // The commands are still listed.
  const auto help = without("--help");
  CHECK(has(help.out, "infer"));
  CHECK(has(help.out, "refine"));
}
