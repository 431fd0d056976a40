// roe simulate end to end: the roe binary (exit codes, --list-presets, identical bytes twice) and the
// committed datasets/sample being what scripts/make-sample.sh generates today.
#include <sys/wait.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "roe/app/simulate.hpp"

namespace fs = std::filesystem;
using namespace roe;

namespace {
std::string slurp(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// Runs a shell command; returns (exit code, stdout).
std::pair<int, std::string> run(const std::string& cmd) {
  std::string out;
  FILE* p = ::popen((cmd + " 2>/dev/null").c_str(), "r");
  REQUIRE(p != nullptr);
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
  const int status = ::pclose(p);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

fs::path temp_dir(const std::string& name) {
  const fs::path p =
      fs::temp_directory_path() / ("roe_test_simcli_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(p);
  return p;
}
}  // namespace

TEST_CASE("roe simulate: CLI exit codes, presets list and identical bytes", "[app][simulate][cli]") {
  const fs::path roe = ROE_BINARY;
  if (!fs::exists(roe)) {
    WARN("skipped: roe binary not built at " << roe);
    return;
  }
  const std::string bin = "'" + roe.string() + "'";
  const auto [rc_list, list] = run(bin + " --json simulate --list-presets");
  CHECK(rc_list == 0);
  const auto j = nlohmann::json::parse(list);
  CHECK(j.at("presets").size() == app::list_presets().size());

  const fs::path dir = temp_dir("cli");
  const std::string a = (dir / "a").string(), b = (dir / "b").string();
  const auto [rc_a, out_a] =
      run(bin + " --json simulate --preset paper-seq4 --seed 1 --duration 5 --out '" + a + "'");
  REQUIRE(rc_a == 0);
  const auto summary = nlohmann::json::parse(out_a);
  CHECK(summary.at("imu_samples") == 1001);
  CHECK(summary.at("objects").size() == 4);
  REQUIRE(run(bin + " -q simulate --preset paper-seq4 --seed 1 --duration 5 --out '" + b + "'").first == 0);
  for (const char* f : {"roe.json", "mav0/imu0/data.csv", "mav0/state_groundtruth_estimate0/data.csv",
                        "mav0/mocap0/data.csv", "mav0/cam0/data.csv", "detections/sim/detections.csv"})
    CHECK(slurp(dir / "a" / f) == slurp(dir / "b" / f));

  // Bad usage and bad input: exit code 2, nothing written.
  CHECK(run(bin + " simulate --preset paper-seq4 --out '" + a + "'").first == 2);  // not empty
  CHECK(run(bin + " simulate --preset nope --out '" + (dir / "c").string() + "'").first == 2);
  CHECK(run(bin + " simulate --preset paper-seq4 --seed -1 --out '" + (dir / "c").string() + "'").first == 2);
  CHECK(run(bin + " simulate --preset paper-seq4").first == 2);  // no --out
  std::ofstream(dir / "bad.json") << R"({"detection": {"outliers": 0.1}})";
  CHECK(run(bin + " simulate --config '" + (dir / "bad.json").string() + "' --out '" + (dir / "c").string() +
            "'")
            .first == 2);
  CHECK_FALSE(fs::exists(dir / "c"));
  fs::remove_all(dir);
}

TEST_CASE("datasets/sample is what scripts/make-sample.sh generates", "[app][simulate][sample]") {
  const fs::path sample = fs::path(ROE_SOURCE_DIR) / "datasets" / "sample";
  REQUIRE(fs::exists(sample / "roe.json"));
  const fs::path dir = temp_dir("sample");
  app::SimulateOptions opt;
  opt.preset = "paper-seq4";
  opt.seed = 1;
  opt.duration_s = 30.0;
  app::simulate(opt, dir / "sample");
  for (const auto& e : fs::recursive_directory_iterator(dir / "sample")) {
    if (!e.is_regular_file()) continue;
    const fs::path rel = fs::relative(e.path(), dir / "sample");
    if (rel == "detections/sim/meta.json") continue;  // names the roe version
    INFO(rel.string() << " differs from a fresh simulation: run `make sample` and commit datasets/sample");
    CHECK(slurp(e.path()) == slurp(sample / rel));
  }
  fs::remove_all(dir);
}
