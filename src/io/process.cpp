#include "roe/io/process.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include "roe/core/error.hpp"
#include "roe/io/output.hpp"

namespace roe::io {

namespace fs = std::filesystem;

fs::path find_executable(const std::string& name) {
  std::error_code ec;
  if (name.find('/') != std::string::npos) return fs::exists(name, ec) ? fs::path(name) : fs::path();
  const char* path_env = std::getenv("PATH");
  const std::string dirs = path_env ? path_env : "";
  std::size_t start = 0;
  while (start <= dirs.size()) {
    const std::size_t end = std::min(dirs.find(':', start), dirs.size());
    const fs::path dir = end > start ? fs::path(dirs.substr(start, end - start)) : fs::path(".");
    const fs::path cand = dir / name;
    if (fs::is_regular_file(cand, ec) && ::access(cand.c_str(), X_OK) == 0) return cand;
    start = end + 1;
  }
  return {};
}

ProcessResult run_process(const std::vector<std::string>& argv) {
  if (argv.empty()) throw InternalError("run_process: empty argv");
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) throw Error(std::string("cannot create a pipe: ") + std::strerror(errno));
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    throw Error(std::string("cannot start ") + argv[0] + ": " + std::strerror(errno));
  }
  if (pid == 0) {
    // Only async-signal-safe calls between fork and exec.
    ::setpgid(0, 0);
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(137);  // roe died before prctl
    ::dup2(fds[1], 1);
    ::dup2(fds[1], 2);
    ::execv(args[0], args.data());
    ::_exit(127);
  }
  const int slot = register_child_process(pid);
  ::setpgid(pid, pid);  // also here: no window in which the child is still in roe's group
  ::close(fds[1]);
  ProcessResult r;
  char buf[4096];
  for (;;) {
    const ssize_t n = ::read(fds[0], buf, sizeof buf);
    if (n > 0) {
      r.output.append(buf, static_cast<std::size_t>(n));
      if (r.output.size() > 131072) r.output.erase(0, r.output.size() - 65536);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    break;
  }
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  unregister_child_process(slot);
  if (WIFEXITED(status)) {
    r.exit_code = WEXITSTATUS(status);
    r.exec_failed = r.exit_code == 127 && r.output.empty();
  } else if (WIFSIGNALED(status)) {
    r.term_signal = WTERMSIG(status);
  }
  if (r.output.size() > 65536) r.output.erase(0, r.output.size() - 65536);
  return r;
}

}  // namespace roe::io
