// `roe` only: the commands that need OpenCV or LibTorch run in helper executables (roe-image,
// roe-infer) so that no other command pays for loading them (issue 24: `roe --version` went from
// 288 mapped libraries and 0.6-0.9 s to a handful and milliseconds). `roe` lists those commands in its
// help and, when one is asked for, replaces itself with the helper: same arguments, same process id,
// so exit codes, signals and stdout are the helper's own and a caller sees one `roe` process.
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>
#include <system_error>

#include "command.hpp"
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

}  // namespace

const ForwardedCommand* forward_to_helper(int argc, char** argv, std::string& error) {
  const ForwardedCommand* c = forwarded_command(argc, argv);
  if (c == nullptr) return nullptr;
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
  error = std::string("the command '") + (c->parent[0] ? std::string(c->parent) + " " : "") + c->name +
          "' runs in the helper " + c->helper + ", which is not installed (looked for " + tried +
          "); reinstall roe";
  return c;
}

}  // namespace roe::cli
