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

json run_calib_check(const ReportOptions& o, const std::string& gt) {
  CalibCheckOptions co;
  std::error_code ec;
  if (fs::exists(fs::path(gt) / "roe.json", ec))
    co.dataset = gt;
  else
    co.no_dataset = true;
  try {
    return calib_check(o.run_dir, co).to_json();
  } catch (const InputError& e) {  // e.g. a trajectory-only folder: the report says why, and goes on
    return {{"error", e.what()}};
  }
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
  const json run = record ? store::run_record_to_json(*record) : json();
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
    json c = run_calib_check(opt, opt.gt);
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
  const json calib = calib_future.get();
  t = std::chrono::steady_clock::now();
  const std::string html = report_html(ev.report, run, calib, figs, fig_dir, record ? &*record : nullptr);
  {
    io::DeferSignals defer;  // the report and its figures folder appear together
    io::write_file_atomic(out, html, o.force);
    if (keep) keep->commit();
  }
  const double html_s = seconds_since(t);

  ReportResult r;
  json names = json::array();
  for (const Figure& f : figs.figures) names.push_back(f.name);
  json skipped = json::array();
  for (const auto& [n, why] : figs.skipped) skipped.push_back({{"name", n}, {"reason", why}});
  r.summary = {{"out", o.out},
               {"bytes", html.size()},
               {"run", o.run_dir},
               {"gt", opt.gt},
               {"figures", names},
               {"figures_skipped", skipped},
               {"figures_dir", o.figures_dir.empty() ? json(nullptr) : json(o.figures_dir)},
               {"label", ev.report.label},
               {"per_axis", store::to_json(ev.report.per_axis)},
               {"ape_trans_rmse_m", ev.report.ape_trans_m.rmse},
               {"ape_rot_rmse_deg", ev.report.ape_rot_deg.rmse},
               {"calib_check", calib.contains("error") ? json{{"error", calib["error"]}}
                                                       : json{{"passed", calib["passed"]}, {"counts", calib["counts"]}}},
               {"timing_s",
                {{"eval", eval_s}, {"calib_check", calib_s}, {"figures", fig_s}, {"html", html_s},
                 {"total", seconds_since(t_start)}}},
               {"warnings", ev.report.warnings}};
  r.eval = ev.report;
  return r;
}

std::string ReportResult::to_text() const {
  const json& s = summary;
  std::string t = fmt::format("roe report: {} ({:.1f} MB, {} figures)\n", s["out"].get<std::string>(),
                              s["bytes"].get<double>() / 1e6, s["figures"].size());
  const Eigen::Vector3d& p = eval.per_axis.pos_rmse_m;
  const Eigen::Vector3d& e = eval.per_axis.rpy_deg.rmse;
  t += fmt::format("  RMSE x/y/z {:.4f} {:.4f} {:.4f} m, roll/pitch/yaw {:.3f} {:.3f} {:.3f} deg\n", p.x(), p.y(),
                   p.z(), e.x(), e.y(), e.z());
  const json& c = s["calib_check"];
  if (c.contains("error"))
    t += "  calib-check: not run (" + c["error"].get<std::string>() + ")\n";
  else
    t += fmt::format("  calib-check: {}\n", c["passed"].get<bool>() ? "PASS" : "FAIL");
  for (const json& k : s["figures_skipped"])
    t += fmt::format("  {} not drawn: {}\n", k["name"].get<std::string>(), k["reason"].get<std::string>());
  const json& ti = s["timing_s"];
  t += fmt::format("  {:.2f} s (eval {:.2f}, figures {:.2f} with calib-check {:.2f} alongside, html {:.2f})\n",
                   ti["total"].get<double>(), ti["eval"].get<double>(), ti["figures"].get<double>(),
                   ti["calib_check"].get<double>(), ti["html"].get<double>());
  return t;
}

}  // namespace roe::app
