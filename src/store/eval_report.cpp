// roe eval's output files from a typed eval::Report (docs/eval.md "Output").
#include "roe/store/eval_report.hpp"

#include <algorithm>
#include <cmath>
#include <functional>

#include <fmt/format.h>

#include "roe/core/error.hpp"
#include "roe/core/parallel.hpp"
#include "roe/io/csv.hpp"
#include "roe/io/json.hpp"
#include "roe/io/trajectory_io.hpp"
#include "roe/version.hpp"

namespace roe::store {

// store reads and writes through io's primitives.
using io::CsvWriter;
using io::OutputDir;
using io::TrajectoryFormat;
using io::json;
using io::write_file_atomic;
using io::write_trajectory;

using nlohmann::json;

namespace {

json stats_json(const eval::Stats& s) {
  return {{"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median}, {"std", s.std},
          {"min", s.min},   {"max", s.max},   {"sse", s.sse},       {"n", s.n}};
}
// The keys of the RMSE blocks, written here and read back by read_axis_rmse.
constexpr const char* kPosRmse = "pos_rmse_m";
constexpr const char* kRpyRmse = "rpy_rmse_deg";
constexpr const char* kXyz[] = {"x", "y", "z"};
constexpr const char* kRpy[] = {"roll", "pitch", "yaw"};

json xyz_json(const Eigen::Vector3d& v) { return {{kXyz[0], v.x()}, {kXyz[1], v.y()}, {kXyz[2], v.z()}}; }
json rpy_json(const Eigen::Vector3d& v) { return {{kRpy[0], v.x()}, {kRpy[1], v.y()}, {kRpy[2], v.z()}}; }
json optional_json(const std::optional<double>& v) { return v ? json(*v) : json(nullptr); }

json euler_stats_json(const eval::EulerStats& e) {
  return {{"rmse", rpy_json(e.rmse)}, {"mean", rpy_json(e.mean)}, {"std", rpy_json(e.std)}};
}

/// per_axis: position and Euler figures; with a metric other than `error` also the rotation error's
/// figures, the share of 360° jumps and a warning.
json per_axis_json(const eval::ApeResult& ape) {
  const eval::EulerMetric m = ape.euler_metric;
  json j = {{kPosRmse, xyz_json(ape.pos_rmse_m)},
            {"pos_mean_m", xyz_json(ape.pos_mean_m)},
            {kRpyRmse, rpy_json(ape.rpy_rmse_deg)},
            {"rpy_mean_deg", rpy_json(ape.rpy.mean)},
            {"rpy_std_deg", rpy_json(ape.rpy.std)},
            {"euler_metric", eval::to_string(m)},
            {"euler_definition", eval::euler_metric_definition(m)},
            {"pos_error", "p_est - p_gt"},
            {"rot_error", "R_est^T*R_gt"},
            {"euler", "ZYX (R=Rz*Ry*Rx)"},
            {"wrap", m == eval::EulerMetric::kAbsoluteUnwrapped ? "none: (-360,360)" : "[-180,180)"}};
  if (m != eval::EulerMetric::kError) {
    j["rotation_error_euler_deg"] = euler_stats_json(ape.rpy_error);
    j["rotation_error_euler_deg"]["definition"] = eval::euler_metric_definition(eval::EulerMetric::kError);
    json jump = rpy_json(ape.jump_share);
    jump["any"] = ape.jump_share_any;
    j["jump_360_share"] = jump;
    j["warning"] = "rpy_* are differences of absolute Euler angles, not a rotation error: "
                   "rotation_error_euler_deg holds the rotation error's figures";
  }
  return j;
}

/// The NEES: in the estimator's gauge where the run and the truth allow it (the headline), and
/// relative to the alignment (its rotation error inflates the orientation NEES: not headlined).
json consistency_json(const eval::Report& r, const EvalReportContext& c) {
  const eval::ApeResult& ape = r.ape;
  json gauge = {{"available", r.gauge.has_value()}};
  if (r.gauge) {
    const eval::GaugeConsistency& g = *r.gauge;
    const Pose& T = g.truth.T_Wt_Wg;
    gauge.update({{"description", g.truth.description},
                  {"n", g.n},
                  {"anees_p", optional_json(g.anees_p)},
                  {"anees_r", optional_json(g.anees_r)},
                  {"T_Wt_Wg", {{"p", {T.p.x(), T.p.y(), T.p.z()}}, {"q", {T.q.x(), T.q.y(), T.q.z(), T.q.w()}}}}});
  } else {
    gauge["reason"] = r.cov.empty() ? std::string("no covariances") : c.no_gauge_reason;
  }
  const bool in_gauge = r.gauge.has_value();
  return {{"available", !r.cov.empty()},
          {"source", c.cov_source},
          {"frame", r.cov.empty() ? "none" : in_gauge ? "estimator gauge" : "alignment"},
          {"anees_p", optional_json(in_gauge ? r.gauge->anees_p : ape.anees_p)},
          {"anees_r", optional_json(in_gauge ? r.gauge->anees_r : std::nullopt)},
          {"dof", 3},
          {"expected", 3.0},
          {"gauge", gauge},
          {"aligned",
           {{"anees_p", optional_json(ape.anees_p)},
            {"anees_r", optional_json(ape.anees_r)},
            {"note", "relative to the alignment, which is fitted on positions: its rotation error is in no "
                     "covariance and inflates anees_r (not a consistency figure)"}}},
          {"definition",
           "estimator gauge: NEES of the unaligned estimate against the truth mapped into the estimator's world "
           "(T_Wg_Wt from the anchor, eval/gauge.hpp) with the estimate's own covariance, from the anchor's first "
           "sight; alignment: NEES_p = e_p^T P_p^-1 e_p (e_p = p_gt - p_est, P_p rotated by the alignment), "
           "NEES_R = dtheta^T P_theta^-1 dtheta, dtheta = Log(R_est^T R_gt). anees_r is given only in the "
           "estimator's gauge"}};
}

/// The body-frame rotation fit: R_off and the metrics without (the headline) and with it removed.
json body_rotation_json(const eval::Report& r) {
  if (!r.body_rotation) return nullptr;
  const eval::BodyRotationFit& b = *r.body_rotation;
  const auto metrics = [](const eval::ApeResult& a) {
    return json{{"ape_rot_deg", stats_json(a.rot_deg)},
                {kRpyRmse, rpy_json(a.rpy_rmse_deg)},
                {"rpy_mean_deg", rpy_json(a.rpy.mean)},
                {"rpy_std_deg", rpy_json(a.rpy.std)},
                {"euler_metric", eval::to_string(a.euler_metric)}};
  };
  return {{"q_xyzw", {b.q_off.x(), b.q_off.y(), b.q_off.z(), b.q_off.w()}},
          {"angle_deg", b.angle_deg},
          {"rpy_deg", rpy_json(b.rpy_deg)},
          {"definition", "R_off = mean on SO(3) of R_est^T*R_gt after the alignment; 'with' replaces R_est by "
                         "R_est*R_off (positions unchanged). A diagnostic: the headline figures do not use it"},
          {"without", metrics(r.ape)},
          {"with", metrics(b.ape)}};
}

json rpe_json(const eval::Report& r) {
  json out = json::array();
  for (const eval::RpeResult& e : r.rpe) {
    const eval::RpeOptions& ro = e.options;
    out.push_back({{"delta", ro.delta},
                   {"unit", eval::to_string(ro.unit)},
                   {"all_pairs", ro.all_pairs},
                   {"pairs_from", eval::to_string(ro.pairs_from)},
                   {"rel_tol", ro.rel_tol},
                   {"n_pairs", e.pairs.size()},
                   {"trans_m", e.pairs.empty() ? json(nullptr) : stats_json(e.trans_m)},
                   {"rot_deg", e.pairs.empty() ? json(nullptr) : stats_json(e.rot_deg)},
                   {"drift_pct", e.trans_pct.n == 0 ? json(nullptr) : stats_json(e.trans_pct)}});
  }
  return out;
}

json fit_json(const eval::ObjectFit& f) {
  if (f.n == 0) return json{{"n", 0}};
  return json{{"n", f.n},
              {kPosRmse, xyz_json(f.pos_rmse_m)},
              {kRpyRmse, rpy_json(f.rpy_rmse_deg)},
              {"ape_trans_rmse_m", f.ape_trans_rmse_m},
              {"ape_rot_rmse_deg", f.ape_rot_rmse_deg}};
}

json per_object_json(const eval::Report& r) {
  json out = json::array();
  for (const eval::ObjectReport& o : r.objects)
    out.push_back({{"object_id", o.object_id},
                   {"n_detections", o.n_detections},
                   {"counts", o.counts},
                   {"n_valid_pose", o.n_valid_pose},
                   {"n_matched", o.n_matched},
                   {"all", fit_json(o.all)},
                   {"accepted", fit_json(o.accepted)}});
  return out;
}

json alignment_json(const eval::Report& r) {
  const eval::Alignment& al = r.alignment;
  const Eigen::Quaterniond qa = al.q();
  json R = json::array();
  for (int i = 0; i < 3; ++i) R.push_back({al.R(i, 0), al.R(i, 1), al.R(i, 2)});
  return {{"type", eval::to_string(r.align_type())},
          {"n_aligned", al.n_used},
          {"n_align_requested", r.params.n_align},
          {"scale", al.s},
          {"R", R},
          {"t", {al.t.x(), al.t.y(), al.t.z()}},
          {"q_xyzw", {qa.x(), qa.y(), qa.z(), qa.w()}},
          {"applied", "p' = s*R*p + t, R'_est = R*R_est"}};
}

json association_json(const eval::Report& r) {
  const eval::AssociationOptions& ao = r.params.assoc;
  return {{"max_dt_s", ao.max_dt_s},
          {"offset_s", ao.offset_s},
          {"policy", eval::to_string(ao.policy)},
          {"n_gt", r.n_gt},
          {"n_est", r.n_est},
          {"n_matched", r.association.size()},
          {"n_overlap_max", r.overlap.n_max()},
          {"n_dropped_unique", r.association.n_dropped_unique},
          {"max_abs_dt_s", r.max_abs_dt_s},
          {"rule", "nearest neighbour from the shorter trajectory, |t_gt - (t_est + offset)| <= max_dt (evo)"}};
}

/// Every pair's errors (Report::error), computed on every allowed CPU for the two error tables.
std::vector<eval::PoseError> pair_errors(const eval::Report& r) {
  std::vector<eval::PoseError> e(r.n_pairs());
  parallel_ranges(e.size(), eval::kPairsPerTask, available_cpus(), [&](std::size_t b, std::size_t end) {
    for (std::size_t k = b; k < end; ++k) e[k] = r.error(k);
  });
  return e;
}

std::string errors_csv(const eval::Report& r, const std::vector<eval::PoseError>& errors) {
  CsvWriter w;
  std::vector<std::string> h = {"t_gt",     "t_est",    "dt",        "ex_m",    "ey_m",     "ez_m",
                                "e_norm_m", "roll_deg", "pitch_deg", "yaw_deg", "angle_deg"};
  if (!r.cov.empty()) {
    h.push_back("nees_p");
    h.push_back("nees_r");
  }
  // --euler absolute / absolute-unwrapped: that metric's per-pair figures too, named after it.
  const eval::EulerMetric m = r.params.euler;
  if (m != eval::EulerMetric::kError) {
    std::string name = eval::to_string(m);
    std::replace(name.begin(), name.end(), '-', '_');
    for (const char* axis : {"roll", "pitch", "yaw"}) h.push_back(name + "_" + axis + "_deg");
  }
  w.header(h);
  for (std::size_t k = 0; k < r.association.size(); ++k) {
    const eval::PoseError& e = errors[k];
    w.add_seconds(r.t_gt(k)).add_seconds(r.t_est(k)).add(to_seconds(r.association.dt_ns[k]));
    w.add(e.dp.x()).add(e.dp.y()).add(e.dp.z()).add(e.dp.norm());
    w.add(e.rpy_deg.x()).add(e.rpy_deg.y()).add(e.rpy_deg.z()).add(e.angle_deg);
    if (!r.cov.empty()) w.add(r.ape.nees[k].pos).add(r.ape.nees[k].rot);
    if (m != eval::EulerMetric::kError) {
      const Eigen::Vector3d f = eval::euler_figure_deg(r.est_aligned(k), r.gt(k), e, m);
      w.add(f.x()).add(f.y()).add(f.z());
    }
    w.end_row();
  }
  return w.str();
}

/// cnspy PoseTypedStamped error file (type5: p_est - p_gt, q = R_est^T R_gt).
std::string cnspy_errors_csv(const eval::Report& r, const std::vector<eval::PoseError>& errors) {
  CsvWriter w;
  w.header({"t", "tx", "ty", "tz", "qx", "qy", "qz", "qw", "scale", "est_err_type"});
  const double scale = r.path_length_est_m > 0.0 ? r.path_length_gt_m / r.path_length_est_m : 1.0;
  for (std::size_t k = 0; k < r.association.size(); ++k) {
    const eval::PoseError& e = errors[k];
    w.add_seconds(r.t_gt(k)).add(e.dp.x()).add(e.dp.y()).add(e.dp.z());
    w.add(e.q_err.x()).add(e.q_err.y()).add(e.q_err.z()).add(e.q_err.w()).add(scale).add("type5").end_row();
  }
  return w.str();
}

std::string summary_csv(const eval::Report& r, const EvalReportContext& c) {
  CsvWriter w;
  w.header({"gt_file",      "est_file",    "alignment", "n_aligned",     "max_dt_s",       "t_offset_s",
            "n_gt",         "n_est",       "n_matched", "scale",         "ate_rmse_m",     "ate_mean_m",
            "ate_median_m", "ate_std_m",   "ate_min_m", "ate_max_m",     "rot_rmse_deg",   "rot_mean_deg",
            "rmse_x_m",     "rmse_y_m",    "rmse_z_m",  "rmse_roll_deg", "rmse_pitch_deg", "rmse_yaw_deg",
            "armse_p_m",    "armse_r_deg", "anees_p",   "anees_r",       "euler_metric"});
  const eval::ApeResult& ape = r.ape;
  w.add(c.gt_path).add(c.est_path).add(eval::to_string(r.params.align)).add(r.alignment.n_used);
  w.add(r.params.assoc.max_dt_s).add(r.params.assoc.offset_s).add(static_cast<std::int64_t>(r.n_gt));
  w.add(static_cast<std::int64_t>(r.n_est)).add(static_cast<std::int64_t>(r.association.size()));
  w.add(r.alignment.s);
  w.add(ape.trans_m.rmse).add(ape.trans_m.mean).add(ape.trans_m.median).add(ape.trans_m.std);
  w.add(ape.trans_m.min).add(ape.trans_m.max).add(ape.rot_deg.rmse).add(ape.rot_deg.mean);
  for (int k = 0; k < 3; ++k) w.add(ape.pos_rmse_m(k));
  for (int k = 0; k < 3; ++k) w.add(ape.rpy_rmse_deg(k));
  w.add(ape.armse_p_m).add(ape.armse_r_deg);
  // The headline NEES (report.json consistency): in the estimator's gauge, else position after the alignment.
  const std::optional<double> anees_p = r.gauge ? r.gauge->anees_p : ape.anees_p;
  const std::optional<double> anees_r = r.gauge ? r.gauge->anees_r : std::nullopt;
  for (const auto& v : {anees_p, anees_r}) {
    if (v)
      w.add(*v);
    else
      w.add_empty();
  }
  w.add(eval::to_string(ape.euler_metric));
  w.end_row();
  return w.str();
}

std::string rpe_csv(const eval::Report& r) {
  CsvWriter w;
  w.header({"delta", "unit", "t_i", "t_j", "dt_s", "path_gt_m", "trans_m", "rot_deg", "drift_pct"});
  for (const eval::RpeResult& e : r.rpe) {
    for (const eval::RpePair& p : e.pairs) {
      w.add(e.options.delta).add(eval::to_string(e.options.unit)).add_seconds(r.t_gt(p.i)).add_seconds(r.t_gt(p.j));
      w.add(dt_seconds(r.t_gt(p.i), r.t_gt(p.j))).add(p.path_gt_m).add(p.trans_m).add(p.rot_deg);
      if (std::isfinite(p.trans_pct))
        w.add(p.trans_pct);
      else
        w.add_empty();
      w.end_row();
    }
  }
  return w.str();
}

std::string rpe_summary_csv(const eval::Report& r) {
  CsvWriter sw;
  sw.header({"delta", "unit", "all_pairs", "pairs_from", "n_pairs", "trans_rmse_m", "trans_mean_m",
             "trans_median_m", "trans_std_m", "trans_min_m", "trans_max_m", "rot_rmse_deg", "rot_mean_deg",
             "rot_median_deg", "rot_std_deg", "rot_min_deg", "rot_max_deg", "drift_mean_pct",
             "drift_median_pct"});
  for (const eval::RpeResult& e : r.rpe) {
    sw.add(e.options.delta).add(eval::to_string(e.options.unit)).add(e.options.all_pairs ? "true" : "false");
    sw.add(eval::to_string(e.options.pairs_from)).add(static_cast<std::int64_t>(e.pairs.size()));
    for (const eval::Stats* st : {&e.trans_m, &e.rot_deg}) {
      if (e.pairs.empty()) {
        for (int k = 0; k < 6; ++k) sw.add_empty();
        continue;
      }
      sw.add(st->rmse).add(st->mean).add(st->median).add(st->std).add(st->min).add(st->max);
    }
    if (e.trans_pct.n == 0)
      sw.add_empty().add_empty();
    else
      sw.add(e.trans_pct.mean).add(e.trans_pct.median);
    sw.end_row();
  }
  return sw.str();
}

std::string reprojection_csv(const eval::Report& r) {
  CsvWriter w;
  w.header({"timestamp_ns", "object_id", "tx", "ty", "tz", "qx", "qy", "qz", "qw", "status", "nis"});
  for (const eval::DetectionPose& d : r.detections_aligned) {
    const Pose& T = d.T_W_I;
    w.add(static_cast<std::int64_t>(d.t_ns)).add(d.object_id).add(T.p.x()).add(T.p.y()).add(T.p.z());
    w.add(T.q.x()).add(T.q.y()).add(T.q.z()).add(T.q.w()).add(d.status).add(d.nis).end_row();
  }
  return w.str();
}

std::string per_object_csv(const eval::Report& r) {
  CsvWriter p;
  p.header({"object_id", "n_detections", "n_matched", "rmse_x_m", "rmse_y_m", "rmse_z_m", "rmse_roll_deg",
            "rmse_pitch_deg", "rmse_yaw_deg", "n_accepted_matched", "acc_rmse_x_m", "acc_rmse_y_m",
            "acc_rmse_z_m", "acc_rmse_roll_deg", "acc_rmse_pitch_deg", "acc_rmse_yaw_deg", "counts"});
  for (const eval::ObjectReport& o : r.objects) {
    p.add(o.object_id).add(static_cast<std::int64_t>(o.n_detections)).add(static_cast<std::int64_t>(o.n_matched));
    for (const eval::ObjectFit* f : {&o.all, &o.accepted}) {
      if (f == &o.accepted) p.add(static_cast<std::int64_t>(f->n));
      if (f->n == 0) {
        for (int k = 0; k < 6; ++k) p.add_empty();
        continue;
      }
      for (int k = 0; k < 3; ++k) p.add(f->pos_rmse_m(k));
      for (int k = 0; k < 3; ++k) p.add(f->rpy_rmse_deg(k));
    }
    std::string counts;
    for (const auto& [status, n] : o.counts) counts += (counts.empty() ? "" : ";") + status + "=" + std::to_string(n);
    p.add(counts).end_row();
  }
  return p.str();
}

json sigma_calibration_json(const eval::SigmaCalibration& c) {
  json q = json::object();
  for (std::size_t i = 0; i < eval::kNisProbabilities.size(); ++i)
    q[fmt::format("p{:02.0f}", 100.0 * eval::kNisProbabilities[i])] = c.nis_quantiles[i];
  return {{"n", c.n},
          {"within_sigma_t", c.within_t},
          {"within_sigma_r", c.within_r},
          {"nis_mean", c.nis_mean},
          {"nis_quantiles", q},
          {"frac_above_gate", c.frac_above_gate},
          {"ks_statistic", c.ks_statistic},
          {"ks_p_value", c.ks_p_value},
          {"sigma_scale", c.sigma_scale},
          {"sigma_scale_ci95", {c.sigma_scale_lo, c.sigma_scale_hi}},
          {"R_scale", c.sigma_scale * c.sigma_scale},
          {"sigma_scale_t", c.sigma_scale_t},
          {"sigma_scale_r", c.sigma_scale_r},
          {"sigma_scale_median", c.sigma_scale_median}};
}

/// report.json's detection_calibration: null without one.
json detection_calibration_json(const eval::Report& r, const EvalReportContext& c) {
  if (!r.detection_calibration) return nullptr;
  const eval::DetectionCalibration& d = *r.detection_calibration;
  json q = json::object();
  const auto chi2 = eval::chi2_6_quantiles();
  for (std::size_t i = 0; i < eval::kNisProbabilities.size(); ++i)
    q[fmt::format("p{:02.0f}", 100.0 * eval::kNisProbabilities[i])] = chi2[i];
  json objects = json::array();
  for (const auto& o : d.objects) {
    json j = sigma_calibration_json(o.cal);
    j["object_id"] = o.object_id;
    objects.push_back(std::move(j));
  }
  return {{"source", c.detections_source},
          {"n_detections", d.n_detections},
          {"n_evaluated", d.all.n},
          {"n_without_sigma", d.n_without_sigma},
          {"n_without_object_truth", d.n_without_object_truth},
          {"n_outside_truth", d.n_outside_truth},
          {"all", sigma_calibration_json(d.all)},
          {"per_object", objects},
          {"expected",
           {{"within_sigma", eval::expected_within()},
            {"nis_mean", 6.0},
            {"nis_quantiles", q},
            {"frac_above_gate", 0.05},
            {"gate", eval::nis_gate()},
            {"sigma_scale", 1.0}}},
          {"definition",
           "e = [t_meas - t_true ; Log(R_meas R_true^T)] in camera axes (m, rad), T_C_O_true = (T_W_I T_I_C)^-1 T_W_O "
           "at t_cam + camera time offset; z = e / sigma; within_sigma_t/_r = fraction of |z| <= 1, 2, 3 over the "
           "3 translation / rotation axes; NIS = |z|^2 vs chi2(6); sigma_scale = sqrt(sum NIS / 6n) (ML, R_scale = "
           "sigma_scale^2), ci95 from chi2(6n); sigma_scale_median = sqrt(median NIS / chi2(6) median)"}};
}

std::string detection_sigmas_csv(const eval::DetectionCalibration& d) {
  CsvWriter w;
  w.header({"timestamp_ns", "object_id", "e_tx_m", "e_ty_m", "e_tz_m", "e_rx_rad", "e_ry_rad", "e_rz_rad", "sigma_tx",
            "sigma_ty", "sigma_tz", "sigma_rx", "sigma_ry", "sigma_rz", "nis"});
  for (const auto& r : d.residuals) {
    w.add(r.t_ns).add(r.object_id);
    for (int i = 0; i < 6; ++i) w.add(r.error[i]);
    for (int i = 0; i < 6; ++i) w.add(r.sigma[i]);
    w.add(r.nis).end_row();
  }
  return w.str();
}

}  // namespace

AxisRmse read_axis_rmse(const json& block, const std::string& file, const std::string& path) {
  const auto three = [&](const char* key, const char* const (&names)[3]) {
    Eigen::Vector3d v;
    for (int i = 0; i < 3; ++i) {
      const json* x = block.is_object() && block.contains(key) && block[key].is_object() && block[key].contains(names[i])
                          ? &block[key][names[i]]
                          : nullptr;
      if (!x || !x->is_number())
        throw InputError(fmt::format("not a roe eval report: missing number {}.{}.{}", path, key, names[i]),
                         {file, 0, 0, fmt::format("{}.{}.{}", path, key, names[i])});
      v[i] = x->get<double>();
    }
    return v;
  };
  return {three(kPosRmse, kXyz), three(kRpyRmse, kRpy)};
}

json eval_report_json(const eval::Report& r, const EvalReportContext& c) {
  const eval::ApeResult& ape = r.ape;
  return {
      {"info",
       {{"title", "roe eval: " + c.label},
        {"ref_name", c.gt_path},
        {"est_name", c.est_path},
        {"label", c.label},
        {"roe_version", kVersion}}},
      {"inputs", c.inputs},
      {"association", association_json(r)},
      {"alignment", alignment_json(r)},
      {"ape_trans_m", stats_json(ape.trans_m)},
      {"ape_rot_deg", stats_json(ape.rot_deg)},
      {"euler_metric", eval::to_string(ape.euler_metric)},
      {"per_axis", per_axis_json(ape)},
      {"cnspy",
       {{"ARMSE_p", ape.armse_p_m},
        {"ARMSE_R", ape.armse_r_deg},
        {"ANEES_p", optional_json(ape.anees_p)},
        {"ANEES_R", optional_json(ape.anees_r)},
        {"note", "ARMSE_* are cnspy's report values: the mean of the per-pose error norms (m, deg); ANEES_* are "
                 "relative to the alignment, as cnspy computes them"}}},
      {"consistency", consistency_json(r, c)},
      {"body_rotation", body_rotation_json(r)},
      {"rpe", rpe_json(r)},
      {"rpe_definition",
       "E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j), Q ground truth, P aligned estimate (evo RPE); trans_m = |trans(E)|, "
       "rot_deg = angle of rot(E), drift_pct = 100 trans_m / ground-truth path length from i to j"},
      {"per_object", per_object_json(r)},
      {"detection_calibration", detection_calibration_json(r, c)},
      {"path_length_m", {{"est", r.path_length_est_m}, {"gt", r.path_length_gt_m}}},
      {"options", c.options},
      {"warnings", c.warnings}};
}

std::vector<std::string> write_eval_files(const OutputDir& dir, const eval::Report& r,
                                          const EvalReportContext& c) {
  std::vector<std::string> files;
  const auto put = [&](const std::string& name, const std::string& text) {
    write_file_atomic(dir.file(name), text);
    files.push_back(name);
  };
  // The matched trajectories, streamed (the largest tables: memory does not grow with them).
  const std::function<StampedPose(std::size_t)> est = [&r](std::size_t k) {
    return StampedPose{r.t_est(k), r.est_aligned(k)};
  };
  const std::function<StampedPose(std::size_t)> gt = [&r](std::size_t k) { return StampedPose{r.t_gt(k), r.gt(k)}; };
  const auto put_trajectory = [&](const std::string& name, const std::function<StampedPose(std::size_t)>& at,
                                  TrajectoryFormat format) {
    write_trajectory(dir.file(name), r.n_pairs(), at, format);
    files.push_back(name);
  };
  put_trajectory("est_matched_aligned.csv", est, TrajectoryFormat::kCsv);
  put_trajectory("gt_matched.csv", gt, TrajectoryFormat::kCsv);
  put_trajectory("est_matched_aligned.tum", est, TrajectoryFormat::kTum);
  put_trajectory("gt_matched.tum", gt, TrajectoryFormat::kTum);
  {
    const std::vector<eval::PoseError> errors = pair_errors(r);
    put("errors.csv", errors_csv(r, errors));
    put("err_matched_aligned.csv", cnspy_errors_csv(r, errors));
  }
  put("summary.csv", summary_csv(r, c));
  if (!r.rpe.empty()) {
    put("rpe.csv", rpe_csv(r));
    put("rpe_summary.csv", rpe_summary_csv(r));
  }
  if (r.has_detections) {
    put("reprojection_aligned.csv", reprojection_csv(r));
    put("per_object.csv", per_object_csv(r));
  }
  if (r.detection_calibration) put("detection_sigmas.csv", detection_sigmas_csv(*r.detection_calibration));
  return files;
}

}  // namespace roe::store
