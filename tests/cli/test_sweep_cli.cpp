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
#include <functional>
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
  CHECK_THAT(r.out, Catch::Contains("seq 0 8 | parallel -q --jobs 2 --sshloginfile 'hosts.txt'"));
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

TEST_CASE("roe sweep: a job of a spec with eval.t_offset_s auto evaluates with --t-offset auto", "[cli][sweep]") {
  roe::test::TempDir tmp("roe_sweep_toffset");
  const fs::path spec = tmp.write("spec.json", R"({"axes": {"datasets": [{"preset": "paper-seq1", "duration_s": 3}]},
                                                   "eval": {"t_offset_s": "auto"}})");
  const fs::path s = tmp / "s";
  REQUIRE(roe::test::run_roe("sweep plan " + q(spec) + " --out " + q(s) + " -q").code == 0);
  const std::string id = json::parse(slurp(s / "jobs.jsonl"))["id"];
  REQUIRE(roe::test::run_roe("sweep run " + q(s) + " --index 0 -q").code == 0);
  const json report = json::parse(slurp(s / "jobs" / id / "run" / "eval" / "report.json"));
  CHECK(report["options"]["t_offset_auto"] == true);
  REQUIRE(report.contains("time_offset"));  // the estimated offset with its sigma, as `roe eval --t-offset auto` writes it
  CHECK(std::abs(report["time_offset"]["offset_s"].get<double>()) < 0.05);  // the estimate's own stamps: no shift
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

// ---- Hostile sweep folders (issue 40) ---------------------------------------------------------------

namespace {

/// `s` as one word for sh, whatever it holds.
std::string sh(const std::string& s) {
  std::string r = "'";
  for (char c : s) r += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return r + "'";
}

/// Rewrites jobs.jsonl's first line through `edit`.
void edit_first_job(const fs::path& sweep, const std::function<void(json&)>& edit) {
  std::string text = slurp(sweep / "jobs.jsonl");
  const std::size_t nl = text.find('\n');
  json j = json::parse(text.substr(0, nl));
  edit(j);
  std::ofstream(sweep / "jobs.jsonl", std::ios::trunc) << j.dump() << text.substr(nl);
}

const char* kTwoJobSpec =
    R"({"format": "roe-sweep-spec/1", "axes": {"datasets": [{"preset": "paper-seq1", "duration_s": 2}], "seeds": [1, 2]}})";

}  // namespace

TEST_CASE("roe sweep run: a job id from jobs.jsonl never names a folder outside the sweep", "[cli][sweep][hostile]") {
  roe::test::TempDir tmp("roe_sweep_escape");
  const fs::path spec = tmp.write("spec.json", kTwoJobSpec);
  for (const std::string& bad : {std::string("../../victim"), (tmp / "victim").string(), std::string("a/b"),
                                std::string(""), std::string("0123456789ABCDEF"), std::string("..")}) {
    CAPTURE(bad);
    fs::remove_all(tmp / "sw");
    fs::create_directories(tmp / "victim");
    std::ofstream(tmp / "victim" / "keep") << "x";
    REQUIRE(roe::test::run_roe("sweep plan " + q(spec) + " --out " + q(tmp / "sw") + " -q").code == 0);
    edit_first_job(tmp / "sw", [&](json& j) { j["id"] = bad; });
    for (const std::string cmd : {"run", "status"}) {
      const auto r = roe::test::run_roe("sweep " + cmd + " " + q(tmp / "sw") + (cmd == "run" ? " --index 0" : ""));
      CHECK(r.code == 2);
      CHECK_THAT(r.out, Catch::Contains("jobs.jsonl:1") && Catch::Contains("16 lower-case hex digits"));
    }
    CHECK(fs::exists(tmp / "victim" / "keep"));
    CHECK(!fs::exists(tmp / "victim.old"));
    CHECK(!fs::exists(tmp / "victim.lock"));
  }
  // A detection set name that leaves detections/, and a work/ that is a symlink, are refused too.
  fs::remove_all(tmp / "sw");
  REQUIRE(roe::test::run_roe("sweep plan " + q(spec) + " --out " + q(tmp / "sw") + " -q").code == 0);
  edit_first_job(tmp / "sw", [](json& j) { j["job"]["detections"] = "../../x"; });
  auto r = roe::test::run_roe("sweep run " + q(tmp / "sw") + " --index 1");
  CHECK(r.code == 2);
  CHECK_THAT(r.out, Catch::Contains("job.detections"));
  fs::remove_all(tmp / "sw");
  REQUIRE(roe::test::run_roe("sweep plan " + q(spec) + " --out " + q(tmp / "sw") + " -q").code == 0);
  fs::create_directory_symlink(tmp / "victim", tmp / "sw" / "work");
  r = roe::test::run_roe("sweep run " + q(tmp / "sw") + " --index 0");
  CHECK(r.code == 2);
  CHECK_THAT(r.out, Catch::Contains("symbolic link"));
  CHECK(fs::exists(tmp / "victim" / "keep"));
}

TEST_CASE("roe sweep aggregate: --out inside the sweep's own folders is refused, even with --force",
          "[cli][sweep][hostile]") {
  roe::test::TempDir tmp("roe_sweep_aggout");
  const fs::path spec = tmp.write("spec.json", kTwoJobSpec);
  const fs::path sw = tmp / "sw";
  REQUIRE(roe::test::run_roe("sweep plan " + q(spec) + " --out " + q(sw) + " -q").code == 0);
  const std::string id = json::parse(slurp(sw / "jobs.jsonl").substr(0, slurp(sw / "jobs.jsonl").find('\n')))["id"];
  fs::create_directories(sw / "jobs" / id);
  std::ofstream(sw / "jobs" / id / "result.json") << "{}";
  for (const fs::path& out : {sw / "jobs", sw / "jobs" / id, sw / "work", sw / "locks" / "x", sw, tmp.path})
    CHECK(roe::test::run_roe("sweep aggregate " + q(sw) + " --out " + q(out) + " --force").code == 2);
  CHECK(fs::exists(sw / "jobs" / id / "result.json"));
  CHECK(fs::exists(sw / "jobs.jsonl"));
}

TEST_CASE("roe sweep plan: a spec of 10^9 jobs is refused at once, --max-jobs raises the limit",
          "[cli][sweep][hostile]") {
  roe::test::TempDir tmp("roe_sweep_limit");
  json values = json::array();
  for (int i = 0; i < 1000; ++i) values.push_back(0.9 + i * 1e-5);
  json big = {{"format", "roe-sweep-spec/1"},
              {"axes",
               {{"datasets", {"paper-seq1"}},
                {"overrides",
                 {{"filter.chi2_confidence", values}, {"filter.meas_sigma_p_m", values}, {"filter.meas_sigma_ray_m", values}}}}}};
  const fs::path spec = tmp.write("big.json", big.dump());
  const auto t0 = std::chrono::steady_clock::now();
  auto r = roe::test::run_roe("sweep plan " + q(spec) + " --out " + q(tmp / "sw"));
  CHECK(r.code == 2);
  CHECK_THAT(r.out, Catch::Contains("1000000000 jobs") && Catch::Contains("--max-jobs") &&
                        Catch::Contains("big.json:1:"));
  CHECK(std::chrono::steady_clock::now() - t0 < std::chrono::seconds(5));
  CHECK(!fs::exists(tmp / "sw"));
  // 4 jobs against a limit of 3, then 4.
  const fs::path small = tmp.write("small.json", R"({"format": "roe-sweep-spec/1", "axes": {"datasets": ["paper-seq1"],
      "seeds": [1, 2], "configs": ["default", "paper"]}})");
  CHECK(roe::test::run_roe("sweep plan " + q(small) + " --out " + q(tmp / "s4") + " --max-jobs 3").code == 2);
  CHECK(roe::test::run_roe("sweep plan " + q(small) + " --out " + q(tmp / "s4") + " --max-jobs 4 -q").code == 0);
  // Detection names that leave detections/ and a duration the simulator refuses fail at plan time.
  for (const std::string axes : {R"({"datasets": ["paper-seq1"], "detections": ["../x"]})",
                                 R"({"datasets": ["paper-seq1"], "detections": ["a/b"]})",
                                 R"({"datasets": [{"preset": "paper-seq1", "duration_s": 1e9}]})"}) {
    const fs::path bad = tmp.write("bad.json", R"({"format": "roe-sweep-spec/1", "axes": )" + axes + "}");
    r = roe::test::run_roe("sweep plan " + q(bad) + " --out " + q(tmp / "bad"));
    CHECK(r.code == 2);
    CHECK_THAT(r.out, Catch::Contains("bad.json:1:"));
    CHECK(!fs::exists(tmp / "bad"));
  }
}

TEST_CASE("roe sweep emit: GNU parallel runs the script on a folder named with spaces, quotes and $( )",
          "[cli][sweep][parallel][hostile]") {
  if (!have("parallel")) {
    WARN("skipped: GNU parallel is not installed (Debian: apt-get install parallel; scripts/install-deps.sh)");
    return;
  }
  roe::test::TempDir tmp("roe_sweep_quoted");
  const fs::path spec = tmp.write("spec.json", kTwoJobSpec);
  const fs::path s = tmp / "sw 'single' \"double\" $(touch INJECTED) `touch INJECTED2` ;x";
  REQUIRE(roe::test::run_roe("sweep plan " + sh(spec.string()) + " --out " + sh(s.string()) + " -q").code == 0);
  REQUIRE(roe::test::run_roe("sweep emit parallel " + sh(s.string()) + " -j 2 --out " + sh((tmp / "run.sh").string()) +
                             " -q")
              .code == 0);
  const int rc = std::system(("cd " + sh(tmp.path.string()) + " && HOME=" + sh(tmp.path.string()) + " bash run.sh" +
                              " >/dev/null 2>&1")
                                 .c_str());
  CHECK(WEXITSTATUS(rc) == 0);
  CHECK(!fs::exists(tmp / "INJECTED"));
  CHECK(!fs::exists(tmp / "INJECTED2"));
  const auto st = roe::test::run_roe("sweep status " + sh(s.string()) + " --json", false);
  REQUIRE(st.code == 0);
  CHECK(json::parse(st.out)["done"] == 2);
  // A newline in a #SBATCH value would add a directive: refused. The comment shows no raw newline either.
  auto r = roe::test::run_roe("sweep emit slurm " + sh(s.string()) + " --job-name " + sh("x\n#SBATCH --mem=999G"));
  CHECK(r.code == 2);
  CHECK_THAT(r.out, Catch::Contains("--job-name"));
  r = roe::test::run_roe("sweep emit slurm " + sh(s.string()), false);
  REQUIRE(r.code == 0);
  CHECK_THAT(r.out, Catch::Contains("exec '"));
}
