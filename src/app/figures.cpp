// The figure set of a run: runs the embedded scripts/plot_run.py (one python process) and reads back
// its figures.json.
#include "roe/app/figures.hpp"

#include <fmt/format.h>
#include <signal.h>
#include <string.h>

#include <chrono>
#include <cstdlib>

#include "roe/core/error.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"
#include "roe/io/process.hpp"

namespace roe::app {
namespace detail {
const std::string& embedded_plot_run_script();
}

namespace fs = std::filesystem;
using nlohmann::json;

const std::string& plot_run_script() { return detail::embedded_plot_run_script(); }

namespace {

/// The last `n` non-empty lines of `text`, at most 1200 characters.
std::string last_lines(const std::string& text, int n) {
  std::size_t end = text.find_last_not_of(" \t\r\n");
  if (end == std::string::npos) return "";
  std::size_t begin = end + 1;
  for (int k = 0; k < n && begin > 0; ++k) {
    const std::size_t nl = text.rfind('\n', begin - 1);
    begin = nl == std::string::npos ? 0 : nl;
    if (nl == std::string::npos) break;
  }
  std::string s = text.substr(begin, end + 1 - begin);
  while (!s.empty() && (s.front() == '\n' || s.front() == '\r')) s.erase(0, 1);
  if (s.size() > 1200) s = "..." + s.substr(s.size() - 1200);
  return s;
}

bool is_id_list(const std::string& s) {
  if (s.empty()) return false;
  bool digit = false;
  for (char c : s) {
    if (c >= '0' && c <= '9') digit = true;
    else if (c == ',' && digit) digit = false;
    else return false;
  }
  return digit;
}

FigureSet read_manifest(const fs::path& file) {
  FigureSet set;
  set.manifest = io::parse_json_file(file);
  for (const json& f : set.manifest.at("figures")) {
    Figure fig;
    fig.name = f.at("name").get<std::string>();
    fig.title = f.at("title").get<std::string>();
    fig.caption = f.at("caption").get<std::string>();
    for (const auto& [k, v] : f.at("files").items()) fig.files[k] = v.get<std::string>();
    set.figures.push_back(std::move(fig));
  }
  for (const json& s : set.manifest.at("skipped"))
    set.skipped.emplace_back(s.at("name").get<std::string>(), s.at("reason").get<std::string>());
  return set;
}

}  // namespace

void check_figure_options(const FigureOptions& o) {
  if (o.objects != "anchor" && o.objects != "all" && !is_id_list(o.objects))
    throw InputError(fmt::format("--objects: expected anchor, all or a comma-separated list of object ids, got '{}'",
                                 o.objects),
                     {"", 0, 0, "objects"});
  if (o.plot_mode != "xy" && o.plot_mode != "xz" && o.plot_mode != "yz" && o.plot_mode != "xyz")
    throw InputError(fmt::format("--plot-mode: expected xy, xz, yz or xyz, got '{}'", o.plot_mode),
                     {"", 0, 0, "plot-mode"});
  if (o.vector != "pdf" && o.vector != "svg" && o.vector != "none")
    throw InputError(fmt::format("--vector: expected pdf, svg or none, got '{}'", o.vector), {"", 0, 0, "vector"});
}

std::string FigureSet::status() const {
  std::string s;
  for (const Figure& f : figures) s += (s.empty() ? "" : ", ") + f.name;
  std::string formats;
  if (!figures.empty())
    for (const auto& [k, v] : figures.front().files) formats += (formats.empty() ? "." : " + .") + k;
  return s + (formats.empty() ? "" : " (" + formats + ")");
}

double run_plot_script(const std::string& script_text, const std::string& name, const fs::path& dir,
                       const std::vector<std::string>& args) {
  // Debian's interpreter (the python3 on PATH may be a build without matplotlib); ROE_PYTHON overrides.
  const char* env = std::getenv("ROE_PYTHON");
  const std::string python = env && *env ? env : "/usr/bin/python3";
  const fs::path exe = io::find_executable(python);
  if (exe.empty()) {
    throw InputError(fmt::format("cannot draw the figures: the Python interpreter {} was not found{} (install "
                                 "python3, python3-numpy and python3-matplotlib, or point ROE_PYTHON at an "
                                 "interpreter that has them)",
                                 python, python.find('/') == std::string::npos ? " on PATH" : ""));
  }
  const fs::path script = dir / ("." + name);
  io::write_file_atomic(script, script_text);
  std::vector<std::string> argv = {exe.string(), script.string()};
  argv.insert(argv.end(), args.begin(), args.end());
  const auto t0 = std::chrono::steady_clock::now();
  io::ProcessResult r;
  try {
    r = io::run_process(argv);
  } catch (...) {
    std::error_code ec;
    fs::remove(script, ec);
    throw;
  }
  std::error_code ec;
  fs::remove(script, ec);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::string why = last_lines(r.output, 1);
  if (r.exec_failed || (r.exit_code == 126 || r.exit_code == 127))
    throw InputError(fmt::format("cannot draw the figures: {} could not be run (exit {}){}", exe.string(),
                                 r.exit_code, why.empty() ? "" : ": " + why));
  const bool import_failed = r.exit_code != 0 && (r.output.find("ModuleNotFoundError") != std::string::npos ||
                                                  r.output.find("ImportError") != std::string::npos);
  if (r.exit_code == 3 || import_failed)
    throw InputError(fmt::format("cannot draw the figures: {} was found but importing matplotlib or numpy failed: "
                                 "{} (Debian: apt install python3-matplotlib python3-numpy)",
                                 exe.string(), why));
  if (r.exit_code == 2) throw InputError("cannot draw the figures: " + why);
  if (r.term_signal != 0)
    throw Error(fmt::format("{} was killed by signal {} ({})", name, r.term_signal, strsignal(r.term_signal)));
  if (r.exit_code != 0)
    throw Error(fmt::format("{} failed (exit {}):\n{}", name, r.exit_code, last_lines(r.output, 12)));
  return wall;
}

FigureSet render_figures(const fs::path& eval_dir, const fs::path& run_dir, const fs::path& dataset,
                         const fs::path& out_dir, const FigureOptions& o) {
  check_figure_options(o);
  std::vector<std::string> args = {"--eval", eval_dir.string(), "--out", out_dir.string(), "--objects", o.objects,
                                   "--plot-mode", o.plot_mode, "--vector", o.vector};
  if (!run_dir.empty()) args.insert(args.end(), {"--run", run_dir.string()});
  if (!dataset.empty()) args.insert(args.end(), {"--dataset", dataset.string()});
  if (o.color_by_error) args.push_back("--color-by-error");
  const double wall = run_plot_script(plot_run_script(), "plot_run.py", out_dir, args);
  FigureSet set = read_manifest(out_dir / "figures.json");
  set.wall_s = wall;
  for (const Figure& f : set.figures)
    for (const auto& [k, v] : f.files)
      if (!fs::exists(out_dir / v))
        throw Error(fmt::format("plot_run.py listed {} but did not write it", (out_dir / v).string()));
  return set;
}

}  // namespace roe::app
