// roe eval: association -> alignment -> metrics -> report files (DESIGN §4, notes/eval.md §7).
#include <future>
#include "roe/app/eval.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>

#include "roe/core/error.hpp"
#include "roe/io/json.hpp"
#include "roe/io/ros/message_bag.hpp"
#include "roe/store/eval_report.hpp"
#include "roe/store/run_record.hpp"
#include "roe/io/evo_result.hpp"
#include "roe/io/csv.hpp"
#include "roe/io/input.hpp"
#include "roe/io/output.hpp"

namespace roe::app {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

struct Estimate {
  EvalInput in;
  bool run = false;
  std::vector<eval::DetectionPose> reprojection;
  bool have_reprojection = false;
  std::vector<std::optional<eval::PoseCovariance>> cov;
  std::string cov_source;
};

/// Why a run folder has no `file`: what its run.json's output level left out (store::run_file_absent_reason),
/// else that it is missing.
std::string absent_run_file(const fs::path& run_dir, const std::string& file) {
  const fs::path rj = run_dir / "run.json";
  if (io::path_exists(rj)) {
    const std::string why = store::run_file_absent_reason(store::read_run_json(rj).config, file);
    if (!why.empty()) return why;
  }
  return "the run folder has no " + file;
}

Estimate load_estimate(const EvalOptions& o, std::vector<std::string>& warnings) {
  Estimate e;
  e.in.path = o.est;
  if (o.est.empty()) throw InputError("an estimate (RUN_DIR or EST_FILE) is required", {"roe eval"});
  if (auto bag = load_bag_trajectory(o.est, warnings)) {  // BAG:TOPIC
    e.in = std::move(*bag);
    return e;
  }
  if (!io::path_exists(e.in.path)) throw InputError("estimate not found", {o.est});
  if (io::is_folder(e.in.path)) {
    const fs::path traj = e.in.path / "trajectory.csv";
    if (!io::path_exists(traj)) {
      if (!io::detect_bag_kind(e.in.path).empty())
        throw InputError("this is a ROS bag (a rosbag2 folder), not a run folder: name the pose topic, "
                         "BAG:TOPIC (BAG:/tf:PARENT.CHILD for tf), or use evo's form "
                         "`roe eval bag2 BAG REF_TOPIC EST_TOPIC`",
                         {o.est});
      throw InputError(
          "not a run folder: it has no trajectory.csv (pass a trajectory file or a `roe run` output)",
          {o.est});
    }
    e.run = true;
    e.in.kind = "run";
    if (o.est_format != "auto")
      warnings.push_back(
          fmt::format("--est-format {} is ignored for a run folder (its trajectory.csv is read "
                      "as roe writes it)",
                      o.est_format));
    e.in.traj = io::read_trajectory(traj, io::TrajectoryFormat::kAuto);
    e.in.description = fmt::format("run folder {} (trajectory.csv)", o.est);
    const fs::path rep = e.in.path / "reprojection.csv";
    if (io::path_exists(rep)) {
      e.reprojection = read_reprojection_csv(rep);
      e.have_reprojection = true;
    } else {
      warnings.push_back("per-object reprojection traces not computed: " + absent_run_file(e.in.path, "reprojection.csv"));
    }
    const fs::path states = e.in.path / "states.csv";
    if (!io::path_exists(states)) {
      warnings.push_back("NEES not computed: " + absent_run_file(e.in.path, "states.csv"));
    } else {
      std::string why;
      e.cov = read_states_covariance(states, e.in.traj.t_ns, &why);
      if (e.cov.empty()) {
        warnings.push_back("NEES not computed: " + why);
      } else {
        e.cov_source = "states.csv (diagonal: one standard deviation per axis)";
      }
    }
  } else {
    e.in.kind = "file";
    e.in.traj = io::read_trajectory(e.in.path, io::parse_trajectory_format(o.est_format));
    if (!o.est_times.empty()) io::apply_kitti_times(e.in.traj, o.est_times);
    e.in.description = fmt::format("{} ({})", o.est, io::to_string(e.in.traj.format));
    if (!e.in.traj.cov.empty()) {
      e.cov.resize(e.in.traj.size());
      for (std::size_t i = 0; i < e.in.traj.size(); ++i) {
        eval::PoseCovariance c;
        c.P_p = e.in.traj.cov[i].topLeftCorner<3, 3>();
        // cnspy type1: position error in the body frame -> world: R P Rᵀ.
        if (e.in.traj.cov_position_local)
          c.P_p = e.in.traj.poses[i].R() * c.P_p * e.in.traj.poses[i].R().transpose();
        c.P_theta = e.in.traj.cov[i].bottomRightCorner<3, 3>();
        e.cov[i] = c;
      }
      e.cov_source = "covariance columns of the estimate file";
    }
  }
  return e;
}

/// InputError naming the option for an unknown trajectory format.
io::TrajectoryFormat parse_format_option(const std::string& value, const std::string& option) {
  try {
    return io::parse_trajectory_format(value);
  } catch (const InputError& e) {
    throw InputError(option + ": " + e.bare_message(), {"", 0, 0, option.substr(2)});
  }
}

void check_gt_source(const std::string& v) {
  if (v != "auto" && v != "groundtruth" && v != "mocap")
    throw InputError(fmt::format("unknown --gt-source '{}' (expected auto, groundtruth or mocap)", v),
                     {"", 0, 0, "gt-source"});
}

/// `roe eval RUN_DIR` without --gt: the dataset the run's run.json names (store::find_run_dataset). `note` says where the ground truth came from.
EvalOptions with_ground_truth(EvalOptions o, std::string& note) {
  if (!o.gt.empty()) return o;
  if (!o.est.empty() && !io::path_exists(o.est)) throw InputError("estimate not found", {o.est});
  if (o.est.empty() || !io::is_folder(o.est))
    throw InputError("--gt DATASET|GT_FILE is required (only a run folder's run.json names its dataset)",
                     {"roe eval"});
  const fs::path rj = fs::path(o.est) / "run.json";
  if (!io::path_exists(rj))
    throw InputError("--gt DATASET is required: this folder has no run.json naming the dataset it ran on",
                     {o.est});
  if (const auto d = store::find_run_dataset(store::read_run_json(rj))) {
    o.gt = d->string();
    note = fmt::format("the dataset {} names ({})", rj.string(), o.gt);
    return o;
  }
  throw InputError("--gt DATASET is required: the dataset this run names is not there any more (pass --gt)",
                   {rj.string(), 0, 0, "inputs.dataset"});
}

/// KITTI files without times are associated by index (evo's convention), which needs both of them so.
void check_kitti_pairing(const EvalInput& est, const std::string& est_times, const EvalInput& gt,
                         const std::string& gt_times) {
  const bool est_index = est.traj.format == io::TrajectoryFormat::kKitti && est_times.empty();
  const bool gt_index = gt.traj.format == io::TrajectoryFormat::kKitti && gt_times.empty();
  if (est_index == gt_index) {
    if (est_index && est.traj.size() != gt.traj.size())
      throw InputError(fmt::format("KITTI files are associated by index (as evo does) but the estimate has {} "
                                   "poses and the ground truth {}: pass their times files (--est-times, "
                                   "--gt-times)",
                                   est.traj.size(), gt.traj.size()),
                       {est.path.string()});
    return;
  }
  throw InputError(fmt::format("the {} is a KITTI pose file without stamps (associated by index) but the {} has "
                               "time stamps: pass its times file with {}",
                               est_index ? "estimate" : "ground truth", est_index ? "ground truth" : "estimate",
                               est_index ? "--est-times" : "--gt-times"),
                   {(est_index ? est.path : gt.path).string()});
}

/// Seconds as decimal text (the trajectory readers' rule) into ns; InputError naming `key`.
Timestamp parse_time_option(const std::string& text, const char* key) {
  if (const auto t = io::parse_seconds_ns(text)) return *t;
  throw InputError(fmt::format("--{} '{}' is not a time in seconds", key, text), {"", 0, 0, key});
}

/// --gt-body-pose's value: the 7 numbers, or a file whose first line that is not a comment holds them
/// (commas or blanks between them).
Pose read_body_pose_option(const std::string& v) {
  if (v.find(',') != std::string::npos && !io::path_exists(v)) return eval::parse_pose_text(v, "gt-body-pose");
  if (!io::path_exists(v))
    throw InputError("--gt-body-pose: neither x,y,z,qx,qy,qz,qw nor an existing file", {v, 0, 0, "gt-body-pose"});
  const std::string text = io::read_file(v);
  std::int64_t line_no = 0;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t end = std::min(text.find('\n', start), text.size());
    std::string line = text.substr(start, end - start);
    ++line_no;
    start = end + 1;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::replace(line.begin(), line.end(), '\t', ' ');
    std::string joined;  // blanks or commas between the numbers
    bool sep = false;
    for (char c : line.substr(first)) {
      if (c == ' ' || c == ',' || c == '\r') {
        sep = !joined.empty();
        continue;
      }
      if (sep) joined += ',';
      sep = false;
      joined += c;
    }
    try {
      return eval::parse_pose_text(joined, "gt-body-pose");
    } catch (const InputError& e) {
      throw InputError(e.bare_message(), {v, line_no, 0, "gt-body-pose"});
    }
  }
  throw InputError("--gt-body-pose: the file holds no pose line (x,y,z,qx,qy,qz,qw)", {v, 0, 0, "gt-body-pose"});
}

/// --t-offset auto, the body pose and the windows as evaluation parameters.
void apply_frame_options(const EvalOptions& o, eval::EvalParams& p) {
  p.auto_offset = o.t_offset_auto;
  p.auto_offset_max_s = o.t_offset_max_s;
  if (!o.gt_body_pose.empty()) p.gt_body_pose = read_body_pose_option(o.gt_body_pose);
  p.fit_body_pose = o.fit_body_pose;
  p.kitti = o.kitti;
  if (!o.t_start.empty()) p.t_start_ns = parse_time_option(o.t_start, "t-start");
  if (!o.t_end.empty()) p.t_end_ns = parse_time_option(o.t_end, "t-end");
  if (!o.align_window.empty()) {
    const auto colon = o.align_window.find(':');
    if (colon == std::string::npos)
      throw InputError(fmt::format("--align-window '{}': expected T0:T1 (seconds)", o.align_window),
                       {"", 0, 0, "align-window"});
    p.align_window_ns = {parse_time_option(o.align_window.substr(0, colon), "align-window"),
                         parse_time_option(o.align_window.substr(colon + 1), "align-window")};
  }
}

/// The evaluation parameters from the options, and the warnings they alone imply. Every option value is
/// checked, even where it does not apply to the inputs given, before any file is read.
eval::EvalParams eval_params(const EvalOptions& o, std::vector<std::string>& warnings) {
  eval::EvalParams p;
  p.align = eval::parse_align_type(o.align);
  p.n_align = o.n_align;
  p.assoc.max_dt_s = o.max_dt_s;
  p.assoc.offset_s = o.t_offset_s;
  p.assoc.policy = eval::parse_assoc_policy(o.assoc);
  p.euler = eval::parse_euler_metric(o.euler);
  p.fit_body_rotation = o.fit_body_rotation;
  apply_frame_options(o, p);
  (void)eval::check_params(p);  // --max-dt and --n-align before the other options
  if (o.no_out && !o.out.empty())
    throw InputError(fmt::format("--no-out and --out {} contradict each other: pass one of them", o.out),
                     {"", 0, 0, "no-out"});
  (void)parse_format_option(o.est_format, "--est-format");
  (void)parse_format_option(o.gt_format, "--gt-format");
  check_gt_source(o.gt_source);
  if (o.plot) check_figure_options(o.figures);
  for (double d : o.rpe_delta) {
    eval::RpeOptions r;
    r.delta = d;
    r.unit = eval::parse_delta_unit(o.rpe_unit);
    r.all_pairs = o.rpe_all_pairs;
    r.pairs_from = eval::parse_pairs_from(o.rpe_pairs_from);
    r.rel_tol = o.rpe_tol;
    p.rpe.push_back(r);
  }
  warnings = eval::check_params(p);
  return p;
}

store::ReportInput report_input(const EvalInput& in) {
  return {in.path.string(), in.kind, io::to_string(in.traj.format), in.description, in.traj.size(),
          in.traj.count_duplicate_stamps()};
}

nlohmann::json options_json(const EvalOptions& o) {
  json j = {{"est_format", o.est_format},         {"gt_format", o.gt_format},
            {"rpe_all_pairs", o.rpe_all_pairs}, {"rpe_pairs_from", o.rpe_pairs_from},
            {"rpe_tol", o.rpe_tol},             {"detections", o.detections},
            {"euler", o.euler},                 {"fit_body_rotation", o.fit_body_rotation},
            {"t_offset_auto", o.t_offset_auto}, {"fit_body_pose", o.fit_body_pose},
            {"kitti", o.kitti}};
  for (const auto& [key, v] : {std::pair{"gt_body_pose", &o.gt_body_pose}, std::pair{"t_start", &o.t_start},
                               std::pair{"t_end", &o.t_end}, std::pair{"align_window", &o.align_window}})
    if (!v->empty()) j[key] = *v;
  for_each_sweep_eval_setting(o, [&j](const char* key, const auto& value) { j[key] = value; });
  if (!o.est_times.empty()) j["est_times"] = o.est_times;
  if (!o.gt_times.empty()) j["gt_times"] = o.gt_times;
  return j;
}

/// --plot without --out for a file estimate: ./eval_LABEL, the label's characters outside [A-Za-z0-9._-] as '_'.
fs::path default_plot_folder(const std::string& label) {
  std::string name = "eval_" + label;
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_' && c != '-') c = '_';
  return fs::path(name);
}

/// The output folder: --out, else RUN_DIR/eval for a run folder; empty for none.
fs::path output_folder(const EvalOptions& o, const Estimate& est) {
  if (o.no_out) return {};
  if (!o.out.empty()) return o.out;
  return est.run ? est.in.path / "eval" : fs::path();
}

}  // namespace

void check_sweep_eval_setting(const EvalOptions& o, const std::string& key) {
  eval::EvalParams p;  // the defaults, with the one setting `key` from `o`
  if (key == "align") (void)eval::parse_align_type(o.align);
  if (key == "assoc") (void)eval::parse_assoc_policy(o.assoc);
  if (key == "gt_source") check_gt_source(o.gt_source);
  if (key == "rpe_unit") (void)eval::parse_delta_unit(o.rpe_unit);
  if (key == "n_align") p.n_align = o.n_align;
  if (key == "max_dt_s") p.assoc.max_dt_s = o.max_dt_s;
  if (key == "rpe_delta")
    for (double d : o.rpe_delta) {
      eval::RpeOptions r;
      r.delta = d;
      p.rpe.push_back(r);
    }
  (void)eval::check_params(p);
}

void read_sweep_t_offset(const json& value, EvalOptions& o) {
  o.t_offset_auto = value.is_string() && value.get<std::string>() == "auto";
  o.t_offset_s = 0.0;
  if (o.t_offset_auto) return;
  if (!value.is_number() || !std::isfinite(value.get<double>()))
    throw InputError("expected seconds (a finite number) or \"auto\" (--t-offset auto), got " + io::dump_json(value),
                     {"", 0, 0, "t_offset_s"});
  o.t_offset_s = value.get<double>();
}

json sweep_t_offset_json(const EvalOptions& o) { return o.t_offset_auto ? json("auto") : json(o.t_offset_s); }

std::string label_of(const EvalInput& in, bool is_dir) {
  if (in.kind != "bag" || in.topic.empty()) return label_from_path(in.path, is_dir);
  const std::string topic = in.topic[0] == '/' ? in.topic.substr(1) : in.topic;
  return label_from_path(in.path, false) + ":" + topic;
}

std::string label_from_path(const fs::path& path, bool is_dir) {
  fs::path p = io::without_trailing_separator(path);
  std::string name = is_dir ? p.filename().string() : p.stem().string();
  // A generic file name (EuRoC's data.csv, a run's trajectory.csv) names nothing: use the closest folder
  // that is not part of a dataset's layout (V1_01_easy for V1_01_easy/mav0/state_groundtruth_estimate0).
  static const char* const kGenericFiles[] = {"data", "trajectory", "traj", "groundtruth", "estimate",
                                              "stamped_traj_estimate", "stamped_groundtruth", "poses",
                                              "trajectory_estimate", "est", "gt"};
  static const char* const kLayoutFolders[] = {"mav0", "state_groundtruth_estimate0", "mocap0", "vicon0",
                                               "leica0", "eval", "imu0", "cam0", "cam1"};
  const auto in = [](const std::string& s, const auto& list) {
    return std::find(std::begin(list), std::end(list), s) != std::end(list);
  };
  if (is_dir || !in(name, kGenericFiles)) return name.empty() ? p.string() : name;
  for (fs::path q = p.parent_path(); !q.empty() && q.has_filename(); q = q.parent_path()) {
    const std::string f = q.filename().string();
    if (f != "." && f != ".." && !in(f, kLayoutFolders)) return f;
    if (q == q.parent_path()) break;
  }
  return name;
}

EvalResult run_eval(const EvalOptions& options) {
  std::vector<std::string> warnings;
  const eval::EvalParams params = eval_params(options, warnings);
  std::string gt_note;
  const EvalOptions o = with_ground_truth(options, gt_note);

  // The two inputs are independent: parse the ground truth on a second thread while the estimate is
  // read here (large files are parse-bound; this halves the wall time on two cores).
  std::vector<std::string> gt_warnings;
  auto gt_future = std::async(std::launch::async, [&o, &gt_warnings] { return load_ground_truth(o, gt_warnings); });
  Estimate est;
  try {
    est = load_estimate(o, warnings);
  } catch (...) {
    gt_future.wait();  // never leave the thread running past the exception
    throw;
  }
  EvalInput gt = gt_future.get();
  if (!gt_note.empty()) gt.description = "from " + gt_note + ": " + gt.description;
  warnings.insert(warnings.end(), gt_warnings.begin(), gt_warnings.end());

  check_kitti_pairing(est.in, o.est_times, gt, o.gt_times);
  const std::optional<DetectionSigmaSource> sig = load_detection_sigmas(o, est.run, warnings);
  std::optional<eval::DetectionSigmaInput> sig_in;
  if (sig) sig_in.emplace(eval::DetectionSigmaInput{sig->detections, sig->T_I_C, sig->camera_time_offset_s, sig->T_W_O});
  eval::EstimateInput ei{est.in.traj.t_ns, est.in.traj.poses, est.cov,
                         est.have_reprojection ? &est.reprojection : nullptr, o.est};
  ei.detection_sigmas = sig_in ? &*sig_in : nullptr;
  std::string no_gauge = "the estimate is not a run folder (its anchor defines the estimator's gauge)";
  const std::optional<eval::GaugeTruth> gauge = est.run ? load_gauge_truth(est.in.path, gt, &no_gauge) : std::nullopt;
  ei.gauge = gauge ? &*gauge : nullptr;
  const eval::Report rep = eval::evaluate(ei, {gt.traj.t_ns, gt.traj.poses}, params);
  warnings.insert(warnings.end(), rep.warnings.begin(), rep.warnings.end());

  store::EvalReportContext ctx;
  ctx.label = o.label.empty() ? label_of(est.in, est.run) : o.label;
  ctx.est_path = est.in.path.string();
  ctx.gt_path = gt.path.string();
  ctx.est = report_input(est.in);
  ctx.gt = report_input(gt);
  ctx.options = options_json(o);
  ctx.cov_source = est.cov_source;
  if (!gauge) ctx.no_gauge_reason = no_gauge;
  if (sig) ctx.detections_source = sig->description;
  ctx.warnings = warnings;
  store::EvalReportFile report = store::make_eval_report_file(rep, ctx);

  EvalResult res;
  // evo's result file: checked before anything is written, written after the folder (nothing half-written).
  std::optional<io::EvoResult> evo;
  if (!o.save_results.empty()) {
    io::check_file_output(o.save_results, o.force, {o.est, o.gt}, "--save_results file");
    // evo_rpe's file with --rpe-delta (one delta per file, as evo writes it), else evo_ape's.
    if (o.rpe_delta.size() > 1)
      throw InputError(fmt::format("--save_results writes one result file and --rpe-delta names {} deltas: evo_rpe "
                                   "saves one delta per file, so run one evaluation per delta",
                                   o.rpe_delta.size()),
                       {"", 0, 0, "save_results"});
    const bool by_index = est.in.traj.format == io::TrajectoryFormat::kKitti && o.est_times.empty();
    evo = o.rpe_delta.empty() ? io::evo_ape_result(rep, ctx.gt_path, ctx.est_path)
                              : io::evo_rpe_result(rep, 0, !by_index, ctx.gt_path, ctx.est_path);
    report.evo_results = o.save_results;
  }
  fs::path out = output_folder(o, est);
  if (o.plot && out.empty()) {
    if (o.no_out)
      throw InputError("--plot draws into an output folder and --no-out writes none: pass one of them",
                       {"", 0, 0, "plot"});
    out = default_plot_folder(ctx.label);  // evo shows a window; roe draws files: into ./eval_LABEL
    report.warnings.push_back(fmt::format("--plot without --out: the figures and files go to {} (pass --out DIR to "
                                          "choose)",
                                          out.string()));
  }
  if (!out.empty()) {
    io::OutputDir dir(out, o.force, {o.est, o.gt});
    report.outputs = store::ReportOutputs{out.string(), store::write_eval_files(dir, rep, ctx)};
    io::write_file_atomic(dir.file("report.json"), io::dump_json(store::to_json(report), 2) + "\n");
    if (o.plot) {
      res.plot_status = render_eval_plots(dir.tmp(), o);  // throws: a plotting failure commits nothing
      report.plots = store::ReportPlots{true, res.plot_status};
      io::write_file_atomic(dir.file("report.json"), io::dump_json(store::to_json(report), 2) + "\n");
    }
    dir.commit();
    res.out = out;
  }
  if (evo) io::write_evo_result(o.save_results, *evo);
  res.report = std::move(report);
  return res;
}

namespace {

/// The per-object table: each object's RMSE over all its matched detections (the outliers the filter
/// rejected included) and over the accepted ones alone, on two labelled rows.
std::string per_object_text(const std::vector<store::ReportObject>& objects, const std::string& euler_metric) {
  std::string s = "\n  per object (reprojected IMU pose of each raw detection, same alignment; 'all' includes the\n"
                  "  detections the filter rejected as outliers, 'accepted' only those it used)\n";
  if (euler_metric != "error") s += "  (roll/pitch/yaw under the Euler metric '" + euler_metric + "', not a rotation error)\n";
  s += "  object  detections  matched  subset        n   rmse x/y/z [m]              rmse roll/pitch/yaw [deg]   "
       "statuses\n";
  for (const store::ReportObject& o : objects) {
    std::string counts;
    for (const auto& [k, v] : o.counts) counts += (counts.empty() ? "" : ", ") + k + " " + std::to_string(v);
    for (const auto& [subset, f] : {std::pair<const char*, const store::ReportFit*>{"all", &o.all},
                                    std::pair<const char*, const store::ReportFit*>{"accepted", &o.accepted}}) {
      const bool first = f == &o.all;
      const std::string head = first ? fmt::format("  {:>6}  {:>10}  {:>7}", o.object_id, o.n_detections, o.n_matched)
                                     : std::string(29, ' ');
      const std::string tail = first ? "     " + counts : "";
      if (f->n == 0) {
        s += fmt::format("{}  {:<9} {:>5}   (no matched pose){}\n", head, subset, 0, first ? "         " + counts : "");
        continue;
      }
      const Eigen::Vector3d& p = f->pos_rmse_m;
      const Eigen::Vector3d& e = f->rpy_rmse_deg;
      s += fmt::format("{}  {:<9} {:>5}   {:7.3f} {:7.3f} {:7.3f}     {:7.2f} {:7.2f} {:7.2f}{}\n", head, subset, f->n,
                       p.x(), p.y(), p.z(), e.x(), e.y(), e.z(), tail);
    }
  }
  return s;
}

double number(const std::optional<double>& v) { return v.value_or(NAN); }

std::string rpy_row(const char* name, const Eigen::Vector3d& v) {
  return fmt::format("  {:<10} {:8.3f}  {:8.3f}  {:8.3f}\n", name, v.x(), v.y(), v.z());
}

std::string euler_rows(const eval::EulerStats& e) {
  return rpy_row("rmse", e.rmse) + rpy_row("mean", e.mean) + rpy_row("std", e.std);
}

/// The per-axis table: position RMSE, then the Euler figures (RMSE, mean, std) under their metric's name,
/// and for a metric other than `error` the rotation error's figures, the 360° jumps and a warning.
std::string per_axis_text(const store::ReportPerAxis& pa) {
  std::string s = "\n  RMSE            x         y         z   |     roll     pitch       yaw\n";
  const Eigen::Vector3d& p = pa.pos_rmse_m;
  const Eigen::Vector3d& e = pa.rpy_deg.rmse;
  s += fmt::format("  {:<10} {:9.4f} {:9.4f} {:9.4f}   | {:8.3f}  {:8.3f}  {:8.3f}   (m | deg)\n", "per-axis", p.x(),
                   p.y(), p.z(), e.x(), e.y(), e.z());
  s += fmt::format("\n  Euler [deg], metric '{}': {}\n               roll     pitch       yaw\n", pa.euler_metric,
                   pa.euler_definition);
  s += euler_rows(pa.rpy_deg);
  if (pa.euler_metric != eval::to_string(eval::EulerMetric::kError)) {
    s += "  rotation error R_est^T*R_gt (metric 'error'):\n";
    s += euler_rows(pa.rotation_error_euler_deg);
    const Eigen::Vector3d& j = pa.jump_360_share;
    s += fmt::format("  360-deg jumps of the absolute-angle difference: roll {:.2f} %, pitch {:.2f} %, yaw {:.2f} %, "
                     "any axis {:.2f} % of the pairs\n",
                     100 * j.x(), 100 * j.y(), 100 * j.z(), 100 * pa.jump_360_share_any);
    s += "  warning: the '" + pa.euler_metric + "' figures are differences of absolute Euler angles, not a rotation error\n";
  }
  return s;
}

/// --fit-body-rotation: the constant body-frame rotation and the figures with and without it.
std::string body_rotation_text(const store::ReportBodyRotation& b) {
  std::string s = fmt::format(
      "\n  body-frame rotation fit (diagnostic, not applied above): R_off = mean of R_est^T*R_gt, angle {:.3f} deg, "
      "roll/pitch/yaw {:.3f} {:.3f} {:.3f} deg\n",
      b.angle_deg, b.rpy_deg.x(), b.rpy_deg.y(), b.rpy_deg.z());
  s += fmt::format("  {:<26} {:>9} | Euler rmse roll/pitch/yaw ('{}')\n", "", "rot rmse", b.with.euler_metric);
  for (const auto& [name, m] : {std::pair{"as evaluated (without)", &b.without}, std::pair{"with R_off removed", &b.with}}) {
    const Eigen::Vector3d& e = m->rpy_deg.rmse;
    s += fmt::format("  {:<26} {:9.3f} | {:8.3f}  {:8.3f}  {:8.3f}\n", name, m->ape_rot_deg.rmse, e.x(), e.y(), e.z());
  }
  return s;
}

/// The NEES: in the estimator's gauge when there is one; else the position's after the alignment, and
/// no orientation figure (the alignment's rotation error is in no covariance).
std::string consistency_text(const store::ReportConsistency& c) {
  const store::ReportGauge& g = c.gauge;
  if (g.available)
    return fmt::format("\n  ANEES position {:.3f}, orientation {:.3f} in the estimator's gauge (expected 3 for a "
                       "consistent filter; {} poses; {})\n",
                       number(g.anees_p), number(g.anees_r), g.n, g.description);
  return fmt::format("\n  ANEES position {:.3f} after the alignment (expected 3 for a consistent filter); no orientation "
                     "ANEES: the alignment's rotation error is in no covariance, and no truth in the estimator's gauge "
                     "({})\n",
                     number(c.aligned_anees_p), g.reason);
}

/// The detection σ calibration: per object and for all, the fractions within 1/2/3σ, the NIS against
/// χ²₆ and the σ scale that would make them consistent.
std::string detection_calibration_text(const store::ReportDetectionCalibration& d) {
  static_assert(eval::kNisProbabilities[2] == 0.5, "the median is nis_quantiles[2]");
  std::string s = "\n  detection sigmas against the truth (" + d.source + ")\n";
  s += fmt::format("  {:<8} {:>5}   {:<15}  {:<15}  | {:>8} {:>7} {:>6} | {:>6} {:<7}| {:>6} {:<14}  {:>6} {:>6} {:>6}\n",
                   "object", "n", "t 1/2/3 sig [%]", "r 1/2/3 sig [%]", "NIS mean", "median", ">gate", "KS D", "p",
                   "scale", "[95 %]", "t", "r", "median");
  const auto row = [&s](const std::string& name, const eval::SigmaCalibration& c) {
    const auto pct = [](const std::array<double, 3>& a) {
      return fmt::format("{:4.1f} {:4.1f} {:5.1f}", 100 * a[0], 100 * a[1], 100 * a[2]);
    };
    s += fmt::format("  {:<8} {:>5}   {}  {}  | {:8.2f} {:7.2f} {:5.1f}% | {:6.3f} {:<7.2g}| {:6.3f} {:<14}  {:6.3f} "
                     "{:6.3f} {:6.3f}\n",
                     name, c.n, pct(c.within_t), pct(c.within_r), c.nis_mean, c.nis_quantiles[2],
                     100 * c.frac_above_gate, c.ks_statistic, c.ks_p_value, c.sigma_scale,
                     fmt::format("[{:.3f}, {:.3f}]", c.sigma_scale_lo, c.sigma_scale_hi), c.sigma_scale_t,
                     c.sigma_scale_r, c.sigma_scale_median);
  };
  for (const eval::ObjectCalibration& o : d.per_object) row(std::to_string(o.object_id), o.cal);
  row("all", d.all);
  const store::ExpectedCalibration ex = store::expected_calibration();
  const auto& w = ex.within_sigma;
  s += fmt::format("  consistent: {:.1f} {:.1f} {:.1f} % within 1/2/3 sigma, NIS mean 6, median {:.2f}, {:.0f} % above the "
                   "gate {:.2f}, scale 1 (scale = true errors / reported sigma; R would need scale^2)\n",
                   100 * w[0], 100 * w[1], 100 * w[2], ex.nis_quantiles[2], 100 * ex.frac_above_gate, ex.gate);
  return s;
}

/// The RPE table: one row per block.
std::string rpe_text(const std::vector<store::ReportRpe>& rpe) {
  std::string s = "\n  RPE            pairs  trans rmse [m]   mean    median   |  rot rmse [deg]   mean   |  drift [%]\n";
  for (const store::ReportRpe& e : rpe) {
    const std::string what =
        fmt::format("{} {}{}{}", e.delta, e.unit, e.all_pairs ? ", all" : "", e.pairs_from == "gt" ? ", gt" : "");
    if (e.n_pairs == 0 || !e.trans_m || !e.rot_deg) {
      s += fmt::format("  {:<13} {:>6}  (none)\n", what, 0);
      continue;
    }
    s += fmt::format("  {:<13} {:>6}  {:13.4f} {:8.4f} {:8.4f}   | {:14.3f} {:7.3f}   | {:8}\n", what, e.n_pairs,
                     e.trans_m->rmse, e.trans_m->mean, e.trans_m->median, e.rot_deg->rmse, e.rot_deg->mean,
                     e.drift_pct ? fmt::format("{:.2f}", e.drift_pct->mean) : std::string("-"));
  }
  return s;
}

/// --kitti: the devkit's figures over all lengths, then per length.
std::string kitti_text(const eval::KittiDrift& k) {
  std::string s = fmt::format("\n  KITTI (devkit rule, {} segments): t_rel {:.4f} %, r_rel {:.4f} deg/100 m\n", k.n_segments,
                              k.t_rel_pct, k.r_rel_deg_per_100m);
  s += "    length [m]  segments   t_rel [%]   r_rel [deg/100 m]\n";
  for (const eval::KittiLength& l : k.per_length)
    s += fmt::format("    {:10.0f}  {:8}   {:9.4f}   {:9.4f}\n", l.length_m, l.n_segments, l.t_rel_pct,
                     l.r_rel_deg_per_100m);
  return s;
}

/// The time offset, the body pose and the windows, where asked for.
std::string frames_text(const store::EvalReportFile& r) {
  std::string s;
  if (r.time_offset) {
    const store::ReportTimeOffset& o = *r.time_offset;
    s += fmt::format("  time offset (--t-offset auto) {:+.4f} s ± {:.4f} s (t_gt = t_est + offset; angular-rate "
                     "correlation {:+.4f} s, peak {:.2f}{}){}\n",
                     o.offset_s, o.sigma_s, o.coarse_offset_s, o.correlation,
                     o.peak_at_edge ? ", at the edge of the search" : "", o.refined ? "" : "; APE refinement failed");
  }
  if (r.body_pose) {
    const store::ReportBodyPose& b = *r.body_pose;
    s += fmt::format("  body pose T_B_I ({}) p {:.4f} {:.4f} {:.4f} m, rotation {:.3f} deg (roll/pitch/yaw {:.3f} {:.3f} "
                     "{:.3f})\n",
                     b.source, b.p[0], b.p[1], b.p[2], b.angle_deg, b.rpy_deg.x(), b.rpy_deg.y(), b.rpy_deg.z());
    if (b.fit)
      s += fmt::format("    sigma p {:.4f} {:.4f} {:.4f} m, rotation {:.3f} deg; rotation spread {:.1f}..{:.1f} deg; "
                       "lever arm {}\n",
                       b.fit->sigma_p_m[0], b.fit->sigma_p_m[1], b.fit->sigma_p_m[2], b.fit->sigma_rot_deg,
                       b.fit->rotation_spread_min_deg, b.fit->rotation_spread_max_deg, b.fit->verdict);
  }
  if (r.window) {
    const store::ReportWindow& w = *r.window;
    const auto t = [](const std::optional<double>& v) { return v ? fmt::format("{:.3f}", *v) : std::string("-"); };
    if (w.t_start_s || w.t_end_s)
      s += fmt::format("  window {} .. {} s (ground-truth clock): {} matched pairs left out\n", t(w.t_start_s),
                       t(w.t_end_s), w.n_cropped);
    if (w.align_window_s)
      s += fmt::format("  alignment window {:.3f} .. {:.3f} s\n", (*w.align_window_s)[0], (*w.align_window_s)[1]);
  }
  return s;
}

}  // namespace

nlohmann::json EvalResult::report_json() const { return store::to_json(report); }

std::string EvalResult::to_text() const {
  const store::EvalReportFile& r = report;
  std::string s;
  const store::ReportAssociation& as = r.association;
  const store::ReportAlignment& al = r.alignment;
  s += fmt::format("roe eval: {}\n", r.label);
  s += fmt::format("  estimate     {}\n", r.est.description);
  s += fmt::format("  ground truth {}\n", r.gt.description);
  s += fmt::format("  matched {} of {} estimate / {} ground-truth poses (max dt {} s, offset {} s, {})\n", as.n_matched,
                   as.n_est, as.n_gt, as.max_dt_s, as.offset_s, as.policy);
  s += fmt::format("  alignment {} on {} pairs, scale {:.6f}{}\n", al.type, al.n_aligned, al.scale,
                   al.tilt_deg ? fmt::format(", tilt of z {:.2f} deg", *al.tilt_deg) : std::string());
  s += frames_text(r);
  s += per_axis_text(r.per_axis);
  if (r.body_rotation) s += body_rotation_text(*r.body_rotation);
  s += "\n  APE            rmse      mean    median       std       min       max\n";
  for (const auto& [st, name] : {std::pair{&r.ape_trans_m, "trans [m]"}, std::pair{&r.ape_rot_deg, "rot [deg]"}})
    s += fmt::format("  {:<10} {:9.4f} {:9.4f} {:9.4f} {:9.4f} {:9.4f} {:9.4f}\n", name, st->rmse, st->mean, st->median,
                     st->std, st->min, st->max);
  if (!r.rpe.empty()) s += rpe_text(r.rpe);
  if (r.kitti) s += kitti_text(*r.kitti);
  if (r.consistency.available) s += consistency_text(r.consistency);
  if (!r.per_object.empty()) s += per_object_text(r.per_object, r.euler_metric);
  if (r.detection_calibration) s += detection_calibration_text(*r.detection_calibration);
  for (const std::string& w : r.warnings) s += "  warning: " + w + "\n";
  if (!out.empty()) s += fmt::format("\n  wrote {}\n", out.string());
  if (!plot_status.empty()) s += "  plots: " + plot_status + "\n";
  return s;
}

}  // namespace roe::app
