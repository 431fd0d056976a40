// The strict JSON loader of RunConfig (FilterOptions, HealthLimits and the output options) and
// its echo. Each options struct lists its fields once, in a table of (key, member, check): the table
// loads, validates and echoes (run.json "config"), in this order.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include "roe/store/run_config.hpp"
#include "roe/core/error.hpp"
#include "roe/io/json.hpp"

namespace roe::store {
namespace {
using io::json;
using io::JsonObject;

[[noreturn]] void fail(const JsonObject& r, const std::string& key, const std::string& what) {
  throw ConfigError(what, {r.source(), 0, 0, r.key_path(key)});
}

/// One key of an options struct S: how it is read (and validated) and how it is echoed.
template <typename S>
struct Field {
  const char* key;
  std::function<void(JsonObject&, S&)> load;
  std::function<json(const S&)> echo;
};

/// A check returns the error message for a bad value, or nullptr.
template <typename T>
using Check = const char* (*)(const T&);

template <typename S, typename T>
Field<S> field(const char* key, T S::*m, Check<T> check = nullptr) {
  return {key,
          [key, m, check](JsonObject& r, S& s) {
            r.get(key, s.*m);
            if constexpr (std::is_floating_point_v<T>)
              if (!std::isfinite(s.*m)) fail(r, key, "must be finite");
            if (check)
              if (const char* what = check(s.*m)) fail(r, key, what);
          },
          [m](const S& s) { return json(s.*m); }};
}

Field<ekf::FilterOptions> vec3_field(const char* key, Eigen::Vector3d ekf::FilterOptions::*m) {
  return {key,
          [key, m](JsonObject& r, ekf::FilterOptions& s) {
            const json* v = r.raw(key);
            if (!v || v->is_null()) return;
            if (!v->is_array() || v->size() != 3) fail(r, key, "expected an array of 3 numbers");
            Eigen::Vector3d out;
            for (int i = 0; i < 3; ++i) {
              if (!(*v)[i].is_number()) fail(r, key, "expected an array of 3 numbers");
              out[i] = (*v)[i].get<double>();
            }
            if (!out.allFinite()) fail(r, key, "values must be finite");
            s.*m = out;
          },
          [m](const ekf::FilterOptions& s) { return json::array({(s.*m).x(), (s.*m).y(), (s.*m).z()}); }};
}

/// An enum read by name: `parse` returns false for an unknown name, `what` says what is allowed.
template <typename E>
Field<ekf::FilterOptions> enum_field(const char* key, E ekf::FilterOptions::*m, bool (*parse)(const std::string&, E&),
                                     std::string (*name)(E), const char* what) {
  return {key,
          [=](JsonObject& r, ekf::FilterOptions& s) {
            std::string v = name(s.*m);
            r.get(key, v);
            if (!parse(v, s.*m)) fail(r, key, what);
          },
          [=](const ekf::FilterOptions& s) { return json(name(s.*m)); }};
}

const char* positive(const double& v) { return v > 0.0 ? nullptr : "must be a positive number"; }
const char* non_negative(const double& v) { return v >= 0.0 ? nullptr : "must be a number >= 0"; }
// IMU densities: negative (= from the dataset) or >= 0; only finiteness is checked.
const char* any_finite(const double&) { return nullptr; }

const std::vector<Field<ekf::FilterOptions>>& filter_fields() {
  using O = ekf::FilterOptions;
  static const std::vector<Field<O>> t = {
      enum_field("residual_frame", &O::residual_frame, &ekf::parse_residual_frame, &ekf::to_string,
                 "must be \"object\" (paper: T_O_C) or \"camera\" (T_C_O)"),
      field("meas_sigma_p_m", &O::meas_sigma_p_m, &positive),
      field("meas_sigma_rot_deg", &O::meas_sigma_rot_deg, &positive),
      field<O, bool>("meas_sigma_in_camera", &O::meas_sigma_in_camera),
      field("meas_sigma_p_per_depth", &O::meas_sigma_p_per_depth, &non_negative),
      field("meas_sigma_ray_m", &O::meas_sigma_ray_m, &any_finite),
      field("meas_sigma_ray_per_depth", &O::meas_sigma_ray_per_depth, &non_negative),
      field<O, bool>("use_detection_sigmas", &O::use_detection_sigmas),
      field<O, bool>("adapt_detection_sigma_scale", &O::adapt_detection_sigma_scale),
      field("detection_error_correlation_s", &O::detection_error_correlation_s, &non_negative),
      field<O, bool>("detection_error_states", &O::detection_error_states),
      field<O, double>("detection_error_correlated_share", &O::detection_error_correlated_share,
                       [](const double& v) -> const char* {
                         return v > 0.0 && v < 1.0 ? nullptr : "must be in (0, 1), e.g. 0.9";
                       }),
      field<O, bool>("consider_correlated_errors", &O::consider_correlated_errors),
      field("min_score", &O::min_score, &non_negative),
      field<O, bool>("chi2_gate", &O::chi2_gate),
      field<O, double>("chi2_confidence", &O::chi2_confidence,
                       [](const double& v) -> const char* {
                         return v > 0.0 && v < 1.0 ? nullptr : "must be in (0, 1), e.g. 0.95";
                       }),
      enum_field("gate_mode", &O::gate_mode, &ekf::parse_gate_mode, &ekf::to_string,
                 "must be \"joint\" (one 6-dof test, paper) or \"split\" (position and rotation, 3 + 3)"),
      field<O, int>("anchor_id", &O::anchor_id,
                    [](const int& v) -> const char* {
                      return v >= -1 ? nullptr : "must be an object id >= 0, or -1 for the first object seen";
                    }),
      field("relock_after_s", &O::relock_after_s, &non_negative),
      field<O, int>("relock_min_detections", &O::relock_min_detections,
                    [](const int& v) -> const char* { return v >= 3 ? nullptr : "must be >= 3"; }),
      enum_field("anchor_gauge", &O::anchor_gauge, &ekf::parse_anchor_gauge, &ekf::to_string,
                 "must be \"position\" (paper), \"position_yaw\" or \"pose\""),
      field<O, bool>("require_anchor", &O::require_anchor),
      field<O, int>("init_min_detections", &O::init_min_detections,
                    [](const int& v) -> const char* {
                      return v >= 1 ? nullptr : "must be >= 1 (1 = the paper: first detection)";
                    }),
      field("init_gate_p_m", &O::init_gate_p_m, &positive),
      field("init_gate_rot_deg", &O::init_gate_rot_deg, &positive),
      field<O, bool>("estimate_extrinsics", &O::estimate_extrinsics),
      field("extrinsics_sigma_p_m", &O::extrinsics_sigma_p_m, &positive),
      field("extrinsics_sigma_rot_deg", &O::extrinsics_sigma_rot_deg, &positive),
      field<O, bool>("estimate_time_offset", &O::estimate_time_offset),
      field("time_offset_sigma_s", &O::time_offset_sigma_s, &positive),
      field("gyro_noise_density", &O::gyro_noise_density, &any_finite),
      field("gyro_random_walk", &O::gyro_random_walk, &any_finite),
      field("accel_noise_density", &O::accel_noise_density, &any_finite),
      field("accel_random_walk", &O::accel_random_walk, &any_finite),
      field("imu_noise_scale", &O::imu_noise_scale, &positive),
      field("init_window_s", &O::init_window_s, &non_negative),
      vec3_field("init_gyro_bias", &O::init_gyro_bias),
      field<O, bool>("init_gyro_bias_from_rest", &O::init_gyro_bias_from_rest),
      field("init_rest_max_gyro_std", &O::init_rest_max_gyro_std, &positive),
      field("init_rest_max_accel_std", &O::init_rest_max_accel_std, &positive),
      vec3_field("init_accel_bias", &O::init_accel_bias),
      field("init_sigma_p_m", &O::init_sigma_p_m, &positive),
      field("init_sigma_v_mps", &O::init_sigma_v_mps, &positive),
      field("init_sigma_roll_pitch_deg", &O::init_sigma_roll_pitch_deg, &positive),
      field("init_sigma_yaw_deg", &O::init_sigma_yaw_deg, &positive),
      field("init_sigma_gyro_bias", &O::init_sigma_gyro_bias, &positive),
      field("init_sigma_accel_bias", &O::init_sigma_accel_bias, &positive),
      field("max_position_m", &O::max_position_m, &positive),
      field("max_velocity_mps", &O::max_velocity_mps, &positive),
      field("max_gyro_bias", &O::max_gyro_bias, &positive),
      field("max_accel_bias", &O::max_accel_bias, &positive),
      field("max_time_offset_s", &O::max_time_offset_s, &positive),
      field<O, int>("pd_check_every", &O::pd_check_every,
                    [](const int& v) -> const char* {
                      return v >= 0 ? nullptr : "must be >= 0 (0 = only after initialisations)";
                    }),
  };
  return t;
}

// What no single key can say: the ray-aligned σ's consistency.
void check_filter(JsonObject& f, const ekf::FilterOptions& o) {
  if (o.meas_sigma_ray_m >= 0.0 && o.meas_sigma_ray_m + o.meas_sigma_ray_per_depth <= 0.0)
    fail(f, "meas_sigma_ray_m", "must be > 0 (or meas_sigma_ray_per_depth > 0), or negative for σ_ray = σ_lat");
  const bool camera_sigma = o.meas_sigma_in_camera || o.residual_frame == ekf::ResidualFrame::kCamera;
  if (!camera_sigma && (o.meas_sigma_ray_m >= 0.0 || o.meas_sigma_p_per_depth > 0.0))
    fail(f, "meas_sigma_ray_m",
         "the ray-aligned, depth-dependent σ describe the detected T_C_O: set meas_sigma_in_camera true");
}

const std::vector<Field<ekf::HealthLimits>>& health_fields() {
  using H = ekf::HealthLimits;
  static const std::vector<Field<H>> t = {
      field("support_window_s", &H::support_window_s, &non_negative),
      field<H, double>("min_supported_fraction", &H::min_supported_fraction,
                       [](const double& v) -> const char* {
                         return v >= 0.0 && v <= 1.0 ? nullptr : "must be in [0, 1] (0 = no check)";
                       }),
      field("max_dead_reckoning_s", &H::max_dead_reckoning_s, &any_finite),
      field("max_nis_median_ratio", &H::max_nis_median_ratio, &non_negative),
  };
  return t;
}

template <typename S>
void load(JsonObject& r, S& s, const std::vector<Field<S>>& fields) {
  for (const auto& f : fields) f.load(r, s);
}

template <typename S>
json echo(const S& s, const std::vector<Field<S>>& fields) {
  json j = json::object();
  for (const auto& f : fields) j[f.key] = f.echo(s);
  return j;
}

/// "estimator", or the key it replaced, "smoother": "none" | "rts" (configs and run.json files written before
/// issue 48), read as "filter" and "smoother"; both given must agree.
void read_estimator(JsonObject& root, RunConfig& c) {
  const auto& names = estimators();
  // Both keys are read (marked) even when absent, so that one misplaced under "filter" is answered with
  // "did you mean the top-level ...".
  root.get("estimator", c.estimator);
  if (root.has("estimator") && std::find(names.begin(), names.end(), c.estimator) == names.end())
    fail(root, "estimator", "must be \"filter\", \"smoother\" or \"batch\"");
  std::string legacy;
  root.get("smoother", legacy);
  if (!root.has("smoother")) return;
  if (legacy != "none" && legacy != "rts")
    fail(root, "smoother", "must be \"none\" or \"rts\" (the key is now \"estimator\": \"filter\", \"smoother\" or \"batch\")");
  const std::string as = legacy == "rts" ? "smoother" : "filter";
  if (root.has("estimator") && !(c.estimator == as || (legacy == "rts" && c.estimator == "batch")))
    fail(root, "smoother", fmt::format("\"smoother\": \"{}\" contradicts \"estimator\": \"{}\" (give \"estimator\" only)",
                                       legacy, c.estimator));
  if (!root.has("estimator")) c.estimator = as;
}

}  // namespace

ekf::FilterOptions recommended_filter_options() {
  ekf::FilterOptions o;
  o.require_anchor = false;  // the anchor leaves the view of flights (EuRoC snippet: 62 % of detections)
  o.meas_sigma_p_m = 0.02;   // lateral 2 cm + 2 % of the depth, along the ray 6 cm + 10 %
  o.meas_sigma_p_per_depth = 0.02;
  o.meas_sigma_ray_m = 0.06;
  o.meas_sigma_ray_per_depth = 0.1;
  o.init_gyro_bias_from_rest = true;  // falls back to init_gyro_bias (with a warning) when the IMU moves
  o.imu_noise_scale = 4.0;
  o.use_detection_sigmas = true;         // the detector's own σ where detections.csv has them,
  o.adapt_detection_sigma_scale = true;  // trusted up to one scale learned online
  o.gate_mode = ekf::GateMode::kSplit;   // a wrong rotation does not throw the position away
  o.relock_after_s = 0.5;  // a drifted estimate is re-locked to the refused detections that agree
  return o;
}

RunConfig run_config_from_json(const json& j, const std::string& source) {
  RunConfig c;
  JsonObject root(j, source);
  {
    JsonObject f = root.child("filter");
    load(f, c.filter, filter_fields());
    check_filter(f, c.filter);
    f.finish();
  }
  {
    JsonObject out = root.child("output");
    out.get("rate", c.output_rate);
    if (c.output_rate != "imu" && c.output_rate != "images")
      fail(out, "rate", "must be \"imu\" or \"images\"");
    out.get("level", c.output_level);
    const auto& levels = output_levels();
    if (std::find(levels.begin(), levels.end(), c.output_level) == levels.end())
      fail(out, "level", "must be \"full\", \"standard\" or \"minimal\"");
    out.finish();
  }
  {
    JsonObject h = root.child("health");
    load(h, c.health, health_fields());
    h.finish();
  }
  read_estimator(root, c);
  root.get("description", c.description);
  root.finish();
  return c;
}

json run_config_to_json(const RunConfig& c, bool every_key) {
  json j = {{"filter", echo(c.filter, filter_fields())},
            {"output", {{"rate", c.output_rate}}},
            {"estimator", c.estimator},
            {"health", echo(c.health, health_fields())}};
  if (every_key || c.output_level != "full") j["output"]["level"] = c.output_level;
  if (!c.description.empty()) j["description"] = c.description;
  return j;
}

const std::vector<std::string>& estimators() {
  static const std::vector<std::string> names = {"filter", "smoother", "batch"};
  return names;
}

const std::vector<std::string>& output_levels() {
  static const std::vector<std::string> levels = {"full", "standard", "minimal"};
  return levels;
}

bool run_folder_has(const RunConfig& c, const std::string& file) {
  if (file == "run.json" || file == "trajectory.csv" || file == "trajectory.tum") return true;
  if (c.output_level == "minimal") return false;
  if (file.find("_filter.") != std::string::npos) return c.smoothed();
  return true;
}

std::string run_file_absent_reason(const RunConfig& c, const std::string& file) {
  if (run_folder_has(c, file)) return {};
  if (c.output_level == "minimal")
    return "the run was written with output level minimal: trajectory.csv/.tum and run.json only (`roe run "
           "--output standard` or full writes the other files)";
  return fmt::format("the run's estimate is the filter's own (\"estimator\": \"{}\"), so no {}", c.estimator, file);
}

bool sigma_at_every_row(const RunConfig& c) { return c.output_level == "full" || c.output_rate == "images"; }

}  // namespace roe::store
