// roe eval --plot: the figure set of scripts/plot_run.py (app/figures.hpp) into the eval folder's plots/.
#include <fmt/format.h>

#include "roe/app/eval.hpp"
#include "roe/app/figures.hpp"

namespace roe::app {

namespace fs = std::filesystem;

std::string render_eval_plots(const fs::path& eval_dir, const EvalOptions& o) {
  const fs::path plots = eval_dir / "plots";
  fs::create_directories(plots);
  // The run folder's states/objects and the dataset's truth add Fig. 4, the extrinsics and NEES.
  std::error_code ec;
  const fs::path run = fs::is_directory(o.est, ec) ? fs::path(o.est) : fs::path();
  const fs::path dataset = fs::exists(fs::path(o.gt) / "roe.json", ec) ? fs::path(o.gt) : fs::path();
  const FigureSet set = render_figures(eval_dir, run, dataset, plots, o.figures);
  std::string s = "plots/: " + set.status();
  for (const auto& [name, why] : set.skipped) s += fmt::format("; {} skipped: {}", name, why);
  return s;
}

}  // namespace roe::app
