// The commands that need a library `roe` itself never loads run in helper executables: OpenCV (roe-image:
// import realsense), LibTorch (roe-infer: infer) and Ceres with its SuiteSparse, BLAS and glog (roe-refine:
// refine), so that no other command pays for loading them (issue 24: `roe --version` went from 288 mapped
// libraries and 0.6-0.9 s to a handful and milliseconds; issue 53: Ceres had brought it back to 41 ms).
// `roe` lists those commands in its help and, when one is asked for, replaces itself with the helper:
// same arguments, same process id, so exit codes, signals and stdout are the helper's own and a caller
// sees one `roe` process. Every executable links this file: a helper runs its own command itself
// (runs_here) and forwards the others.
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <iostream>
#include <stdexcept>
#include <string>

#include "command.hpp"
#include "roe/features.hpp"
#include "roe/io/install_paths.hpp"

namespace roe::cli {

RunFn setup_forwarded(CLI::App& sub) {
  // Only listed in the help: a forwarded command is executed by its helper before parsing.
  sub.allow_extras();
  return []() -> int { throw std::logic_error("a forwarded command reached the dispatcher of an executable without it"); };
}

namespace {

const BuildFeature& feature_of(const ForwardedCommand& c) {
  for (const BuildFeature& f : kBuildFeatures)
    if (std::string(f.key) == c.feature_key) return f;
  throw std::logic_error(std::string("forwarded command with an unknown feature: ") + c.feature_key);
}

/// The command path named by argv: its first two words that do not start with '-' (global flags take
/// no values), e.g. {"import", "realsense"} or {"infer", "DATASET"}.
const ForwardedCommand* forwarded_command(int argc, char** argv) {
  std::string words[2];
  int n = 0;
  for (int i = 1; i < argc && n < 2; ++i) {
    if (argv[i][0] == '-') continue;
    words[n++] = argv[i];
  }
  for (const ForwardedCommand& c : kForwardedCommands) {
    const bool top = c.parent[0] == '\0';
    if (top ? words[0] == c.name : (words[0] == c.parent && words[1] == c.name)) return &c;
  }
  return nullptr;
}

bool asks_for_help(int argc, char** argv) {
  for (int i = 1; i < argc && std::string(argv[i]) != "--"; ++i)
    if (std::string(argv[i]) == "--help" || std::string(argv[i]) == "-h") return true;
  return false;
}

std::string command_path(const ForwardedCommand& c) {
  return (c.parent[0] ? std::string(c.parent) + " " : "") + c.name;
}

std::string how_to_add(const ForwardedCommand& c) {
  return std::string("add it from the build folder: cmake --build BUILD --target ") + c.helper +
         " && cmake --install BUILD --prefix PREFIX (or make install PREFIX=...), docs/install.md";
}

}  // namespace

bool exec_helper(const ForwardedCommand& c, int argc, char** argv, std::string& error, int& exit_code,
                 const std::string& asked_for) {
  const BuildFeature& feature = feature_of(c);
  const std::string what = asked_for.empty() ? command_path(c) : asked_for;
  if (!feature.built) {  // no such helper in this build (cmake/features.cmake)
    if (asks_for_help(argc, argv)) {
      std::cout << c.description << "\nUsage: " << c.synopsis << "\n\n"
                << not_built_message(feature, what) << "\n";
      return true;
    }
    error = not_built_message(feature, what);
    exit_code = 2;
    return false;
  }
  const std::string here = io::executable_dir().string();
  // The build tree keeps the helpers beside roe; an installation puts them in PREFIX/libexec/roe.
  std::string tried;
  for (const std::string& candidate : {here + "/" + c.helper, here + "/../libexec/roe/" + c.helper}) {
    if (::access(candidate.c_str(), X_OK) != 0) {
      tried += (tried.empty() ? "" : ", ") + candidate;
      continue;
    }
    std::cout.flush();
    ::execv(candidate.c_str(), argv);
    error = "cannot start " + candidate + ": " + std::strerror(errno);
    exit_code = 3;
    return false;
  }
  if (asks_for_help(argc, argv)) {  // answered here: the helper is not needed to say what it would do
    std::cout << c.description << "\nUsage: " << c.synopsis << "\n\n"
              << "This command runs in the helper " << c.helper << ", which is not installed with this roe\n"
              << "(looked for " << tried << "). Its options are listed here once it is;\n"
              << how_to_add(c) << ".\n";
    return true;
  }
  exit_code = 3;
  error = "the command '" + what + "' runs in the helper " + c.helper +
          ", which is not installed with this roe (looked for " + tried + "); " + how_to_add(c);
  return false;
}

const ForwardedCommand* forward_to_helper(int argc, char** argv, std::string& error, int& exit_code) {
  const ForwardedCommand* c = forwarded_command(argc, argv);
  if (c == nullptr || runs_here(c->parent, c->name)) return nullptr;
  error.clear();
  if (exec_helper(*c, argc, argv, error, exit_code)) error.clear();
  return c;
}

}  // namespace roe::cli
