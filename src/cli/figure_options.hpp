#pragma once
// The figure options shared by `roe eval --plot` and `roe report` (app/figures.hpp).
#include <CLI/CLI.hpp>

#include "roe/app/figures.hpp"

namespace roe::cli {

/// Binds --objects, --plot-mode, --color-by-error, --vector and --style to `o`, in the group "Figures"; returns
/// the options (eval marks them as needing --plot).
inline std::vector<CLI::Option*> add_figure_options(CLI::App& sub, app::FigureOptions& o) {
  return {
      sub.add_option("--objects", o.objects,
                     "Reprojected raw detections drawn in Fig. 3 and the trajectory: anchor, all or ID[,ID...]")
          ->capture_default_str()
          ->group("Figures"),
      sub.add_option("--plot-mode,--plot_mode", o.plot_mode, "Trajectory figure: the plane xy, xz, yz, or 3-D xyz")
          ->capture_default_str()
          ->check(CLI::IsMember({"xy", "xz", "yz", "xyz"}))
          ->group("Figures"),
      sub.add_flag("--color-by-error", o.color_by_error, "Colour the trajectory by the position error")
          ->group("Figures"),
      sub.add_flag("--correspondences", o.correspondences,
                   "Trajectory figure: a line from each matched estimate pose to its ground truth (at most 500)")
          ->group("Figures"),
      sub.add_option("--vector", o.vector, "Vector format written beside every PNG: pdf, svg or none")
          ->capture_default_str()
          ->check(CLI::IsMember({"pdf", "svg", "none"}))
          ->group("Figures"),
      sub.add_option("--style", o.style,
                     "default (titles, footer) or paper (no titles or footers, 3.5/7.16 in wide, fonts embedded)")
          ->capture_default_str()
          ->check(CLI::IsMember({"default", "paper"}))
          ->group("Figures"),
  };
}

}  // namespace roe::cli
