// roe refine: a run folder + its dataset → batch MAP (refine/) → a run folder (DESIGN §4).
#include "roe/core/clock.hpp"
#include "roe/app/refine.hpp"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <map>
#include <set>

#include "roe/app/run.hpp"
#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/ekf/images.hpp"
#include "roe/ekf/measurement.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"
#include "roe/io/pose_json.hpp"
#include "roe/store/run_files.hpp"
#include "roe/store/run_record.hpp"
#include "roe/io/trajectory_io.hpp"
#include "roe/version.hpp"

namespace roe::app {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using Clock = SteadyClock;

/// The run.json refine starts from: one of roe run with an anchor.
store::RunRecord read_run(const fs::path& run_dir) {
  store::RunRecord r = store::read_run_folder_record(run_dir);
  const std::string src = (run_dir / "run.json").string();
  if (r.command != "run")
    throw InputError(fmt::format("refines the output of roe run, not of roe {}", r.command), {src, 0, 0, "command"});
  if (r.refine)
    throw InputError("the run's estimate is already the batch's (\"estimator\": \"batch\"): refine a run once",
                     {src, 0, 0, "config.estimator"});
  if (r.anchor_id < 0)
    throw InputError("the run has no anchor (anchor_id -1): nothing to refine against", {src, 0, 0, "anchor_id"});
  return r;
}

/// The dataset the run read, checked against the run's hashes of the IMU and the detections, and the run's
/// anchor against its objects.
Dataset read_run_dataset(const store::RunRecord& run, const fs::path& dataset, const fs::path& run_json) {
  const std::string& set = run.inputs.detections;
  const std::vector<std::pair<std::string, fs::path>> files = {
      {"mav0/imu0/data.csv", store::imu_csv_path(dataset)},
      {"detections/" + set + "/detections.csv", store::detections_dir(dataset, set) / "detections.csv"}};
  for (const auto& [key, path] : files) {
    const auto it = run.inputs.sha256.find(key);
    if (it == run.inputs.sha256.end()) throw InputError("missing key", {run_json.string(), 0, 0, "inputs.sha256." + key});
    if (io::sha256_file(path) != it->second)
      throw InputError(fmt::format("{} is not the file the run read (another dataset, or changed since the run)", key),
                       {path.string()});
  }
  store::DatasetParts parts;
  parts.frames = parts.mocap = parts.groundtruth = false;
  parts.detection_names = {set};
  Dataset ds = store::read_dataset(dataset, parts);
  // The objects: roe.json's, or, where it lists none, the detections' ids (as roe run takes them).
  std::set<int> ids;
  for (const auto& o : ds.manifest.objects) ids.insert(o.id);
  if (ids.empty())
    for (const auto& d : ds.detections.at(set)) ids.insert(d.object_id);
  if (ids.count(run.anchor_id)) return ds;
  const std::string listed = ids.empty() ? std::string("none") : fmt::format("{}", fmt::join(ids, ", "));
  throw InputError(fmt::format("the anchor object {} is not an object of the dataset {} (its objects: {})",
                               run.anchor_id, dataset.string(), listed),
                   {run_json.string(), 0, 0, "anchor_id"});
}

ekf::DetectionStatus parse_status(const std::string& s, const fs::path& file) {
  using S = ekf::DetectionStatus;
  for (const S v : {S::kAccepted, S::kInitialized, S::kRejectedChi2, S::kRejectedNoMain, S::kRejectedScore,
                    S::kRejectedNoImu, S::kPendingInit})
    if (ekf::to_string(v) == s) return v;
  throw InputError(fmt::format("unknown status '{}'", s), {file.string(), 0, 0, "status"});
}

/// A detection enters the batch when the filter used it or gated it (accepted, initialized, rejected_chi2).
bool used_by_refine(ekf::DetectionStatus s) {
  return s == ekf::DetectionStatus::kAccepted || s == ekf::DetectionStatus::kInitialized ||
         s == ekf::DetectionStatus::kRejectedChi2;
}

/// What refine starts from besides run.json: the run's states, each object's final T_O_W and every detection's
/// row of reprojection.csv (in the file's order) with the status the run gave it. Read from RUN_DIR by roe
/// refine, taken from the run in memory by roe run's batch estimator.
struct RunTables {
  struct Row {
    Timestamp t_ns = 0;
    int object_id = 0;
    ekf::DetectionStatus status = ekf::DetectionStatus::kAccepted;
  };
  std::vector<store::RecordedState> states;
  std::map<int, Pose> T_O_W;  ///< each object's last row
  std::vector<Row> rows;
};

/// states.csv within the run's own guard rails (config.filter.max_*: the filter stops beyond them, so a row
/// beyond is not the run's) and within the IMU stream it is refined against: named, before Ceres sees it.
void check_states(const std::vector<store::RecordedState>& states, const store::RunRecord& run,
                  const std::vector<ImuSample>& imu, const fs::path& file) {
  if (states.size() < 2) throw InputError("fewer than 2 state rows", {file.string()});
  const ekf::FilterOptions& f = run.config.filter;
  for (std::size_t i = 0; i < states.size(); ++i) {
    const store::RecordedState& s = states[i];
    const auto beyond = [&](const char* what, double v, double limit, const char* key) {
      if (!(v <= limit))
        throw InputError(fmt::format("state row {} (t = {} ns): |{}| = {:.4g} beyond the run's config.filter.{} = "
                                     "{:.4g}: not a state the run's filter could have written",
                                     i + 1, s.t_ns, what, v, key, limit),
                         {file.string()});
    };
    beyond("p_W_I", s.x.p_W_I.norm(), f.max_position_m, "max_position_m");
    beyond("v_W_I", s.x.v_W_I.norm(), f.max_velocity_mps, "max_velocity_mps");
    beyond("b_g", s.x.b_g.norm(), f.max_gyro_bias, "max_gyro_bias");
    beyond("b_a", s.x.b_a.norm(), f.max_accel_bias, "max_accel_bias");
    beyond("p_I_C", s.T_I_C.p.norm(), f.max_position_m, "max_position_m");
  }
  if (imu.empty() || states.front().t_ns < imu.front().t_ns || states.back().t_ns > imu.back().t_ns)
    throw InputError(fmt::format("the states span {:.6f} .. {:.6f} s, outside the IMU stream of the dataset ({}): "
                                 "not the states of this run and dataset (shifted, or another run's)",
                                 to_seconds(states.front().t_ns), to_seconds(states.back().t_ns),
                                 imu.empty() ? std::string("empty")
                                             : fmt::format("{:.6f} .. {:.6f} s", to_seconds(imu.front().t_ns),
                                                           to_seconds(imu.back().t_ns))),
                     {file.string()});
}

/// A run whose filter estimated the time offset stamps each detection's row with the time its image was
/// processed, t + (t_d − declared) (ekf/driver.cpp), not the image's. The rows are in image order, each image's in
/// its detections' order: they are put back on the images' stamps in that order. Rows that do not pair with the
/// detections one to one are left as they are (the strict check that follows names the first difference).
template <typename Row>
void restamp_rows(std::vector<Row>& rows, const std::vector<ekf::ImageDetections>& images) {
  std::vector<Timestamp> t(rows.size());
  std::size_t k = 0;
  for (const auto& im : images)
    for (const auto& d : im.detections) {
      if (k == rows.size() || rows[k].object_id != d.object_id) return;
      t[k++] = im.t_ns;
    }
  if (k != rows.size()) return;
  for (k = 0; k < rows.size(); ++k) rows[k].t_ns = t[k];
}

/// The run's tables, every one checked against run.json and the dataset before anything is solved (issue 51:
/// refine reads as strictly as run): each error names its file.
RunTables read_tables(const fs::path& run_dir, const store::RunRecord& run, const Dataset& ds,
                      const std::vector<ekf::ImageDetections>& images) {
  RunTables t;
  const fs::path states_csv = run_dir / "states.csv", objects_csv = run_dir / "objects.csv",
                 reprojection_csv = run_dir / "reprojection.csv";
  t.states = store::read_states_csv(states_csv);
  check_states(t.states, run, ds.imu, states_csv);
  for (const auto& row : store::read_objects_csv(objects_csv)) {
    if (row.T_O_W.p.norm() > run.config.filter.max_position_m)
      throw InputError(fmt::format("object {} at t = {} ns: |p_O_W| = {:.4g} beyond the run's "
                                   "config.filter.max_position_m = {:.4g}",
                                   row.object_id, row.t_ns, row.T_O_W.p.norm(), run.config.filter.max_position_m),
                       {objects_csv.string()});
    t.T_O_W[row.object_id] = row.T_O_W;
  }
  if (!t.T_O_W.count(run.anchor_id))
    throw InputError(fmt::format("no row of the anchor object {} (run.json anchor_id): the run initialised it, so "
                                 "its objects.csv has its rows",
                                 run.anchor_id),
                     {objects_csv.string()});
  std::vector<eval::DetectionPose> rows = store::read_reprojection_csv(reprojection_csv);
  if (run.final_time_offset && run.final_time_offset->estimated) restamp_rows(rows, images);
  store::check_reprojection_rows(rows, images, reprojection_csv);
  for (const auto& p : rows) t.rows.push_back({p.t_ns, p.object_id, parse_status(p.status, reprojection_csv)});
  return t;
}

refine::RefineInput make_input(const store::RunRecord& run, const Dataset& ds, const RunTables& t,
                               const std::vector<ekf::ImageDetections>& images) {
  refine::RefineInput in;
  in.imu = ds.imu;
  in.noise = run.imu_noise;
  in.filter = run.config.filter;
  in.detection_sigma_scale = run.detection_sigmas.final_scale;
  for (const auto& o : ds.manifest.objects)
    if (!o.symmetry.empty()) in.symmetries[o.id] = o.symmetry;
  std::map<std::pair<Timestamp, int>, ekf::DetectionStatus> status;
  for (const auto& row : t.rows) status[{row.t_ns, row.object_id}] = row.status;
  for (const auto& im : images) {
    ekf::ImageDetections used{im.t_ns, {}};
    for (const auto& d : im.detections) {
      const auto s = status.find({im.t_ns, d.object_id});
      if (s != status.end() && used_by_refine(s->second)) used.detections.push_back(d);
    }
    if (!used.detections.empty()) in.images.push_back(std::move(used));
  }
  for (const auto& s : t.states) in.initial.push_back({s.t_ns, s.x});
  in.prior_T_I_C = run.init.T_I_C;
  in.initial_T_I_C = t.states.back().T_I_C;
  in.initial_T_O_W = t.T_O_W;
  in.anchor_id = run.anchor_id;
  in.prior_b_g = run.init.gyro_bias;
  in.prior_b_a = run.config.filter.init_accel_bias;
  // The time offset: estimated when the run's filter estimated it (filter.estimate_time_offset), from its
  // estimate, with the filter's prior about the declared offset (docs/refine.md §2b).
  in.declared_time_offset_s = ds.manifest.camera ? ds.manifest.camera->time_offset_s : 0.0;
  in.estimate_time_offset = run.config.filter.estimate_time_offset;
  in.initial_time_offset_s = run.final_time_offset && run.final_time_offset->estimated ? run.final_time_offset->value_s
                                                                                       : in.declared_time_offset_s;
  return in;
}

Vector6d sigma_of(const refine::Mat6& C) { return C.diagonal().cwiseMax(0.0).cwiseSqrt(); }

std::vector<store::RecordedState> refined_states(const refine::RefineResult& r, const RunTables& t,
                                                 const std::vector<ImuSample>& imu) {
  std::vector<Timestamp> times;
  times.reserve(t.states.size());
  for (const auto& s : t.states) times.push_back(s.t_ns);
  const std::vector<refine::StateSample> x = refine::states_at(r, imu, times);
  std::vector<store::RecordedState> rows(t.states.size());
  const Vector6d s_extr = sigma_of(r.cov_T_I_C);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    rows[i].t_ns = x[i].t_ns;
    rows[i].x = x[i].x;
    rows[i].T_I_C = r.T_I_C;
    rows[i].sigma.head<15>() = t.states[i].sigma.head<15>();  // the run's: refine marginalises the calibration only
    // A row without σ in the run (output level standard) stays without.
    rows[i].sigma.tail<6>() = std::isnan(t.states[i].sigma(0)) ? t.states[i].sigma.tail<6>() : s_extr;
    // The batch's t_d (the declared offset, σ 0, when it held it).
    rows[i].time_offset_s = r.time_offset_s;
    rows[i].sigma_time_offset_s = std::isnan(t.states[i].sigma(0)) ? t.states[i].sigma(0) : r.sigma_time_offset_s;
  }
  return rows;
}

std::vector<store::ObjectRow> refined_objects(const refine::RefineResult& r) {
  std::vector<store::ObjectRow> rows;
  const Timestamp t = r.nodes.back().t_ns;
  for (const auto& [id, o] : r.objects) {
    store::ObjectRow row;
    row.t_ns = t;
    row.object_id = id;
    row.anchor = o.anchor;
    row.T_O_W = o.T_O_W;
    row.sigma = sigma_of(o.cov);
    const refine::Mat6 J = ekf::inverse_pose_jacobian(o.T_O_W);
    row.sigma_W_O = sigma_of(J * o.cov * J.transpose());
    if (!o.anchor) row.sigma_A_O = sigma_of(o.cov_relative);
    rows.push_back(row);
  }
  return rows;
}

/// The run's reprojection rows with the refined calibration: T_W_I = T_O_W⁻¹ · T_C_O⁻¹ · T_I_C⁻¹.
std::vector<store::ReprojectionRow> refined_reprojection(const refine::RefineResult& r, const RunTables& t,
                                                      const std::vector<ekf::ImageDetections>& images) {
  std::map<std::pair<Timestamp, int>, const Detection*> det;
  for (const auto& im : images)
    for (const auto& d : im.detections) det[{im.t_ns, d.object_id}] = &d;
  std::map<std::pair<Timestamp, int>, double> chi2;
  for (const auto& f : r.detections) chi2[{f.t_ns, f.object_id}] = f.chi2;
  std::vector<store::ReprojectionRow> rows;
  rows.reserve(t.rows.size());
  for (const auto& p : t.rows) {
    store::ReprojectionRow row;
    row.t_ns = p.t_ns;
    row.object_id = p.object_id;
    row.outcome.object_id = p.object_id;
    row.outcome.status = p.status;
    if (const auto c = chi2.find({p.t_ns, p.object_id}); c != chi2.end()) row.outcome.nis = c->second;
    const auto d = det.find({p.t_ns, p.object_id});
    const auto o = r.objects.find(p.object_id);
    if (d != det.end() && o != r.objects.end()) {
      row.outcome.has_T_W_I = true;
      row.outcome.T_W_I = o->second.T_O_W.inverse() * d->second->T_C_O.inverse() * r.T_I_C.inverse();
    }
    rows.push_back(row);
  }
  return rows;
}

/// The solve as run.json records it (its "refine" block; the detection-error model of docs/refine.md §2
/// the last solve whitened with).
store::RefineRecord refine_record(const refine::RefineResult& r, const refine::RefineOptions& o) {
  const refine::SolveReport& s = r.report;
  store::RefineRecord rec;
  rec.loss = refine::to_string(o.loss);
  rec.loss_scale = o.loss_scale;
  rec.max_iterations = o.max_iterations;
  rec.linear_solver = o.linear_solver;
  rec.covariance = o.covariance;
  rec.tau_s_option = o.tau_s;
  rec.fit_rounds = o.fit_rounds;
  rec.gross_chi2 = o.gross_chi2;
  rec.imu_noise_scale = o.imu_noise_scale;
  const refine::DetectionErrorModel& m = s.error_model;
  rec.error_model = {m.tau_s, m.scale_translation, m.scale_rotation, m.whitened_lag1, m.used, m.gross, m.fitted_tau};
  rec.solves = s.solves;
  rec.nodes = s.nodes;
  rec.imu_factors = s.imu_factors;
  rec.detection_factors = s.detection_factors;
  for (const auto& d : r.detections) rec.detections_weight_below_half += d.weight < 0.5 ? 1 : 0;
  rec.parameters = s.parameters;
  rec.residuals = s.residuals;
  rec.iterations = s.iterations;
  rec.initial_cost = s.initial_cost;
  rec.final_cost = s.final_cost;
  rec.termination = s.termination;
  rec.covariance_ok = s.covariance_ok;
  return rec;
}

/// The solve and the files of the refined estimate (states.csv, objects.csv, reprojection.csv, trajectory.csv/.tum,
/// each where the run's output level keeps it), and run.json's record of it: `rec` (the run's) gets the refined
/// final, the refine block, the solve's timings and warnings. Shared by roe refine (into RUN_DIR2) and roe run's
/// batch estimator (into RUN_DIR).
refine::RefineResult refine_and_write(const store::RunRecord& run, const Dataset& ds, const RunTables& tables,
                                      const std::vector<ekf::ImageDetections>& images, const refine::RefineOptions& opt,
                                      const io::OutputDir& dir, store::RunRecord& rec) {
  const refine::RefineInput in = make_input(run, ds, tables, images);
  log::info("refine: {} images with used detections, {} objects, anchor {}", in.images.size(), in.initial_T_O_W.size(),
            in.anchor_id);
  refine::RefineResult r = refine::refine(in, opt);
  log::info("refine: {} iterations, cost {:.6g} → {:.6g}, {:.3f} s (+ covariance {:.3f} s)", r.report.iterations,
            r.report.initial_cost, r.report.final_cost, r.report.solve_s, r.report.covariance_s);
  if (opt.covariance && !r.report.covariance_ok)
    rec.warnings.push_back("the marginal covariances could not be computed (rank-deficient problem): σ written as 0");

  const auto t_write = Clock::now();
  const auto has = [&](const char* file) { return store::run_folder_has(run.config, file); };
  const std::vector<store::RecordedState> states = refined_states(r, tables, ds.imu);
  if (has("states.csv")) store::write_states_csv(dir.file("states.csv"), states);
  if (has("objects.csv")) store::write_objects_csv(dir.file("objects.csv"), refined_objects(r));
  if (has("reprojection.csv"))
    store::write_reprojection_csv(dir.file("reprojection.csv"), refined_reprojection(r, tables, images));
  for (const auto format : {io::TrajectoryFormat::kCsv, io::TrajectoryFormat::kTum})
    io::write_trajectory(dir.file(format == io::TrajectoryFormat::kCsv ? "trajectory.csv" : "trajectory.tum"),
                         states.size(),
                         [&states](std::size_t i) { return StampedPose{states[i].t_ns, Pose(states[i].x.q_W_I, states[i].x.p_W_I)}; },
                         format);

  rec.roe_version = kVersion;
  rec.final_T_I_C = r.T_I_C;
  rec.final_objects.clear();
  for (const auto& [id, o] : r.objects) rec.final_objects.push_back({id, o.anchor, o.T_O_W});
  rec.final_time_offset = store::FinalTimeOffset{r.time_offset_estimated, in.declared_time_offset_s, r.time_offset_s,
                                                 r.sigma_time_offset_s};
  rec.refine = refine_record(r, opt);
  rec.refine->dataset = run.inputs.dataset;
  rec.timing_s["solve"] = r.report.solve_s;
  rec.timing_s["solve_residuals"] = r.report.residual_s;
  rec.timing_s["solve_jacobians"] = r.report.jacobian_s;
  rec.timing_s["solve_linear"] = r.report.linear_solver_s;
  rec.timing_s["covariance"] = r.report.covariance_s;
  rec.timing_s["write_refined"] = seconds_since(t_write);
  return r;
}

}  // namespace

void batch_estimate(const Dataset& ds, const std::string& set, const pipeline::RunOutput& run,
                    const io::OutputDir& dir, store::RunRecord& rec) {
  const Timestamp offset_ns = ds.manifest.camera ? from_seconds(ds.manifest.camera->time_offset_s) : 0;
  const std::vector<ekf::ImageDetections> images = ekf::group_images(ds.detections.at(set), offset_ns);
  RunTables tables;  // what roe refine reads from RUN_DIR, from the run in memory
  tables.states = run.states;
  for (const auto& [id, T_O_W] : run.summary.final_T_O_W) tables.T_O_W[id] = T_O_W;
  for (const auto& row : run.reprojection) tables.rows.push_back({row.t_ns, row.object_id, row.outcome.status});
  restamp_rows(tables.rows, images);  // on the images' stamps where the filter processed them at t + t_d
  const store::RunRecord as_run = rec;
  (void)refine_and_write(as_run, ds, tables, images, refine::RefineOptions{}, dir, rec);
}

RefineCommandResult refine_run(const fs::path& run_dir_in, const fs::path& out_dir, const RefineCommandOptions& opt) {
  const auto t_start = Clock::now();
  const fs::path run_dir = io::without_trailing_separator(run_dir_in);
  const store::RunRecord run = read_run(run_dir);
  if (const std::string why = store::run_file_absent_reason(run.config, "states.csv"); !why.empty())
    throw InputError("roe refine starts from the run's states.csv, objects.csv and reprojection.csv: " + why,
                     {(run_dir / "run.json").string(), 0, 0, "config.output.level"});
  fs::path dataset = io::without_trailing_separator(opt.dataset);
  if (opt.dataset.empty()) {
    const auto named = store::find_run_dataset(run);
    if (!named)
      throw InputError(fmt::format("the dataset the run read ({}) is not there any more (give --dataset)",
                                   run.inputs.dataset_abs),
                       {(run_dir / "run.json").string(), 0, 0, "inputs.dataset_abs"});
    dataset = *named;
  }
  io::OutputDir dir(out_dir, opt.force, {run_dir, dataset});
  const Dataset ds = read_run_dataset(run, dataset, run_dir / "run.json");
  const Timestamp offset_ns = ds.manifest.camera ? from_seconds(ds.manifest.camera->time_offset_s) : 0;
  const std::vector<ekf::ImageDetections> images = ekf::group_images(ds.detections.at(run.inputs.detections), offset_ns);
  const RunTables tables = read_tables(run_dir, run, ds, images);
  const double read_s = seconds_since(t_start);

  RefineCommandResult res;
  res.out = out_dir;
  store::RunRecord& rec = res.record;
  rec = run;
  rec.command = "refine";
  rec.warnings.clear();
  rec.timing_s = {{"read", read_s}};
  res.result = refine_and_write(run, ds, tables, images, opt.refine, dir, rec);
  rec.refine->input_run = run_dir.string();
  rec.refine->input_run_abs = io::provenance_path(run_dir);
  rec.refine->dataset = dataset.string();
  res.warnings = rec.warnings;
  rec.timing_s["write"] = rec.timing_s.at("write_refined");
  rec.timing_s.erase("write_refined");
  rec.timing_s["total"] = seconds_since(t_start);
  store::write_run_json(dir.file("run.json"), rec);
  dir.commit();
  return res;
}

json RefineCommandResult::to_json() const {
  return {{"command", "refine"}, {"out", out.string()}, {"refine", store::run_record_to_json(record).at("refine")},
          {"timing_s", record.timing_s}, {"warnings", warnings}};
}
std::string RefineCommandResult::to_text() const {
  const refine::SolveReport& s = result.report;
  std::string t = fmt::format("roe refine → {}\n", out.string());
  t += fmt::format("  {} nodes, {} IMU factors, {} detection factors; {} iterations, cost {:.6g} → {:.6g} ({})\n",
                   s.nodes, s.imu_factors, s.detection_factors, s.iterations, s.initial_cost, s.final_cost,
                   s.termination);
  const Vector6d se = result.cov_T_I_C.diagonal().cwiseMax(0.0).cwiseSqrt();
  t += fmt::format("  T_I_C p = [{:.4f} {:.4f} {:.4f}] m, σ {:.1f} mm / {:.3f}°\n", result.T_I_C.p.x(), result.T_I_C.p.y(),
                   result.T_I_C.p.z(), se.head<3>().maxCoeff() * 1e3, se.tail<3>().maxCoeff() * 180.0 / M_PI);
  t += fmt::format("  solve {:.3f} s, covariance {:.3f} s, total {:.3f} s\n", s.solve_s, s.covariance_s,
                   record.timing_s.at("total"));
  return t;
}

}  // namespace roe::app
