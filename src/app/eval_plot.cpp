// roe eval --plot: runs the embedded scripts/plot_eval.py with Debian's python3 + matplotlib.
#include <fmt/format.h>
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>

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
}  // namespace

std::string render_eval_plots(const fs::path& eval_dir, bool& ok) {
  ok = false;
  // Debian's interpreter (the python3 on PATH may be a build without matplotlib); ROE_PYTHON overrides.
  const char* env = std::getenv("ROE_PYTHON");
  const std::string python = env && *env ? env : "/usr/bin/python3";
  if (!fs::exists(python))
    return fmt::format("not rendered: {} not found (install python3 and python3-matplotlib)", python);
  if (run(shell_quote(python) + " -c 'import matplotlib' >/dev/null 2>&1") != 0)
    return fmt::format("not rendered: {} has no matplotlib (Debian: apt install python3-matplotlib)", python);
  const fs::path script = eval_dir / ".plot_eval.py";
  io::write_file_atomic(script, plot_eval_script());
  const fs::path log = eval_dir / ".plot_eval.log";
  const int rc = run(shell_quote(python) + " " + shell_quote(script.string()) + " " +
                     shell_quote(eval_dir.string()) + " >" + shell_quote(log.string()) + " 2>&1");
  std::string detail;
  if (rc != 0) {
    std::ifstream f(log);
    detail.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  }
  std::error_code ec;
  fs::remove(script, ec);
  fs::remove(log, ec);
  if (rc != 0) return fmt::format("not rendered: plot_eval.py failed (exit {}): {}", rc, detail);
  ok = true;
  return "plots/trajectory_top.png, plots/xyz.png, plots/rpy.png, plots/errors.png";
}

}  // namespace roe::app
