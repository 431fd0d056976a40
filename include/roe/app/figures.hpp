#pragma once
/// @file
/// The figures of one run (docs/report.md): the paper's Fig. 3 and Fig. 4, the extrinsics, consistency,
/// trajectory, errors and RPE, each as PNG and PDF/SVG, drawn by scripts/plot_run.py (embedded at build
/// time) in one /usr/bin/python3 process with matplotlib. Used by `roe eval --plot` and `roe report`.

#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "roe/core/symmetry.hpp"

namespace roe::app {

struct FigureOptions {
  std::string objects = "anchor";  ///< --objects: anchor | all | ID[,ID...] (reprojected detections drawn)
  std::string plot_mode = "xy";    ///< --plot-mode: xy | xz | yz | xyz
  bool color_by_error = false;     ///< --color-by-error: the trajectory coloured by the position error
  bool correspondences = false;    ///< --correspondences: lines from matched estimate poses to their truth
  std::string vector = "pdf";      ///< --vector: pdf | svg | none (beside every PNG)
  /// --style: default (titles, footer, screen sizes) | paper (no titles or footers, 3.5 in / 7.16 in wide,
  /// embedded TrueType fonts, dense scatters rasterised inside the vector file).
  std::string style = "default";
};

/// InputError naming the option for a value plot_run.py would refuse (checked before any work).
void check_figure_options(const FigureOptions& options);

struct Figure {
  /// Title and caption as figures.json has them: plain Unicode, no TeX; X_{sub} and X^{sup} mark
  /// sub- and superscripts (caption_html turns them into HTML).
  std::string name, title, caption;
  std::map<std::string, std::string> files;  ///< format ("png", "pdf", "svg") -> file name in the folder
};

struct FigureSet {
  std::vector<Figure> figures;
  std::vector<std::pair<std::string, std::string>> skipped;  ///< (figure, why)
  nlohmann::json manifest;                                   ///< figures.json as written
  double wall_s = 0.0;                                       ///< the script's wall time
  std::string status() const;                                ///< "fig3, fig4_obj5, ... (.png + .pdf)"
};

/// Runs an embedded Python plotting script (its text, written to DIR/.NAME and removed after) with
/// /usr/bin/python3 (or $ROE_PYTHON) and `args`, in its own process group, dying with roe. Throws
/// InputError (exit 2) when the interpreter is missing, cannot import matplotlib/numpy, or the script
/// rejects its input (exit 2), roe::Error (exit 3) when it fails otherwise. Returns its wall time [s].
/// The one door to Python for every plot roe draws (figures, sweep box plots).
double run_plot_script(const std::string& script_text, const std::string& name, const std::filesystem::path& dir,
                       const std::vector<std::string>& args);

/// A plotting script started before its input exists: python and matplotlib import (≈ 0.6 s of CPU)
/// while roe computes what the figures show. The script is run with `--args-from FILE` and waits for
/// FILE; run() writes it (the arguments) and waits for the script, with run_plot_script's errors. A
/// process never run() is told to exit and waited for on destruction (an earlier stage threw).
class PlotProcess {
 public:
  PlotProcess(const std::string& script_text, const std::string& name, const std::filesystem::path& dir);
  ~PlotProcess();
  PlotProcess(const PlotProcess&) = delete;
  PlotProcess& operator=(const PlotProcess&) = delete;
  /// Hands `args` over and waits; throws as run_plot_script. Returns the wall time since the start [s].
  double run(const std::vector<std::string>& args);

 private:
  struct State;
  std::unique_ptr<State> s_;
};

/// The plotting script (scripts/plot_run.py).
const std::string& plot_run_script();

/// The objects' symmetries for the figures (plot_run.py --symmetries): {"<id>": {"discrete": [pose...],
/// "continuous": {"axis": [..], "offset": [..]} or null}} for each object of `objects` with one; empty
/// object when none.
nlohmann::json symmetries_json(const std::vector<std::pair<int, ObjectSymmetry>>& objects);

/// Draws the figures of the `roe eval` output in `eval_dir` (plus, when not empty, the run folder's
/// states/objects/run.json and the dataset's truth) into the existing folder `out_dir`, with
/// /usr/bin/python3 (or $ROE_PYTHON: a path, or a name looked up on PATH). Throws InputError (exit 2)
/// when the interpreter is missing, cannot import matplotlib/numpy, or the script rejects its input
/// (each case with its own message), roe::Error (exit 3) when the script fails otherwise. The script
/// runs in its own process group and dies with roe (Ctrl-C, SIGTERM); no temporary is left.
/// `started`: plot_run_script() already started in `out_dir` (PlotProcess), or null to start it here.
FigureSet render_figures(const std::filesystem::path& eval_dir, const std::filesystem::path& run_dir,
                         const std::filesystem::path& dataset, const std::filesystem::path& out_dir,
                         const FigureOptions& options, PlotProcess* started = nullptr);

}  // namespace roe::app
