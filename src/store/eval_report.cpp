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
using io::AtomicFile;
using io::CsvWriter;
using io::OutputDir;
using io::TrajectoryFormat;
using io::write_file_atomic;
using io::write_trajectory;


namespace {

/// Every pair's errors (Report::error), computed on every allowed CPU for the two error tables.
std::vector<eval::PoseError> pair_errors(const eval::Report& r) {
  std::vector<eval::PoseError> e(r.n_pairs());
  parallel_ranges(e.size(), eval::kPairsPerTask, available_cpus(), [&](std::size_t b, std::size_t end) {
    for (std::size_t k = b; k < end; ++k) e[k] = r.error(k);
  });
  return e;
}

/// errors.csv, streamed into `file` (a row per pair: an hour at IMU rate is 1.4 M rows).
void errors_csv(const eval::Report& r, const std::vector<eval::PoseError>& errors, AtomicFile& file) {
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
    w.flush_to(file, CsvWriter::kFlushBytes);
  }
  w.flush_to(file);
}

/// cnspy PoseTypedStamped error file (type5: p_est - p_gt, q = R_est^T R_gt), streamed into `file`.
void cnspy_errors_csv(const eval::Report& r, const std::vector<eval::PoseError>& errors, AtomicFile& file) {
  CsvWriter w;
  w.header({"t", "tx", "ty", "tz", "qx", "qy", "qz", "qw", "scale", "est_err_type"});
  const double scale = r.path_length_est_m > 0.0 ? r.path_length_gt_m / r.path_length_est_m : 1.0;
  for (std::size_t k = 0; k < r.association.size(); ++k) {
    const eval::PoseError& e = errors[k];
    w.add_seconds(r.t_gt(k)).add(e.dp.x()).add(e.dp.y()).add(e.dp.z());
    w.add(e.q_err.x()).add(e.q_err.y()).add(e.q_err.z()).add(e.q_err.w()).add(scale).add("type5").end_row();
    w.flush_to(file, CsvWriter::kFlushBytes);
  }
  w.flush_to(file);
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
    const auto stream = [&](const std::string& name, auto&& write) {
      AtomicFile f(dir.file(name));
      write(r, errors, f);
      f.commit();
      files.push_back(name);
    };
    stream("errors.csv", errors_csv);
    stream("err_matched_aligned.csv", cnspy_errors_csv);
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
