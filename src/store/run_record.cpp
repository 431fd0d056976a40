// run.json, typed (store/run_record.hpp): the one writer and the one strict reader.
#include "roe/store/run_record.hpp"

#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <set>

#include "roe/core/dataset.hpp"
#include "roe/core/error.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"
#include "roe/io/pose_json.hpp"

namespace roe::store {
namespace fs = std::filesystem;
using io::json;
using io::JsonObject;

namespace {

// ---------------------------------------------------------------------------------------------- writing

json v3(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }

json counts_json(const ekf::DetectionCounts& c) {
  return {{"detections", c.detections},       {"accepted", c.accepted},
          {"initialized", c.initialized},     {"rejected_chi2", c.rejected_chi2},
          {"rejected_no_main", c.rejected_no_main}, {"rejected_score", c.rejected_score},
          {"rejected_no_imu", c.rejected_no_imu},   {"pending_init", c.pending_init}};
}

json counts_json(const RunCounts& c) {
  json per = json::object();
  for (const auto& [id, n] : c.per_object) per[std::to_string(id)] = counts_json(n);
  json d = counts_json(c.detections);
  d["per_object"] = per;
  return {{"imu_samples", c.imu_samples},
          {"camera_frames", c.camera_frames},
          {"images_with_detections", c.images_with_detections},
          {"updates", c.updates},
          {"trajectory_rows", c.trajectory_rows},
          {"detections", d}};
}

json nis_json(const ekf::NisStats& n) {
  if (n.count == 0) return {{"count", 0}, {"dof", 6}, {"gate", n.gate}};
  return {{"count", n.count}, {"dof", 6},       {"median", n.median}, {"p25", n.p25},
          {"p75", n.p75},     {"p95", n.p95},   {"max", n.max},       {"mean", n.mean},
          {"gate", n.gate},   {"fraction_above_gate", n.fraction_above_gate},
          {"median_ratio", n.median_ratio}};
}

json health_json(const RunHealthRecord& h) {
  const ekf::HealthLimits& l = h.limits;
  return {{"healthy", h.healthy()},
          {"problems", h.problems},
          {"duration_s", h.duration_s},
          {"accepted_updates", h.accepted_updates},
          {"supported_fraction", h.supported_fraction},
          {"longest_dead_reckoning_s", h.longest_dead_reckoning_s},
          {"longest_dead_reckoning_from_s", h.longest_dead_reckoning_from_s},
          {"longest_dead_reckoning_to_s", h.longest_dead_reckoning_to_s},
          {"nis_median_ratio", h.nis_median_ratio},
          {"limits",
           {{"support_window_s", l.support_window_s},
            {"min_supported_fraction", l.min_supported_fraction},
            {"max_dead_reckoning_s", l.max_dead_reckoning_s},
            {"max_nis_median_ratio", l.max_nis_median_ratio}}}};
}

json relocks_json(const std::vector<RelockRecord>& relocks) {
  json a = json::array();
  for (const auto& e : relocks)
    a.push_back({{"t_s", e.t_s},
                 {"refused_since_s", e.refused_since_s},
                 {"offset", v3(e.offset)},
                 {"drift_per_s", v3(e.drift_per_s)},
                 {"residual_sigma", e.residual_sigma},
                 {"detections", e.detections},
                 {"objects", e.objects}});
  return a;
}

json init_json(const RunInit& s) {
  json j = {{"T_I_C", io::pose_to_json(s.T_I_C)},
            {"window_samples", s.window_samples},
            {"window_s", s.window_s},
            {"accel_mean", v3(s.accel_mean)},
            {"accel_std", v3(s.accel_std)},
            {"gyro_mean", v3(s.gyro_mean)},
            {"gyro_std", v3(s.gyro_std)},
            {"gyro_bias", v3(s.gyro_bias)},
            {"gyro_bias_from", s.gyro_bias_from}};
  if (!s.gyro_bias_rest_refused.empty()) j["gyro_bias_rest_refused"] = s.gyro_bias_rest_refused;
  return j;
}

constexpr const char* kNoiseKeys[4] = {"gyro_noise_density", "gyro_random_walk", "accel_noise_density",
                                       "accel_random_walk"};

json imu_noise_json(const ekf::ImuNoiseParams& n, const std::array<std::string, 4>& from) {
  json j = io::imu_noise_to_json(n);
  json f = json::object();
  for (int i = 0; i < 4; ++i) f[kNoiseKeys[i]] = from[i];
  j["from"] = f;
  return j;
}

json refine_json(const RefineRecord& r) {
  const RefineRecord::ErrorModel& m = r.error_model;
  return {{"options",
           {{"loss", r.loss},
            {"loss_scale", r.loss_scale},
            {"max_iterations", r.max_iterations},
            {"linear_solver", r.linear_solver},
            {"covariance", r.covariance},
            {"tau_s", r.tau_s_option},
            {"fit_rounds", r.fit_rounds},
            {"gross_chi2", r.gross_chi2},
            {"imu_noise_scale", r.imu_noise_scale}}},
          {"detection_error_model",
           {{"tau_s", m.tau_s},
            {"fitted_tau", m.fitted_tau},
            {"scale_translation", m.scale_translation},
            {"scale_rotation", m.scale_rotation},
            {"whitened_lag1", m.whitened_lag1},
            {"used", m.used},
            {"gross", m.gross}}},
          {"solves", r.solves},
          {"nodes", r.nodes},
          {"imu_factors", r.imu_factors},
          {"detection_factors", r.detection_factors},
          {"detections_weight_below_half", r.detections_weight_below_half},
          {"parameters", r.parameters},
          {"residuals", r.residuals},
          {"iterations", r.iterations},
          {"initial_cost", r.initial_cost},
          {"final_cost", r.final_cost},
          {"termination", r.termination},
          {"covariance_ok", r.covariance_ok},
          {"input_run", r.input_run},
          {"input_run_abs", r.input_run_abs},
          {"dataset", r.dataset}};
}

// ---------------------------------------------------------------------------------------------- reading

[[noreturn]] void fail(const JsonObject& o, const std::string& key, const std::string& what) {
  throw ConfigError(what, {o.source(), 0, 0, o.key_path(key)});
}

template <typename T>
void req(JsonObject& o, const char* key, T& out) {
  if (!o.has(key)) fail(o, key, "missing key (is this a run.json written by this version of roe?)");
  o.get(key, out);
}

/// A required number; null (the writer's NaN) reads as NaN.
void num(JsonObject& o, const char* key, double& out) {
  if (const json* v = o.raw(key); v && v->is_null()) {
    out = std::numeric_limits<double>::quiet_NaN();
    return;
  }
  req(o, key, out);
}

JsonObject req_child(JsonObject& o, const char* key) {
  if (!o.has(key)) fail(o, key, "missing key (is this a run.json written by this version of roe?)");
  return o.child(key);
}

void vec3(JsonObject& o, const char* key, Eigen::Vector3d& out) {
  std::vector<double> v;
  req(o, key, v);
  if (v.size() != 3) fail(o, key, "expected 3 numbers");
  out = Eigen::Vector3d(v[0], v[1], v[2]);
}

Pose pose(JsonObject& o, const char* key) {
  if (!o.has(key)) fail(o, key, "missing key (is this a run.json written by this version of roe?)");
  return io::pose_from_json(*o.raw(key), o.source(), o.key_path(key));
}

void read_counts(JsonObject& o, ekf::DetectionCounts& c) {
  req(o, "detections", c.detections);
  req(o, "accepted", c.accepted);
  req(o, "initialized", c.initialized);
  req(o, "rejected_chi2", c.rejected_chi2);
  req(o, "rejected_no_main", c.rejected_no_main);
  req(o, "rejected_score", c.rejected_score);
  req(o, "rejected_no_imu", c.rejected_no_imu);
  req(o, "pending_init", c.pending_init);
}

void read_counts(JsonObject o, RunCounts& c) {
  req(o, "imu_samples", c.imu_samples);
  req(o, "camera_frames", c.camera_frames);
  req(o, "images_with_detections", c.images_with_detections);
  req(o, "updates", c.updates);
  req(o, "trajectory_rows", c.trajectory_rows);
  JsonObject d = req_child(o, "detections");
  read_counts(d, c.detections);
  JsonObject per = req_child(d, "per_object");
  for (const auto& [key, v] : d.raw("per_object")->items()) {
    int id = 0;
    try {
      std::size_t used = 0;
      id = std::stoi(key, &used);
      if (used != key.size()) throw std::invalid_argument(key);
    } catch (const std::exception&) {
      fail(per, key, "expected an object id");
    }
    JsonObject one = per.child(key.c_str());
    read_counts(one, c.per_object[id]);
    one.finish();
  }
  per.finish();
  d.finish();
  o.finish();
}

void read_nis(JsonObject o, ekf::NisStats& n) {
  req(o, "count", n.count);
  int dof = 0;
  req(o, "dof", dof);
  if (dof != 6) fail(o, "dof", "expected 6 (the 6-dof detection NIS)");
  num(o, "gate", n.gate);
  if (n.count == 0) return;
  num(o, "median", n.median);
  num(o, "p25", n.p25);
  num(o, "p75", n.p75);
  num(o, "p95", n.p95);
  num(o, "max", n.max);
  num(o, "mean", n.mean);
  num(o, "fraction_above_gate", n.fraction_above_gate);
  num(o, "median_ratio", n.median_ratio);
  o.finish();
}

void read_health(JsonObject o, RunHealthRecord& h) {
  bool healthy = false;
  req(o, "healthy", healthy);
  req(o, "problems", h.problems);
  if (healthy != h.healthy()) fail(o, "healthy", "contradicts problems (healthy means no problem)");
  num(o, "duration_s", h.duration_s);
  req(o, "accepted_updates", h.accepted_updates);
  num(o, "supported_fraction", h.supported_fraction);
  num(o, "longest_dead_reckoning_s", h.longest_dead_reckoning_s);
  num(o, "longest_dead_reckoning_from_s", h.longest_dead_reckoning_from_s);
  num(o, "longest_dead_reckoning_to_s", h.longest_dead_reckoning_to_s);
  num(o, "nis_median_ratio", h.nis_median_ratio);
  JsonObject l = req_child(o, "limits");
  num(l, "support_window_s", h.limits.support_window_s);
  num(l, "min_supported_fraction", h.limits.min_supported_fraction);
  num(l, "max_dead_reckoning_s", h.limits.max_dead_reckoning_s);
  num(l, "max_nis_median_ratio", h.limits.max_nis_median_ratio);
  l.finish();
  o.finish();
}

void read_relocks(const json& a, const std::string& source, std::vector<RelockRecord>& out) {
  if (!a.is_array()) throw ConfigError("expected an array", {source, 0, 0, "relocks"});
  for (std::size_t i = 0; i < a.size(); ++i) {
    JsonObject o(a[i], source, fmt::format("relocks[{}]", i));
    RelockRecord e;
    num(o, "t_s", e.t_s);
    num(o, "refused_since_s", e.refused_since_s);
    vec3(o, "offset", e.offset);
    vec3(o, "drift_per_s", e.drift_per_s);
    num(o, "residual_sigma", e.residual_sigma);
    req(o, "detections", e.detections);
    req(o, "objects", e.objects);
    o.finish();
    out.push_back(e);
  }
}

void read_init(JsonObject o, RunInit& s) {
  s.T_I_C = pose(o, "T_I_C");
  req(o, "window_samples", s.window_samples);
  num(o, "window_s", s.window_s);
  vec3(o, "accel_mean", s.accel_mean);
  vec3(o, "accel_std", s.accel_std);
  vec3(o, "gyro_mean", s.gyro_mean);
  vec3(o, "gyro_std", s.gyro_std);
  vec3(o, "gyro_bias", s.gyro_bias);
  req(o, "gyro_bias_from", s.gyro_bias_from);
  if (s.gyro_bias_from != "rest" && s.gyro_bias_from != "config") fail(o, "gyro_bias_from", "expected rest or config");
  o.get("gyro_bias_rest_refused", s.gyro_bias_rest_refused);
  o.finish();
}

void read_imu_noise(JsonObject o, RunRecord& r) {
  ImuNoise n;
  io::read_imu_noise(o, n);
  if (!n.known()) throw ConfigError("the four noise values are required", {o.source(), 0, 0, "imu_noise"});
  r.imu_noise = {n.gyro_noise_density, n.gyro_random_walk, n.accel_noise_density, n.accel_random_walk};
  JsonObject f = req_child(o, "from");
  for (int i = 0; i < 4; ++i) {
    req(f, kNoiseKeys[i], r.imu_noise_from[i]);
    if (r.imu_noise_from[i] != "config" && r.imu_noise_from[i] != "dataset")
      fail(f, kNoiseKeys[i], "expected config or dataset");
  }
  f.finish();
  o.finish();
}

void read_final(JsonObject o, RunRecord& r) {
  r.final_T_I_C = pose(o, "T_I_C");
  if (!o.has("objects")) fail(o, "objects", "missing key");
  const json& a = *o.raw("objects");
  if (!a.is_array()) fail(o, "objects", "expected an array");
  for (std::size_t i = 0; i < a.size(); ++i) {
    JsonObject ob(a[i], o.source(), fmt::format("final.objects[{}]", i));
    FinalObject f;
    req(ob, "id", f.id);
    req(ob, "anchor", f.anchor);
    f.T_O_W = pose(ob, "T_O_W");
    ob.finish();
    r.final_objects.push_back(f);
  }
  if (o.has("time_offset")) {
    JsonObject t = o.child("time_offset");
    FinalTimeOffset f;
    req(t, "estimated", f.estimated);
    num(t, "declared_s", f.declared_s);
    num(t, "value_s", f.value_s);
    num(t, "sigma_s", f.sigma_s);
    t.finish();
    r.final_time_offset = f;
  }
  o.finish();
}

/// The options and the detection-error model of today's refine block (docs/refine.md §2).
void read_refine_options(JsonObject& o, RefineRecord& r) {
  {
    JsonObject p = req_child(o, "options");
    req(p, "loss", r.loss);
    num(p, "loss_scale", r.loss_scale);
    req(p, "max_iterations", r.max_iterations);
    req(p, "linear_solver", r.linear_solver);
    req(p, "covariance", r.covariance);
    num(p, "tau_s", r.tau_s_option);
    req(p, "fit_rounds", r.fit_rounds);
    num(p, "gross_chi2", r.gross_chi2);
    num(p, "imu_noise_scale", r.imu_noise_scale);
    p.finish();
  }
  {
    JsonObject m = req_child(o, "detection_error_model");
    RefineRecord::ErrorModel& e = r.error_model;
    num(m, "tau_s", e.tau_s);
    req(m, "fitted_tau", e.fitted_tau);
    num(m, "scale_translation", e.scale_translation);
    num(m, "scale_rotation", e.scale_rotation);
    num(m, "whitened_lag1", e.whitened_lag1);
    req(m, "used", e.used);
    req(m, "gross", e.gross);
    m.finish();
  }
  req(o, "solves", r.solves);
}

/// The refine block of a roe refine before issue 48 (2026-12-07): white detection factors whose marginals were
/// inflated by a fitted correlation ("options.correlated_errors", "detection_error_model.autocovariance"). Its
/// options are read as far as today's record has them; its error model has no counterpart and is checked to be
/// an object and left out (RefineRecord::earlier_layout says so, the model's numbers read as nan).
void read_refine_options_before_whitening(JsonObject& o, RefineRecord& r) {
  JsonObject p = req_child(o, "options");
  req(p, "loss", r.loss);
  num(p, "loss_scale", r.loss_scale);
  req(p, "max_iterations", r.max_iterations);
  req(p, "linear_solver", r.linear_solver);
  req(p, "covariance", r.covariance);
  bool correlated = false;
  req(p, "correlated_errors", correlated);
  p.finish();
  const json* m = o.raw("detection_error_model");
  if (!m || !m->is_object()) fail(o, "detection_error_model", "expected an object");
  r.earlier_layout = true;
  r.solves = 1;
  r.fit_rounds = 1;
  RefineRecord::ErrorModel& e = r.error_model;
  e.tau_s = e.scale_translation = e.scale_rotation = e.whitened_lag1 = std::numeric_limits<double>::quiet_NaN();
}

void read_refine(JsonObject o, RefineRecord& r) {
  const json* options = o.has("options") ? o.raw("options") : nullptr;
  if (options && options->is_object() && options->contains("correlated_errors")) {
    read_refine_options_before_whitening(o, r);
  } else {
    read_refine_options(o, r);
  }
  for (const auto& [key, field] : {std::pair{"nodes", &RefineRecord::nodes}, std::pair{"imu_factors", &RefineRecord::imu_factors},
                                   std::pair{"detection_factors", &RefineRecord::detection_factors},
                                   std::pair{"detections_weight_below_half", &RefineRecord::detections_weight_below_half},
                                   std::pair{"parameters", &RefineRecord::parameters},
                                   std::pair{"residuals", &RefineRecord::residuals}})
    req(o, key, r.*field);
  req(o, "iterations", r.iterations);
  num(o, "initial_cost", r.initial_cost);
  num(o, "final_cost", r.final_cost);
  req(o, "termination", r.termination);
  req(o, "covariance_ok", r.covariance_ok);
  req(o, "input_run", r.input_run);
  req(o, "input_run_abs", r.input_run_abs);
  req(o, "dataset", r.dataset);
  o.finish();
}

}  // namespace

json run_record_to_json(const RunRecord& r) {
  json inputs = {{"dataset", r.inputs.dataset},
                 {"dataset_abs", r.inputs.dataset_abs},
                 {"detections", r.inputs.detections},
                 {"sha256", r.inputs.sha256}};
  if (!r.inputs.config.empty()) {
    inputs["config"] = r.inputs.config;
    inputs["config_abs"] = r.inputs.config_abs;
  }
  json objs = json::array();
  for (const auto& o : r.final_objects)
    objs.push_back({{"id", o.id}, {"anchor", o.anchor}, {"T_O_W", io::pose_to_json(o.T_O_W)}});
  json final_json = {{"T_I_C", io::pose_to_json(r.final_T_I_C)}, {"objects", objs}};
  if (const auto& t = r.final_time_offset)
    final_json["time_offset"] = {
        {"estimated", t->estimated}, {"declared_s", t->declared_s}, {"value_s", t->value_s}, {"sigma_s", t->sigma_s}};
  json j = {{"roe_version", r.roe_version},
            {"command", r.command},
            {"config", run_config_to_json(r.config)},
            {"inputs", inputs},
            {"anchor_id", r.anchor_id},
            {"counts", counts_json(r.counts)},
            {"nis", nis_json(r.nis)},
            {"health", health_json(r.health)},
            {"relocks", relocks_json(r.relocks)},
            {"detection_sigmas",
             {{"present", r.detection_sigmas.present},
              {"used", r.detection_sigmas.used},
              {"final_scale", r.detection_sigmas.final_scale}}},
            {"init", init_json(r.init)},
            {"imu_noise", imu_noise_json(r.imu_noise, r.imu_noise_from)},
            {"final", final_json},
            {"warnings", r.warnings},
            {"timing_s", r.timing_s}};
  if (r.refine) j["refine"] = refine_json(*r.refine);
  return j;
}

/// run.json records the whole configuration a run ran with (run_config_to_json writes every key): a key of
/// `whole` (the defaults, written the same way) missing from `written` is refused, naming its path, instead of
/// being filled with a default the run may not have used. Object values are compared key by key.
///
/// The one exception is a key added to the configuration after run.json files were already written (an older
/// roe wrote none): each is listed here with what its default means, and that default must be exactly what
/// the older roe did, so an absent key reads as the configuration the run really used (docs/filter.md §9).
namespace {
const std::set<std::string>& keys_added_later() {
  static const std::set<std::string> keys = {
      "config.filter.estimate_time_offset",  // issue 49, 2026-12-07: false = no t_d state (the older filter)
      "config.filter.time_offset_sigma_s",   // its prior σ: unused while estimate_time_offset is false
      "config.filter.max_time_offset_s",      // its guard rail: unused while estimate_time_offset is false
      "config.filter.detection_error_states",  // issue 49 item 1, 2026-12-07: false = no Gauss–Markov error states
      "config.filter.detection_error_correlated_share",  // their share of the variance: unused while they are off
      "config.filter.consider_correlated_errors",  // issue 49 item 1: false = no consider covariance (σ from P)
  };
  return keys;
}

void require_whole_config(const json& written, const json& whole, const std::string& source, const std::string& path) {
  if (!written.is_object() || !whole.is_object()) return;  // the strict reader says what is wrong with the value
  for (const auto& [key, value] : whole.items()) {
    const std::string at = path + "." + key;
    if (!written.contains(key) && keys_added_later().count(at)) continue;
    // "estimator" replaced "smoother" (issue 48): a run.json written before has the old key, read as its value.
    if (at == "config.estimator" && written.contains("smoother")) continue;
    if (!written.contains(key))
      throw ConfigError("missing key: run.json records the whole configuration the run used (a run.json of another "
                        "version of roe, or edited?)",
                        {source, 0, 0, at});
    require_whole_config(written[key], value, source, at);
  }
}
}  // namespace

RunRecord run_record_from_json(const json& j, const std::string& source) {
  RunRecord r;
  if (!j.is_object()) throw ConfigError("expected a JSON object (a run.json of roe run)", {source});
  JsonObject o(j, source);
  req(o, "roe_version", r.roe_version);
  req(o, "command", r.command);
  if (r.command != "run" && r.command != "refine")
    fail(o, "command", fmt::format("a run.json of roe run or roe refine, not of roe {}", r.command));
  if (!o.has("config")) fail(o, "config", "missing key (is this a run.json written by this version of roe?)");
  require_whole_config(*o.raw("config"), run_config_to_json(RunConfig{}), source, "config");
  try {  // its own strict reader; its key paths are under "config."
    r.config = run_config_from_json(*o.raw("config"), source);
  } catch (const ConfigError& e) {
    const ErrorContext& c = e.context();
    throw ConfigError(e.bare_message(), {c.file, c.line, c.column, c.key.empty() ? "config" : "config." + c.key});
  }
  {
    JsonObject in = req_child(o, "inputs");
    req(in, "dataset", r.inputs.dataset);
    req(in, "dataset_abs", r.inputs.dataset_abs);
    req(in, "detections", r.inputs.detections);
    req(in, "sha256", r.inputs.sha256);
    in.get("config", r.inputs.config);
    in.get("config_abs", r.inputs.config_abs);
    in.finish();
  }
  req(o, "anchor_id", r.anchor_id);
  read_counts(req_child(o, "counts"), r.counts);
  read_nis(req_child(o, "nis"), r.nis);
  read_health(req_child(o, "health"), r.health);
  if (!o.has("relocks")) fail(o, "relocks", "missing key");
  read_relocks(*o.raw("relocks"), source, r.relocks);
  {
    JsonObject d = req_child(o, "detection_sigmas");
    req(d, "present", r.detection_sigmas.present);
    req(d, "used", r.detection_sigmas.used);
    req(d, "final_scale", r.detection_sigmas.final_scale);
    const double k = r.detection_sigmas.final_scale;
    if (!(k >= kMinDetectionSigmaScale && k <= kMaxDetectionSigmaScale))
      fail(d, "final_scale",
           fmt::format("{:g} is not a scale the filter writes (it keeps the detections' σ scale within [{:g}, "
                       "{:g}])",
                       k, kMinDetectionSigmaScale, kMaxDetectionSigmaScale));
    d.finish();
  }
  read_init(req_child(o, "init"), r.init);
  read_imu_noise(req_child(o, "imu_noise"), r);
  read_final(req_child(o, "final"), r);
  req(o, "warnings", r.warnings);
  req(o, "timing_s", r.timing_s);
  if (r.command == "refine" || r.config.estimator == "batch") {  // roe refine, or roe run's batch estimator
    r.refine.emplace();
    read_refine(req_child(o, "refine"), *r.refine);
  }
  o.finish();
  return r;
}

std::string format_run_json(const RunRecord& r) { return io::dump_json(run_record_to_json(r), 2) + "\n"; }

void write_run_json(const fs::path& file, const RunRecord& r) { io::write_file_atomic(file, format_run_json(r)); }

RunRecord read_run_json(const fs::path& file) { return io::read_json_file(file, run_record_from_json); }

RunRecord read_run_folder_record(const fs::path& run_dir) {
  std::error_code ec;
  if (!fs::is_regular_file(run_dir / "run.json", ec))
    throw InputError("not a run folder: run.json is missing", {run_dir.string()});
  return read_run_json(run_dir / "run.json");
}

std::optional<fs::path> find_run_dataset(const RunRecord& r) {
  std::error_code ec;
  for (const std::string& d : {r.inputs.dataset_abs, r.inputs.dataset})
    if (!d.empty() && fs::is_regular_file(fs::path(d) / "roe.json", ec)) return fs::path(d);
  return std::nullopt;
}

}  // namespace roe::store
