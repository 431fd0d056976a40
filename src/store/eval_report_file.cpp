// report.json as one typed value (store/eval_report.hpp): one field mapping per block, walked by a writer
// (to_json) and by a strict reader (read_eval_report), so the keys are spelled once, here.
#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <type_traits>

#include "roe/core/error.hpp"
#include "roe/io/json.hpp"
#include "roe/math/euler.hpp"
#include "roe/math/so3.hpp"
#include "roe/store/eval_report.hpp"
#include "roe/version.hpp"
#include "json_fields.hpp"

namespace roe::store {

using nlohmann::json;

namespace {

constexpr const char* kXyz[] = {"x", "y", "z"};
constexpr const char* kRpy[] = {"roll", "pitch", "yaw"};
// The RMSE blocks of per_axis and of each per-object subset.
constexpr const char* kPosRmse = "pos_rmse_m";
constexpr const char* kRpyRmse = "rpy_rmse_deg";

// ---- the dialect -----------------------------------------------------------------------------------

/// report.json's dialect: keys beyond the mapping are tolerated (a later roe's additions), a missing or
/// mistyped one is an InputError naming the file and the key path.
struct EvalReportJson {
  static constexpr bool kStrictKeys = false;
  static constexpr bool kNullIsAbsent = false;
  [[noreturn]] static void fail(const std::string& file, const std::string& path, json_fields::Problem p,
                                const std::string& detail) {
    throw InputError(fmt::format("not a roe eval report: {} {}", path.empty() ? "the document" : path,
                                 json_fields::phrase(p, detail)),
                     {file, 0, 0, path});
  }
};
using Writer = json_fields::Writer<EvalReportJson>;

// ---- the field mappings: one per block, used by both walkers ---------------------------------------

template <class A>
void fields(A& a, eval::Stats& s) {
  a("rmse", s.rmse), a("mean", s.mean), a("median", s.median), a("std", s.std);
  a("min", s.min), a("max", s.max), a("sse", s.sse), a("n", s.n);
}

template <class A>
void fields(A& a, eval::EulerStats& e) {
  a.axes("rmse", e.rmse, kRpy), a.axes("mean", e.mean, kRpy), a.axes("std", e.std, kRpy);
}

/// rpy_rmse_deg, rpy_mean_deg and rpy_std_deg beside each other (per_axis, body_rotation's metrics).
template <class A>
void rpy_fields(A& a, eval::EulerStats& e) {
  a.axes(kRpyRmse, e.rmse, kRpy), a.axes("rpy_mean_deg", e.mean, kRpy), a.axes("rpy_std_deg", e.std, kRpy);
}

template <class A>
void fields(A& a, ReportInput& in) {
  a("path", in.path), a("kind", in.kind), a("format", in.format), a("description", in.description);
  a("n_poses", in.n_poses), a("duplicate_stamps", in.duplicate_stamps);
}

template <class A>
void fields(A& a, ReportAssociation& as) {
  a("max_dt_s", as.max_dt_s), a("offset_s", as.offset_s), a("policy", as.policy), a("n_gt", as.n_gt);
  a("n_est", as.n_est), a("n_matched", as.n_matched), a("n_overlap_max", as.n_overlap_max);
  a("n_dropped_unique", as.n_dropped_unique), a("max_abs_dt_s", as.max_abs_dt_s);
  a.fixed("rule", "nearest neighbour from the shorter trajectory, |t_gt - (t_est + offset)| <= max_dt (evo)");
}

template <class A>
void fields(A& a, ReportAlignment& al) {
  a("type", al.type), a("n_aligned", al.n_aligned), a("n_align_requested", al.n_align_requested);
  a("scale", al.scale), a("R", al.R), a("t", al.t), a("q_xyzw", al.q_xyzw);
  a.fixed("applied", "p' = s*R*p + t, R'_est = R*R_est");
  a.omittable("tilt_deg", al.tilt_deg), a.omittable("posyaw_rot_rmse_deg", al.posyaw_rot_rmse_deg);
}

template <class A>
void fields(A& a, ReportTimeOffset& o) {
  a("offset_s", o.offset_s), a("sigma_s", o.sigma_s), a("search_s", o.search_s);
  a("coarse_offset_s", o.coarse_offset_s), a("correlation", o.correlation), a("peak_ratio", o.peak_ratio);
  a("peak_at_edge", o.peak_at_edge), a("refined", o.refined), a("n_pairs", o.n_pairs), a("ape_rmse_m", o.ape_rmse_m);
  a.fixed("definition",
          "t_gt = t_est + offset_s (added to the estimate stamps, evo's --t_offset); coarse: peak of the normalised "
          "cross-correlation of the two trajectories' angular-rate magnitudes; refined: Gauss-Newton minimum of the "
          "aligned position and orientation residuals (each block weighted by its effective samples over its "
          "variance) with the ground truth interpolated at t_est + offset, the alignment re-fitted at each step; "
          "sigma_s from the curvature of that cost");
}

template <class A>
void fields(A& a, ReportOffsetCheck& c) {
  a("shift_s", c.shift_s), a("sigma_s", c.sigma_s);
  a.fixed("definition", "the APE minimum lies at the offset used + shift_s (Gauss-Newton from the offset used)");
}

template <class A>
void fields(A& a, ReportBodyPoseFit& f) {
  a("sigma_p_m", f.sigma_p_m), a("sigma_rot_deg", f.sigma_rot_deg);
  a("rotation_spread_min_deg", f.rotation_spread_min_deg), a("rotation_spread_max_deg", f.rotation_spread_max_deg);
  a("lever_arm_rank", f.lever_arm_rank), a("verdict", f.verdict), a("n_pairs", f.n_pairs);
}

template <class A>
void fields(A& a, ReportBodyPose& b) {
  a("source", b.source), a("p", b.p), a("q_xyzw", b.q_xyzw), a("angle_deg", b.angle_deg);
  a.axes("rpy_deg", b.rpy_deg, kRpy), a("fit", b.fit);
  a.fixed("definition", "T_B_I: the estimate's body I in the ground truth's body B, T_W_I = T_W_B * T_B_I, applied to "
                        "every ground-truth pose before the evaluation");
}

template <class A>
void fields(A& a, eval::KittiLength& l) {
  a("length_m", l.length_m), a("n_segments", l.n_segments), a("t_rel_pct", l.t_rel_pct);
  a("r_rel_deg_per_100m", l.r_rel_deg_per_100m);
}

template <class A>
void fields(A& a, eval::KittiDrift& d) {
  a("t_rel_pct", d.t_rel_pct), a("r_rel_deg_per_100m", d.r_rel_deg_per_100m), a("n_segments", d.n_segments);
  a("per_length", d.per_length);
  a.fixed("definition", "KITTI odometry devkit: every 10th pose as a start, lengths 100..800 m of ground-truth path, "
                        "E = (P_i^-1 P_j)^-1 (Q_i^-1 Q_j); t_rel = 100 * mean(|trans E| / L) %, r_rel = mean(angle E / "
                        "L) in deg per 100 m, over every segment of every length");
}

template <class A>
void fields(A& a, ReportWindow& w) {
  a("t_start_s", w.t_start_s), a("t_end_s", w.t_end_s), a("n_cropped", w.n_cropped);
  a("align_window_s", w.align_window_s);
  a.fixed("clock", "the ground truth's stamps of the pairs");
}

template <class A>
void fields(A& a, ReportPerAxis& p) {
  a("euler_metric", p.euler_metric);  // first: it decides which fields follow
  a.axes(kPosRmse, p.pos_rmse_m, kXyz), a.axes("pos_mean_m", p.pos_mean_m, kXyz);
  rpy_fields(a, p.rpy_deg);
  a("euler_definition", p.euler_definition), a("wrap", p.wrap);
  a.fixed("pos_error", "p_est - p_gt"), a.fixed("rot_error", "R_est^T*R_gt"), a.fixed("euler", "ZYX (R=Rz*Ry*Rx)");
  if (p.euler_metric == eval::to_string(eval::EulerMetric::kError)) return;
  a.nested("rotation_error_euler_deg", [&](auto& r) {
    fields(r, p.rotation_error_euler_deg);
    r.fixed("definition", eval::euler_metric_definition(eval::EulerMetric::kError));
  });
  a.nested("jump_360_share", [&](auto& r) {
    for (int i = 0; i < 3; ++i) r(kRpy[i], p.jump_360_share[i]);
    r("any", p.jump_360_share_any);
  });
  a.fixed("warning", "rpy_* are differences of absolute Euler angles, not a rotation error: "
                     "rotation_error_euler_deg holds the rotation error's figures");
}

template <class A>
void fields(A& a, ReportCnspy& c) {
  a("ARMSE_p", c.armse_p_m), a("ARMSE_R", c.armse_r_deg), a("ANEES_p", c.anees_p), a("ANEES_R", c.anees_r);
  a.fixed("note", "ARMSE_* are cnspy's report values: the mean of the per-pose error norms (m, deg); ANEES_* are "
                  "relative to the alignment, as cnspy computes them");
}

template <class A>
void fields(A& a, ReportGauge& g) {
  a("available", g.available);  // first: it decides which fields follow
  if (!g.available) return a("reason", g.reason);
  a("description", g.description), a("n", g.n), a("anees_p", g.anees_p), a("anees_r", g.anees_r);
  a.nested("T_Wt_Wg", [&](auto& r) { r("p", g.T_Wt_Wg_p), r("q", g.T_Wt_Wg_q); });
}

template <class A>
void fields(A& a, ReportConsistency& c) {
  a("available", c.available), a("source", c.source), a("frame", c.frame);
  a("anees_p", c.anees_p), a("anees_r", c.anees_r), a("gauge", c.gauge);
  a.fixed("dof", 3), a.fixed("expected", 3.0);
  a.nested("aligned", [&](auto& r) {
    r("anees_p", c.aligned_anees_p), r("anees_r", c.aligned_anees_r);
    r.fixed("note", "relative to the alignment, which is fitted on positions: its rotation error is in no "
                    "covariance and inflates anees_r (not a consistency figure)");
  });
  a.fixed("definition",
          "estimator gauge: NEES of the unaligned estimate against the truth mapped into the estimator's world "
          "(T_Wg_Wt from the anchor, eval/gauge.hpp) with the estimate's own covariance, from the anchor's first "
          "sight; alignment: NEES_p = e_p^T P_p^-1 e_p (e_p = p_gt - p_est, P_p rotated by the alignment), "
          "NEES_R = dtheta^T P_theta^-1 dtheta, dtheta = Log(R_est^T R_gt). anees_r is given only in the "
          "estimator's gauge");
}

template <class A>
void fields(A& a, ReportBodyMetrics& m) {
  a("ape_rot_deg", m.ape_rot_deg), a("euler_metric", m.euler_metric);
  rpy_fields(a, m.rpy_deg);
}

template <class A>
void fields(A& a, ReportBodyRotation& b) {
  a("q_xyzw", b.q_xyzw), a("angle_deg", b.angle_deg), a.axes("rpy_deg", b.rpy_deg, kRpy);
  a.fixed("definition", "R_off = mean on SO(3) of R_est^T*R_gt after the alignment; 'with' replaces R_est by "
                        "R_est*R_off (positions unchanged). A diagnostic: the headline figures do not use it");
  a("without", b.without), a("with", b.with);
}

template <class A>
void fields(A& a, ReportRpe& e) {
  a("delta", e.delta), a("unit", e.unit), a("all_pairs", e.all_pairs), a("pairs_from", e.pairs_from);
  a("rel_tol", e.rel_tol), a("n_pairs", e.n_pairs), a("trans_m", e.trans_m), a("rot_deg", e.rot_deg);
  a("drift_pct", e.drift_pct);
}

template <class A>
void fields(A& a, ReportFit& f) {
  a("n", f.n);  // first: a subset without matches has nothing else
  if (f.n == 0) return;
  a.axes(kPosRmse, f.pos_rmse_m, kXyz), a.axes(kRpyRmse, f.rpy_rmse_deg, kRpy);
  a("ape_trans_rmse_m", f.ape_trans_rmse_m), a("ape_rot_rmse_deg", f.ape_rot_rmse_deg);
}

template <class A>
void fields(A& a, ReportObject& o) {
  a("object_id", o.object_id), a("n_detections", o.n_detections), a("counts", o.counts);
  a("n_valid_pose", o.n_valid_pose), a("n_matched", o.n_matched), a("all", o.all), a("accepted", o.accepted);
}

/// nis_quantiles as report.json names them: p05, p25, p50, p75, p95 (eval::kNisProbabilities).
std::string quantile_key(std::size_t i) { return fmt::format("p{:02.0f}", 100.0 * eval::kNisProbabilities[i]); }

template <class A>
void fields(A& a, eval::SigmaCalibration& c) {
  a("n", c.n), a("within_sigma_t", c.within_t), a("within_sigma_r", c.within_r), a("nis_mean", c.nis_mean);
  a.nested("nis_quantiles", [&](auto& r) {
    for (std::size_t i = 0; i < c.nis_quantiles.size(); ++i) r(quantile_key(i).c_str(), c.nis_quantiles[i]);
  });
  a("frac_above_gate", c.frac_above_gate), a("ks_statistic", c.ks_statistic), a("ks_p_value", c.ks_p_value);
  a("sigma_scale", c.sigma_scale);
  std::array<double, 2> ci{c.sigma_scale_lo, c.sigma_scale_hi};
  a("sigma_scale_ci95", ci);
  if constexpr (A::kReading) c.sigma_scale_lo = ci[0], c.sigma_scale_hi = ci[1];
  a.fixed("R_scale", c.sigma_scale * c.sigma_scale);
  a("sigma_scale_t", c.sigma_scale_t), a("sigma_scale_r", c.sigma_scale_r);
  a("sigma_scale_median", c.sigma_scale_median);
}

template <class A>
void fields(A& a, eval::ObjectCalibration& o) {
  fields(a, o.cal);
  a("object_id", o.object_id);
}

template <class A>
void fields(A& a, ExpectedCalibration& e) {
  a("within_sigma", e.within_sigma), a("nis_mean", e.nis_mean);
  a.nested("nis_quantiles", [&](auto& r) {
    for (std::size_t i = 0; i < e.nis_quantiles.size(); ++i) r(quantile_key(i).c_str(), e.nis_quantiles[i]);
  });
  a("frac_above_gate", e.frac_above_gate), a("gate", e.gate), a("sigma_scale", e.sigma_scale);
}

template <class A>
void fields(A& a, ReportDetectionCalibration& d) {
  a("source", d.source), a("n_detections", d.n_detections), a("n_evaluated", d.n_evaluated);
  a("n_without_sigma", d.n_without_sigma), a("n_without_object_truth", d.n_without_object_truth);
  a("n_outside_truth", d.n_outside_truth), a("all", d.all), a("per_object", d.per_object);
  if constexpr (!A::kReading) a.fixed("expected", Writer::value(expected_calibration()));
  a.fixed("definition",
          "e = [t_meas - t_true ; Log(R_meas R_true^T)] in camera axes (m, rad), T_C_O_true = (T_W_I T_I_C)^-1 T_W_O "
          "at t_cam + camera time offset; z = e / sigma; within_sigma_t/_r = fraction of |z| <= 1, 2, 3 over the "
          "3 translation / rotation axes; NIS = |z|^2 vs chi2(6); sigma_scale = sqrt(sum NIS / 6n) (ML, R_scale = "
          "sigma_scale^2), ci95 from chi2(6n); sigma_scale_median = sqrt(median NIS / chi2(6) median)");
}

template <class A>
void fields(A& a, ReportOutputs& o) {
  a("dir", o.dir), a("files", o.files);
}

template <class A>
void fields(A& a, ReportPlots& p) {
  a("ok", p.ok), a("status", p.status);
}

template <class A>
void fields(A& a, EvalReportFile& f) {
  a.nested("info", [&](auto& r) {
    r("title", f.title), r("ref_name", f.ref_name), r("est_name", f.est_name), r("label", f.label);
    r("roe_version", f.roe_version);
  });
  a.nested("inputs", [&](auto& r) { r("est", f.est), r("gt", f.gt); });
  a("association", f.association), a("alignment", f.alignment), a("ape_trans_m", f.ape_trans_m);
  a("ape_rot_deg", f.ape_rot_deg), a("euler_metric", f.euler_metric), a("per_axis", f.per_axis);
  a("cnspy", f.cnspy), a("consistency", f.consistency), a("body_rotation", f.body_rotation), a("rpe", f.rpe);
  a.omittable("time_offset", f.time_offset), a.omittable("time_offset_check", f.time_offset_check);
  a.omittable("body_pose", f.body_pose), a.omittable("window", f.window), a.omittable("kitti", f.kitti);
  a.fixed("rpe_definition",
          "E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j), Q ground truth, P aligned estimate (evo RPE); trans_m = |trans(E)|, "
          "rot_deg = angle of rot(E), drift_pct = 100 trans_m / ground-truth path length from i to j");
  a("per_object", f.per_object), a("detection_calibration", f.detection_calibration);
  a.nested("path_length_m", [&](auto& r) { r("est", f.path_length_est_m), r("gt", f.path_length_gt_m); });
  a("options", f.options), a("warnings", f.warnings);
  a.omittable("evo_results", f.evo_results), a.omittable("outputs", f.outputs), a.omittable("plots", f.plots);
}

ReportPerAxis per_axis_of(const eval::ApeResult& ape) {
  ReportPerAxis p;
  const eval::EulerMetric m = ape.euler_metric;
  p.pos_rmse_m = ape.pos_rmse_m;
  p.pos_mean_m = ape.pos_mean_m;
  p.rpy_deg = {ape.rpy_rmse_deg, ape.rpy.mean, ape.rpy.std};
  p.euler_metric = eval::to_string(m);
  p.euler_definition = eval::euler_metric_definition(m);
  p.wrap = m == eval::EulerMetric::kAbsoluteUnwrapped ? "none: (-360,360)" : "[-180,180)";
  if (m != eval::EulerMetric::kError) {
    p.rotation_error_euler_deg = ape.rpy_error;
    p.jump_360_share = ape.jump_share;
    p.jump_360_share_any = ape.jump_share_any;
  }
  return p;
}

/// The NEES: in the estimator's gauge where the run and the truth allow it (the headline), and
/// relative to the alignment (its rotation error inflates the orientation NEES: not headlined).
ReportConsistency consistency_of(const eval::Report& r, const EvalReportContext& c) {
  ReportConsistency out;
  ReportGauge& g = out.gauge;
  g.available = r.gauge.has_value();
  if (r.gauge) {
    const Pose& T = r.gauge->truth.T_Wt_Wg;
    g.description = r.gauge->truth.description;
    g.n = r.gauge->n;
    g.anees_p = r.gauge->anees_p;
    g.anees_r = r.gauge->anees_r;
    g.T_Wt_Wg_p = {T.p.x(), T.p.y(), T.p.z()};
    g.T_Wt_Wg_q = {T.q.x(), T.q.y(), T.q.z(), T.q.w()};
  } else {
    g.reason = r.cov.empty() ? std::string("no covariances") : c.no_gauge_reason;
  }
  out.available = !r.cov.empty();
  out.source = c.cov_source;
  out.frame = r.cov.empty() ? "none" : g.available ? "estimator gauge" : "alignment";
  out.anees_p = g.available ? r.gauge->anees_p : r.ape.anees_p;
  out.anees_r = g.available ? r.gauge->anees_r : std::nullopt;
  out.aligned_anees_p = r.ape.anees_p;
  out.aligned_anees_r = r.ape.anees_r;
  return out;
}

ReportBodyMetrics body_metrics_of(const eval::ApeResult& a) {
  return {a.rot_deg, {a.rpy_rmse_deg, a.rpy.mean, a.rpy.std}, eval::to_string(a.euler_metric)};
}

std::vector<ReportRpe> rpe_of(const eval::Report& r) {
  std::vector<ReportRpe> out;
  for (const eval::RpeResult& e : r.rpe) {
    const eval::RpeOptions& ro = e.options;
    ReportRpe b{ro.delta, eval::to_string(ro.unit), ro.all_pairs, eval::to_string(ro.pairs_from), ro.rel_tol,
                e.pairs.size(), std::nullopt, std::nullopt, std::nullopt};
    if (!e.pairs.empty()) b.trans_m = e.trans_m, b.rot_deg = e.rot_deg;
    if (e.trans_pct.n != 0) b.drift_pct = e.trans_pct;
    out.push_back(std::move(b));
  }
  return out;
}

ReportFit fit_of(const eval::ObjectFit& f) {
  return {f.n, f.pos_rmse_m, f.rpy_rmse_deg, f.ape_trans_rmse_m, f.ape_rot_rmse_deg};
}

ReportAlignment alignment_of(const eval::Report& r) {
  const eval::Alignment& al = r.alignment;
  const Eigen::Quaterniond qa = al.q();
  ReportAlignment out{eval::to_string(r.align_type()), al.n_used, r.params.n_align, al.s, {}, {}, {}, {}, {}};
  for (int i = 0; i < 3; ++i) out.R[static_cast<std::size_t>(i)] = {al.R(i, 0), al.R(i, 1), al.R(i, 2)};
  out.t = {al.t.x(), al.t.y(), al.t.z()};
  out.q_xyzw = {qa.x(), qa.y(), qa.z(), qa.w()};
  out.tilt_deg = r.tilt_deg;
  out.posyaw_rot_rmse_deg = r.posyaw_rot_rmse_deg;
  return out;
}

ReportBodyPose body_pose_of(const Pose& T, const eval::BodyPoseFit* fit) {
  ReportBodyPose b;
  b.source = fit ? "fitted" : "given";
  b.p = {T.p.x(), T.p.y(), T.p.z()};
  b.q_xyzw = {T.q.x(), T.q.y(), T.q.z(), T.q.w()};
  b.angle_deg = math::log_quat(T.q).norm() * math::kDegPerRad;
  b.rpy_deg = math::euler_zyx(T.R()) * math::kDegPerRad;
  if (fit)
    b.fit = ReportBodyPoseFit{{fit->sigma_p_m.x(), fit->sigma_p_m.y(), fit->sigma_p_m.z()},
                              fit->sigma_rot_deg, fit->rotation_spread_min_deg, fit->rotation_spread_max_deg,
                              fit->lever_arm_rank, fit->verdict, fit->n_pairs};
  return b;
}

/// The time offset, the body pose and the windows of an evaluation (absent where not asked for).
void frames_of(const eval::Report& r, EvalReportFile& f) {
  if (r.time_offset) {
    const eval::TrajectoryOffset& o = *r.time_offset;
    f.time_offset = ReportTimeOffset{o.offset_s,         o.sigma_s,     r.params.auto_offset_max_s,
                                     o.coarse_offset_s,  o.coarse.correlation, o.coarse.peak_ratio,
                                     o.coarse.peak_at_edge, o.refined, o.n_pairs, o.ape_rmse_m};
  }
  if (r.offset_check && r.offset_check->valid)
    f.time_offset_check = ReportOffsetCheck{r.offset_check->shift_s, r.offset_check->sigma_s};
  if (r.params.gt_body_pose) f.body_pose = body_pose_of(*r.params.gt_body_pose, nullptr);
  f.kitti = r.kitti;
  if (r.body_pose) f.body_pose = body_pose_of(r.body_pose->T_B_I, &*r.body_pose);
  const eval::EvalParams& p = r.params;
  if (p.t_start_ns || p.t_end_ns || p.align_window_ns) {
    ReportWindow w;
    if (p.t_start_ns) w.t_start_s = to_seconds(*p.t_start_ns);
    if (p.t_end_ns) w.t_end_s = to_seconds(*p.t_end_ns);
    w.n_cropped = r.n_cropped;
    if (p.align_window_ns) w.align_window_s = std::array<double, 2>{to_seconds(p.align_window_ns->first), to_seconds(p.align_window_ns->second)};
    f.window = w;
  }
}

}  // namespace

ExpectedCalibration expected_calibration() {
  ExpectedCalibration e;
  e.within_sigma = eval::expected_within();
  e.nis_quantiles = eval::chi2_6_quantiles();
  e.gate = eval::nis_gate();
  return e;
}

EvalReportFile make_eval_report_file(const eval::Report& r, const EvalReportContext& c) {
  const eval::ApeResult& ape = r.ape;
  EvalReportFile f;
  f.title = "roe eval: " + c.label;
  f.ref_name = c.gt_path;
  f.est_name = c.est_path;
  f.label = c.label;
  f.roe_version = kVersion;
  f.est = c.est;
  f.gt = c.gt;
  const eval::AssociationOptions& ao = r.params.assoc;
  f.association = {ao.max_dt_s,          ao.offset_s,       eval::to_string(ao.policy),
                   r.n_gt,               r.n_est,           r.association.size(),
                   r.overlap.n_max(),    r.association.n_dropped_unique, r.max_abs_dt_s};
  f.alignment = alignment_of(r);
  f.ape_trans_m = ape.trans_m;
  f.ape_rot_deg = ape.rot_deg;
  f.euler_metric = eval::to_string(ape.euler_metric);
  f.per_axis = per_axis_of(ape);
  f.cnspy = {ape.armse_p_m, ape.armse_r_deg, ape.anees_p, ape.anees_r};
  f.consistency = consistency_of(r, c);
  if (r.body_rotation) {
    const eval::BodyRotationFit& b = *r.body_rotation;
    f.body_rotation = ReportBodyRotation{{b.q_off.x(), b.q_off.y(), b.q_off.z(), b.q_off.w()}, b.angle_deg,
                                         b.rpy_deg, body_metrics_of(r.ape), body_metrics_of(b.ape)};
  }
  frames_of(r, f);
  f.rpe = rpe_of(r);
  for (const eval::ObjectReport& o : r.objects)
    f.per_object.push_back({o.object_id, o.n_detections, o.counts, o.n_valid_pose, o.n_matched, fit_of(o.all),
                            fit_of(o.accepted)});
  if (r.detection_calibration) {
    const eval::DetectionCalibration& d = *r.detection_calibration;
    f.detection_calibration = ReportDetectionCalibration{
        c.detections_source, d.n_detections,    d.all.n, d.n_without_sigma, d.n_without_object_truth,
        d.n_outside_truth,   d.all,             d.objects};
  }
  f.path_length_est_m = r.path_length_est_m;
  f.path_length_gt_m = r.path_length_gt_m;
  f.options = c.options;
  f.warnings = c.warnings;
  return f;
}

json to_json(const EvalReportFile& f) { return json_fields::write<EvalReportJson>(f); }

json to_json(const ReportPerAxis& p) { return json_fields::write<EvalReportJson>(p); }

EvalReportFile read_eval_report(const json& j, const std::string& file) {
  EvalReportFile f;
  json_fields::read<EvalReportJson>(j, f, file);
  return f;
}

EvalReportFile read_eval_report_file(const std::filesystem::path& path) {
  return read_eval_report(io::parse_json_file(path), path.string());
}

std::vector<ReportCell> per_axis_rmse_cells(const EvalReportFile& f) {
  std::vector<ReportCell> out;
  for (int i = 0; i < 3; ++i)
    out.push_back({fmt::format("per_axis.{}.{}", kPosRmse, kXyz[i]), f.per_axis.pos_rmse_m[i]});
  for (int i = 0; i < 3; ++i)
    out.push_back({fmt::format("per_axis.{}.{}", kRpyRmse, kRpy[i]), f.per_axis.rpy_deg.rmse[i]});
  return out;
}

std::vector<ReportCell> ape_cells(const EvalReportFile& f, bool rotation) {
  const eval::Stats& s = rotation ? f.ape_rot_deg : f.ape_trans_m;
  const std::string block = rotation ? "ape_rot_deg" : "ape_trans_m";
  std::vector<ReportCell> out;
  for (const auto& [key, v] : {std::pair{"rmse", s.rmse}, std::pair{"mean", s.mean}, std::pair{"median", s.median},
                               std::pair{"std", s.std}, std::pair{"min", s.min}, std::pair{"max", s.max}})
    out.push_back({block + "." + key, v});
  return out;
}

std::vector<NeesFrame> nees_frames(const EvalReportFile& f) {
  const ReportConsistency& c = f.consistency;
  std::vector<NeesFrame> out;
  if (c.gauge.available)
    out.push_back({"estimator gauge", c.frame == "estimator gauge",
                   {{"consistency.gauge.anees_p", c.gauge.anees_p}, {"consistency.gauge.anees_r", c.gauge.anees_r}}});
  out.push_back({"after the alignment", c.frame == "alignment",
                 {{"consistency.aligned.anees_p", c.aligned_anees_p}, {"consistency.aligned.anees_r", c.aligned_anees_r}}});
  return out;
}

const std::vector<std::string>& headline_metric_names() {
  static const std::vector<std::string> names = {"rmse_x_m",       "rmse_y_m",     "rmse_z_m",  "rmse_roll_deg",
                                                 "rmse_pitch_deg", "rmse_yaw_deg", "ate_rmse_m", "rot_rmse_deg"};
  return names;
}

std::vector<std::pair<std::string, double>> headline_metrics(const EvalReportFile& f) {
  const Eigen::Vector3d& p = f.per_axis.pos_rmse_m;
  const Eigen::Vector3d& e = f.per_axis.rpy_deg.rmse;
  const double v[] = {p.x(), p.y(), p.z(), e.x(), e.y(), e.z(), f.ape_trans_m.rmse, f.ape_rot_deg.rmse};
  const auto& names = headline_metric_names();
  std::vector<std::pair<std::string, double>> out;
  for (std::size_t k = 0; k < names.size(); ++k) out.emplace_back(names[k], v[k]);
  return out;
}

}  // namespace roe::store
