// End-to-end checks of the roe executable's global behaviour: help, version, exit codes for bad usage.
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "support/test_util.hpp"

namespace fs = std::filesystem;
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

TEST_CASE("verbose: -v logs what simulate and run read and wrote on stderr, -q keeps it quiet", "[cli]") {
  roe::test::TempDir d;
  const std::string ds = (d / "ds").string(), out = (d / "run").string();
  auto r = run_roe("-v simulate --preset paper-seq4 --duration 1 --out " + ds);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("roe: info: simulated paper-seq4: seed 1, 201 IMU samples") != std::string::npos);
  r = run_roe("-v run " + ds + " --out " + out);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("roe: info: config: roe's defaults (no --config)") != std::string::npos);
  CHECK(r.out.find("roe: info: read " + ds + " in ") != std::string::npos);
  CHECK(r.out.find("roe: info: filter: ") != std::string::npos);
  CHECK(r.out.find("roe: info: wrote " + out + " (201 trajectory rows)") != std::string::npos);
  r = run_roe("--force run " + ds + " --out " + out);
  CHECK(r.out.find("roe: info:") == std::string::npos);
  r = run_roe("-v -q --force run " + ds + " --out " + out);
  CHECK(r.out.find("roe: info:") == std::string::npos);
}

TEST_CASE("json summaries: every command's summary has command, out and warnings", "[cli]") {
  roe::test::TempDir d;
  const std::string ds = (d / "ds").string(), run = (d / "run").string();
  const auto json_of = [](const std::string& args) {
    const auto r = run_roe("--json " + args, false);  // stdout only
    INFO(args << "\n" << r.out);
    REQUIRE(r.code == 0);
    return nlohmann::json::parse(r.out);
  };
  auto j = json_of("simulate --preset paper-seq4 --duration 1 --out " + ds);
  CHECK(j.at("command") == "simulate");
  CHECK(j.at("out") == ds);
  CHECK(j.at("warnings").is_array());
  j = json_of("run " + ds + " --out " + run);
  CHECK(j.at("command") == "run");
  CHECK(j.at("out") == run);
  j = json_of("eval " + run + " --gt " + ds);
  CHECK(j.at("command") == "eval");
  CHECK(j.at("out") == run + "/eval");
  j = json_of("eval " + run + " --gt " + ds + " --no-out");
  CHECK(j.at("out").is_null());
  j = json_of("eval --summary " + run + "/eval/report.json --out " + (d / "table").string());
  CHECK(j.at("command") == "eval");
  CHECK(j.at("out") == (d / "table.csv").string());
  CHECK(j.at("written").size() == 3);
  CHECK(j.at("warnings").is_array());
  // --out naming one of the three files: `out` is that file.
  j = json_of("--force eval --summary " + run + "/eval/report.json --out " + (d / "table.md").string());
  CHECK(j.at("out") == (d / "table.md").string());
  const auto tum = d.write("gt.tum", "1.0 0 0 0 0 0 0 1\n1.1 0.1 0 0 0 0 0 1\n1.2 0.2 0 0 0 0 0 1\n");
  j = json_of("import mocap " + tum.string() + " --format tum --into " + (d / "m").string());
  CHECK(j.at("command") == "import mocap");
  CHECK(j.at("out") == (d / "m").string());
  CHECK(j.at("warnings").is_array());
  j = json_of("simulate --list-presets");
  CHECK(j.at("out").is_null());
  CHECK(j.at("presets").size() >= 11);
}

TEST_CASE("simulate --seed must be a non-negative integer, and says so", "[cli]") {
  for (const char* bad : {"1.5", "abc", "-1", "1e3"}) {
    INFO(bad);
    const auto r = run_roe(std::string("simulate --preset paper-seq1 --duration 0.1 --out /nonexistent/x --seed ") + bad);
    CHECK(r.code == 2);
    CHECK(r.out.find(std::string("--seed: must be an integer >= 0 (at most 18 digits), got '") + bad + "'") !=
          std::string::npos);
  }
}

namespace {
/// Starts `roe simulate` of 3000 s (about a minute) into `out`, silenced; the caller ends it.
pid_t spawn_long_simulation(const fs::path& out, bool ignore_hup) {
  const pid_t pid = ::fork();
  if (pid != 0) return pid;
  if (ignore_hup) ::signal(SIGHUP, SIG_IGN);  // kept across exec
  const int null = ::open("/dev/null", O_WRONLY);
  ::dup2(null, 1);
  ::dup2(null, 2);
  ::execl(ROE_BINARY, "roe", "simulate", "--preset", "paper-seq4", "--duration", "3000", "--out", out.c_str(),
          static_cast<char*>(nullptr));
  ::_exit(127);
}
}  // namespace

TEST_CASE("roe: SIGTERM or SIGINT during a long command leaves no temporary output behind", "[cli]") {
  // `timeout`, Ctrl-C and batch schedulers end commands with these; the hidden .NAME.tmp-* folder of
  // the output in progress (80 MB after 2 s of this simulation) must go with the process.
  roe::test::TempDir tmp("roe_cli_signal");
  for (const int sig : {SIGTERM, SIGINT}) {
    const std::string name = "big" + std::to_string(sig);
    const fs::path out = tmp.path / name;
    const pid_t pid = spawn_long_simulation(out, false);
    REQUIRE(pid >= 0);
    const auto temporaries = [&] {
      int n = 0;
      for (const auto& e : fs::directory_iterator(tmp.path))
        if (e.path().filename().string().rfind("." + name, 0) == 0) ++n;
      return n;
    };
    for (int i = 0; i < 600 && temporaries() == 0; ++i) ::usleep(100'000);  // at most 60 s
    REQUIRE(temporaries() == 1);
    ::kill(pid, sig);
    int status = 0;
    REQUIRE(::waitpid(pid, &status, 0) == pid);
    CHECK(WIFSIGNALED(status));
    CHECK(WTERMSIG(status) == sig);
    CHECK(temporaries() == 0);
    CHECK_FALSE(fs::exists(out));
  }
}

TEST_CASE("roe: a signal the caller ignores stays ignored (nohup, background jobs)", "[cli]") {
  roe::test::TempDir tmp("roe_cli_sigign");
  const fs::path out = tmp.path / "big";
  const pid_t pid = spawn_long_simulation(out, true);  // SIGHUP ignored, as nohup does
  REQUIRE(pid >= 0);
  ::usleep(300'000);
  ::kill(pid, SIGHUP);
  ::usleep(300'000);
  int status = 0;
  CHECK(::waitpid(pid, &status, WNOHANG) == 0);  // still running
  ::kill(pid, SIGTERM);
  REQUIRE(::waitpid(pid, &status, 0) == pid);
  CHECK(WIFSIGNALED(status));
  CHECK(WTERMSIG(status) == SIGTERM);
}

TEST_CASE("roe: a number option out of range says what it must be, briefly", "[cli]") {
  // CLI11's own PositiveNumber printed its range up to DBL_MAX in full (300 digits).
  for (const auto& [args, what] : std::vector<std::pair<std::string, std::string>>{
           {"infer ds --model m --every 0", "--every: must be an integer >= 1, got '0'"},
           {"infer ds --model m --every 2.5", "--every: must be an integer >= 1, got '2.5'"},
           {"import mocap f --into d --max-offset -1", "--max-offset: must be a positive number, got '-1'"},
           {"import realsense b --out d --crop-width -5", "--crop-width: must be an integer >= 0, got '-5'"},
           {"import realsense b --out d --crop-width 1.5", "--crop-width: must be an integer >= 0, got '1.5'"},
           {"infer ds --model m --every 1e20", "--every: must be an integer >= 1, got '1e20'"},
           {"calib-check r --confidence 0.5", "--confidence: must be a number in (0.5, 1), got '0.5'"},
           {"calib-check r --max-sigma-p nan", "--max-sigma-p: must be a positive number, got 'nan'"},
           {"calib-check r --settle-fraction 0", "--settle-fraction: must be a number in (0, 1], got '0'"}}) {
    const auto r = run_roe(args);
    INFO(args << "\n" << r.out);
    CHECK(r.code == 2);
    CHECK(r.out.find(what) != std::string::npos);
    CHECK(r.out.size() < 200);
  }
}

TEST_CASE("roe: an unknown command is named, with the commands there are", "[cli]") {
  auto r = run_roe("bogus");
  CHECK(r.code == 2);
  CHECK(r.out.find("unknown command 'bogus' (commands: import, simulate, run, refine, infer, eval, calib-check, report, sweep)") !=
        std::string::npos);
  r = run_roe("sweep bogus");
  CHECK(r.code == 2);
  CHECK(r.out.find("unknown command 'bogus' (subcommands of sweep: plan, run, status, emit, aggregate)") !=
        std::string::npos);
  r = run_roe("-q import bogus x");
  CHECK(r.code == 2);
  CHECK(r.out.find("unknown command 'bogus' (subcommands of import: realsense, mocap, kalibr, poet)") !=
        std::string::npos);
  r = run_roe("");
  CHECK(r.code == 2);
  CHECK(r.out.find("a command is required") != std::string::npos);
}

TEST_CASE("roe: an unknown option points to the help of the level it was given at", "[cli]") {
  // Before the command: a global option, so `roe --help`.
  auto r = run_roe("--bogus-flag eval x --gt y");
  CHECK(r.code == 2);
  CHECK(r.out.find("--bogus-flag") != std::string::npos);
  CHECK(r.out.find("(see roe --help)") != std::string::npos);
  r = run_roe("-qz eval x --gt y");
  CHECK(r.code == 2);
  CHECK(r.out.find("(see roe --help)") != std::string::npos);
  // After it: the command's own help; known global flags before it do not change that.
  r = run_roe("-q --json eval x --gt y --bogus-flag");
  CHECK(r.code == 2);
  CHECK(r.out.find("(see roe eval --help)") != std::string::npos);
  r = run_roe("-qv import mocap --bogus-flag");
  CHECK(r.code == 2);
  CHECK(r.out.find("(see roe import mocap --help)") != std::string::npos);
}

TEST_CASE("roe: a word before the command is an unknown command, not a missing argument", "[cli]") {
  const auto r = run_roe("seq4 run");
  CHECK(r.code == 2);
  CHECK(r.out.find("unknown command 'seq4' (did you mean `roe run seq4`?)") != std::string::npos);
  CHECK(r.out.find("DATASET is required") == std::string::npos);
}

TEST_CASE("roe --json: every failure is one JSON document on stdout, and --version too", "[cli]") {
  roe::test::TempDir tmp("roe_cli_json_err");
  // A command's error: the location of the bad value.
  const fs::path bad = tmp.write("bad.tum", "1 0 0 0 0 0 0 1\n2 0 0 zero 0 0 0 1\n");
  auto r = run_roe("--json eval " + bad.string() + " --gt " + bad.string() + " --no-out", false);
  CHECK(r.code == 2);
  auto j = nlohmann::json::parse(r.out);
  CHECK(j["command"] == "eval");
  CHECK(j["exit_code"] == 2);
  CHECK(j["error"]["file"] == bad.string());
  CHECK(j["error"]["line"] == 2);
  CHECK(j["error"]["column"] == 4);
  CHECK(j["error"]["message"].get<std::string>().find("zero") != std::string::npos);
  // A config key.
  const fs::path cfg = tmp.write("c.json", R"({"filter": {"smoother": "rts"}})");
  r = run_roe("--json run nowhere --config " + cfg.string() + " --out " + (tmp / "o").string(), false);
  CHECK(r.code == 2);
  j = nlohmann::json::parse(r.out);
  CHECK(j["command"] == "run");
  CHECK(j["error"]["key"] == "filter.smoother");
  CHECK(j["error"]["message"] == "unknown key (did you mean the top-level \"smoother\"?)");
  const fs::path cfg2 = tmp.write("c2.json", R"({"filter": {"estimator": "batch"}})");
  r = run_roe("--json run nowhere --config " + cfg2.string() + " --out " + (tmp / "o").string(), false);
  CHECK(r.code == 2);
  j = nlohmann::json::parse(r.out);
  CHECK(j["error"]["key"] == "filter.estimator");
  CHECK(j["error"]["message"] == "unknown key (did you mean the top-level \"estimator\"?)");
  // Bad usage (before any command runs) and an unknown command.
  for (const char* args : {"--json eval --align", "--json bogus", "--json eval --no-such-option"}) {
    r = run_roe(args, false);
    CHECK(r.code == 2);
    j = nlohmann::json::parse(r.out);
    CHECK(j["exit_code"] == 2);
    CHECK(j["error"]["message"].is_string());
  }
  r = run_roe("--json --version", false);
  CHECK(r.code == 0);
  j = nlohmann::json::parse(r.out);
  CHECK(j["version"].get<std::string>().rfind("0.", 0) == 0);
}

TEST_CASE("roe -q simulate --list-presets prints the listing: it is the answer, not chatter", "[cli]") {
  const auto r = run_roe("-q simulate --list-presets", false);
  CHECK(r.code == 0);
  CHECK(r.out.find("paper-seq4") != std::string::npos);
}
