// The strict JSON loader of RunConfig (FilterOptions, HealthLimits and the output options) and
// its echo. Each options struct lists its fields once, in a table of (key, member, check): the table
// loads, validates and echoes (run.json "config"), in this order; RunConfig itself is one field mapping
// (config_fields) walked by the store's writer and strict reader (json_fields.hpp).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include "roe/store/run_config.hpp"
#include "roe/core/error.hpp"
#include "roe/io/json.hpp"
#include "json_fields.hpp"

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
  constexpr const char* kRay = "meas_sigma_ray_m";  // the key an inconsistency is reported at
  if (o.meas_sigma_ray_m >= 0.0 && o.meas_sigma_ray_m + o.meas_sigma_ray_per_depth <= 0.0)
    fail(f, kRay, "must be > 0 (or meas_sigma_ray_per_depth > 0), or negative for σ_ray = σ_lat");
  const bool camera_sigma = o.meas_sigma_in_camera || o.residual_frame == ekf::ResidualFrame::kCamera;
  if (!camera_sigma && (o.meas_sigma_ray_m >= 0.0 || o.meas_sigma_p_per_depth > 0.0))
    fail(f, kRay, "the ray-aligned, depth-dependent σ describe the detected T_C_O: set meas_sigma_in_camera true");
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

/// "smoother", the key "estimator" replaced: "none" | "rts" (configs and run.json files written before issue 48),
/// read as "filter" and "smoother"; with both given they must agree. Read (marked) even when absent, so that one
/// misplaced under "filter" is answered with "did you mean the top-level ...".
void read_legacy_smoother(JsonObject& root, const char* estimator_key, RunConfig& c) {
  constexpr const char* kSmoother = "smoother";
  std::string legacy;
  root.get(kSmoother, legacy);
  if (!root.has(kSmoother)) return;
  if (legacy != "none" && legacy != "rts")
    fail(root, kSmoother, "must be \"none\" or \"rts\" (the key is now \"estimator\": \"filter\", \"smoother\" or \"batch\")");
  const Estimator as = legacy == "rts" ? Estimator::kSmoother : Estimator::kFilter;
  const bool given = root.has(estimator_key);
  if (given && !(c.estimator == as || (legacy == "rts" && c.estimator == Estimator::kBatch)))
    fail(root, kSmoother, fmt::format("\"smoother\": \"{}\" contradicts \"estimator\": \"{}\" (give \"estimator\" only)",
                                      legacy, to_string(c.estimator)));
  if (!given) c.estimator = as;
}

/// A setting by its name: a string, one of the enum's names (`what` says which).
template <class E>
void read_name(const json& x, E& v, const std::string& file, const std::string& path, const char* what);

/// The configuration's dialect (configs/*.json, run.json's "config"): strict, every key optional (absent or
/// null: its default), the settings by name; errors are ConfigErrors naming the file and the key path.
struct ConfigJson : json_fields::StrictDialect {
  static json write_leaf(const Estimator& v) { return to_string(v); }
  static json write_leaf(const OutputRate& v) { return to_string(v); }
  static json write_leaf(const OutputLevel& v) { return to_string(v); }
  static void read_leaf(const json& x, Estimator& v, const std::string& file, const std::string& path) {
    read_name(x, v, file, path, "must be \"filter\", \"smoother\" or \"batch\"");
  }
  static void read_leaf(const json& x, OutputRate& v, const std::string& file, const std::string& path) {
    read_name(x, v, file, path, "must be \"imu\" or \"images\"");
  }
  static void read_leaf(const json& x, OutputLevel& v, const std::string& file, const std::string& path) {
    read_name(x, v, file, path, "must be \"full\", \"standard\" or \"minimal\"");
  }
};

template <class E>
void read_name(const json& x, E& v, const std::string& file, const std::string& path, const char* what) {
  if (!x.is_string()) ConfigJson::fail(file, path, json_fields::Problem::kNotString, {});
  if (!parse(x.get<std::string>(), v)) ConfigJson::fail(file, path, json_fields::Problem::kInvalid, what);
}

/// RunConfig's one mapping: the filter's and the health limits' keys are their tables' (filter_fields,
/// health_fields); output.level is written only away from "full" unless `every_key`.
template <class A>
void config_fields(A& a, RunConfig& c, bool every_key) {
  constexpr const char* kEstimator = "estimator";
  a.nested_opt("filter", [&](auto& f) {
    f.merge([&](json& j) { j = echo(c.filter, filter_fields()); },
            [&](JsonObject& o) {
              load(o, c.filter, filter_fields());
              check_filter(o, c.filter);
            });
  });
  a.nested_opt("output", [&](auto& o) {
    o.opt("rate", c.output_rate), o.opt("level", c.output_level, every_key || c.output_level != OutputLevel::kFull);
  });
  a.nested_opt("health", [&](auto& h) {
    h.merge([&](json& j) { j = echo(c.health, health_fields()); },
            [&](JsonObject& o) { load(o, c.health, health_fields()); });
  });
  a.opt(kEstimator, c.estimator);
  a.merge([](json&) {}, [&](JsonObject& root) { read_legacy_smoother(root, kEstimator, c); });
  a.opt("description", c.description, !c.description.empty());
}

/// The name of `v` in `names` (the enum's order).
template <class E>
const std::string& name_of(const std::vector<std::string>& names, E v) {
  return names.at(static_cast<std::size_t>(v));
}

template <class E>
bool parse_name(const std::vector<std::string>& names, const std::string& name, E& out) {
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end()) return false;
  out = static_cast<E>(it - names.begin());
  return true;
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
  JsonObject root(j, source);  // null: an empty configuration
  const json empty = json::object();
  json_fields::Reader<ConfigJson> r{root, j.is_null() ? empty : j, ""};
  config_fields(r, c, false);
  root.finish();
  return c;
}

json run_config_to_json(const RunConfig& c, bool every_key) {
  json j = json::object();
  json_fields::Writer<ConfigJson> w{j};
  config_fields(w, const_cast<RunConfig&>(c), every_key);  // the writer only reads c
  return j;
}

json health_limits_to_json(const ekf::HealthLimits& h) { return echo(h, health_fields()); }

ekf::HealthLimits health_limits_from_json(const json& j, const std::string& source, const std::string& path) {
  ekf::HealthLimits h;
  JsonObject o(j, source, path);
  load(o, h, health_fields());
  o.finish();
  return h;
}

const std::vector<std::string>& estimators() {
  static const std::vector<std::string> names = {"filter", "smoother", "batch"};
  return names;
}

const std::vector<std::string>& output_rates() {
  static const std::vector<std::string> names = {"imu", "images"};
  return names;
}

const std::vector<std::string>& output_levels() {
  static const std::vector<std::string> names = {"full", "standard", "minimal"};
  return names;
}

const std::string& to_string(Estimator e) { return name_of(estimators(), e); }
const std::string& to_string(OutputRate r) { return name_of(output_rates(), r); }
const std::string& to_string(OutputLevel l) { return name_of(output_levels(), l); }
bool parse(const std::string& name, Estimator& out) { return parse_name(estimators(), name, out); }
bool parse(const std::string& name, OutputRate& out) { return parse_name(output_rates(), name, out); }
bool parse(const std::string& name, OutputLevel& out) { return parse_name(output_levels(), name, out); }

bool run_folder_has(const RunConfig& c, const std::string& file) {
  if (file == "run.json" || file == "trajectory.csv" || file == "trajectory.tum") return true;
  if (c.output_level == OutputLevel::kMinimal) return false;
  if (file.find("_filter.") != std::string::npos) return c.smoothed();
  return true;
}

std::string run_file_absent_reason(const RunConfig& c, const std::string& file) {
  if (run_folder_has(c, file)) return {};
  if (c.output_level == OutputLevel::kMinimal)
    return "the run was written with output level minimal: trajectory.csv/.tum and run.json only (`roe run "
           "--output standard` or full writes the other files)";
  return fmt::format("the run's estimate is the filter's own (\"estimator\": \"{}\"), so no {}", to_string(c.estimator), file);
}

bool sigma_at_every_row(const RunConfig& c) {
  return c.output_level == OutputLevel::kFull || c.output_rate == OutputRate::kImages;
}

}  // namespace roe::store
