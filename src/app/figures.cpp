// The figure set of a run: runs the embedded scripts/plot_run.py (one python process) and reads back
// its figures.json.
#include "roe/app/figures.hpp"

#include <fmt/format.h>
#include <signal.h>
#include <string.h>

#include <chrono>
#include <cmath>
#include <future>
#include <map>
#include <cstdlib>

#include "roe/core/error.hpp"
#include "roe/io/csv.hpp"
#include "roe/store/dataset.hpp"
#include "roe/store/run_record.hpp"
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
  if (o.style != "default" && o.style != "paper")
    throw InputError(fmt::format("--style: expected default or paper, got '{}'", o.style), {"", 0, 0, "style"});
}

json symmetries_json(const std::vector<std::pair<int, ObjectSymmetry>>& objects) {
  json out = json::object();
  const auto pose = [](const Pose& p) {
    return json{{"p", {p.p.x(), p.p.y(), p.p.z()}}, {"q", {p.q.x(), p.q.y(), p.q.z(), p.q.w()}}};
  };
  for (const auto& [id, s] : objects) {
    if (s.empty()) continue;
    json d = json::array();
    for (const Pose& S : s.discrete) d.push_back(pose(S));
    json c = nullptr;
    if (s.continuous)
      c = {{"axis", {s.continuous->axis.x(), s.continuous->axis.y(), s.continuous->axis.z()}},
           {"offset", {s.continuous->offset.x(), s.continuous->offset.y(), s.continuous->offset.z()}}};
    out[std::to_string(id)] = {{"discrete", d}, {"continuous", c}};
  }
  return out;
}

std::string FigureSet::status() const {
  std::string s;
  for (const Figure& f : figures) s += (s.empty() ? "" : ", ") + f.name;
  std::string formats;
  if (!figures.empty())
    for (const auto& [k, v] : figures.front().files) formats += (formats.empty() ? "." : " + .") + k;
  return s + (formats.empty() ? "" : " (" + formats + ")");
}

namespace {

/// The interpreter: Debian's (the python3 on PATH may be a build without matplotlib); ROE_PYTHON overrides.
fs::path python_executable() {
  const char* env = std::getenv("ROE_PYTHON");
  const std::string python = env && *env ? env : "/usr/bin/python3";
  const fs::path exe = io::find_executable(python);
  if (exe.empty()) {
    throw InputError(fmt::format("cannot draw the figures: the Python interpreter {} was not found{} (install "
                                 "python3, python3-numpy and python3-matplotlib, or point ROE_PYTHON at an "
                                 "interpreter that has them)",
                                 python, python.find('/') == std::string::npos ? " on PATH" : ""));
  }
  return exe;
}

/// The script's exit turned into roe's errors (see run_plot_script).
void check_result(const io::ProcessResult& r, const fs::path& exe, const std::string& name) {
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
}

}  // namespace

struct PlotProcess::State {
  std::string name;
  fs::path exe, script, go;
  std::chrono::steady_clock::time_point t0;
  std::future<io::ProcessResult> result;
};

PlotProcess::PlotProcess(const std::string& script_text, const std::string& name, const fs::path& dir)
    : s_(std::make_unique<State>()) {
  s_->name = name;
  s_->exe = python_executable();
  s_->script = dir / ("." + name);
  s_->go = dir / ("." + name + ".args.json");
  io::write_file_atomic(s_->script, script_text);
  const std::vector<std::string> argv = {s_->exe.string(), s_->script.string(), "--args-from", s_->go.string()};
  s_->t0 = std::chrono::steady_clock::now();
  try {
    s_->result = std::async(std::launch::async, [argv] { return io::run_process(argv); });
  } catch (...) {
    std::error_code ec;
    fs::remove(s_->script, ec);
    throw;
  }
}

PlotProcess::~PlotProcess() {
  if (!s_->result.valid()) return;
  try {  // never run(): the script exits on {"abort": true}
    io::write_file_atomic(s_->go, io::dump_json(nlohmann::json{{"abort", true}}));
  } catch (...) {  // it then waits until roe is gone (PR_SET_PDEATHSIG); nothing more to do here
  }
  s_->result.wait();
  std::error_code ec;
  fs::remove(s_->script, ec);
  fs::remove(s_->go, ec);
}

double PlotProcess::run(const std::vector<std::string>& args) {
  io::ProcessResult r;
  try {
    io::write_file_atomic(s_->go, io::dump_json(nlohmann::json{{"args", args}}));
    r = s_->result.get();  // (an exception here is run_process's own: no process could be created)
  } catch (...) {
    if (s_->result.valid()) {
      try {
        io::write_file_atomic(s_->go, io::dump_json(nlohmann::json{{"abort", true}}));
      } catch (...) {
      }
      s_->result.wait();
    }
    std::error_code ec;
    fs::remove(s_->script, ec);
    fs::remove(s_->go, ec);
    throw;
  }
  std::error_code ec;
  fs::remove(s_->script, ec);
  fs::remove(s_->go, ec);
  check_result(r, s_->exe, s_->name);
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - s_->t0).count();
}

double run_plot_script(const std::string& script_text, const std::string& name, const fs::path& dir,
                       const std::vector<std::string>& args) {
  const fs::path exe = python_executable();
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
  check_result(r, exe, name);
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

namespace {

/// The CSV `csv` as a raw float64 file (row-major, the header's columns) for plot_run.py, which reads
/// it with np.fromfile instead of parsing the text again (the states of a 300 s run are 56 MB). A column
/// whose first field is not a number (reprojection.csv's status, used) is text: stored as the index of
/// each value in its list of distinct values, which the entry carries ("text": {column: [values]}).
/// Returns its entry of the --tables manifest, or null when the file is absent or a numeric column has a
/// field that is not a number (the script then reads the CSV itself, with its own checks and messages).
json export_table(const fs::path& csv, const fs::path& bin) {
  std::error_code ec;
  if (!fs::is_regular_file(csv, ec)) return nullptr;
  try {
    io::CsvOptions co;
    co.quotes = false;
    io::CsvReader r(csv, co);
    const std::size_t n = r.header().size();
    // Written as the rows are read, a piece at a time (the states of an hour at IMU rate are ~0.7 GB as
    // float64): the uncommitted file is removed if a field turns out not to be a number.
    io::AtomicFile out(bin);
    std::vector<double> v;
    const std::size_t piece = std::max<std::size_t>(n, (std::size_t{1} << 20) / sizeof(double));
    const auto flush = [&] {
      out.append(std::string_view(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(double)));
      v.clear();
    };
    v.reserve(piece + n);
    std::size_t rows = 0;
    std::vector<std::map<std::string, double, std::less<>>> text(n);  // value -> index, per text column
    std::vector<bool> is_text(n, false);
    for (bool first = true; r.next(); first = false, ++rows) {
      for (std::size_t i = 0; i < n; ++i) {
        if (first && !r.is_empty(i)) {
          try {
            r.get_double_nonfinite(i);
          } catch (const InputError&) {
            is_text[i] = true;
          }
        }
        if (!is_text[i]) {
          v.push_back(r.is_empty(i) ? std::nan("") : r.get_double_nonfinite(i));
          continue;
        }
        const std::string_view f = r.field(i);
        auto it = text[i].find(f);
        if (it == text[i].end()) it = text[i].emplace(std::string(f), static_cast<double>(text[i].size())).first;
        v.push_back(it->second);
      }
      if (v.size() >= piece) flush();
    }
    flush();
    out.commit();
    json entry = {{"bin", bin.string()}, {"columns", r.header()}, {"rows", n ? rows : 0}};
    for (std::size_t i = 0; i < n; ++i) {
      if (!is_text[i]) continue;
      json values = json::array();
      for (std::size_t k = 0; k < text[i].size(); ++k) values.push_back("");
      for (const auto& [value, k] : text[i]) values[static_cast<std::size_t>(k)] = value;
      entry["text"][r.header()[i]] = values;
    }
    return entry;
  } catch (const InputError&) {
    return nullptr;
  }
}

/// The large numeric tables the figures read, converted on both cores (export_table); the manifest
/// {csv path: entry} is written to `manifest`. Returns the files written (to remove afterwards).
std::vector<fs::path> export_tables(const std::vector<fs::path>& tables, const fs::path& dir, const fs::path& manifest) {
  std::vector<json> entries(tables.size());
  std::vector<fs::path> written;
  for (std::size_t i = 0; i < tables.size(); ++i) written.push_back(dir / fmt::format(".table{}.f64", i));
  {
    auto half = std::async(std::launch::async, [&] {
      for (std::size_t i = 1; i < tables.size(); i += 2) entries[i] = export_table(tables[i], written[i]);
    });
    for (std::size_t i = 0; i < tables.size(); i += 2) entries[i] = export_table(tables[i], written[i]);
    half.get();
  }
  json m = json::object();
  for (std::size_t i = 0; i < tables.size(); ++i)
    if (!entries[i].is_null()) m[tables[i].string()] = entries[i];
  io::write_file_atomic(manifest, io::dump_json(m));
  written.push_back(manifest);
  return written;
}

}  // namespace

FigureSet render_figures(const fs::path& eval_dir, const fs::path& run_dir, const fs::path& dataset,
                         const fs::path& out_dir, const FigureOptions& o, PlotProcess* started) {
  check_figure_options(o);
  std::vector<std::string> args = {"--eval", eval_dir.string(), "--out", out_dir.string(), "--objects", o.objects,
                                   "--plot-mode", o.plot_mode, "--vector", o.vector, "--style", o.style};
  if (!run_dir.empty()) {
    args.insert(args.end(), {"--run", run_dir.string()});
    // A run written with output level minimal: the figures that need its tables say why they are skipped.
    if (io::path_exists(run_dir / "run.json")) {
      const std::string why = store::run_file_absent_reason(store::read_run_json(run_dir / "run.json").config, "objects.csv");
      if (!why.empty()) args.insert(args.end(), {"--run-absent", why});
    }
  }
  const fs::path sym_file = out_dir / ".symmetries.json";
  if (!dataset.empty()) {
    args.insert(args.end(), {"--dataset", dataset.string()});
    // The symmetries as the dataset reader resolved them (models_info): Fig. 4 of a symmetric object.
    std::vector<std::pair<int, ObjectSymmetry>> objects;
    for (const ObjectInfo& obj : store::read_manifest(dataset).objects) objects.emplace_back(obj.id, obj.symmetry);
    const json sym = symmetries_json(objects);
    if (!sym.empty()) {
      io::write_file_atomic(sym_file, io::dump_json(sym));
      args.insert(args.end(), {"--symmetries", sym_file.string()});
    }
  }
  if (o.color_by_error) args.push_back("--color-by-error");
  if (o.correspondences) args.push_back("--correspondences");
  // Larger tables first: the two threads share them about evenly.
  std::vector<fs::path> tables = {eval_dir / "errors.csv", eval_dir / "est_matched_aligned.csv",
                                  eval_dir / "gt_matched.csv", eval_dir / "reprojection_aligned.csv"};
  if (!run_dir.empty()) {
    std::error_code ec;
    const bool smoothed = fs::exists(run_dir / "states_filter.csv", ec);
    tables.insert(tables.begin(), {run_dir / (smoothed ? "states_filter.csv" : "states.csv"), run_dir / "objects.csv"});
    tables.push_back(run_dir / "reprojection.csv");
  }
  std::vector<fs::path> temporaries = {sym_file};
  const auto remove_temporaries = [&] {
    std::error_code ec;
    for (const fs::path& f : temporaries) fs::remove(f, ec);
  };
  double wall = 0.0;
  try {
    const fs::path manifest = out_dir / ".tables.json";
    const auto written = export_tables(tables, out_dir, manifest);
    temporaries.insert(temporaries.end(), written.begin(), written.end());
    args.insert(args.end(), {"--tables", manifest.string()});
    wall = started ? started->run(args) : run_plot_script(plot_run_script(), "plot_run.py", out_dir, args);
  } catch (...) {
    remove_temporaries();
    throw;
  }
  remove_temporaries();
  FigureSet set = read_manifest(out_dir / "figures.json");
  set.wall_s = wall;
  for (const Figure& f : set.figures)
    for (const auto& [k, v] : f.files)
      if (!fs::exists(out_dir / v))
        throw Error(fmt::format("plot_run.py listed {} but did not write it", (out_dir / v).string()));
  return set;
}

}  // namespace roe::app
