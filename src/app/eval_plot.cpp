// roe eval --plot: runs the embedded scripts/plot_eval.py with Debian's python3 + matplotlib.
#include <fmt/format.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <iterator>

#include "roe/app/eval.hpp"
#include "roe/core/error.hpp"
#include "roe/io/output.hpp"

namespace roe::app {
namespace detail {
const std::string& embedded_plot_eval_script();
}

namespace fs = std::filesystem;

const std::string& plot_eval_script() { return detail::embedded_plot_eval_script(); }

namespace {
std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += (c == '\'') ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}
int run(const std::string& cmd) {
  const int rc = std::system(cmd.c_str());
  if (rc == -1) return -1;
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

/// The interpreter's path: as given when it contains a '/', else looked up on $PATH (as the shell
/// would). Empty when there is no such executable.
fs::path find_interpreter(const std::string& name) {
  std::error_code ec;
  if (name.find('/') != std::string::npos) return fs::exists(name, ec) ? fs::path(name) : fs::path();
  const char* path_env = std::getenv("PATH");
  std::string dirs = path_env ? path_env : "";
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

/// The last non-empty line of `text` (a Python traceback ends with the exception), at most 300 chars.
std::string last_line(const std::string& text) {
  std::size_t end = text.find_last_not_of(" \t\r\n");
  if (end == std::string::npos) return "";
  const std::size_t begin = text.rfind('\n', end);
  std::string line = text.substr(begin == std::string::npos ? 0 : begin + 1,
                                 end + 1 - (begin == std::string::npos ? 0 : begin + 1));
  if (line.size() > 300) line = line.substr(0, 300) + "...";
  return line;
}

std::string read_text(const fs::path& p) {
  std::ifstream f(p);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}
}  // namespace

std::string render_eval_plots(const fs::path& eval_dir, bool& ok) {
  ok = false;
  // Debian's interpreter (the python3 on PATH may be a build without matplotlib); ROE_PYTHON overrides
  // (a path, or a name looked up on PATH).
  const char* env = std::getenv("ROE_PYTHON");
  const std::string python = env && *env ? env : "/usr/bin/python3";
  const fs::path exe = find_interpreter(python);
  if (exe.empty()) {
    return fmt::format(
        "not rendered: the Python interpreter {} was not found{} (install python3 and "
        "python3-matplotlib, or point ROE_PYTHON at an interpreter)",
        python, python.find('/') == std::string::npos ? " on PATH" : "");
  }
  {
    // What the script needs; the interpreter's own message says what is missing.
    const fs::path log = eval_dir / ".plot_eval_check.log";
    const int rc = run(shell_quote(exe.string()) + " -c 'import matplotlib; import matplotlib.pyplot' >" +
                       shell_quote(log.string()) + " 2>&1");
    const std::string out = read_text(log);
    std::error_code ec;
    fs::remove(log, ec);
    if (rc != 0) {
      const std::string why = last_line(out);
      if (rc == 126 || rc == 127)
        return fmt::format("not rendered: {} could not be run (exit {}){}", exe.string(), rc,
                           why.empty() ? "" : ": " + why);
      return fmt::format(
          "not rendered: {} was found but importing matplotlib failed{} (Debian: apt install "
          "python3-matplotlib)",
          exe.string(), why.empty() ? fmt::format(" (exit {})", rc) : ": " + why);
    }
  }
  const fs::path script = eval_dir / ".plot_eval.py";
  io::write_file_atomic(script, plot_eval_script());
  const fs::path log = eval_dir / ".plot_eval.log";
  const int rc = run(shell_quote(exe.string()) + " " + shell_quote(script.string()) + " " +
                     shell_quote(eval_dir.string()) + " >" + shell_quote(log.string()) + " 2>&1");
  std::string detail;
  if (rc != 0) detail = read_text(log);
  std::error_code ec;
  fs::remove(script, ec);
  fs::remove(log, ec);
  if (rc != 0) return fmt::format("not rendered: plot_eval.py failed (exit {}): {}", rc, detail);
  ok = true;
  std::string written;  // rpe.png only exists with --rpe-delta
  for (const char* name : {"trajectory_top", "xyz", "rpy", "errors", "rpe"}) {
    const std::string f = fmt::format("plots/{}.png", name);
    if (io::path_exists(eval_dir / f)) written += (written.empty() ? "" : ", ") + f;
  }
  return written;
}

}  // namespace roe::app
