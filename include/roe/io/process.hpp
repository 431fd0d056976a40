#pragma once
/// @file
/// Running a helper program (the plotting script) the way roe's output rules need: no shell, its output
/// captured, in its own process group so that a terminal's Ctrl-C reaches roe alone, and killed with
/// roe (registered with remove_temporaries_on_signals(), and PR_SET_PDEATHSIG for a SIGKILLed roe).

#include <filesystem>
#include <string>
#include <vector>

namespace roe::io {

struct ProcessResult {
  int exit_code = -1;      ///< the exit status when it exited, else -1
  int term_signal = 0;     ///< the signal that ended it, else 0
  bool exec_failed = false;  ///< it could not be started (then exit_code is 127)
  std::string output;      ///< stdout and stderr interleaved (the last 64 KiB)
  bool ok() const { return exit_code == 0; }
};

/// Runs `argv[0]` (a path to an executable, not looked up on PATH) with `argv` and waits for it.
/// Throws nothing for a failing child; roe::Error when no process can be created at all.
ProcessResult run_process(const std::vector<std::string>& argv);

/// The executable's path: `name` itself when it contains a '/', else the first executable `name` on
/// $PATH (as the shell would find it). Empty when there is none.
std::filesystem::path find_executable(const std::string& name);

}  // namespace roe::io
