// roe run: the strict JSON loader of RunConfig (FilterOptions + output options) and its echo.
#include <fmt/format.h>

#include <cmath>

#include "roe/app/run.hpp"
#include "roe/core/error.hpp"
#include "roe/io/json.hpp"

namespace roe::app {
namespace {
using io::json;
using io::JsonObject;

[[noreturn]] void fail(const JsonObject& r, const std::string& key, const std::string& what) {
  throw ConfigError(what, {r.source(), 0, 0, r.key_path(key)});
}

void read_vec3(JsonObject& r, const char* key, Eigen::Vector3d& out) {
  const json* v = r.raw(key);
  if (!v || v->is_null()) return;
  if (!v->is_array() || v->size() != 3) fail(r, key, "expected an array of 3 numbers");
  for (int i = 0; i < 3; ++i) {
    if (!(*v)[i].is_number()) fail(r, key, "expected an array of 3 numbers");
    out[i] = (*v)[i].get<double>();
  }
  if (!out.allFinite()) fail(r, key, "values must be finite");
}

void positive(JsonObject& r, const char* key, double& v) {
  r.get(key, v);
  if (!(v > 0.0) || !std::isfinite(v)) fail(r, key, "must be a positive number");
}
void non_negative(JsonObject& r, const char* key, double& v) {
  r.get(key, v);
  if (!(v >= 0.0) || !std::isfinite(v)) fail(r, key, "must be a number >= 0");
}
// IMU densities: negative (= from the dataset) or >= 0.
void density(JsonObject& r, const char* key, double& v) {
  r.get(key, v);
  if (!std::isfinite(v)) fail(r, key, "must be finite (negative = take the dataset's value)");
}

}  // namespace

RunConfig run_config_from_json(const json& j, const std::string& source) {
  RunConfig c;
  JsonObject root(j, source);
  {
    JsonObject f = root.child("filter");
    ekf::FilterOptions& o = c.filter;
    std::string frame = ekf::to_string(o.residual_frame);
    f.get("residual_frame", frame);
    if (!ekf::parse_residual_frame(frame, o.residual_frame))
      fail(f, "residual_frame", "must be \"object\" (paper: T_O_C) or \"camera\" (T_C_O)");
    positive(f, "meas_sigma_p_m", o.meas_sigma_p_m);
    positive(f, "meas_sigma_rot_deg", o.meas_sigma_rot_deg);
    f.get("meas_sigma_in_camera", o.meas_sigma_in_camera);
    non_negative(f, "meas_sigma_p_per_depth", o.meas_sigma_p_per_depth);
    f.get("meas_sigma_ray_m", o.meas_sigma_ray_m);
    non_negative(f, "meas_sigma_ray_per_depth", o.meas_sigma_ray_per_depth);
    if (o.meas_sigma_ray_m >= 0.0 && o.meas_sigma_ray_m + o.meas_sigma_ray_per_depth <= 0.0)
      fail(f, "meas_sigma_ray_m", "must be > 0 (or meas_sigma_ray_per_depth > 0), or negative for σ_ray = σ_lat");
    const bool camera_sigma = o.meas_sigma_in_camera || o.residual_frame == ekf::ResidualFrame::kCamera;
    if (!camera_sigma && (o.meas_sigma_ray_m >= 0.0 || o.meas_sigma_p_per_depth > 0.0))
      fail(f, "meas_sigma_ray_m",
           "the ray-aligned, depth-dependent σ describe the detected T_C_O: set meas_sigma_in_camera true");
    f.get("use_detection_sigmas", o.use_detection_sigmas);
    non_negative(f, "min_score", o.min_score);
    f.get("chi2_gate", o.chi2_gate);
    f.get("chi2_confidence", o.chi2_confidence);
    if (!(o.chi2_confidence > 0.0 && o.chi2_confidence < 1.0))
      fail(f, "chi2_confidence", "must be in (0, 1), e.g. 0.95");
    f.get("anchor_id", o.anchor_id);
    if (o.anchor_id < -1) fail(f, "anchor_id", "must be an object id >= 0, or -1 for the first object seen");
    std::string gauge = ekf::to_string(o.anchor_gauge);
    f.get("anchor_gauge", gauge);
    if (!ekf::parse_anchor_gauge(gauge, o.anchor_gauge))
      fail(f, "anchor_gauge", "must be \"position\" (paper), \"position_yaw\" or \"pose\"");
    f.get("require_anchor", o.require_anchor);
    f.get("init_min_detections", o.init_min_detections);
    if (o.init_min_detections < 1)
      fail(f, "init_min_detections", "must be >= 1 (1 = the paper: first detection)");
    positive(f, "init_gate_p_m", o.init_gate_p_m);
    positive(f, "init_gate_rot_deg", o.init_gate_rot_deg);
    f.get("estimate_extrinsics", o.estimate_extrinsics);
    positive(f, "extrinsics_sigma_p_m", o.extrinsics_sigma_p_m);
    positive(f, "extrinsics_sigma_rot_deg", o.extrinsics_sigma_rot_deg);
    density(f, "gyro_noise_density", o.gyro_noise_density);
    density(f, "gyro_random_walk", o.gyro_random_walk);
    density(f, "accel_noise_density", o.accel_noise_density);
    density(f, "accel_random_walk", o.accel_random_walk);
    positive(f, "imu_noise_scale", o.imu_noise_scale);
    non_negative(f, "init_window_s", o.init_window_s);
    read_vec3(f, "init_gyro_bias", o.init_gyro_bias);
    f.get("init_gyro_bias_from_rest", o.init_gyro_bias_from_rest);
    positive(f, "init_rest_max_gyro_std", o.init_rest_max_gyro_std);
    positive(f, "init_rest_max_accel_std", o.init_rest_max_accel_std);
    read_vec3(f, "init_accel_bias", o.init_accel_bias);
    positive(f, "init_sigma_p_m", o.init_sigma_p_m);
    positive(f, "init_sigma_v_mps", o.init_sigma_v_mps);
    positive(f, "init_sigma_roll_pitch_deg", o.init_sigma_roll_pitch_deg);
    positive(f, "init_sigma_yaw_deg", o.init_sigma_yaw_deg);
    positive(f, "init_sigma_gyro_bias", o.init_sigma_gyro_bias);
    positive(f, "init_sigma_accel_bias", o.init_sigma_accel_bias);
    positive(f, "max_position_m", o.max_position_m);
    positive(f, "max_velocity_mps", o.max_velocity_mps);
    positive(f, "max_gyro_bias", o.max_gyro_bias);
    positive(f, "max_accel_bias", o.max_accel_bias);
    f.get("pd_check_every", o.pd_check_every);
    if (o.pd_check_every < 0) fail(f, "pd_check_every", "must be >= 0 (0 = only after initialisations)");
    f.finish();
  }
  {
    JsonObject out = root.child("output");
    out.get("rate", c.output_rate);
    if (c.output_rate != "imu" && c.output_rate != "images")
      fail(out, "rate", "must be \"imu\" or \"images\"");
    out.finish();
  }
  {
    JsonObject h = root.child("health");
    ekf::HealthLimits& l = c.health;
    non_negative(h, "support_window_s", l.support_window_s);
    non_negative(h, "min_supported_fraction", l.min_supported_fraction);
    if (l.min_supported_fraction > 1.0) fail(h, "min_supported_fraction", "must be in [0, 1] (0 = no check)");
    h.get("max_dead_reckoning_s", l.max_dead_reckoning_s);
    if (!std::isfinite(l.max_dead_reckoning_s))
      fail(h, "max_dead_reckoning_s", "must be a number of seconds (negative = no check)");
    non_negative(h, "max_nis_median_ratio", l.max_nis_median_ratio);
    h.finish();
  }
  root.get("smoother", c.smoother);
  if (c.smoother != "none" && c.smoother != "rts") fail(root, "smoother", "must be \"none\" or \"rts\"");
  root.get("description", c.description);
  root.finish();
  return c;
}

RunConfig run_config_from_file(const std::filesystem::path& file) {
  return run_config_from_json(io::parse_json_file(file), file.string());
}

json run_config_to_json(const RunConfig& c) {
  const ekf::FilterOptions& o = c.filter;
  const auto v3 = [](const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); };
  json f = {
      {"residual_frame", ekf::to_string(o.residual_frame)},
      {"meas_sigma_p_m", o.meas_sigma_p_m},
      {"meas_sigma_rot_deg", o.meas_sigma_rot_deg},
      {"meas_sigma_in_camera", o.meas_sigma_in_camera},
      {"meas_sigma_p_per_depth", o.meas_sigma_p_per_depth},
      {"meas_sigma_ray_m", o.meas_sigma_ray_m},
      {"meas_sigma_ray_per_depth", o.meas_sigma_ray_per_depth},
      {"use_detection_sigmas", o.use_detection_sigmas},
      {"min_score", o.min_score},
      {"chi2_gate", o.chi2_gate},
      {"chi2_confidence", o.chi2_confidence},
      {"anchor_id", o.anchor_id},
      {"anchor_gauge", ekf::to_string(o.anchor_gauge)},
      {"require_anchor", o.require_anchor},
      {"init_min_detections", o.init_min_detections},
      {"init_gate_p_m", o.init_gate_p_m},
      {"init_gate_rot_deg", o.init_gate_rot_deg},
      {"estimate_extrinsics", o.estimate_extrinsics},
      {"extrinsics_sigma_p_m", o.extrinsics_sigma_p_m},
      {"extrinsics_sigma_rot_deg", o.extrinsics_sigma_rot_deg},
      {"gyro_noise_density", o.gyro_noise_density},
      {"gyro_random_walk", o.gyro_random_walk},
      {"accel_noise_density", o.accel_noise_density},
      {"accel_random_walk", o.accel_random_walk},
      {"imu_noise_scale", o.imu_noise_scale},
      {"init_window_s", o.init_window_s},
      {"init_gyro_bias", v3(o.init_gyro_bias)},
      {"init_gyro_bias_from_rest", o.init_gyro_bias_from_rest},
      {"init_rest_max_gyro_std", o.init_rest_max_gyro_std},
      {"init_rest_max_accel_std", o.init_rest_max_accel_std},
      {"init_accel_bias", v3(o.init_accel_bias)},
      {"init_sigma_p_m", o.init_sigma_p_m},
      {"init_sigma_v_mps", o.init_sigma_v_mps},
      {"init_sigma_roll_pitch_deg", o.init_sigma_roll_pitch_deg},
      {"init_sigma_yaw_deg", o.init_sigma_yaw_deg},
      {"init_sigma_gyro_bias", o.init_sigma_gyro_bias},
      {"init_sigma_accel_bias", o.init_sigma_accel_bias},
      {"max_position_m", o.max_position_m},
      {"max_velocity_mps", o.max_velocity_mps},
      {"max_gyro_bias", o.max_gyro_bias},
      {"max_accel_bias", o.max_accel_bias},
      {"pd_check_every", o.pd_check_every},
  };
  const ekf::HealthLimits& l = c.health;
  json h = {{"support_window_s", l.support_window_s},
            {"min_supported_fraction", l.min_supported_fraction},
            {"max_dead_reckoning_s", l.max_dead_reckoning_s},
            {"max_nis_median_ratio", l.max_nis_median_ratio}};
  json j = {{"filter", f}, {"output", {{"rate", c.output_rate}}}, {"smoother", c.smoother}, {"health", h}};
  if (!c.description.empty()) j["description"] = c.description;
  return j;
}

}  // namespace roe::app
