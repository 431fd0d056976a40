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
#include "roe/io/trajectory_io.hpp"
#include "roe/version.hpp"

namespace roe::app {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using Clock = SteadyClock;

/// What refine reads of run.json, typed.
struct RunInfo {
  json raw;
  RunConfig config;
  std::string dataset_abs, detections;
  std::map<std::string, std::string> sha256;
  int anchor_id = -1;
  Pose prior_T_I_C;
  Eigen::Vector3d init_gyro_bias = Eigen::Vector3d::Zero();
  ekf::ImuNoiseParams noise;
  double detection_sigma_scale = 1.0;
};

RunInfo read_run_json(const fs::path& file) {
  RunInfo r;
  r.raw = io::parse_json_file(file);
  const std::string src = file.string();
  io::JsonObject o(r.raw, src);
  if (!o.has("config") || !o.has("inputs") || !o.has("anchor_id") || !o.has("init") || !o.has("imu_noise"))
    throw InputError("not a run.json of roe run (config, inputs, anchor_id, init or imu_noise missing)", {src});
  std::string command;
  o.require("command", command);
  if (command != "run") throw InputError(fmt::format("refines the output of roe run, not of roe {}", command), {src, 0, 0, "command"});
  r.config = run_config_from_json(r.raw.at("config"), src);
  io::JsonObject in = o.child("inputs");
  in.require("dataset_abs", r.dataset_abs);
  in.require("detections", r.detections);
  in.require("sha256", r.sha256);
  if (!r.raw.at("anchor_id").is_number_integer())
    throw InputError("the run has no anchor (anchor_id null): nothing to refine against", {src, 0, 0, "anchor_id"});
  o.get("anchor_id", r.anchor_id);
  io::JsonObject init = o.child("init");
  std::vector<double> bg;
  init.require("gyro_bias", bg);
  if (bg.size() != 3) throw InputError("expected 3 numbers", {src, 0, 0, "init.gyro_bias"});
  r.init_gyro_bias = Eigen::Vector3d(bg[0], bg[1], bg[2]);
  r.prior_T_I_C = io::pose_from_json(r.raw.at("init").at("T_I_C"), src, "init.T_I_C");
  ImuNoise n;
  io::JsonObject noise = o.child("imu_noise");
  io::read_imu_noise(noise, n);
  if (!n.known()) throw InputError("imu_noise: the four noise values are required", {src, 0, 0, "imu_noise"});
  r.noise = {n.gyro_noise_density, n.gyro_random_walk, n.accel_noise_density, n.accel_random_walk};
  if (o.has("detection_sigmas")) o.child("detection_sigmas").get("final_scale", r.detection_sigma_scale);
  return r;
}

/// The dataset the run read, checked against the run's hashes of the IMU and the detections.
Dataset read_run_dataset(const RunInfo& run, const fs::path& dataset, const fs::path& run_json) {
  const std::vector<std::pair<std::string, fs::path>> files = {
      {"mav0/imu0/data.csv", store::imu_csv_path(dataset)},
      {"detections/" + run.detections + "/detections.csv", store::detections_dir(dataset, run.detections) / "detections.csv"}};
  for (const auto& [key, path] : files) {
    const auto it = run.sha256.find(key);
    if (it == run.sha256.end()) throw InputError("missing key", {run_json.string(), 0, 0, "inputs.sha256." + key});
    if (io::sha256_file(path) != it->second)
      throw InputError(fmt::format("{} is not the file the run read (another dataset, or changed since the run)", key),
                       {path.string()});
  }
  store::DatasetParts parts;
  parts.frames = parts.mocap = parts.groundtruth = false;
  parts.detection_names = {run.detections};
  return store::read_dataset(dataset, parts);
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

struct RunTables {
  std::vector<store::StateRow> states;
  std::map<int, Pose> T_O_W;  ///< each object's last row
  std::vector<eval::DetectionPose> reprojection;
  std::map<std::pair<Timestamp, int>, ekf::DetectionStatus> status;
};

RunTables read_tables(const fs::path& run_dir) {
  RunTables t;
  t.states = store::read_states_csv(run_dir / "states.csv");
  for (const auto& row : store::read_objects_csv(run_dir / "objects.csv")) t.T_O_W[row.object_id] = row.T_O_W;
  t.reprojection = store::read_reprojection_csv(run_dir / "reprojection.csv");
  for (const auto& p : t.reprojection)
    t.status[{p.t_ns, p.object_id}] = parse_status(p.status, run_dir / "reprojection.csv");
  if (t.states.size() < 2) throw InputError("fewer than 2 state rows", {(run_dir / "states.csv").string()});
  return t;
}

refine::RefineInput make_input(const RunInfo& run, const Dataset& ds, const RunTables& t,
                               const std::vector<ekf::ImageDetections>& images) {
  refine::RefineInput in;
  in.imu = ds.imu;
  in.noise = run.noise;
  in.filter = run.config.filter;
  in.detection_sigma_scale = run.detection_sigma_scale;
  for (const auto& o : ds.manifest.objects)
    if (!o.symmetry.empty()) in.symmetries[o.id] = o.symmetry;
  for (const auto& im : images) {
    ekf::ImageDetections used{im.t_ns, {}};
    for (const auto& d : im.detections) {
      const auto s = t.status.find({im.t_ns, d.object_id});
      if (s != t.status.end() && used_by_refine(s->second)) used.detections.push_back(d);
    }
    if (!used.detections.empty()) in.images.push_back(std::move(used));
  }
  for (const auto& s : t.states) in.initial.push_back({s.t_ns, s.x});
  in.prior_T_I_C = run.prior_T_I_C;
  in.initial_T_I_C = t.states.back().T_I_C;
  in.initial_T_O_W = t.T_O_W;
  in.anchor_id = run.anchor_id;
  in.prior_b_g = run.init_gyro_bias;
  in.prior_b_a = run.config.filter.init_accel_bias;
  return in;
}

Vector6d sigma_of(const refine::Mat6& C) { return C.diagonal().cwiseMax(0.0).cwiseSqrt(); }

std::vector<store::StateRow> refined_states(const refine::RefineResult& r, const RunTables& t,
                                         const std::vector<ImuSample>& imu) {
  std::vector<Timestamp> times;
  times.reserve(t.states.size());
  for (const auto& s : t.states) times.push_back(s.t_ns);
  const std::vector<refine::StateSample> x = refine::states_at(r, imu, times);
  std::vector<store::StateRow> rows(t.states.size());
  const Vector6d s_extr = sigma_of(r.cov_T_I_C);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    rows[i].t_ns = x[i].t_ns;
    rows[i].x = x[i].x;
    rows[i].T_I_C = r.T_I_C;
    rows[i].sigma.head<15>() = t.states[i].sigma.head<15>();  // the run's: refine marginalises the calibration only
    rows[i].sigma.tail<6>() = s_extr;
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
                                                      const std::vector<ekf::ImageDetections>& images,
                                                      const fs::path& file) {
  std::map<std::pair<Timestamp, int>, const Detection*> det;
  for (const auto& im : images)
    for (const auto& d : im.detections) det[{im.t_ns, d.object_id}] = &d;
  std::map<std::pair<Timestamp, int>, double> chi2;
  for (const auto& f : r.detections) chi2[{f.t_ns, f.object_id}] = f.chi2;
  std::vector<store::ReprojectionRow> rows;
  rows.reserve(t.reprojection.size());
  for (const auto& p : t.reprojection) {
    store::ReprojectionRow row;
    row.t_ns = p.t_ns;
    row.object_id = p.object_id;
    row.outcome.object_id = p.object_id;
    row.outcome.status = parse_status(p.status, file);
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

/// The correlated-error model the solve used (docs/refine.md §2b), with the autocovariance it was fitted to.
json error_model_json(const refine::SolveReport& s) {
  const refine::DetectionErrorModel& m = s.error_model;
  json ac = json::array();
  for (const auto& b : m.autocovariance) ac.push_back({{"lag_s", b.lag_s}, {"cov", b.cov}, {"pairs", b.pairs}});
  return {{"correlated", m.correlated},   {"tau_s", m.tau_s},
          {"sigma_bias", m.sigma_bias}, {"sigma_white", m.sigma_white},
          {"autocovariance", ac}};
}

json solve_json(const refine::RefineResult& r, const refine::RefineOptions& o) {
  const refine::SolveReport& s = r.report;
  std::size_t down = 0;
  for (const auto& d : r.detections) down += d.weight < 0.5 ? 1 : 0;
  return {{"options",
           {{"loss", refine::to_string(o.loss)},
            {"loss_scale", o.loss_scale},
            {"max_iterations", o.max_iterations},
            {"linear_solver", o.linear_solver},
            {"covariance", o.covariance},
            {"correlated_errors", o.correlated_errors}}},
          {"detection_error_model", error_model_json(s)},
          {"nodes", s.nodes},
          {"imu_factors", s.imu_factors},
          {"detection_factors", s.detection_factors},
          {"detections_weight_below_half", down},
          {"parameters", s.parameters},
          {"residuals", s.residuals},
          {"iterations", s.iterations},
          {"initial_cost", s.initial_cost},
          {"final_cost", s.final_cost},
          {"termination", s.termination},
          {"covariance_ok", s.covariance_ok}};
}

}  // namespace

RefineCommandResult refine_run(const fs::path& run_dir_in, const fs::path& out_dir, const RefineCommandOptions& opt) {
  const auto t_start = Clock::now();
  const fs::path run_dir = io::without_trailing_separator(run_dir_in);
  std::error_code ec;
  if (!fs::is_regular_file(run_dir / "run.json", ec))
    throw InputError("not a run folder: run.json is missing", {run_dir.string()});
  const RunInfo run = read_run_json(run_dir / "run.json");
  const fs::path dataset = opt.dataset.empty() ? fs::path(run.dataset_abs) : io::without_trailing_separator(opt.dataset);
  io::OutputDir dir(out_dir, opt.force, {run_dir, dataset});
  const Dataset ds = read_run_dataset(run, dataset, run_dir / "run.json");
  const RunTables tables = read_tables(run_dir);
  const Timestamp offset_ns = ds.manifest.camera ? from_seconds(ds.manifest.camera->time_offset_s) : 0;
  const std::vector<ekf::ImageDetections> images = ekf::group_images(ds.detections.at(run.detections), offset_ns);
  const double read_s = seconds_since(t_start);

  RefineCommandResult res;
  res.out = out_dir;
  const refine::RefineInput in = make_input(run, ds, tables, images);
  log::info("refine: {} images with used detections, {} objects, anchor {}", in.images.size(), in.initial_T_O_W.size(),
            in.anchor_id);
  res.result = refine::refine(in, opt.refine);
  const refine::RefineResult& r = res.result;
  log::info("refine: {} iterations, cost {:.6g} → {:.6g}, {:.3f} s (+ covariance {:.3f} s)", r.report.iterations,
            r.report.initial_cost, r.report.final_cost, r.report.solve_s, r.report.covariance_s);
  if (opt.refine.covariance && !r.report.covariance_ok)
    res.warnings.push_back("the marginal covariances could not be computed (rank-deficient problem): σ written as 0");

  const auto t_write = Clock::now();
  const std::vector<store::StateRow> states = refined_states(r, tables, ds.imu);
  store::write_states_csv(dir.file("states.csv"), states);
  store::write_objects_csv(dir.file("objects.csv"), refined_objects(r));
  store::write_reprojection_csv(dir.file("reprojection.csv"),
                             refined_reprojection(r, tables, images, run_dir / "reprojection.csv"));
  for (const auto format : {io::TrajectoryFormat::kCsv, io::TrajectoryFormat::kTum})
    io::write_trajectory(dir.file(format == io::TrajectoryFormat::kCsv ? "trajectory.csv" : "trajectory.tum"),
                         states.size(),
                         [&states](std::size_t i) { return StampedPose{states[i].t_ns, Pose(states[i].x.q_W_I, states[i].x.p_W_I)}; },
                         format);

  json report = run.raw;
  report["roe_version"] = kVersion;
  report["command"] = "refine";
  report["final"]["T_I_C"] = io::pose_to_json(r.T_I_C);
  json objs = json::array();
  for (const auto& [id, o] : r.objects)
    objs.push_back({{"id", id}, {"anchor", o.anchor}, {"T_O_W", io::pose_to_json(o.T_O_W)}});
  report["final"]["objects"] = objs;
  report["refine"] = solve_json(r, opt.refine);
  report["refine"]["input_run"] = run_dir.string();
  report["refine"]["input_run_abs"] = io::provenance_path(run_dir);
  report["refine"]["dataset"] = dataset.string();
  report["warnings"] = res.warnings;
  report["timing_s"] = {{"read", read_s},
                        {"solve", r.report.solve_s},
                        {"solve_residuals", r.report.residual_s},
                        {"solve_jacobians", r.report.jacobian_s},
                        {"solve_linear", r.report.linear_solver_s},
                        {"covariance", r.report.covariance_s},
                        {"write", seconds_since(t_write)},
                        {"total", seconds_since(t_start)}};
  io::write_file_atomic(dir.file("run.json"), io::dump_json(report, 2) + "\n");
  dir.commit();
  res.report = report;
  return res;
}

json RefineCommandResult::to_json() const {
  return {{"command", "refine"}, {"out", out.string()}, {"refine", report.at("refine")},
          {"timing_s", report.at("timing_s")}, {"warnings", warnings}};
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
                   report.at("timing_s").at("total").get<double>());
  return t;
}

}  // namespace roe::app
