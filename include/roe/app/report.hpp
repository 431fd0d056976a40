#pragma once
/// @file
/// `roe report`: one self-contained HTML file per run (docs/report.md).
///
///   roe report RUN_DIR [--gt DATASET|GT_FILE] --out REPORT.html [--figures DIR] [--align ...] [--label L]
///              [--objects anchor|all|ID,...] [--plot-mode xy|xz|yz|xyz] [--color-by-error] [--vector pdf|svg|none]
///              [--style default|paper] [--rpe-delta D[,D...] [--rpe-unit m|s|f|deg|rad]]
///
/// Evaluates the run in-process (app/eval.hpp, into a temporary folder), runs the calibration checks
/// in-process (app/calib_check.hpp), draws the figure set once (app/figures.hpp) and writes one HTML
/// file with the run's configuration, health, counts per object, the evaluation tables, the
/// calib-check verdicts and every figure embedded as base64 PNG: it needs no network and no other file.
/// Atomic: REPORT.html (and the --figures folder) appear complete or not at all; an existing one is
/// replaced only with --force. Ctrl-C kills the plotting process and removes every temporary.

#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "roe/app/calib_check.hpp"
#include "roe/app/figures.hpp"
#include "roe/store/eval_report.hpp"
#include "roe/store/run_record.hpp"

namespace roe::app {

struct ReportOptions {
  std::string run_dir;      ///< RUN_DIR (written by roe run)
  std::string gt;           ///< --gt; default: the dataset named in run.json (inputs.dataset_abs)
  std::string out;          ///< --out REPORT.html
  std::string figures_dir;  ///< --figures DIR: also keep the figures (PNG + PDF/SVG) in this new folder
  std::string align = "se3";  ///< --align (as roe eval)
  std::string label;        ///< --label (default: the run folder's name)
  std::vector<double> rpe_delta;  ///< --rpe-delta: relative pose error per delta (table and figure), as roe eval
  std::string rpe_unit = "m";     ///< --rpe-unit, as roe eval
  FigureOptions figures;    ///< --objects, --plot-mode, --color-by-error, --vector, --style
  bool force = false;       ///< --force: replace an existing REPORT.html / figures folder
};

/// The calibration checks as the report shows them: calib-check's result, or why it could not run (a
/// trajectory-only folder: the report says so and goes on).
struct ReportCalib {
  std::optional<CalibCheckResult> result;
  std::string error;  ///< set when `result` is empty
};

struct ReportResult {
  std::string out;                 ///< REPORT.html
  std::size_t bytes = 0;           ///< its size
  std::string run, gt;             ///< RUN_DIR and the ground truth used
  std::vector<std::string> figures;                           ///< the figures drawn, by name
  std::vector<std::pair<std::string, std::string>> skipped;   ///< figures not drawn: name, reason
  std::string figures_dir;         ///< --figures ("" when not kept)
  ReportCalib calib;               ///< the calib-check outcome the report shows
  std::map<std::string, double> timing_s;  ///< eval, calib_check, figures, html, total (wall seconds)
  store::EvalReportFile eval;      ///< the evaluation's report.json
  /// The --json summary: out, bytes, figures, evaluation headline, calib-check verdict, timing.
  nlohmann::json to_json() const;
  std::string to_text() const;
};

/// InputError for bad options or inputs (exit 2), as roe eval and calib-check report them; a failing
/// calib check or an unhealthy run is reported in the file, not an error.
ReportResult write_report(const ReportOptions& options);

/// A title or caption of figures.json as HTML: escaped, X_{sub} → X<sub>sub</sub>, X^{sup} → X<sup>sup</sup>
/// (nested braces inside a mark are kept as text; an unclosed mark stays as written).
std::string caption_html(const std::string& text);

/// The HTML document (exposed for tests): `eval` is roe eval's report.json, `run` the run's run.json (null
/// when the folder has none: the detection counts, health and configuration are then left out), `calib`
/// calib-check's outcome, `figures` the figure set whose files lie in `figures_dir`.
std::string report_html(const store::EvalReportFile& eval, const store::RunRecord* run, const ReportCalib& calib,
                        const FigureSet& figures, const std::filesystem::path& figures_dir);

}  // namespace roe::app
