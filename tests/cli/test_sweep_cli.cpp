// End-to-end: roe sweep plan | run | status | emit | aggregate on short simulated sequences. Sharding 4
// ways with tasks killed at random and resumed gives the same job folders as one uninterrupted run
// (timings and the sweep folder's own path aside); a failing job records its exit code and the sweep
// goes on; a held job lock keeps a second runner off the job; a sweep folder of another format version is
// refused; GNU parallel (Debian `parallel`) runs a sweep from the emitted script.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <thread>

#include "support/test_util.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string q(const fs::path& p) { return "'" + p.string() + "'"; }

std::string slurp(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// Two short sequences × 2 seeds × 2 configs, and one job that fails (an anchor that is never seen).
std::string small_spec() {
  return R"({
  "format": "roe-sweep-spec/1",
  "description": "test: 8 short jobs and one that fails",
  "axes": [
    {"datasets": [{"preset": "paper-seq1", "duration_s": 3}, {"preset": "paper-seq4", "duration_s": 3}],
     "seeds": [1, 2], "configs": ["default", "paper"]},
    {"datasets": [{"preset": "paper-seq1", "duration_s": 3}], "seeds": [1], "configs": ["default"],
     "overrides": {"filter.anchor_id": [99]}}
  ]
})";
}

void strip_timings(json& j) {
  if (j.is_object()) {
    j.erase("timing_s");
    j.erase("wall_s");
    for (auto& [k, v] : j.items()) strip_timings(v);
  } else if (j.is_array()) {
    for (auto& v : j) strip_timings(v);
  }
}

void replace_all(std::string& s, const std::string& from, const std::string& to) {
  for (std::size_t p = s.find(from); p != std::string::npos; p = s.find(from, p + to.size())) s.replace(p, from.size(), to);
}

/// Every file of jobs/: path -> content with the sweep folder's path replaced and JSON timings removed.
std::map<std::string, std::string> job_files(const fs::path& sweep) {
  std::map<std::string, std::string> out;
  const std::string abs = fs::canonical(sweep).string();
  for (const auto& e : fs::recursive_directory_iterator(sweep / "jobs")) {
    if (!e.is_regular_file()) continue;
    std::string text = slurp(e.path());
    replace_all(text, abs, "SWEEP");
    if (e.path().extension() == ".json") {
      json j = json::parse(text);
      strip_timings(j);
      text = j.dump(1);
    }
    out[fs::relative(e.path(), sweep).string()] = text;
  }
  return out;
}

json status_of(const fs::path& sweep) {
  const auto r = roe::test::run_roe("sweep status " + q(sweep) + " --json", false);
  REQUIRE(r.code == 0);
  return json::parse(r.out);
}

pid_t spawn_roe(const std::string& args) {
  const pid_t pid = fork();
  if (pid == 0) {
    setpgid(0, 0);
    execl("/bin/sh", "sh", "-c", (std::string("exec ") + ROE_BINARY + " " + args + " -q >/dev/null 2>&1").c_str(),
          static_cast<char*>(nullptr));
    _exit(127);
  }
  return pid;
}

bool have(const char* tool) { return std::system((std::string("command -v ") + tool + " >/dev/null 2>&1").c_str()) == 0; }

}  // namespace

TEST_CASE("roe sweep: 4 shards killed at random and resumed == one uninterrupted run", "[cli][sweep]") {
  roe::test::TempDir tmp("roe_sweep");
  const fs::path spec = tmp.write("spec.json", small_spec());
  const fs::path a = tmp / "a", b = tmp / "b";
  auto r = roe::test::run_roe("sweep plan " + q(spec) + " --out " + q(a));
  REQUIRE(r.code == 0);
  CHECK_THAT(r.out, Catch::Contains("9 jobs"));
  REQUIRE(roe::test::run_roe("sweep plan " + q(spec) + " --out " + q(b) + " -q").code == 0);
  CHECK(slurp(a / "jobs.jsonl") == slurp(b / "jobs.jsonl"));  // same ids, same order

  // Uninterrupted: every job; the failing one does not stop the others; exit 1 says one failed.
  r = roe::test::run_roe("sweep run " + q(a) + " --json", false);
  CHECK(r.code == 1);
  const json ra = json::parse(r.out);
  CHECK(ra["failed"] == 1);
  json st = status_of(a);
  CHECK(st["done"] == 8);
  CHECK(st["failed"] == 1);
  CHECK(st["pending"] == 0);
  REQUIRE(st["failures"].size() == 1);
  CHECK_THAT(st["failures"][0]["message"].get<std::string>(), Catch::Contains("99"));
  // Running again skips everything.
  r = roe::test::run_roe("sweep run " + q(a) + " --json", false);
  CHECK(r.code == 0);
  for (const auto& j : json::parse(r.out)["jobs"]) CHECK(j["action"].get<std::string>().rfind("skipped", 0) == 0);

  // Sharded 4 ways, tasks killed (SIGKILL: no clean-up) at random moments, then every shard resumed.
  std::mt19937 rng(7);
  for (int round = 0; round < 2; ++round) {
    std::vector<pid_t> pids;
    for (int s = 0; s < 4; ++s) pids.push_back(spawn_roe("sweep run " + q(b) + " --shard " + std::to_string(s) + "/4"));
    std::this_thread::sleep_for(std::chrono::milliseconds(150 + rng() % 900));
    for (int s = 0; s < 4; ++s)
      if (rng() % 2 == 0) kill(-pids[s], SIGKILL);
    for (pid_t p : pids) waitpid(p, nullptr, 0);
  }
  const json killed = status_of(b);
  INFO("after the kills: " << killed["done"] << " done, " << killed["pending"] << " pending");
  for (int s = 0; s < 4; ++s)
    roe::test::run_roe("sweep run " + q(b) + " --shard " + std::to_string(s) + "/4 -q");
  st = status_of(b);
  CHECK(st["done"] == 8);
  CHECK(st["failed"] == 1);
  CHECK((!fs::exists(b / "work") || fs::is_empty(b / "work")));
  const auto fa = job_files(a), fb = job_files(b);
  REQUIRE(fa.size() == fb.size());
  CHECK(fa.size() >= 8 * 6);
  for (const auto& [path, text] : fa) {
    INFO(path);
    REQUIRE(fb.count(path) == 1);
    CHECK(fb.at(path) == text);
  }

  // Aggregation: tables in four formats, the failure counted, comparisons default vs paper.
  r = roe::test::run_roe("sweep aggregate " + q(a) + " --out " + q(tmp / "agg") + " --json", false);
  REQUIRE(r.code == 0);
  const json ag = json::parse(r.out);
  CHECK(ag["n_jobs"] == 8);
  CHECK(ag["n_failed"] == 1);
  for (const char* f : {"summary.md", "summary.tex", "summary.csv", "summary.json", "comparisons.csv", "jobs.csv"})
    CHECK(fs::is_regular_file(tmp / "agg" / f));
  bool paired = false;
  for (const auto& c : ag["comparisons"])
    if (c["a"] == "default" && c["b"] == "paper" && c["n_pairs"] == 4) paired = true;
  CHECK(paired);
  CHECK(roe::test::run_roe("sweep aggregate " + q(a) + " --out " + q(tmp / "agg") + " -q").code == 2);  // exists
  if (std::system("/usr/bin/python3 -c 'import matplotlib' >/dev/null 2>&1") == 0) {
    r = roe::test::run_roe("sweep aggregate " + q(a) + " --out " + q(tmp / "agg-plots") + " --plot --group-by config -q");
    CHECK(r.code == 0);
    CHECK(fs::is_regular_file(tmp / "agg-plots" / "plots" / "box_ate_rmse_m.png"));
    CHECK(slurp(tmp / "agg-plots" / "summary.md").find("| default |") != std::string::npos);
  }
  CHECK(roe::test::run_roe("sweep aggregate " + q(a) + " --out " + q(tmp / "agg2") + " --group-by nope").code == 2);

  // Emit: the array covers every index; the resources are passed through.
  r = roe::test::run_roe("sweep emit slurm " + q(a) + " --max-parallel 3 --partition debug --time 00:10:00", false);
  REQUIRE(r.code == 0);
  CHECK_THAT(r.out, Catch::Contains("#SBATCH --array=0-8%3") && Catch::Contains("#SBATCH --partition=debug") &&
                        Catch::Contains("--index \"$SLURM_ARRAY_TASK_ID\""));
  r = roe::test::run_roe("sweep emit parallel " + q(a) + " -j 2 --sshloginfile hosts.txt", false);
  REQUIRE(r.code == 0);
  CHECK_THAT(r.out, Catch::Contains("seq 0 8 | parallel --jobs 2 --sshloginfile 'hosts.txt'"));
}

TEST_CASE("roe sweep: a held job lock, another format version, bad usage", "[cli][sweep]") {
  roe::test::TempDir tmp("roe_sweep_lock");
  const fs::path spec = tmp.write("spec.json", R"({"axes": {"datasets": [{"preset": "paper-seq1", "duration_s": 3}]}})");
  const fs::path s = tmp / "s";
  REQUIRE(roe::test::run_roe("sweep plan " + q(spec) + " --out " + q(s) + " -q").code == 0);
  const std::string id = json::parse(slurp(s / "jobs.jsonl"))["id"];
  if (have("flock")) {
    // Another runner holds the job: this one leaves it alone, status says running.
    fs::create_directories(s / "locks");
    const pid_t holder = fork();
    if (holder == 0) {
      setpgid(0, 0);  // flock and its sleep (which inherits the lock) end together
      execlp("flock", "flock", (s / "locks" / (id + ".lock")).c_str(), "sleep", "30", static_cast<char*>(nullptr));
      _exit(127);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    auto r = roe::test::run_roe("sweep run " + q(s) + " --index 0 --json", false);
    CHECK(r.code == 0);
    CHECK(json::parse(r.out)["jobs"][0]["action"] == "busy");
    CHECK(status_of(s)["running"] == 1);
    kill(-holder, SIGTERM);
    waitpid(holder, nullptr, 0);
  }
  CHECK(roe::test::run_roe("sweep run " + q(s) + " --index 1").code == 2);  // out of range
  CHECK(roe::test::run_roe("sweep run " + q(s) + " --shard 2/2").code == 2);
  CHECK(roe::test::run_roe("sweep run " + q(s) + " --index 0 --shard 0/2").code == 2);
  // A sweep folder of another version is refused, not misread.
  std::string m = slurp(s / "sweep.json");
  m.replace(m.find("roe-sweep/1"), 11, "roe-sweep/0");
  std::ofstream(s / "sweep.json") << m;
  auto r = roe::test::run_roe("sweep status " + q(s));
  CHECK(r.code == 2);
  CHECK_THAT(r.out, Catch::Contains("roe-sweep/0") && Catch::Contains("plan the sweep again"));
  // A spec error exits 2 naming the key path; nothing is created.
  const fs::path bad = tmp.write("bad.json", R"({"axes": {"datasets": ["paper-seq1"], "configs": ["default", "paper", "nope"]}})");
  r = roe::test::run_roe("sweep plan " + q(bad) + " --out " + q(tmp / "x"));
  CHECK(r.code == 2);
  CHECK_THAT(r.out, Catch::Contains("axes.configs[2]"));
  CHECK(!fs::exists(tmp / "x"));
}

TEST_CASE("roe sweep: GNU parallel runs the emitted script", "[cli][sweep][parallel]") {
  if (!have("parallel")) {
    WARN("skipped: GNU parallel is not installed (Debian: apt-get install parallel; scripts/install-deps.sh)");
    return;
  }
  roe::test::TempDir tmp("roe_sweep_parallel");
  const fs::path spec = tmp.write(
      "spec.json", R"({"axes": {"datasets": [{"preset": "paper-seq1", "duration_s": 3}], "seeds": [1, 2, 3, 4]}})");
  const fs::path s = tmp / "s";
  REQUIRE(roe::test::run_roe("sweep plan " + q(spec) + " --out " + q(s) + " -q").code == 0);
  REQUIRE(roe::test::run_roe("sweep emit parallel " + q(s) + " -j 2 --out " + q(tmp / "run.sh") + " -q").code == 0);
  const int rc = std::system(("HOME=" + tmp.path.string() + " bash " + q(tmp / "run.sh") + " >/dev/null 2>&1").c_str());
  CHECK(WEXITSTATUS(rc) == 0);
  const json st = status_of(s);
  CHECK(st["done"] == 4);
  const std::string joblog = slurp(s / "logs" / "parallel.joblog");
  CHECK(std::count(joblog.begin(), joblog.end(), '\n') == 5);  // header + 4 jobs
}
