// roe report: eval + calib-check in-process, the figure set once, one self-contained HTML file.
#include "roe/core/clock.hpp"
#include "roe/app/report.hpp"

#include <fmt/format.h>

#include <chrono>
#include <future>
#include <optional>

#include "roe/app/calib_check.hpp"
#include "roe/app/eval.hpp"
#include "roe/core/error.hpp"
#include "roe/store/eval_report.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"

namespace roe::app {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

/// Usage and output checks before any work: REPORT.html's folder exists, it is not a folder, not
/// replaced without --force, and neither it nor --figures is an input.
void check_outputs(const ReportOptions& o) {
  if (o.out.empty()) throw InputError("--out REPORT.html is required", {"", 0, 0, "out"});
  const fs::path out = o.out;
  std::error_code ec;
  if (fs::is_directory(out, ec))
    throw InputError("--out names a folder; give the HTML file to write (e.g. REPORT.html)", {o.out});
  const fs::path parent = out.parent_path().empty() ? fs::path(".") : out.parent_path();
  if (!fs::is_directory(parent, ec))
    throw InputError("the folder of --out does not exist (roe report creates the file, not its folder)",
                     {parent.string()});
  io::check_file_output(out, o.force, {o.run_dir, o.gt}, "report");
  // An existing file inside an input may be one the report reads (run.json, trajectory.csv, roe.json): only an
  // earlier HTML report is replaced there.
  for (const std::string& in : {o.run_dir, o.gt})
    if (!in.empty() && fs::exists(out, ec) && io::is_within(out, in) &&
        io::read_file_head(out, 15).rfind("<!DOCTYPE html>", 0) != 0)
      throw InputError("--out is a file inside the input " + in + " and not an earlier report: writing the report "
                       "there would replace an input (even --force would)", {o.out});
  if (!o.figures_dir.empty()) io::OutputDir::check(o.figures_dir, o.force, {o.run_dir, o.gt});
}

/// --gt, or the dataset run.json names when it is still there (store::find_run_dataset).
std::string ground_truth(const ReportOptions& o, const std::optional<store::RunRecord>& run) {
  if (!o.gt.empty()) return o.gt;
  if (run)
    if (const auto ds = store::find_run_dataset(*run)) return ds->string();
  throw InputError(!run ? "--gt DATASET|GT_FILE is required (the run folder has no run.json naming its dataset)"
                        : fmt::format("--gt DATASET|GT_FILE is required: the dataset run.json names ({}) "
                                      "is not there any more",
                                      run->inputs.dataset_abs),
                   {o.run_dir});
}

ReportCalib run_calib_check(const ReportOptions& o, const std::string& gt) {
  CalibCheckOptions co;
  std::error_code ec;
  if (fs::exists(fs::path(gt) / "roe.json", ec))
    co.dataset = gt;
  else
    co.no_dataset = true;
  ReportCalib c;
  try {
    c.result = calib_check(o.run_dir, co);
  } catch (const InputError& e) {  // e.g. a trajectory-only folder: the report says why, and goes on
    c.error = e.what();
  }
  return c;
}

}  // namespace

ReportResult write_report(const ReportOptions& o) {
  const auto t_start = std::chrono::steady_clock::now();
  check_figure_options(o.figures);
  if (o.run_dir.empty()) throw InputError("RUN_DIR is required", {"roe report"});
  if (!fs::is_directory(o.run_dir))
    throw InputError("not a run folder (roe report reads the folder roe run wrote)", {o.run_dir});
  check_outputs(o);
  const fs::path run_json_path = fs::path(o.run_dir) / "run.json";
  std::optional<store::RunRecord> record;
  if (fs::exists(run_json_path)) record = store::read_run_json(run_json_path);
  ReportOptions opt = o;
  opt.gt = ground_truth(o, record);

  // Scratch space: a never-committed OutputDir beside the report, removed on return, on an exception
  // and on SIGINT/SIGTERM/SIGHUP (with the plotting process).
  const fs::path out = o.out;
  const fs::path parent = out.parent_path().empty() ? fs::path(".") : out.parent_path();
  io::OutputDir work(parent / ("." + out.filename().string() + ".work"), true);
  std::optional<io::OutputDir> keep;
  if (!o.figures_dir.empty()) keep.emplace(o.figures_dir, o.force, std::vector<fs::path>{o.run_dir, opt.gt});
  const fs::path fig_dir = keep ? keep->tmp() : work.file("figures");
  fs::create_directories(fig_dir);
  // Python and matplotlib import (the figures' fixed ≈ 0.6 s) while eval runs on the other core.
  PlotProcess plot(plot_run_script(), "plot_run.py", fig_dir);

  EvalOptions eo;
  eo.est = o.run_dir;
  eo.gt = opt.gt;
  eo.align = o.align;
  eo.label = o.label;
  eo.rpe_delta = o.rpe_delta;
  eo.rpe_unit = o.rpe_unit;
  eo.out = (work.tmp() / "eval").string();
  auto t = std::chrono::steady_clock::now();
  const EvalResult ev = run_eval(eo);
  const double eval_s = seconds_since(t);
  // The calibration checks (C++, one core) run while the figures are drawn (a Python process).
  double calib_s = 0.0;
  auto calib_future = std::async(std::launch::async, [&opt, &calib_s] {
    const auto tc = std::chrono::steady_clock::now();
    ReportCalib c = run_calib_check(opt, opt.gt);
    calib_s = seconds_since(tc);
    return c;
  });
  t = std::chrono::steady_clock::now();
  std::error_code ec;
  const fs::path dataset = fs::exists(fs::path(opt.gt) / "roe.json", ec) ? fs::path(opt.gt) : fs::path();
  // The HTML embeds the PNGs only: vector files are drawn only when --figures keeps them.
  FigureOptions fo = o.figures;
  if (!keep) fo.vector = "none";
  FigureSet figs;
  try {
    figs = render_figures(work.tmp() / "eval", o.run_dir, dataset, fig_dir, fo, &plot);
  } catch (...) {
    calib_future.wait();  // the thread uses `opt`: it finishes before the exception leaves
    throw;
  }
  const double fig_s = seconds_since(t);
  ReportResult r;
  r.calib = calib_future.get();
  t = std::chrono::steady_clock::now();
  const std::string html = report_html(ev.report, record ? &*record : nullptr, r.calib, figs, fig_dir);
  {
    io::DeferSignals defer;  // the report and its figures folder appear together
    io::write_file_atomic(out, html, o.force);
    if (keep) keep->commit();
  }
  const double html_s = seconds_since(t);

  r.out = o.out;
  r.bytes = html.size();
  r.run = o.run_dir;
  r.gt = opt.gt;
  for (const Figure& f : figs.figures) r.figures.push_back(f.name);
  r.skipped.assign(figs.skipped.begin(), figs.skipped.end());
  r.figures_dir = o.figures_dir;
  r.timing_s = {{"eval", eval_s},  {"calib_check", calib_s},          {"figures", fig_s},
                {"html", html_s}, {"total", seconds_since(t_start)}};
  r.eval = ev.report;
  return r;
}

json ReportResult::to_json() const {
  json skipped_j = json::array();
  for (const auto& [n, why] : skipped) skipped_j.push_back({{"name", n}, {"reason", why}});
  json calib_j = calib.result ? json{{"passed", calib.result->passed()}, {"counts", calib.result->status_counts()}}
                              : json{{"error", calib.error}};
  return {{"out", out},
          {"bytes", bytes},
          {"run", run},
          {"gt", gt},
          {"figures", figures},
          {"figures_skipped", skipped_j},
          {"figures_dir", figures_dir.empty() ? json(nullptr) : json(figures_dir)},
          {"label", eval.label},
          {"per_axis", store::to_json(eval.per_axis)},
          {"ape_trans_rmse_m", eval.ape_trans_m.rmse},
          {"ape_rot_rmse_deg", eval.ape_rot_deg.rmse},
          {"calib_check", calib_j},
          {"timing_s", timing_s},
          {"warnings", eval.warnings}};
}

std::string ReportResult::to_text() const {
  std::string t = fmt::format("roe report: {} ({:.1f} MB, {} figures)\n", out, static_cast<double>(bytes) / 1e6,
                              figures.size());
  const Eigen::Vector3d& p = eval.per_axis.pos_rmse_m;
  const Eigen::Vector3d& e = eval.per_axis.rpy_deg.rmse;
  t += fmt::format("  RMSE x/y/z {:.4f} {:.4f} {:.4f} m, roll/pitch/yaw {:.3f} {:.3f} {:.3f} deg\n", p.x(), p.y(),
                   p.z(), e.x(), e.y(), e.z());
  if (!calib.result)
    t += "  calib-check: not run (" + calib.error + ")\n";
  else
    t += fmt::format("  calib-check: {}\n", calib.result->passed() ? "PASS" : "FAIL");
  for (const auto& [name, why] : skipped) t += fmt::format("  {} not drawn: {}\n", name, why);
  t += fmt::format("  {:.2f} s (eval {:.2f}, figures {:.2f} with calib-check {:.2f} alongside, html {:.2f})\n",
                   timing_s.at("total"), timing_s.at("eval"), timing_s.at("figures"), timing_s.at("calib_check"),
                   timing_s.at("html"));
  return t;
}

}  // namespace roe::app
