// roe calib-check: reads a run folder (and its dataset) into calib::CalibInput and reports the checks.
#include "roe/app/calib_check.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/ekf/images.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"
#include "roe/store/run_files.hpp"
#include "roe/store/run_record.hpp"

namespace roe::app {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr double kDeg = M_PI / 180.0;

struct StatesTrace {
  std::vector<calib::ExtrinsicsSample> extrinsics;
  Eigen::Vector3d final_gyro_bias = Eigen::Vector3d::Zero();
};

// roe run writes only finite numbers in states.csv (the filter stops on a non-finite state): a NaN or a
// non-number in any column, read by a check or not, means the file is damaged (docs/calib-check.md), so
// every column is read. Its σ cells may be empty (output level standard: σ recorded after each image only);
// the trace is the rows with σ (the extrinsics change only at the updates).
StatesTrace read_states(const fs::path& file) {
  StatesTrace t;
  store::for_each_state_row(file, {}, [&](const store::RecordedState& s) {
    if (!s.sigma.tail<6>().array().isNaN().any()) t.extrinsics.push_back({s.t_ns, s.T_I_C, s.sigma.tail<6>()});
    t.final_gyro_bias = s.x.b_g;
  });
  if (t.extrinsics.empty()) throw InputError("no data row", {file.string()});
  return t;
}

/// Each object's last row of objects.csv (its final pose and anchor-relative σ).
std::map<int, calib::ObjectEstimate> read_objects(const fs::path& file) {
  std::map<int, calib::ObjectEstimate> out;
  for (const store::ObjectRow& row : store::read_objects_csv(file)) {
    calib::ObjectEstimate& o = out[row.object_id];
    o.id = row.object_id;
    o.anchor = row.anchor;
    o.T_O_W = row.T_O_W;
    o.sigma_A_O = row.sigma_A_O;
  }
  return out;
}

/// The dataset files the run hashed, compared with their current contents.
calib::CheckResult dataset_identity(const store::RunRecord& run, const fs::path& run_json, const fs::path& dataset,
                                    const std::string& detections) {
  calib::CheckResult r{"dataset.identity", calib::CheckStatus::kPass, "", {}};
  const std::map<std::string, std::string>& sha = run.inputs.sha256;
  std::vector<std::string> changed;
  std::size_t compared = 0;
  const std::vector<std::pair<std::string, fs::path>> files = {
      {"roe.json", store::manifest_path(dataset)},
      {"mav0/imu0/data.csv", store::imu_csv_path(dataset)},
      {"detections/" + detections + "/detections.csv", store::detections_dir(dataset, detections) / "detections.csv"}};
  for (const auto& [key, path] : files) {
    const auto hash = sha.find(key);
    if (hash == sha.end()) throw InputError("missing key", {run_json.string(), 0, 0, "inputs.sha256." + key});
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) {
      changed.push_back(key + " (missing)");
      continue;
    }
    ++compared;
    if (io::sha256_file(path) != hash->second) changed.push_back(key);
  }
  if (changed.empty()) {
    r.message = fmt::format("roe.json, the IMU and detections/{} are the files the run read", detections);
  } else {
    r.status = calib::CheckStatus::kFail;
    r.message = "differs from the files the run read: ";
    for (std::size_t i = 0; i < changed.size(); ++i) r.message += (i ? ", " : "") + changed[i];
    r.message += " (another dataset, or changed since the run; the truth and time-offset checks are not made)";
  }
  r.values = {{"files_changed", static_cast<double>(changed.size())}};
  return r;
}

}  // namespace

int CalibCheckResult::exit_code() const {
  if (report.failed()) return 1;
  if (strict && (report.undecided() || report.within_sigma() || report.unobservable() || !judged())) return 1;
  return 0;
}

bool CalibCheckResult::judged() const {
  for (const auto& c : report.checks) {
    if (c.name == "dataset.identity") continue;  // the files the run read, not its calibration
    const std::string st = calib::to_string(c.status);
    if (st == "pass" || st == "fail" || st == "within-sigma") return true;
  }
  return false;
}

namespace {

/// The verdict's word: FAIL, NOT JUDGED (nothing could be checked), or PASS.
std::string verdict_word(const CalibCheckResult& r) {
  if (r.exit_code() != 0) return "FAIL";
  return r.judged() ? "PASS" : "NOT JUDGED";
}

}  // namespace

std::map<std::string, int> CalibCheckResult::status_counts() const {
  std::map<std::string, int> counts = {{"pass", 0}, {"fail", 0}, {"inconclusive", 0}, {"skipped", 0},
                                       {"within-sigma", 0}, {"unobservable", 0}};
  for (const auto& c : report.checks) ++counts[calib::to_string(c.status)];
  return counts;
}

json CalibCheckResult::to_json() const {
  json checks = json::array();
  for (const auto& c : report.checks) {
    json values = json::object();
    for (const auto& [k, v] : c.values) values[k] = v;
    checks.push_back({{"name", c.name}, {"status", calib::to_string(c.status)}, {"message", c.message},
                      {"values", values}});
  }
  return {{"command", "calib-check"},
          {"out", nullptr},
          {"run", run_dir.string()},
          {"dataset", dataset.empty() ? json(nullptr) : json(dataset)},
          {"dataset_from", dataset_from.empty() ? json(nullptr) : json(dataset_from)},
          {"detections", detections},
          {"strict", strict},
          {"passed", passed()},
          {"verdict", verdict_word(*this)},
          {"counts", status_counts()},
          {"checks", checks},
          {"warnings", warnings}};
}

std::string CalibCheckResult::to_text() const {
  std::string s = fmt::format("calib-check {}", run_dir.string());
  s += dataset.empty() ? " (no dataset)\n"
                       : fmt::format(" (dataset {}{}, detections {})\n", dataset,
                                     dataset_from == "run.json" ? ", named in run.json" : "", detections);
  std::size_t width = 0;
  for (const auto& c : report.checks) width = std::max(width, c.name.size());
  std::map<std::string, int> counts;
  for (const auto& c : report.checks) {
    const std::string st = calib::to_string(c.status);
    ++counts[st];
    s += fmt::format("  {:<13} {:<{}}  {}\n", st, c.name, width, c.message);
  }
  s += fmt::format("{}: {} passed, {} within σ (beyond the limit, explained by the filter's σ), {} unobservable "
                   "(not calibrated by these data, not contradicted), {} failed, {} inconclusive, {} skipped{}\n",
                   verdict_word(*this), counts["pass"], counts["within-sigma"], counts["unobservable"],
                   counts["fail"], counts["inconclusive"], counts["skipped"],
                   strict ? " (--strict: within-sigma, unobservable and inconclusive checks count as failures)" : "");
  if (!judged())
    s += "  no check could judge this run (every one was skipped, inconclusive or unobservable): it is neither "
         "passed nor failed; a run written with --output minimal has no states.csv or reprojection.csv to check\n";
  return s;
}

namespace {

/// The detections per object as run.json counts them (counts.detections.per_object), into `objects`;
/// an object that never entered the state gets an entry of its own.
void add_detection_counts(const store::RunRecord& run, const calib::CalibInput& in,
                          std::map<int, calib::ObjectEstimate>& objects) {
  for (const auto& [id, counts] : run.counts.per_object) {
    auto it = objects.find(id);
    if (it == objects.end()) {
      calib::ObjectEstimate o;
      o.id = id;
      o.anchor = in.anchor_id && id == *in.anchor_id;
      o.detections = counts.detections;
      objects[id] = o;  // never entered the state
    } else {
      it->second.detections = counts.detections;
    }
  }
}

/// The dataset to check against: --dataset, else the one the run read when it is still there
/// (store::find_run_dataset; empty: none). dataset.identity is skipped with --no-dataset and inconclusive
/// when the run's dataset is gone (--strict fails then).
fs::path choose_dataset(const store::RunRecord& run, const CalibCheckOptions& opt, CalibCheckResult& res,
                        calib::CheckResult& identity, calib::CalibInput& in) {
  std::error_code ec;
  if (opt.no_dataset) {
    in.dataset_absent_reason = in.time_offset_absent_reason = "--no-dataset";
    return {};
  }
  if (!opt.dataset.empty()) {
    const fs::path dataset = io::without_trailing_separator(opt.dataset);
    res.dataset_from = "option";
    if (!fs::is_regular_file(store::manifest_path(dataset), ec))
      throw InputError("not a dataset folder: roe.json is missing", {dataset.string()});
    return dataset;
  }
  if (const auto named = store::find_run_dataset(run)) {
    res.dataset_from = "run.json";
    return *named;
  }
  identity.status = calib::CheckStatus::kInconclusive;
  identity.message = fmt::format("the run's dataset {} is not there (give --dataset, or --no-dataset)",
                                 run.inputs.dataset_abs);
  in.dataset_absent_reason = in.time_offset_absent_reason = "no dataset (dataset.identity)";
  res.warnings.push_back(identity.message + ": the truth and time-offset checks are skipped");
  return {};
}

/// What the dataset knows: the truth (when simulated), the declared camera time offset and the offset
/// estimated from the run's detections and the gyro.
void read_dataset_checks(const fs::path& dataset, const CalibCheckOptions& opt, double min_score,
                         const StatesTrace& states, CalibCheckResult& res, calib::CalibInput& in) {
  const DatasetManifest man = store::read_manifest(dataset);
  if (man.truth) {
    in.true_T_I_C = man.truth->T_I_C;
    for (const auto& o : man.truth->objects) in.true_T_W_O[o.id] = o.T_W_O;
  }
  in.declared_time_offset_s = man.camera ? man.camera->time_offset_s : 0.0;
  log::info("estimating the camera-IMU time offset from {} and the gyro", res.detections);
  const auto imu = store::read_imu_csv(store::imu_csv_path(dataset));
  auto dets = store::read_detections_csv(store::detections_dir(dataset, res.detections) / "detections.csv");
  ekf::FilterOptions score_rule;  // the filter's own rule for which detections count (min_score)
  score_rule.min_score = min_score;
  dets.erase(std::remove_if(dets.begin(), dets.end(),
                            [&](const Detection& d) { return !ekf::usable_detection(d, score_rule); }),
             dets.end());
  calib::TimeOffsetOptions to = opt.time_offset;
  to.centre_s = in.declared_time_offset_s;  // search around what the dataset declares
  to.symmetric_ids.clear();  // left out unless described by a models_info (docs/calib-check.md §3)
  for (const auto& o : man.objects) {
    if (o.symmetric) to.symmetric_ids.push_back(o.id), in.symmetric_ids.push_back(o.id);
    if (!o.symmetry.empty()) to.symmetries[o.id] = in.symmetries[o.id] = o.symmetry;
  }
  in.time_offset = calib::estimate_camera_time_offset(imu, states.final_gyro_bias, in.extrinsics.back().T_I_C.q,
                                                      dets, to);
}

}  // namespace

CalibCheckResult calib_check(const fs::path& run_dir_in, const CalibCheckOptions& opt) {
  const fs::path run_dir = io::without_trailing_separator(run_dir_in);
  std::error_code ec;
  if (!fs::is_directory(run_dir, ec)) throw InputError("not a folder (expected a run folder written by roe run)", {run_dir.string()});
  if (!fs::is_regular_file(run_dir / "run.json", ec))
    throw InputError("not a run folder: run.json is missing", {run_dir.string()});
  if (opt.no_dataset && !opt.dataset.empty()) throw InputError("--dataset and --no-dataset exclude each other");

  CalibCheckResult res;
  res.run_dir = run_dir;
  res.strict = opt.strict;
  const store::RunRecord run = store::read_run_json(run_dir / "run.json");
  calib::CalibInput in;
  if (run.final_time_offset) {
    in.declared_time_offset_s = run.final_time_offset->declared_s;
    if (run.final_time_offset->estimated)
      in.online_time_offset = calib::CalibInput::OnlineTimeOffset{run.final_time_offset->value_s,
                                                                  run.final_time_offset->sigma_s};
  }
  const ekf::FilterOptions& filter = run.config.filter;
  in.extrinsics_estimated = filter.estimate_extrinsics;
  in.anchor_id = run.anchor_id;
  const double sp = filter.extrinsics_sigma_p_m;
  const double sr = filter.extrinsics_sigma_rot_deg * kDeg;
  in.prior_sigma << sp, sp, sp, sr, sr, sr;
  in.prior_T_I_C = run.init.T_I_C;
  const double min_score = filter.min_score;
  res.detections = run.inputs.detections;

  // The filter's own (causal) history: with the smoother states.csv holds the smoothed estimate, whose
  // constant states carry their final value and σ at every time, and the filter's is in states_filter.csv.
  // A batch estimate (roe refine, roe run's batch) is judged itself, with its marginals: states.csv.
  // A run written with output level minimal has neither: every check says it cannot judge.
  const fs::path filter_states = run_dir / "states_filter.csv";
  in.estimate_absent_reason = store::run_file_absent_reason(run.config, "states.csv");
  if (run.refine) in.batch_termination = run.refine->termination;
  StatesTrace states;
  if (in.estimate_absent_reason.empty()) {
    const bool filter_trace = !run.refine && fs::is_regular_file(filter_states, ec);
    states = read_states(filter_trace ? filter_states : run_dir / "states.csv");
    in.extrinsics = std::move(states.extrinsics);
    auto objects = read_objects(run_dir / "objects.csv");
    add_detection_counts(run, in, objects);
    for (const auto& [id, o] : objects) in.objects.push_back(o);
  } else {
    res.warnings.push_back("no calibration check could be made: " + in.estimate_absent_reason);
  }

  calib::CheckResult identity{"dataset.identity", calib::CheckStatus::kSkipped, "--no-dataset", {}};
  const fs::path dataset = choose_dataset(run, opt, res, identity, in);
  if (!dataset.empty()) {
    res.dataset = dataset.string();
    identity = dataset_identity(run, run_dir / "run.json", dataset, res.detections);
    if (identity.status == calib::CheckStatus::kPass) {
      if (in.estimate_absent_reason.empty()) read_dataset_checks(dataset, opt, min_score, states, res, in);
    } else {
      in.dataset_absent_reason = in.time_offset_absent_reason =
          "the dataset is not the one the run read (dataset.identity)";
    }
  }

  res.report = calib::check_calibration(in, opt.thresholds);
  res.report.checks.insert(res.report.checks.begin(), identity);
  return res;
}

}  // namespace roe::app
