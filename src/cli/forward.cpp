// `roe` only: the commands that need OpenCV or LibTorch run in helper executables (roe-image,
// roe-infer) so that no other command pays for loading them (issue 24: `roe --version` went from
// 288 mapped libraries and 0.6-0.9 s to a handful and milliseconds). `roe` lists those commands in its
// help and, when one is asked for, replaces itself with the helper: same arguments, same process id,
// so exit codes, signals and stdout are the helper's own and a caller sees one `roe` process.
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <iostream>
#include <string>
#include <system_error>

#include "command.hpp"
#include "roe/features.hpp"
#include "roe/io/install_paths.hpp"

namespace roe::cli {
namespace {

RunFn setup_forwarded(CLI::App& sub) {
  // Only listed in `roe --help`: a forwarded command is executed by its helper before parsing.
  sub.allow_extras();
  return []() -> int { throw std::logic_error("a forwarded command reached roe's own dispatcher"); };
}

const Registrar reg_realsense(kImportRealsenseCommand.parent, kImportRealsenseCommand.name,
                              kImportRealsenseCommand.description, kImportRealsenseCommand.order,
                              &setup_forwarded);
const Registrar reg_infer(kInferCommand.parent, kInferCommand.name, kInferCommand.description,
                          kInferCommand.order, &setup_forwarded);

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

/// The command's synopsis as DESIGN §1 gives it (its full option list is the helper's own --help).
const char* synopsis(const ForwardedCommand& c) {
  if (std::string(c.helper) == "roe-image") return "roe import realsense BAG --out DATASET [OPTIONS]";
  return "roe infer DATASET --model BUNDLE_DIR [--name NAME] [OPTIONS]";
}

std::string command_path(const ForwardedCommand& c) {
  return (c.parent[0] ? std::string(c.parent) + " " : "") + c.name;
}

std::string how_to_add(const ForwardedCommand& c) {
  return std::string("add it from the build folder: cmake --build BUILD --target ") + c.helper +
         " && cmake --install BUILD --prefix PREFIX (or make install PREFIX=...), docs/install.md";
}

}  // namespace

const ForwardedCommand* forward_to_helper(int argc, char** argv, std::string& error, int& exit_code) {
  const ForwardedCommand* c = forwarded_command(argc, argv);
  if (c == nullptr) return nullptr;
  if (!kOpenCVFeature.built) {  // no helpers in this build (cmake/features.cmake)
    if (asks_for_help(argc, argv)) {
      std::cout << c->description << "\nUsage: " << synopsis(*c) << "\n\n"
                << not_built_message(kOpenCVFeature, command_path(*c)) << "\n";
      error.clear();
      return c;
    }
    error = not_built_message(kOpenCVFeature, command_path(*c));
    exit_code = 2;
    return c;
  }
  const std::string here = io::executable_dir().string();
  // The build tree keeps the helpers beside roe; an installation puts them in PREFIX/libexec/roe.
  std::string tried;
  for (const std::string& candidate : {here + "/" + c->helper, here + "/../libexec/roe/" + c->helper}) {
    if (::access(candidate.c_str(), X_OK) != 0) {
      tried += (tried.empty() ? "" : ", ") + candidate;
      continue;
    }
    ::execv(candidate.c_str(), argv);
    error = "cannot start " + candidate + ": " + std::strerror(errno);
    return c;
  }
  if (asks_for_help(argc, argv)) {  // answered here: the helper is not needed to say what it would do
    std::cout << c->description << "\nUsage: " << synopsis(*c) << "\n\n"
              << "This command runs in the helper " << c->helper << ", which is not installed with this roe\n"
              << "(looked for " << tried << "). Its options are listed here once it is;\n"
              << how_to_add(*c) << ".\n";
    error.clear();
    return c;
  }
  exit_code = 3;
  error = "the command '" + command_path(*c) + "' runs in the helper " + c->helper +
          ", which is not installed with this roe (looked for " + tried + "); " + how_to_add(*c);
  return c;
}

}  // namespace roe::cli
