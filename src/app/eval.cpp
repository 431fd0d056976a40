// roe eval: association -> alignment -> metrics -> report files (DESIGN §4, notes/eval.md §7).
#include <future>
#include "roe/app/eval.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "roe/core/error.hpp"
#include "roe/io/json.hpp"
#include "roe/io/csv.hpp"
#include "roe/io/output.hpp"
#include "roe/math/euler.hpp"
#include "roe/version.hpp"

namespace roe::app {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

json stats_json(const eval::Stats& s) {
  return {{"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median}, {"std", s.std},
          {"min", s.min},   {"max", s.max},   {"sse", s.sse},       {"n", s.n}};
}
json xyz_json(const Eigen::Vector3d& v) { return {{"x", v.x()}, {"y", v.y()}, {"z", v.z()}}; }
json rpy_json(const Eigen::Vector3d& v) { return {{"roll", v.x()}, {"pitch", v.y()}, {"yaw", v.z()}}; }

/// Path length of a sequence of positions.
double path_length(const std::vector<Pose>& p) {
  double L = 0.0;
  for (std::size_t i = 1; i < p.size(); ++i) L += (p[i].p - p[i - 1].p).norm();
  return L;
}

struct Estimate {
  EvalInput in;
  bool run = false;
  std::vector<ReprojectionCsvRow> reprojection;
  bool have_reprojection = false;
  std::vector<std::optional<eval::PoseCovariance>> cov;
  std::string cov_source;
};

Estimate load_estimate(const EvalOptions& o, std::vector<std::string>& warnings) {
  Estimate e;
  e.in.path = o.est;
  if (o.est.empty()) throw InputError("an estimate (RUN_DIR or EST_FILE) is required", {"roe eval"});
  if (!io::path_exists(e.in.path)) throw InputError("estimate not found", {o.est});
  if (io::is_folder(e.in.path)) {
    const fs::path traj = e.in.path / "trajectory.csv";
    if (!io::path_exists(traj)) {
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
    }
    const fs::path states = e.in.path / "states.csv";
    if (io::path_exists(states)) {
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

std::string default_label(const fs::path& p) {
  fs::path q = p;
  if (q.filename().empty()) q = q.parent_path();
  return io::is_folder(q) ? q.filename().string() : q.stem().string();
}

}  // namespace

EvalResult run_eval(const EvalOptions& o) {
  std::vector<std::string> warnings;
  // Options first, so usage errors come before any file is read.
  const eval::AlignType align = eval::parse_align_type(o.align);
  eval::AssociationOptions ao;
  ao.max_dt_s = o.max_dt_s;
  ao.offset_s = o.t_offset_s;
  ao.policy = eval::parse_assoc_policy(o.assoc);
  if (!(o.max_dt_s >= 0.0) || !std::isfinite(o.max_dt_s))
    throw InputError(fmt::format("--max-dt must be ≥ 0, got {}", o.max_dt_s), {"", 0, 0, "max-dt"});
  if (o.n_align == 0 || o.n_align < -1)
    throw InputError(fmt::format("--n-align must be -1 (all) or ≥ 1, got {}", o.n_align),
                     {"", 0, 0, "n-align"});
  if (o.no_out && !o.out.empty())
    throw InputError(fmt::format("--no-out and --out {} contradict each other: pass one of them", o.out),
                     {"", 0, 0, "no-out"});
  // Every option value is checked, even where it does not apply to the inputs given.
  (void)parse_format_option(o.est_format, "--est-format");
  (void)parse_format_option(o.gt_format, "--gt-format");
  check_gt_source(o.gt_source);
  std::vector<eval::RpeOptions> rpe_options;
  for (double d : o.rpe_delta) {
    eval::RpeOptions r;
    r.delta = d;
    r.unit = eval::parse_delta_unit(o.rpe_unit);
    r.all_pairs = o.rpe_all_pairs;
    r.pairs_from = eval::parse_pairs_from(o.rpe_pairs_from);
    r.rel_tol = o.rpe_tol;
    eval::check_rpe_options(r);
    for (const eval::RpeOptions& prev : rpe_options)
      if (prev.delta == d)  // two identical blocks would collide in rpe.csv and in --summary's columns
        throw InputError(fmt::format("--rpe-delta lists {} twice", d), {"", 0, 0, "rpe-delta"});
    rpe_options.push_back(r);
  }
  if (o.n_align != -1 && (align == eval::AlignType::kOrigin || align == eval::AlignType::kNone)) {
    // evo ignores --n_to_align with --align_origin; say so instead.
    warnings.push_back(fmt::format("--n-align {} is ignored with --align {}: {}", o.n_align, o.align,
                                   align == eval::AlignType::kOrigin
                                       ? "origin alignment uses the first matched pose pair by definition"
                                       : "nothing is aligned"));
  }

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
  const EvalInput gt = gt_future.get();
  warnings.insert(warnings.end(), gt_warnings.begin(), gt_warnings.end());
  const io::Trajectory& te = est.in.traj;
  const io::Trajectory& tg = gt.traj;
  if (const std::size_t d = te.count_duplicate_stamps()) {
    warnings.push_back(fmt::format("the estimate has {} duplicated time stamp(s) with different poses; {}", d,
                                   ao.policy == eval::AssocPolicy::kNearest
                                       ? "policy 'nearest' keeps every pose (as evo does); --assoc unique "
                                         "keeps the first of each (as cnspy does)"
                                       : "policy 'unique' keeps the first pose of each (as cnspy does)"));
  }
  if (const std::size_t d = tg.count_duplicate_stamps())
    warnings.push_back(
        fmt::format("the ground truth has {} duplicated time stamp(s); the first pose of each is used", d));

  // Association.
  const eval::Association a = eval::associate(te.t_ns, tg.t_ns, ao);
  if (a.size() == 0) throw InputError(eval::explain_no_match(te.t_ns, tg.t_ns, ao), {o.est});
  std::vector<Pose> pe, pg;
  std::vector<Timestamp> t_e, t_g;
  pe.reserve(a.size());
  pg.reserve(a.size());
  t_e.reserve(a.size());
  t_g.reserve(a.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    pe.push_back(te.poses[a.est_index[k]]);
    pg.push_back(tg.poses[a.gt_index[k]]);
    t_e.push_back(te.t_ns[a.est_index[k]]);
    t_g.push_back(tg.t_ns[a.gt_index[k]]);
  }
  // The most pairs to expect: the sparser stream's poses inside the span both trajectories cover (a
  // ground truth covering a longer session than the estimate is not a matching problem).
  const eval::Overlap ov = eval::overlap(te.t_ns, tg.t_ns, ao);
  if (a.size() < ov.n_max() / 2) {
    warnings.push_back(fmt::format(
        "only {} of at most {} poses were matched ({} estimate and {} ground-truth poses lie in the span "
        "[{:.6f}, {:.6f}] s both cover): check --max-dt / --t-offset",
        a.size(), ov.n_max(), ov.n_est, ov.n_gt, to_seconds(ov.begin_ns), to_seconds(ov.end_ns)));
  }

  // Alignment.
  const eval::Alignment al = eval::compute_alignment(align, pe, pg, o.n_align);
  std::vector<Pose> pe_aligned = pe;
  eval::apply_alignment(al, pe_aligned);

  // Covariances of the matched estimate poses, rotated into the aligned frame.
  std::vector<eval::PoseCovariance> cov;
  if (!est.cov.empty()) {
    bool all = true;
    for (std::size_t k = 0; k < a.size() && all; ++k) all = est.cov[a.est_index[k]].has_value();
    if (all) {
      for (std::size_t k = 0; k < a.size(); ++k)
        cov.push_back(eval::align_covariance(*est.cov[a.est_index[k]], al.R, al.s));
    } else {
      warnings.push_back("NEES not computed: some matched estimate poses have no covariance");
    }
  }
  const eval::ApeResult ape = eval::compute_ape(pe_aligned, pg, cov);
  if (align == eval::AlignType::kSe3 || align == eval::AlignType::kSim3) {
    if (o.n_align < 0 && ape.pos_mean_m.cwiseAbs().maxCoeff() > 1e-6)
      warnings.push_back("internal check: the mean position error after Umeyama is not ~0");
  }
  if (align == eval::AlignType::kNone)
    warnings.push_back("no alignment: the results depend on the arbitrary world frames of both trajectories");

  // Relative pose error of the aligned pairs (only a Sim(3) scale changes it), one block per delta.
  std::vector<eval::RpeResult> rpe;
  json rpe_json = json::array();
  for (const eval::RpeOptions& ro : rpe_options) {
    rpe.push_back(eval::compute_rpe(pe_aligned, pg, t_e, t_g, ro));
    const eval::RpeResult& r = rpe.back();
    if (r.pairs.empty())
      warnings.push_back(fmt::format("RPE delta {} {}: no pair of matched poses is that far apart{}", ro.delta,
                                     eval::to_string(ro.unit),
                                     ro.all_pairs ? fmt::format(" (within {} %)", 100.0 * ro.rel_tol) : ""));
    rpe_json.push_back({{"delta", ro.delta},
                        {"unit", eval::to_string(ro.unit)},
                        {"all_pairs", ro.all_pairs},
                        {"pairs_from", eval::to_string(ro.pairs_from)},
                        {"rel_tol", ro.rel_tol},
                        {"n_pairs", r.pairs.size()},
                        {"trans_m", r.pairs.empty() ? json(nullptr) : stats_json(r.trans_m)},
                        {"rot_deg", r.pairs.empty() ? json(nullptr) : stats_json(r.rot_deg)},
                        {"drift_pct", r.trans_pct.n == 0 ? json(nullptr) : stats_json(r.trans_pct)}});
  }

  // Per-object reprojection traces.
  json per_object = json::array();
  std::vector<std::tuple<Timestamp, int, Pose, std::string, double>> rep_aligned;
  if (est.have_reprojection) {
    std::map<int, std::vector<const ReprojectionCsvRow*>> by_obj;
    for (const auto& r : est.reprojection) by_obj[r.object_id].push_back(&r);
    for (const auto& [id, rows] : by_obj) {
      std::map<std::string, std::size_t> counts;
      std::vector<Timestamp> ts;
      std::vector<Pose> ps;
      std::vector<bool> accepted;
      for (const ReprojectionCsvRow* r : rows) {
        ++counts[r->status];
        const bool valid = r->T_W_I.p.allFinite();
        Pose T = valid ? al.apply(r->T_W_I) : r->T_W_I;
        rep_aligned.emplace_back(r->t_ns, id, T, r->status, r->nis);
        if (!valid) continue;
        ts.push_back(r->t_ns);
        ps.push_back(T);
        accepted.push_back(r->status == "accepted" || r->status == "initialized");
      }
      json obj = {
          {"object_id", id}, {"n_detections", rows.size()}, {"counts", counts}, {"n_valid_pose", ts.size()}};
      // Each trace against the ground truth, with the same association options (unique stamps per object).
      const eval::Association ar = ts.empty() ? eval::Association{} : eval::associate(ts, tg.t_ns, ao);
      obj["n_matched"] = ar.size();
      const auto summarize = [&](bool only_accepted) {
        std::vector<Pose> e2, g2;
        for (std::size_t k = 0; k < ar.size(); ++k) {
          if (only_accepted && !accepted[ar.est_index[k]]) continue;
          e2.push_back(ps[ar.est_index[k]]);
          g2.push_back(tg.poses[ar.gt_index[k]]);
        }
        if (e2.empty()) return json{{"n", 0}};
        const eval::ApeResult r = eval::compute_ape(e2, g2);
        return json{{"n", e2.size()},
                    {"pos_rmse_m", xyz_json(r.pos_rmse_m)},
                    {"rpy_rmse_deg", rpy_json(r.rpy_rmse_deg)},
                    {"ape_trans_rmse_m", r.trans_m.rmse},
                    {"ape_rot_rmse_deg", r.rot_deg.rmse}};
      };
      obj["all"] = summarize(false);
      obj["accepted"] = summarize(true);
      per_object.push_back(obj);
    }
  }

  // Report.
  const std::string label = o.label.empty() ? default_label(est.in.path) : o.label;
  double max_abs_dt = 0.0;
  for (Timestamp d : a.dt_ns) max_abs_dt = std::max(max_abs_dt, std::abs(to_seconds(d)));
  const Eigen::Quaterniond qa = al.q();
  json R = json::array();
  for (int r = 0; r < 3; ++r) R.push_back({al.R(r, 0), al.R(r, 1), al.R(r, 2)});
  const double L_est = path_length(pe_aligned), L_gt = path_length(pg);
  json report = {
      {"info",
       {{"title", "roe eval: " + label},
        {"ref_name", gt.path.string()},
        {"est_name", est.in.path.string()},
        {"label", label},
        {"roe_version", kVersion}}},
      {"inputs",
       {{"est",
         {{"path", est.in.path.string()},
          {"kind", est.in.kind},
          {"format", io::to_string(te.format)},
          {"description", est.in.description},
          {"n_poses", te.size()},
          {"duplicate_stamps", te.count_duplicate_stamps()}}},
        {"gt",
         {{"path", gt.path.string()},
          {"kind", gt.kind},
          {"format", io::to_string(tg.format)},
          {"description", gt.description},
          {"n_poses", tg.size()},
          {"duplicate_stamps", tg.count_duplicate_stamps()}}}}},
      {"association",
       {{"max_dt_s", ao.max_dt_s},
        {"offset_s", ao.offset_s},
        {"policy", eval::to_string(ao.policy)},
        {"n_gt", tg.size()},
        {"n_est", te.size()},
        {"n_matched", a.size()},
        {"n_overlap_max", ov.n_max()},
        {"n_dropped_unique", a.n_dropped_unique},
        {"max_abs_dt_s", max_abs_dt},
        {"rule",
         "nearest neighbour from the shorter trajectory, |t_gt - (t_est + offset)| <= max_dt (evo)"}}},
      {"alignment",
       {{"type", eval::to_string(al.type == eval::AlignType::kNone ? align : al.type)},
        {"n_aligned", al.n_used},
        {"n_align_requested", o.n_align},
        {"scale", al.s},
        {"R", R},
        {"t", {al.t.x(), al.t.y(), al.t.z()}},
        {"q_xyzw", {qa.x(), qa.y(), qa.z(), qa.w()}},
        {"applied", "p' = s*R*p + t, R'_est = R*R_est"}}},
      {"ape_trans_m", stats_json(ape.trans_m)},
      {"ape_rot_deg", stats_json(ape.rot_deg)},
      {"per_axis",
       {{"pos_rmse_m", xyz_json(ape.pos_rmse_m)},
        {"pos_mean_m", xyz_json(ape.pos_mean_m)},
        {"rpy_rmse_deg", rpy_json(ape.rpy_rmse_deg)},
        {"pos_error", "p_est - p_gt"},
        {"rot_error", "R_est^T*R_gt"},
        {"euler", "ZYX (R=Rz*Ry*Rx)"},
        {"wrap", "[-180,180)"}}},
      {"cnspy",
       {{"ARMSE_p", ape.armse_p_m},
        {"ARMSE_R", ape.armse_r_deg},
        {"ANEES_p", ape.anees_p ? json(*ape.anees_p) : json(nullptr)},
        {"ANEES_R", ape.anees_r ? json(*ape.anees_r) : json(nullptr)},
        {"note", "ARMSE_* are cnspy's report values: the mean of the per-pose error norms (m, deg)"}}},
      {"consistency",
       {{"available", !cov.empty()},
        {"source", est.cov_source},
        {"anees_p", ape.anees_p ? json(*ape.anees_p) : json(nullptr)},
        {"anees_r", ape.anees_r ? json(*ape.anees_r) : json(nullptr)},
        {"dof", 3},
        {"definition",
         "NEES_p = e_p^T P_p^-1 e_p (e_p = p_gt - p_est, P_p rotated by the alignment); "
         "NEES_R = dtheta^T P_theta^-1 dtheta, dtheta = Log(R_est^T R_gt)"}}},
      {"rpe", rpe_json},
      {"rpe_definition",
       "E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j), Q ground truth, P aligned estimate (evo RPE); trans_m = |trans(E)|, "
       "rot_deg = angle of rot(E), drift_pct = 100 trans_m / ground-truth path length from i to j"},
      {"per_object", per_object},
      {"path_length_m", {{"est", L_est}, {"gt", L_gt}}},
      {"options",
       {{"align", o.align},
        {"n_align", o.n_align},
        {"max_dt_s", o.max_dt_s},
        {"t_offset_s", o.t_offset_s},
        {"assoc", o.assoc},
        {"est_format", o.est_format},
        {"gt_format", o.gt_format},
        {"gt_source", o.gt_source},
        {"rpe_delta", o.rpe_delta},
        {"rpe_unit", o.rpe_unit},
        {"rpe_all_pairs", o.rpe_all_pairs},
        {"rpe_pairs_from", o.rpe_pairs_from},
        {"rpe_tol", o.rpe_tol}}},
      {"warnings", warnings}};

  EvalResult res;
  fs::path out;
  if (!o.no_out) {
    if (!o.out.empty())
      out = o.out;
    else if (est.run)
      out = est.in.path / "eval";
  }
  if (o.plot && out.empty()) {
    throw InputError(
        "--plot needs an output folder: pass --out DIR (plots are rendered from the output files)",
        {"", 0, 0, "plot"});
  }
  if (!out.empty()) {
    io::OutputDir dir(out, o.force, {o.est, o.gt});
    std::vector<std::string> files;
    const auto put = [&](const std::string& name, const std::string& text) {
      io::write_file_atomic(dir.file(name), text);
      files.push_back(name);
    };
    put("est_matched_aligned.csv", io::format_trajectory(t_e, pe_aligned, io::TrajectoryFormat::kCsv));
    put("gt_matched.csv", io::format_trajectory(t_g, pg, io::TrajectoryFormat::kCsv));
    put("est_matched_aligned.tum", io::format_trajectory(t_e, pe_aligned, io::TrajectoryFormat::kTum));
    put("gt_matched.tum", io::format_trajectory(t_g, pg, io::TrajectoryFormat::kTum));
    {
      io::CsvWriter w;
      std::vector<std::string> h = {"t_gt",     "t_est",    "dt",        "ex_m",    "ey_m",     "ez_m",
                                    "e_norm_m", "roll_deg", "pitch_deg", "yaw_deg", "angle_deg"};
      if (!cov.empty()) {
        h.push_back("nees_p");
        h.push_back("nees_r");
      }
      w.header(h);
      for (std::size_t k = 0; k < a.size(); ++k) {
        const auto& e = ape.errors[k];
        w.add_seconds(t_g[k]).add_seconds(t_e[k]).add(to_seconds(a.dt_ns[k]));
        w.add(e.dp.x()).add(e.dp.y()).add(e.dp.z()).add(e.dp.norm());
        w.add(e.rpy_deg.x()).add(e.rpy_deg.y()).add(e.rpy_deg.z()).add(e.angle_deg);
        if (!cov.empty()) w.add(ape.nees[k].pos).add(ape.nees[k].rot);
        w.end_row();
      }
      put("errors.csv", w.str());
    }
    {
      // cnspy PoseTypedStamped error file (type5: p_est - p_gt, q = R_est^T R_gt).
      io::CsvWriter w;
      w.header({"t", "tx", "ty", "tz", "qx", "qy", "qz", "qw", "scale", "est_err_type"});
      const double scale = L_est > 0.0 ? L_gt / L_est : 1.0;
      for (std::size_t k = 0; k < a.size(); ++k) {
        const auto& e = ape.errors[k];
        w.add_seconds(t_g[k]).add(e.dp.x()).add(e.dp.y()).add(e.dp.z());
        w.add(e.q_err.x())
            .add(e.q_err.y())
            .add(e.q_err.z())
            .add(e.q_err.w())
            .add(scale)
            .add("type5")
            .end_row();
      }
      put("err_matched_aligned.csv", w.str());
    }
    {
      io::CsvWriter w;
      w.header({"gt_file",      "est_file",    "alignment", "n_aligned",     "max_dt_s",       "t_offset_s",
                "n_gt",         "n_est",       "n_matched", "scale",         "ate_rmse_m",     "ate_mean_m",
                "ate_median_m", "ate_std_m",   "ate_min_m", "ate_max_m",     "rot_rmse_deg",   "rot_mean_deg",
                "rmse_x_m",     "rmse_y_m",    "rmse_z_m",  "rmse_roll_deg", "rmse_pitch_deg", "rmse_yaw_deg",
                "armse_p_m",    "armse_r_deg", "anees_p",   "anees_r"});
      w.add(gt.path.string()).add(est.in.path.string()).add(eval::to_string(align)).add(al.n_used);
      w.add(ao.max_dt_s).add(ao.offset_s).add(static_cast<std::int64_t>(tg.size()));
      w.add(static_cast<std::int64_t>(te.size())).add(static_cast<std::int64_t>(a.size())).add(al.s);
      w.add(ape.trans_m.rmse).add(ape.trans_m.mean).add(ape.trans_m.median).add(ape.trans_m.std);
      w.add(ape.trans_m.min).add(ape.trans_m.max).add(ape.rot_deg.rmse).add(ape.rot_deg.mean);
      for (int k = 0; k < 3; ++k) w.add(ape.pos_rmse_m(k));
      for (int k = 0; k < 3; ++k) w.add(ape.rpy_rmse_deg(k));
      w.add(ape.armse_p_m).add(ape.armse_r_deg);
      if (ape.anees_p)
        w.add(*ape.anees_p);
      else
        w.add_empty();
      if (ape.anees_r)
        w.add(*ape.anees_r);
      else
        w.add_empty();
      w.end_row();
      put("summary.csv", w.str());
    }
    if (!rpe.empty()) {
      io::CsvWriter w;
      w.header({"delta", "unit", "t_i", "t_j", "dt_s", "path_gt_m", "trans_m", "rot_deg", "drift_pct"});
      for (const eval::RpeResult& r : rpe) {
        for (const eval::RpePair& p : r.pairs) {
          w.add(r.options.delta).add(eval::to_string(r.options.unit)).add_seconds(t_g[p.i]).add_seconds(t_g[p.j]);
          w.add(dt_seconds(t_g[p.i], t_g[p.j])).add(p.path_gt_m).add(p.trans_m).add(p.rot_deg);
          if (std::isfinite(p.trans_pct))
            w.add(p.trans_pct);
          else
            w.add_empty();
          w.end_row();
        }
      }
      put("rpe.csv", w.str());
      io::CsvWriter sw;
      sw.header({"delta", "unit", "all_pairs", "pairs_from", "n_pairs", "trans_rmse_m", "trans_mean_m",
                "trans_median_m", "trans_std_m", "trans_min_m", "trans_max_m", "rot_rmse_deg", "rot_mean_deg",
                "rot_median_deg", "rot_std_deg", "rot_min_deg", "rot_max_deg", "drift_mean_pct",
                "drift_median_pct"});
      for (const eval::RpeResult& r : rpe) {
        sw.add(r.options.delta).add(eval::to_string(r.options.unit)).add(r.options.all_pairs ? "true" : "false");
        sw.add(eval::to_string(r.options.pairs_from)).add(static_cast<std::int64_t>(r.pairs.size()));
        for (const eval::Stats* st : {&r.trans_m, &r.rot_deg}) {
          if (r.pairs.empty()) {
            for (int k = 0; k < 6; ++k) sw.add_empty();
            continue;
          }
          sw.add(st->rmse).add(st->mean).add(st->median).add(st->std).add(st->min).add(st->max);
        }
        if (r.trans_pct.n == 0)
          sw.add_empty().add_empty();
        else
          sw.add(r.trans_pct.mean).add(r.trans_pct.median);
        sw.end_row();
      }
      put("rpe_summary.csv", sw.str());
    }
    if (est.have_reprojection) {
      io::CsvWriter w;
      w.header({"timestamp_ns", "object_id", "tx", "ty", "tz", "qx", "qy", "qz", "qw", "status", "nis"});
      for (const auto& [t, id, T, status, nis] : rep_aligned) {
        w.add(static_cast<std::int64_t>(t)).add(id).add(T.p.x()).add(T.p.y()).add(T.p.z());
        w.add(T.q.x()).add(T.q.y()).add(T.q.z()).add(T.q.w()).add(status).add(nis).end_row();
      }
      put("reprojection_aligned.csv", w.str());
      io::CsvWriter p;
      p.header({"object_id", "n_detections", "n_matched", "rmse_x_m", "rmse_y_m", "rmse_z_m", "rmse_roll_deg",
                "rmse_pitch_deg", "rmse_yaw_deg", "n_accepted_matched", "acc_rmse_x_m", "acc_rmse_y_m",
                "acc_rmse_z_m", "acc_rmse_roll_deg", "acc_rmse_pitch_deg", "acc_rmse_yaw_deg", "counts"});
      for (const auto& obj : per_object) {
        p.add(obj["object_id"].get<int>()).add(obj["n_detections"].get<std::int64_t>());
        p.add(obj["n_matched"].get<std::int64_t>());
        for (const char* sub : {"all", "accepted"}) {
          const json& s = obj[sub];
          if (sub == std::string("accepted")) p.add(s["n"].get<std::int64_t>());
          if (s["n"].get<std::int64_t>() == 0) {
            for (int k = 0; k < 6; ++k) p.add_empty();
            continue;
          }
          for (const char* ax : {"x", "y", "z"}) p.add(s["pos_rmse_m"][ax].get<double>());
          for (const char* ax : {"roll", "pitch", "yaw"}) p.add(s["rpy_rmse_deg"][ax].get<double>());
        }
        std::string c;
        for (const auto& [k, v] : obj["counts"].items())
          c += (c.empty() ? "" : ";") + k + "=" + std::to_string(v.get<int>());
        p.add(c).end_row();
      }
      put("per_object.csv", p.str());
    }
    report["outputs"] = {{"dir", out.string()}, {"files", files}};
    put("report.json", io::dump_json(report, 2) + "\n");
    if (o.plot) {
      bool ok = false;
      res.plot_status = render_eval_plots(dir.tmp(), ok);
      report["plots"] = {{"ok", ok}, {"status", res.plot_status}};
      io::write_file_atomic(dir.file("report.json"), io::dump_json(report, 2) + "\n");
    }
    dir.commit();
    res.out = out;
  }
  res.report = std::move(report);
  return res;
}

std::string EvalResult::to_text() const {
  const json& r = report;
  std::string s;
  const auto& as = r["association"];
  const auto& al = r["alignment"];
  s += fmt::format("roe eval: {}\n", r["info"]["label"].get<std::string>());
  s += fmt::format("  estimate     {}\n", r["inputs"]["est"]["description"].get<std::string>());
  s += fmt::format("  ground truth {}\n", r["inputs"]["gt"]["description"].get<std::string>());
  s += fmt::format("  matched {} of {} estimate / {} ground-truth poses (max dt {} s, offset {} s, {})\n",
                   as["n_matched"].get<std::size_t>(), as["n_est"].get<std::size_t>(),
                   as["n_gt"].get<std::size_t>(), as["max_dt_s"].get<double>(), as["offset_s"].get<double>(),
                   as["policy"].get<std::string>());
  s += fmt::format("  alignment {} on {} pairs, scale {:.6f}\n", al["type"].get<std::string>(),
                   al["n_aligned"].get<int>(), al["scale"].get<double>());
  const auto& pa = r["per_axis"];
  s += "\n  RMSE            x         y         z   |     roll     pitch       yaw\n";
  s += fmt::format("  {:<10} {:9.4f} {:9.4f} {:9.4f}   | {:8.3f}  {:8.3f}  {:8.3f}   (m | deg)\n", "per-axis",
                   pa["pos_rmse_m"]["x"].get<double>(), pa["pos_rmse_m"]["y"].get<double>(),
                   pa["pos_rmse_m"]["z"].get<double>(), pa["rpy_rmse_deg"]["roll"].get<double>(),
                   pa["rpy_rmse_deg"]["pitch"].get<double>(), pa["rpy_rmse_deg"]["yaw"].get<double>());
  s += "\n  APE            rmse      mean    median       std       min       max\n";
  for (const auto& [key, name] :
       {std::pair{"ape_trans_m", "trans [m]"}, std::pair{"ape_rot_deg", "rot [deg]"}}) {
    const auto& st = r[key];
    s += fmt::format("  {:<10} {:9.4f} {:9.4f} {:9.4f} {:9.4f} {:9.4f} {:9.4f}\n", name,
                     st["rmse"].get<double>(), st["mean"].get<double>(), st["median"].get<double>(),
                     st["std"].get<double>(), st["min"].get<double>(), st["max"].get<double>());
  }
  if (!r["rpe"].empty()) {
    s += "\n  RPE            pairs  trans rmse [m]   mean    median   |  rot rmse [deg]   mean   |  drift [%]\n";
    for (const auto& e : r["rpe"]) {
      const std::string what = fmt::format("{} {}{}{}", e["delta"].get<double>(), e["unit"].get<std::string>(),
                                           e["all_pairs"].get<bool>() ? ", all" : "",
                                           e["pairs_from"].get<std::string>() == "gt" ? ", gt" : "");
      if (e["n_pairs"].get<std::size_t>() == 0) {
        s += fmt::format("  {:<13} {:>6}  (none)\n", what, 0);
        continue;
      }
      const auto& tr = e["trans_m"];
      const auto& ro = e["rot_deg"];
      s += fmt::format("  {:<13} {:>6}  {:13.4f} {:8.4f} {:8.4f}   | {:14.3f} {:7.3f}   | {:8}\n", what,
                       e["n_pairs"].get<std::size_t>(), tr["rmse"].get<double>(), tr["mean"].get<double>(),
                       tr["median"].get<double>(), ro["rmse"].get<double>(), ro["mean"].get<double>(),
                       e["drift_pct"].is_null() ? std::string("-")
                                                : fmt::format("{:.2f}", e["drift_pct"]["mean"].get<double>()));
    }
  }
  if (r["consistency"]["available"].get<bool>()) {
    s += fmt::format("\n  ANEES position {:.3f}, orientation {:.3f} (expected 3 for a consistent filter)\n",
                     r["consistency"]["anees_p"].is_null() ? NAN : r["consistency"]["anees_p"].get<double>(),
                     r["consistency"]["anees_r"].is_null() ? NAN : r["consistency"]["anees_r"].get<double>());
    // The alignment is fitted on positions; its own rotation error (often ~1°) is not in the estimate's
    // covariance, which is relative to the estimator's gauge, so the orientation NEES after it is
    // inflated when the estimate's orientation σ is small (docs/eval.md).
    s += "  (both are relative to this alignment, not to the estimator's own gauge: the alignment's rotation\n"
         "   error, fitted on positions, is not in the estimate's covariance and inflates the orientation NEES)\n";
  }
  if (!r["per_object"].empty()) {
    s += "\n  per object (reprojected IMU pose of each raw detection, same alignment)\n";
    s += "  object  detections  matched   rmse x/y/z [m]              rmse roll/pitch/yaw [deg]   statuses\n";
    for (const auto& o : r["per_object"]) {
      std::string counts;
      for (const auto& [k, v] : o["counts"].items())
        counts += (counts.empty() ? "" : ", ") + k + " " + std::to_string(v.get<int>());
      const auto& all = o["all"];
      if (all["n"].get<int>() > 0) {
        s += fmt::format(
            "  {:>6}  {:>10}  {:>7}   {:7.3f} {:7.3f} {:7.3f}     {:7.2f} {:7.2f} {:7.2f}     {}\n",
            o["object_id"].get<int>(), o["n_detections"].get<int>(), o["n_matched"].get<int>(),
            all["pos_rmse_m"]["x"].get<double>(), all["pos_rmse_m"]["y"].get<double>(),
            all["pos_rmse_m"]["z"].get<double>(), all["rpy_rmse_deg"]["roll"].get<double>(),
            all["rpy_rmse_deg"]["pitch"].get<double>(), all["rpy_rmse_deg"]["yaw"].get<double>(), counts);
      } else {
        s += fmt::format("  {:>6}  {:>10}  {:>7}   (no matched pose)     {}\n", o["object_id"].get<int>(),
                         o["n_detections"].get<int>(), o["n_matched"].get<int>(), counts);
      }
    }
  }
  for (const auto& w : r["warnings"]) s += "  warning: " + w.get<std::string>() + "\n";
  if (!out.empty()) s += fmt::format("\n  wrote {}\n", out.string());
  if (!plot_status.empty()) s += "  plots: " + plot_status + "\n";
  return s;
}

}  // namespace roe::app
