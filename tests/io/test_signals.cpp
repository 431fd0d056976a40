// DeferSignals across threads: a SIGTERM that another thread takes during a deferred section waits for
// its end, then still removes the temporary output and ends the process by that signal. Run in a
// forked child, since the handler ends the process.
#include <pthread.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <catch2/catch.hpp>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "roe/io/output.hpp"

namespace fs = std::filesystem;

namespace {
/// Runs `body` in a forked child with roe's signal handler installed; returns the wait status.
template <class F>
int in_child(F body) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    roe::io::remove_temporaries_on_signals();
    body();
    ::_exit(0);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return status;
}
}  // namespace

TEST_CASE("a signal another thread takes during DeferSignals waits for its end, then cleans up",
          "[io][signals]") {
  const fs::path dir = fs::temp_directory_path() / "roe_defer_signals";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const int status = in_child([&] {
    roe::io::OutputDir out(dir / "run", false, {});
    std::ofstream(out.file("a.txt")) << "x";
    // A worker started before the deferred section (as LibTorch's are), so it does not inherit the
    // blocked mask: it takes the signal while this thread defers.
    std::atomic<int> phase{0};
    std::thread other([&] {
      while (phase.load() != 1) ::usleep(1000);
      ::pthread_kill(::pthread_self(), SIGTERM);
      phase.store(2);
    });
    {
      const roe::io::DeferSignals defer;
      phase.store(1);
      while (phase.load() != 2) ::usleep(1000);
      std::ofstream(dir / "after_signal") << "the deferred section went on";
    }
    // The signal is delivered here: the temporary folder is removed and the process ends by SIGTERM.
    std::ofstream(dir / "not_reached") << "";
    other.join();
  });
  CHECK(WIFSIGNALED(status));
  if (WIFSIGNALED(status)) CHECK(WTERMSIG(status) == SIGTERM);
  CHECK(fs::exists(dir / "after_signal"));
  CHECK(!fs::exists(dir / "not_reached"));
  bool temp_left = false;
  for (const auto& e : fs::directory_iterator(dir)) temp_left = temp_left || e.path().filename().string()[0] == '.';
  CHECK(!temp_left);
  CHECK(!fs::exists(dir / "run"));
  fs::remove_all(dir);
}

TEST_CASE("without a deferred section the signal ends the process at once, removing the temporary",
          "[io][signals]") {
  const fs::path dir = fs::temp_directory_path() / "roe_signals_now";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const int status = in_child([&] {
    roe::io::OutputDir out(dir / "run", false, {});
    std::thread other([] { ::pthread_kill(::pthread_self(), SIGTERM); });
    other.join();
    std::ofstream(dir / "not_reached") << "";
  });
  CHECK(WIFSIGNALED(status));
  CHECK(!fs::exists(dir / "not_reached"));
  bool temp_left = false;
  for (const auto& e : fs::directory_iterator(dir)) temp_left = temp_left || e.path().filename().string()[0] == '.';
  CHECK(!temp_left);
  fs::remove_all(dir);
}

namespace {
std::vector<std::string> hidden_names(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename().string()[0] == '.') names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}
}  // namespace

TEST_CASE("the temporaries a SIGKILLed run left are swept by the next run of the same output, no others",
          "[io][signals]") {
  const fs::path dir = fs::temp_directory_path() / "roe_stale_temporaries";
  fs::remove_all(dir);
  fs::create_directories(dir);
  // A run killed with SIGKILL (no handler can run): its temporary folder and staged file stay.
  const int status = in_child([&] {
    roe::io::OutputDir out(dir / "run", false, {});
    std::ofstream(out.file("trajectory.csv")) << "half";
    roe::io::StagedFiles st;
    std::ofstream(st.stage(dir / "roe.json")) << "half";
    ::raise(SIGKILL);
  });
  REQUIRE(WIFSIGNALED(status));
  REQUIRE(WTERMSIG(status) == SIGKILL);
  const auto left = hidden_names(dir);
  REQUIRE(left.size() == 2);
  // Look-alikes that must survive: another host's temporary (same dead PID), a replaced output's
  // backup, a temporary of another output, and one of a live process (this test's parent).
  const std::string killed = left[1].substr(std::string(".run.tmp-").size());  // HOST-PID-COUNTER-RANDOM
  const std::string other_host = std::string(killed[0] == 'f' ? "0" : "f") + killed.substr(1);
  const std::string pid_part = killed.substr(9);  // PID-COUNTER-RANDOM
  const std::string live = killed.substr(0, 9) + std::to_string(::getppid()) +
                           pid_part.substr(pid_part.find('-'));
  for (const std::string& name : {".run.tmp-" + other_host, ".run.tmp-" + killed + ".old", ".runs.tmp-" + killed,
                                  ".run.tmp-" + live, ".run.tmp-" + killed + "x"})
    fs::create_directories(dir / name);
  auto keep = hidden_names(dir);
  keep.erase(std::find(keep.begin(), keep.end(), left[1]));
  keep.erase(std::find(keep.begin(), keep.end(), left[0]));

  {
    roe::io::OutputDir again(dir / "run", false, {});
    REQUIRE(again.stale_removed().size() == 1);
    CHECK(again.stale_removed()[0].filename() == left[1]);
  }
  CHECK(roe::io::remove_stale_temporaries(dir / "roe.json").size() == 1);
  CHECK(hidden_names(dir) == keep);
  CHECK(roe::io::remove_stale_temporaries(dir / "run").empty());
  fs::remove_all(dir);
}
