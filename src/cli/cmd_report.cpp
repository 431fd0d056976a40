// roe report RUN_DIR [--gt DATASET|GT_FILE] --out REPORT.html [--figures DIR] [--rpe-delta D,...] [figure options]
#include <memory>

#include "command.hpp"
#include "figure_options.hpp"
#include "roe/app/report.hpp"
#include "roe/core/error.hpp"

namespace roe::cli {
namespace {

RunFn setup_report(CLI::App& sub) {
  auto o = std::make_shared<app::ReportOptions>();
  sub.add_option("RUN_DIR", o->run_dir, "Run folder written by roe run")->required();
  sub.add_option("--gt", o->gt,
                 "Ground truth: dataset folder or trajectory file (default: the dataset named in run.json)");
  sub.add_option("--out", o->out, "The HTML file to write (self-contained: figures embedded)")->required();
  sub.add_option("--figures", o->figures_dir, "Also keep the figures (PNG + PDF/SVG) in this new folder");
  sub.add_option("--align", o->align, "Alignment, as roe eval: se3, sim3, posyaw, origin or none")
      ->capture_default_str();
  sub.add_option("--label", o->label, "Name of the run in titles and footers (default: the folder's name)");
  auto* rpe_delta = sub.add_option("--rpe-delta", o->rpe_delta,
                                   "Relative pose error over this delta (several: 1,2,5): a table and a figure")
                        ->delimiter(',')
                        ->group("Relative pose error");
  auto* rpe_unit = sub.add_option("--rpe-unit", o->rpe_unit, "Unit of --rpe-delta: m, s, f, deg or rad (as roe eval)")
                       ->capture_default_str()
                       ->group("Relative pose error");
  add_figure_options(sub, o->figures);
  return [o, rpe_delta, rpe_unit]() {
    if (rpe_unit->count() > 0 && rpe_delta->count() == 0)
      throw InputError("--rpe-unit needs --rpe-delta (the relative pose error is computed only when asked)",
                       {"", 0, 0, "rpe-unit"});
    o->force = globals().force;
    const auto r = app::write_report(*o);
    emit(r.to_json(), r.to_text());
    return 0;
  };
}

const Registrar reg_report("", "report",
                           "One self-contained HTML report of a run: tables, verdicts, the paper's figures",
                           75, &setup_report);

}  // namespace
}  // namespace roe::cli
