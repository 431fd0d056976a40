// A real single-node Slurm (tests/cli/slurm_local.sh: Debian slurm-wlm + munge, started here as root,
// stopped by pid files) runs a sweep from `roe sweep emit slurm`'s array script. One array task is
// killed (SIGKILL) in the middle of its job; resubmitting the same script finishes the sweep without
// redoing the jobs that were done. Skipped, saying why, where Slurm cannot start.
#include <catch2/catch.hpp>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "support/test_util.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string q(const fs::path& p) { return "'" + p.string() + "'"; }

std::string sh(const std::string& cmd, int* rc = nullptr) {
  FILE* p = popen((cmd + " 2>&1").c_str(), "r");
  std::string out;
  char buf[4096];
  std::size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
  const int st = pclose(p);
  if (rc) *rc = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return out;
}

struct LocalSlurm {
  fs::path dir;
  std::string env;  ///< "SLURM_CONF=... " prefix for the client commands
  ~LocalSlurm() { sh("bash " + q(fs::path(ROE_SOURCE_DIR) / "tests/cli/slurm_local.sh") + " stop " + q(dir)); }
};

json status_of(const fs::path& sweep) {
  const auto r = roe::test::run_roe("sweep status " + q(sweep) + " --json", false);
  REQUIRE(r.code == 0);
  return json::parse(r.out);
}

/// Waits until `pred` holds (polling every 200 ms) or `seconds` pass.
template <typename Pred>
bool wait_for(Pred pred, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  return pred();
}

}  // namespace

TEST_CASE("roe sweep on a real Slurm: array job, a task killed mid-job, resumed by resubmission",
          "[cli][sweep][slurm]") {
  roe::test::TempDir tmp("roe_sweep_slurm");
  fs::create_directories(tmp / "slurm");
  LocalSlurm slurm{tmp / "slurm", ""};
  int rc = 0;
  const std::string started =
      sh("bash " + q(fs::path(ROE_SOURCE_DIR) / "tests/cli/slurm_local.sh") + " start " + q(slurm.dir), &rc);
  if (rc == 77) {
    WARN("skipped: " << started);
    return;
  }
  REQUIRE(rc == 0);
  slurm.env = "SLURM_CONF=" + q(slurm.dir / "slurm.conf") + " ";

  // Three short jobs and one long one (index 3), the one killed.
  const fs::path spec = tmp.write("spec.json", R"({"axes": [
    {"datasets": [{"preset": "paper-seq1", "duration_s": 5}], "seeds": [1, 2, 3]},
    {"datasets": [{"preset": "paper-seq4", "duration_s": 60}], "seeds": [7]}]})");
  const fs::path sweep = tmp / "sweep";
  REQUIRE(roe::test::run_roe("sweep plan " + q(spec) + " --out " + q(sweep) + " -q").code == 0);
  std::string long_id;
  {
    std::ifstream in(sweep / "jobs.jsonl");
    std::string line;
    while (std::getline(in, line)) long_id = json::parse(line)["id"];
  }
  const fs::path script = tmp / "sweep.sbatch";
  REQUIRE(roe::test::run_roe("sweep emit slurm " + q(sweep) + " -j 2 --partition test --mem 100M --time 00:05:00 --out " +
                             q(script) + " -q")
              .code == 0);

  const std::string submitted = sh(slurm.env + "sbatch --parsable " + q(script), &rc);
  REQUIRE(rc == 0);
  const std::string job = submitted.substr(0, submitted.find_first_of(";\n"));
  // The long job is under way (its work folder exists and it has no result yet): kill its task hard.
  const fs::path work = sweep / "work" / long_id;
  REQUIRE(wait_for([&] { return fs::exists(work / "run") || fs::exists(work / "dataset"); }, 120.0));
  sh(slurm.env + "scancel --signal=KILL " + job + "_3", &rc);
  CHECK(rc == 0);
  REQUIRE(wait_for([&] { return sh(slurm.env + "squeue -h -j " + job).find(job) == std::string::npos; }, 180.0));
  json st = status_of(sweep);
  CHECK(st["done"] == 3);
  CHECK(st["pending"] == 1);
  CHECK(!fs::exists(sweep / "jobs" / long_id));
  std::map<std::string, std::string> before;
  for (const auto& e : fs::directory_iterator(sweep / "jobs")) {
    std::ifstream in(e.path() / "result.json");
    std::stringstream s;
    s << in.rdbuf();
    before[e.path().filename().string()] = s.str();
  }

  // Resubmission: the three done jobs are skipped (their results untouched), the killed one is redone.
  const std::string again = sh(slurm.env + "sbatch --parsable " + q(script), &rc);
  REQUIRE(rc == 0);
  const std::string job2 = again.substr(0, again.find_first_of(";\n"));
  REQUIRE(wait_for([&] { return sh(slurm.env + "squeue -h -j " + job2).find(job2) == std::string::npos; }, 300.0));
  st = status_of(sweep);
  CHECK(st["done"] == 4);
  CHECK(st["pending"] == 0);
  for (const auto& [id, text] : before) {
    std::ifstream in(sweep / "jobs" / id / "result.json");
    std::stringstream s;
    s << in.rdbuf();
    CHECK(s.str() == text);
  }
  CHECK(fs::exists(sweep / "logs"));
}
