// roe eval RUN_DIR|EST_FILE|BAG:TOPIC --gt DATASET|GT_FILE|BAG:TOPIC [--align ...] [--max-dt S] [--t-offset S] [--out DIR]
// [--euler error|absolute|absolute-unwrapped] [--fit-body-rotation]
// [--plot] [--rpe-delta D[,D...] --rpe-unit m|s|f|deg|rad ...] roe eval --summary REPORT_JSON... [--out FILE]
#include <filesystem>
#include <fmt/format.h>

#include <cmath>
#include <functional>
#include <memory>

#include "command.hpp"
#include "evo_syntax.hpp"
#include "figure_options.hpp"
#include "roe/app/eval.hpp"
#include "roe/core/error.hpp"

namespace roe::cli {
namespace fs = std::filesystem;
namespace {

struct EvalArgs {
  app::EvalOptions opt;
  bool evo_align = false, evo_scale = false, evo_origin = false;  // evo's -a, -s (-as), --align_origin
  std::vector<std::string> words;   // positional: EST, or evo's FORMAT REF EST / bag BAG REF EST
  std::string evo_ref;              // evo_traj's --ref
  std::string evo_pose_relation;    // evo's -r/--pose_relation
  std::string t_offset = "0";       // --t-offset S|auto
  bool evo_pairs_from_reference = false;
  std::vector<std::string> summary;
  std::vector<CLI::Option*> eval_only;  // options of an evaluation, meaningless with --summary
  std::vector<CLI::Option*> plot_only;  // figure options, meaningless without --plot
};

/// evo's -a / -s / -as / --align_origin as roe's --align; a contradiction or evo's scale-only
/// correction (-s without -a, which roe has no alignment for) is refused with the roe spelling.
void apply_evo_alignment(EvalArgs& a, bool align_given) {
  const int n = (a.evo_align || a.evo_scale) + a.evo_origin;
  if (n == 0) return;
  if (align_given || n > 1)
    throw InputError("evo's -a/-s/--align_origin and --align name the alignment twice: pass one "
                     "(--align se3|sim3|posyaw|origin|none)",
                     {"", 0, 0, "align"});
  if (a.evo_scale && !a.evo_align)
    throw InputError("-s (evo's --correct_scale without --align) corrects the scale alone, which roe does not "
                     "do: pass -as or --align sim3 (scale and pose), or --align se3",
                     {"", 0, 0, "correct_scale"});
  a.opt.align = a.evo_origin ? "origin" : a.evo_scale ? "sim3" : "se3";
}

/// The positional words and --ref as the estimate, the ground truth and their formats; the reference or a
/// format named twice (evo's form and --gt / --est-format) is refused.
void apply_eval_words(EvalArgs& a) {
  const EvalInputs in = read_eval_words(a.words, a.evo_ref);
  a.opt.est = in.est;
  if (!in.gt.empty()) {
    if (!a.opt.gt.empty())
      throw InputError(fmt::format("the ground truth is named twice: --gt {} and {}", a.opt.gt, in.gt),
                       {"roe eval", 0, 0, "gt"});
    a.opt.gt = in.gt;
  }
  const auto set_format = [](std::string& f, const std::string& v, const char* key) {
    if (v == "auto") return;
    if (f != "auto" && f != v)
      throw InputError(fmt::format("--{} {} contradicts evo's form, which reads it as {}", key, f, v),
                       {"roe eval", 0, 0, key});
    f = v;
  };
  set_format(a.opt.est_format, in.est_format, "est-format");
  set_format(a.opt.gt_format, in.gt_format, "gt-format");
  if (a.evo_pairs_from_reference) a.opt.rpe_pairs_from = "gt";
}

/// The estimate, the ground truth and how they are matched and compared. Returns --align (an evo
/// spelling of the alignment may not name it twice).
CLI::Option* add_input_options(CLI::App& sub, EvalArgs& a) {
  sub.add_option("estimate", a.words,
                 "Run folder (trajectory.csv [+ reprojection.csv, states.csv]), trajectory file, or BAG:TOPIC (ROS 1/2 "
                 "bag); or evo's form: tum|kitti|euroc REF EST, bag|bag2 BAG REF_TOPIC EST_TOPIC");
  a.eval_only.push_back(sub.add_option(
      "--gt", a.opt.gt,
      "Ground truth: dataset folder (state_groundtruth_estimate0 or mocap0), trajectory file or BAG:TOPIC "
      "(default for a run folder: the dataset its run.json names)"));
  CLI::Option* align =
      sub.add_option("--align", a.opt.align, "Alignment: se3, sim3, posyaw, origin or none")
          ->capture_default_str();
  a.eval_only.push_back(align);
  a.eval_only.push_back(
      sub.add_option("--n-align,--n_to_align", a.opt.n_align, "Align on the first N matched pairs (-1: all)")
          ->capture_default_str());
  a.eval_only.push_back(
      sub.add_option("--max-dt,--t_max_diff", a.opt.max_dt_s, "Max |dt| in seconds for a match (evo --t_max_diff)")
          ->capture_default_str());
  a.eval_only.push_back(
      sub.add_option("--t-offset,--t_offset", a.t_offset,
                     "Seconds added to the estimate stamps (evo --t_offset), or auto: estimated from the angular "
                     "rates and refined by minimising the APE, reported with its sigma")
          ->capture_default_str());
  a.eval_only.push_back(sub.add_option("--t-offset-max", a.opt.t_offset_max_s,
                                        "With --t-offset auto: search the offset within +-S seconds")
                             ->capture_default_str()
                             ->check(number_in("positive")));
  a.eval_only.push_back(sub.add_option("--t-start,--t_start", a.opt.t_start,
                                        "Only pairs from this time on (seconds, the ground truth's clock; evo --t_start)"));
  a.eval_only.push_back(sub.add_option("--t-end,--t_end", a.opt.t_end,
                                        "Only pairs up to this time (seconds, the ground truth's clock; evo --t_end)"));
  a.eval_only.push_back(sub.add_option("--align-window", a.opt.align_window,
                                        "Fit the alignment on the pairs between T0:T1 only (seconds, the ground "
                                        "truth's clock); the metrics cover every pair"));
  a.eval_only.push_back(sub.add_option("--gt-body-pose", a.opt.gt_body_pose,
                                        "The estimate's body in the ground truth's body, T_B_I, as x,y,z,qx,qy,qz,qw "
                                        "(m, quaternion x first) or a file holding that line: T_W_I = T_W_B*T_B_I"));
  a.eval_only.push_back(sub.add_flag("--kitti", a.opt.kitti,
                                      "Also the KITTI odometry devkit's drift: t_rel [%] and r_rel [deg/100 m] over "
                                      "segments of 100..800 m from every 10th pose"));
  a.eval_only.push_back(sub.add_flag("--fit-body-pose", a.opt.fit_body_pose,
                                      "Fit T_B_I (rotation and lever arm, hand-eye with the alignment) and evaluate "
                                      "with it; reported with its sigma, the lever arm 'unobservable' where the "
                                      "body turns too little"));
  a.eval_only.push_back(
      sub.add_option("--assoc", a.opt.assoc, "Association: nearest (evo), unique (one-to-one, cnspy-like) or interpolate (the ground truth "
                     "interpolated at each estimate stamp)")
          ->capture_default_str());
  a.eval_only.push_back(sub.add_option("--est-format", a.opt.est_format,
                                        "Estimate file format: auto, tum, euroc, csv (cnspy), csv-ns (roe), kitti")
                             ->capture_default_str());
  a.eval_only.push_back(sub.add_option("--gt-format", a.opt.gt_format,
                                        "Ground-truth file format: auto, tum, euroc, csv, csv-ns, kitti")
                             ->capture_default_str());
  a.eval_only.push_back(
      sub.add_option("--gt-source", a.opt.gt_source, "For a dataset: auto, groundtruth or mocap")
          ->capture_default_str());
  a.eval_only.push_back(sub.add_option("--est-times", a.opt.est_times,
                                        "Times file of a KITTI estimate (seconds, one per pose; default: "
                                        "associate by index, as evo)"));
  a.eval_only.push_back(sub.add_option("--gt-times", a.opt.gt_times, "Times file of a KITTI ground truth"));
  a.eval_only.push_back(
      sub.add_option("--euler", a.opt.euler,
                     "Per-axis Euler figures: error (ZYX of the rotation error R_est^T*R_gt), absolute (wrapped "
                     "difference of the absolute ZYX angles, ov_eval) or absolute-unwrapped (the same without "
                     "the wrap: 360-deg jumps); the last two are not rotation errors")
          ->capture_default_str());
  a.eval_only.push_back(sub.add_flag(
      "--fit-body-rotation", a.opt.fit_body_rotation,
      "Also fit the constant rotation between the estimated and true body frames after the alignment (mean of "
      "R_est^T*R_gt on SO(3)) and report the metrics with it removed (a diagnostic, never applied to the headline)"));
  a.eval_only.push_back(sub.add_option(
      "--detections", a.opt.detections,
      "Calibrate the sigmas of this detection set of the --gt dataset (or this detections.csv) against the "
      "truth (default: the set run.json names, when it has sigmas)"));
  return align;
}

/// Where the results go and how they are labelled and drawn.
void add_output_options(CLI::App& sub, EvalArgs& a) {
  sub.add_option(
      "--out", a.opt.out,
      "Output folder (default RUN_DIR/eval for a run folder); with --summary: FILE[.csv|.json|.md] "
      "writes all three, a folder (existing, or ending in /) gets summary.csv/.json/.md");
  a.eval_only.push_back(sub.add_flag("--no-out", a.opt.no_out, "Write no files, only print the result"));
  a.eval_only.push_back(
      sub.add_option("--label", a.opt.label, "Name of this run in reports and summaries"));
  a.eval_only.push_back(sub.add_flag(
      "-p,--plot", a.opt.plot,
      "Draw the figures (PNG + PDF) into OUT/plots with /usr/bin/python3 + matplotlib (docs/report.md)"));
  a.plot_only = add_figure_options(sub, a.opt.figures);
  a.eval_only.insert(a.eval_only.end(), a.plot_only.begin(), a.plot_only.end());
}

/// --rpe-delta and the RPE options that mean nothing without it.
struct RpeOptions {
  CLI::Option* delta = nullptr;
  std::vector<CLI::Option*> only;  ///< meaningless without --rpe-delta
};

RpeOptions add_rpe_options(CLI::App& sub, EvalArgs& a) {
  auto* rpe_delta =
      sub.add_option("--rpe-delta,--delta", a.opt.rpe_delta,
                     "Relative pose error over this delta (several: 1,2,5); unit from --rpe-unit")
          ->delimiter(',')
          ->group("Relative pose error");
  a.eval_only.push_back(rpe_delta);
  std::vector<CLI::Option*> rpe_only;
  rpe_only.push_back(sub.add_option("--rpe-unit,--delta_unit", a.opt.rpe_unit,
                                    "Unit of --rpe-delta: m (path length), s, f (matched poses), deg or rad "
                                    "(rotation); evo's default is f, evo's d and r are deg and rad")
                         ->capture_default_str()
                         ->transform(CLI::Transformer({{"d", "deg"}, {"r", "rad"}}))
                         ->group("Relative pose error"));
  rpe_only.push_back(sub.add_flag("--rpe-all-pairs,--all_pairs", a.opt.rpe_all_pairs,
                                  "Every pose pair at the delta (evo --all_pairs), not consecutive ones")
                         ->group("Relative pose error"));
  rpe_only.push_back(sub.add_option("--rpe-pairs-from", a.opt.rpe_pairs_from,
                                    "Choose the pairs on the estimate (est, evo's default) or the ground "
                                    "truth (gt, evo --pairs_from_reference)")
                         ->capture_default_str()
                         ->group("Relative pose error"));
  rpe_only.push_back(sub.add_option("--rpe-tol", a.opt.rpe_tol,
                                    "With --rpe-all-pairs: accept pairs within this fraction of the delta")
                         ->capture_default_str()
                         ->check(number_in("non-negative"))
                         ->group("Relative pose error"));
  a.eval_only.insert(a.eval_only.end(), rpe_only.begin(), rpe_only.end());
  return {rpe_delta, rpe_only};
}

/// evo's spellings of roe's options, and the evo options roe answers with its own spelling. Returns the
/// check that refuses those (run in the command's callback).
std::function<void()> add_evo_spellings(CLI::App& sub, EvalArgs& a, std::vector<CLI::Option*>& rpe_only) {
  // evo's spellings (evo_ape / evo_rpe): -a is --align se3, -as --align sim3, --align_origin --align origin.
  const std::vector<CLI::Option*> evo_align = {
      sub.add_flag("-a", a.evo_align, "evo's --align: the same as --align se3")->group("evo spellings"),
      sub.add_flag("-s,--correct_scale", a.evo_scale, "evo's --correct_scale: with -a, --align sim3 (-as)")
          ->group("evo spellings"),
      sub.add_flag("--align_origin", a.evo_origin, "evo's --align_origin: the same as --align origin")
          ->group("evo spellings")};
  a.eval_only.insert(a.eval_only.end(), evo_align.begin(), evo_align.end());
  a.eval_only.push_back(sub.add_option("--ref", a.evo_ref, "evo_traj's --ref: the ground truth (roe's --gt)")
                             ->group("evo spellings"));
  a.eval_only.push_back(sub.add_option("-r,--pose_relation", a.evo_pose_relation,
                                        "evo's pose relation: trans_part, point_distance and angle_deg are all in "
                                        "roe's report (ape_trans_m, ape_rot_deg)")
                             ->group("evo spellings"));
  rpe_only.push_back(sub.add_flag("--pairs_from_reference", a.evo_pairs_from_reference,
                                  "evo's spelling of --rpe-pairs-from gt")
                         ->group("evo spellings"));
  a.eval_only.push_back(rpe_only.back());
  const auto evo_refusals = add_evo_refusals(sub);
  a.eval_only.push_back(sub.add_option("--save_results", a.opt.save_results,
                                        "Also write evo's result file (FILE.zip) of the APE, for evo_res / evo_fig "
                                        "and roe eval --summary")
                             ->group("evo spellings"));
  return evo_refusals;
}

/// --t-offset S|auto.
void apply_t_offset(EvalArgs& a) {
  if (a.t_offset == "auto") {
    a.opt.t_offset_auto = true;
    return;
  }
  std::size_t used = 0;
  double v = 0.0;
  try {
    v = std::stod(a.t_offset, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != a.t_offset.size() || !std::isfinite(v))
    throw InputError(fmt::format("--t-offset '{}': expected seconds or auto", a.t_offset), {"", 0, 0, "t-offset"});
  a.opt.t_offset_s = v;
}

/// Options that depend on others: RPE settings need --rpe-delta, figure options need --plot.
void check_option_dependencies(const EvalArgs& a, const RpeOptions& rpe) {
  if (rpe.delta->count() == 0) {
    // The RPE settings do nothing without a delta: say so instead of ignoring them.
    for (const CLI::Option* op : rpe.only)
      if (op->count() > 0)
        throw InputError(fmt::format("{} needs --rpe-delta (the relative pose error is computed only for the "
                                     "deltas given)",
                                     op->get_name()),
                         {"", 0, 0, op->get_name().substr(2)});
  }
  for (const CLI::Option* op : a.plot_only)
    if (op->count() > 0 && !a.opt.plot)
      throw InputError(fmt::format("{} needs --plot (it is an option of the figures)", op->get_name()),
                       {"", 0, 0, op->get_name().substr(2)});
}

/// roe eval --summary REPORT...: the table of existing reports.
int run_summary(EvalArgs& a) {
  // --summary only reads existing reports: options of an evaluation would be silently ignored.
  std::string given;
  for (const CLI::Option* op : a.eval_only)
    if (op->count() > 0) given += (given.empty() ? "" : ", ") + op->get_name();
  if (!given.empty())
    throw InputError(fmt::format("--summary summarises existing report.json files and cannot be combined "
                                 "with {} (options of an evaluation): run `roe eval ESTIMATE --gt ...` "
                                 "first, then `roe eval --summary REPORT_JSON...`",
                                 given),
                     {"roe eval"});
  if (!a.opt.est.empty()) a.summary.insert(a.summary.begin(), a.opt.est);
  app::EvalSummaryOptions so;
  so.reports = a.summary;
  so.out = a.opt.out;
  so.force = globals().force;
  const auto r = app::summarize_eval_reports(so);
  // `out`: the file --out named when it is one of those written (t.md), else the table (.csv);
  // `written`: all three files.
  nlohmann::json js = r.summary;
  js["out"] = r.written.empty() ? nlohmann::json(nullptr) : nlohmann::json(r.written.front().string());
  for (const auto& w : r.written)
    if (!so.out.empty() && fs::path(so.out).lexically_normal() == w.lexically_normal()) js["out"] = w.string();
  js["written"] = nlohmann::json::array();
  for (const auto& w : r.written) js["written"].push_back(w.string());
  emit(js, r.to_text());
  return 0;
}

RunFn setup_eval(CLI::App& sub) {
  auto a = std::make_shared<EvalArgs>();
  CLI::Option* align = add_input_options(sub, *a);
  add_output_options(sub, *a);
  RpeOptions rpe = add_rpe_options(sub, *a);
  const auto evo_refusals = add_evo_spellings(sub, *a, rpe.only);
  sub.add_option("--summary", a->summary,
                 "Summarise report.json files: mean and std over runs (paper table layout)")
      ->expected(1, -1);
  return [a, rpe, align, evo_refusals]() {
    evo_refusals();
    check_pose_relation(a->evo_pose_relation);
    apply_eval_words(*a);
    apply_evo_alignment(*a, align->count() > 0);
    check_option_dependencies(*a, rpe);
    apply_t_offset(*a);
    if (!a->summary.empty()) return run_summary(*a);
    if (a->opt.est.empty())
      throw InputError("an estimate is required: roe eval RUN_DIR|EST_FILE --gt DATASET|GT_FILE",
                       {"roe eval"});
    a->opt.force = globals().force;
    const auto r = app::run_eval(a->opt);
    emit(r.report_json(), r.to_text());
    return 0;
  };
}

const Registrar reg_eval("", "eval",
                         "Evaluate an estimate against ground truth (evo-compatible APE, per-axis RMSE)", 60,
                         &setup_eval);

}  // namespace
}  // namespace roe::cli
