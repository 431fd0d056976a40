// DeferSignals across threads: a SIGTERM that another thread takes during a deferred section waits for
// its end, then still removes the temporary output and ends the process by that signal. Run in a
// forked child, since the handler ends the process.
#include <pthread.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <catch2/catch.hpp>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <thread>

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
