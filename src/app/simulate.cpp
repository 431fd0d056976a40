// roe simulate: JSON config loading (strict), preset lookup, running the simulator and writing the
// dataset folder.
#include "roe/app/simulate.hpp"

#include <fmt/format.h>
#include <tuple>

#include <algorithm>
#include <cmath>

#include "roe/core/error.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/input.hpp"
#include "roe/io/csv.hpp"
#include "roe/io/json.hpp"
#include "roe/io/kalibr.hpp"
#include "roe/io/models_info.hpp"
#include "roe/core/log.hpp"
#include "roe/io/output.hpp"
#include "roe/io/pose_json.hpp"
#include "roe/sim/pose_groundtruth.hpp"
#include "roe/version.hpp"

namespace roe::app {
namespace detail {
const std::vector<std::pair<std::string, std::string>>& embedded_sim_presets();
}

namespace {
using io::json;
using io::JsonObject;

[[noreturn]] void fail(const JsonObject& r, const std::string& key, const std::string& what) {
  throw ConfigError(what, {r.source(), 0, 0, r.key_path(key)});
}

std::vector<double> numbers(JsonObject& r, const char* key, std::size_t n) {
  const json* v = r.raw(key);
  std::vector<double> out;
  if (!v || v->is_null()) return out;
  if (!v->is_array() || (n != 0 && v->size() != n))
    fail(r, key, n ? fmt::format("expected an array of {} numbers", n) : "expected an array of numbers");
  for (const auto& x : *v) {
    if (!x.is_number()) fail(r, key, "expected numbers in the array");
    out.push_back(x.get<double>());
  }
  return out;
}

void read_vec3(JsonObject& r, const char* key, Eigen::Vector3d& out) {
  const auto v = numbers(r, key, 3);
  if (!v.empty()) out = Eigen::Vector3d(v[0], v[1], v[2]);
}

void read_pose(JsonObject& r, const char* key, Pose& out) {
  if (!r.has(key)) {
    r.raw(key);
    return;
  }
  const Pose base = out;
  out = io::pose_from_json(*r.raw(key), r.source(), r.key_path(key), {1e-6, &base});
}

void read_signal(JsonObject& r, const char* key, sim::SmoothSignal& s) {
  if (!r.has(key)) {
    r.raw(key);
    return;
  }
  JsonObject o = r.child(key);
  o.get("offset", s.offset);
  o.get("rate", s.rate);
  if (const json* terms = o.raw("terms"); terms && !terms->is_null()) {
    if (!terms->is_array()) fail(o, "terms", "expected an array of [amplitude, frequency_hz, phase_rad]");
    s.terms.clear();
    for (const auto& t : *terms) {
      if (!t.is_array() || t.size() != 3 || !t[0].is_number() || !t[1].is_number() || !t[2].is_number())
        fail(o, "terms", "each term must be [amplitude, frequency_hz, phase_rad]");
      s.terms.push_back({t[0].get<double>(), t[1].get<double>(), t[2].get<double>()});
    }
  }
  o.finish();
}

void read_ids(JsonObject& r, const char* key, std::vector<int>& out) {
  const json* v = r.raw(key);
  if (!v || v->is_null()) return;
  if (!v->is_array()) fail(r, key, "expected an array of integer ids");
  out.clear();
  for (const auto& x : *v) {
    if (!x.is_number_integer()) fail(r, key, "expected integer ids");
    out.push_back(x.get<int>());
  }
}

void read_intrinsics(JsonObject& r, const char* key, sim::PinholeCamera& k) {
  JsonObject o = r.child(key);
  o.get("width", k.width);
  o.get("height", k.height);
  o.get("fx", k.fx);
  o.get("fy", k.fy);
  o.get("cx", k.cx);
  o.get("cy", k.cy);
  o.finish();
}

void read_visibility(JsonObject& r, const char* key, sim::VisibilityConfig& v) {
  JsonObject o = r.child(key);
  for (const auto& f : sim::visibility_fields()) o.get(f.key, v.*f.member);
  o.finish();
}

void read_detection(JsonObject& r, const char* key, sim::DetectionNoiseConfig& d) {
  JsonObject o = r.child(key);
  for (const auto& f : sim::detection_fields()) o.get(f.key, d.*f.member);
  o.get("translation_frame", d.translation_frame);
  o.get("reported_failure_sigma", d.reported_failure_sigma);
  o.get("write_sigmas", d.write_sigmas);
  o.finish();
}

void apply(const json& j, const std::string& source, sim::SimConfig& c, int depth);

void apply_base(JsonObject& r, sim::SimConfig& c, int depth) {
  std::string base;
  r.get("base", base);
  if (base.empty()) return;
  if (depth > 8) fail(r, "base", "presets nest too deeply (a cycle of \"base\" keys?)");
  const auto names = list_presets();
  if (std::find(names.begin(), names.end(), base) == names.end())
    fail(r, "base", "unknown preset '" + base + "' (available: " + fmt::format("{}", fmt::join(names, ", ")) + ")");
  const std::string& text = preset_text(base);
  apply(io::parse_json_text(text, "preset " + base), "preset " + base, c, depth + 1);
}

void apply(const json& j, const std::string& source, sim::SimConfig& c, int depth) {
  JsonObject r(j, source);
  apply_base(r, c, depth);  // the base first, then this file's keys on top
  std::string description;
  r.get("description", description);
  r.get("name", c.name);
  r.get("duration_s", c.duration_s);
  r.get("start_time_ns", c.start_time_ns);
  {
    JsonObject t = r.child("trajectory");
    read_vec3(t, "center", c.trajectory.center);
    read_signal(t, "azimuth_rad", c.trajectory.azimuth_rad);
    read_signal(t, "radius_m", c.trajectory.radius_m);
    read_signal(t, "height_m", c.trajectory.height_m);
    read_signal(t, "target_x_m", c.trajectory.target_x_m);
    read_signal(t, "target_y_m", c.trajectory.target_y_m);
    read_signal(t, "target_z_m", c.trajectory.target_z_m);
    read_signal(t, "roll_rad", c.trajectory.roll_rad);
    read_signal(t, "shake_x_m", c.trajectory.shake_x_m);
    read_signal(t, "shake_y_m", c.trajectory.shake_y_m);
    read_signal(t, "shake_z_m", c.trajectory.shake_z_m);
    t.finish();
  }
  {
    JsonObject v = r.child("variation");
    v.get("amplitude_rel", c.variation.amplitude_rel);
    v.get("frequency_rel", c.variation.frequency_rel);
    v.get("phase_rad", c.variation.phase_rad);
    v.get("offset_rel", c.variation.offset_rel);
    v.get("azimuth_start_rad", c.variation.azimuth_start_rad);
    v.finish();
  }
  {
    JsonObject o = r.child("objects");
    if (const json* list = o.raw("list"); list && !list->is_null()) {
      if (!list->is_array()) fail(o, "list", "expected an array of {\"id\": N[, \"T_M_O\": pose]}");
      c.objects.objects.clear();
      for (std::size_t i = 0; i < list->size(); ++i) {
        JsonObject e((*list)[i], source, o.key_path("list") + "[" + std::to_string(i) + "]");
        sim::ObjectSpec s;
        e.require("id", s.id);
        if (e.has("T_M_O")) {
          read_pose(e, "T_M_O", s.T_M_O);
          s.has_pose = true;
        } else {
          e.raw("T_M_O");
        }
        e.finish();
        c.objects.objects.push_back(s);
      }
    }
    read_vec3(o, "area_center", c.objects.area_center);
    o.get("area_size_m", c.objects.area_size_m);
    o.get("min_separation_m", c.objects.min_separation_m);
    o.get("height_jitter_m", c.objects.height_jitter_m);
    o.get("lying_prob", c.objects.lying_prob);
    std::int64_t layout_seed = static_cast<std::int64_t>(c.objects.layout_seed);
    o.get("layout_seed", layout_seed);
    if (layout_seed < 0) fail(o, "layout_seed", "must be >= 0");
    c.objects.layout_seed = static_cast<std::uint64_t>(layout_seed);
    read_ids(o, "symmetric_ids", c.objects.symmetric_ids);
    o.finish();
  }
  {
    JsonObject i = r.child("imu");
    i.get("rate_hz", c.imu.rate_hz);
    io::read_imu_noise(i, c.imu);
    i.get("gyro_bias_sigma", c.imu.gyro_bias_sigma);
    i.get("accel_bias_sigma", c.imu.accel_bias_sigma);
    i.finish();
  }
  {
    JsonObject k = r.child("camera");
    k.get("rate_hz", c.camera.rate_hz);
    read_intrinsics(k, "intrinsics", c.camera.intrinsics);
    read_pose(k, "T_I_C", c.camera.T_I_C);
    read_pose(k, "prior_error", c.camera.prior_error);
    k.get("time_offset_s", c.camera.time_offset_s);
    k.get("declared_time_offset_s", c.camera.declared_time_offset_s);
    k.finish();
  }
  read_visibility(r, "visibility", c.visibility);
  read_detection(r, "detection", c.detection);
  {
    JsonObject m = r.child("mocap");
    m.get("enabled", c.mocap.enabled);
    m.get("rate_hz", c.mocap.rate_hz);
    m.get("position_sigma_m", c.mocap.position_sigma_m);
    m.get("rotation_sigma_deg", c.mocap.rotation_sigma_deg);
    m.get("body", c.mocap.body);
    read_pose(m, "T_B_I", c.mocap.T_B_I);
    m.finish();
  }
  r.finish();
}

json signal_json(const sim::SmoothSignal& s) {
  json terms = json::array();
  for (const auto& t : s.terms) terms.push_back({t.amplitude, t.frequency_hz, t.phase_rad});
  return {{"offset", s.offset}, {"rate", s.rate}, {"terms", terms}};
}
json vec_json(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
json detection_json(const sim::DetectionNoiseConfig& d) {
  json j = {{"translation_frame", d.translation_frame},
            {"reported_failure_sigma", d.reported_failure_sigma},
            {"write_sigmas", d.write_sigmas}};
  for (const auto& f : sim::detection_fields()) j[f.key] = d.*f.member;
  return j;
}
json visibility_json(const sim::VisibilityConfig& v) {
  json j = json::object();
  for (const auto& f : sim::visibility_fields()) j[f.key] = v.*f.member;
  return j;
}
json intrinsics_json(const sim::PinholeCamera& k) {
  return {{"width", k.width}, {"height", k.height}, {"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy}};
}

std::string join_ids(const std::vector<int>& ids) {
  std::string s;
  for (std::size_t i = 0; i < ids.size(); ++i) s += (i ? "," : "") + std::to_string(ids[i]);
  return s;
}
}  // namespace

json sim_config_to_json(const sim::SimConfig& c) {
  json objects = json::array();
  for (const auto& o : c.objects.objects) {
    json e = {{"id", o.id}};
    if (o.has_pose) e["T_M_O"] = io::pose_to_json(o.T_M_O);
    objects.push_back(e);
  }
  const auto& t = c.trajectory;
  json imu = io::imu_noise_to_json(c.imu);
  imu["rate_hz"] = c.imu.rate_hz;
  imu["gyro_bias_sigma"] = c.imu.gyro_bias_sigma;
  imu["accel_bias_sigma"] = c.imu.accel_bias_sigma;
  return {
      {"name", c.name},
      {"duration_s", c.duration_s},
      {"start_time_ns", c.start_time_ns},
      {"trajectory",
       {{"center", vec_json(t.center)},
        {"azimuth_rad", signal_json(t.azimuth_rad)},
        {"radius_m", signal_json(t.radius_m)},
        {"height_m", signal_json(t.height_m)},
        {"target_x_m", signal_json(t.target_x_m)},
        {"target_y_m", signal_json(t.target_y_m)},
        {"target_z_m", signal_json(t.target_z_m)},
        {"roll_rad", signal_json(t.roll_rad)},
        {"shake_x_m", signal_json(t.shake_x_m)},
        {"shake_y_m", signal_json(t.shake_y_m)},
        {"shake_z_m", signal_json(t.shake_z_m)}}},
      {"variation",
       {{"amplitude_rel", c.variation.amplitude_rel},
        {"frequency_rel", c.variation.frequency_rel},
        {"phase_rad", c.variation.phase_rad},
        {"offset_rel", c.variation.offset_rel},
        {"azimuth_start_rad", c.variation.azimuth_start_rad}}},
      {"objects",
       {{"list", objects},
        {"area_center", vec_json(c.objects.area_center)},
        {"area_size_m", c.objects.area_size_m},
        {"min_separation_m", c.objects.min_separation_m},
        {"height_jitter_m", c.objects.height_jitter_m},
        {"lying_prob", c.objects.lying_prob},
        {"layout_seed", c.objects.layout_seed},
        {"symmetric_ids", c.objects.symmetric_ids}}},
      {"imu", imu},
      {"camera",
       {{"rate_hz", c.camera.rate_hz},
        {"intrinsics", intrinsics_json(c.camera.intrinsics)},
        {"T_I_C", io::pose_to_json(c.camera.T_I_C)},
        {"prior_error", io::pose_to_json(c.camera.prior_error)},
        {"time_offset_s", c.camera.time_offset_s},
        {"declared_time_offset_s", c.camera.declared_time_offset_s}}},
      {"visibility", visibility_json(c.visibility)},
      {"detection", detection_json(c.detection)},
      {"mocap",
       {{"enabled", c.mocap.enabled},
        {"rate_hz", c.mocap.rate_hz},
        {"position_sigma_m", c.mocap.position_sigma_m},
        {"rotation_sigma_deg", c.mocap.rotation_sigma_deg},
        {"body", c.mocap.body},
        {"T_B_I", io::pose_to_json(c.mocap.T_B_I)}}},
  };
}

std::vector<std::string> list_presets() {
  std::vector<std::string> names;
  for (const auto& p : detail::embedded_sim_presets()) names.push_back(p.first);
  std::sort(names.begin(), names.end());
  return names;
}

const std::string& preset_text(const std::string& name) {
  for (const auto& p : detail::embedded_sim_presets())
    if (p.first == name) return p.second;
  std::string names;
  for (const auto& n : list_presets()) names += (names.empty() ? "" : ", ") + n;
  throw InputError("unknown preset '" + name + "' (available: " + names + ")", {"--preset"});
}

std::string preset_description(const std::string& name) {
  const json j = io::parse_json_text(preset_text(name), "preset " + name);
  auto it = j.find("description");
  return it != j.end() && it->is_string() ? it->get<std::string>() : std::string();
}

sim::SimConfig sim_config_from_json(const json& j, const std::string& source) {
  sim::SimConfig c;
  apply(j, source, c, 0);
  return c;
}

sim::SimConfig sim_config_from_preset(const std::string& name) {
  sim::SimConfig c =
      sim_config_from_json(io::parse_json_text(preset_text(name), "preset " + name), "preset " + name);
  return c;
}

sim::SimConfig sim_config_from_file(const std::filesystem::path& file) {
  return io::read_json_file(file, sim_config_from_json);
}

namespace {
/// The real streams `--from-groundtruth` reads from a EuRoC/TUM-VI folder (DIR/mav0 or the mav0 folder).
struct GroundTruthInput {
  std::filesystem::path mav0, imu_file, gt_file;
  std::vector<ImuSample> imu;
  std::vector<ImuState> states;  ///< the full state, or the poses with their velocity (pose_only)
  std::string layout;
  bool pose_only = false;
  std::optional<ImuNoise> imu_noise;  ///< from imu0/sensor.yaml (EuRoC's keys = Kalibr's imu.yaml keys)
  std::filesystem::path imu_yaml;     ///< where imu_noise came from
};

/// The names of a stream file's header line (the first line, '#' and blanks trimmed, units kept).
std::vector<std::string> header_names(const std::filesystem::path& file) {
  const std::string head = io::read_file_head(file, 4096);
  std::string line = head.substr(0, head.find('\n'));
  if (!line.empty() && line.back() == '\r') line.pop_back();
  if (line.empty() || line[0] != '#') return {};
  std::vector<std::string> names;
  std::size_t start = 1;
  while (start <= line.size()) {
    const std::size_t end = std::min(line.find(',', start), line.size());
    const std::string cell = line.substr(start, end - start);
    const auto a = cell.find_first_not_of(' '), b = cell.find_last_not_of(' ');
    names.push_back(a == std::string::npos ? std::string() : cell.substr(a, b - a + 1));
    start = end + 1;
  }
  return names;
}

/// A download without a mav0 folder (TUM-VI's and OpenVINS's files as distributed: an IMU file beside a
/// mocap/ground-truth file, e.g. dataset-room1_512_imu.txt and dataset-room1_512_16_gt.csv): the one
/// IMU file (EuRoC imu0 columns) and the one ground-truth file (EuRoC or OpenVINS pose columns, 8 or 17)
/// of `dir`, told apart by their headers. InputError naming what was found otherwise.
std::pair<std::filesystem::path, std::filesystem::path> loose_streams(const std::filesystem::path& dir) {
  std::vector<std::filesystem::path> imu, gt;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    const std::vector<std::string> h = header_names(e.path());
    if (h.size() == 7 && h[1].rfind("w_RS_S_x", 0) == 0 && h[4].rfind("a_RS_S_x", 0) == 0) imu.push_back(e.path());
    if ((h.size() == 8 || h.size() == 17) &&
        ((h[1].rfind("p_RS_R_x", 0) == 0 && h[4].rfind("q_RS_w", 0) == 0) || (h[1] == "px" && h[4] == "qw")))
      gt.push_back(e.path());
  }
  if (imu.size() == 1 && gt.size() == 1) return {imu.front(), gt.front()};
  throw InputError(fmt::format("not a EuRoC mav0 folder (no mav0/imu0/data.csv) nor a download with one IMU file "
                               "(#timestamp [ns],w_RS_S_x [rad s^-1],...) and one ground-truth file "
                               "(#timestamp [ns],p_RS_R_x [m],...,q_RS_w [],... or #time(ns),px,...,qw,...) beside "
                               "it: found {} IMU and {} ground-truth files",
                               imu.size(), gt.size()),
                   {dir.string()});
}

/// A download's IMU noise: the one YAML file beside its streams that reads as a Kalibr IMU file (TUM-VI's
/// imu_config.yaml, a Kalibr imu.yaml); empty when there is none or more than one.
std::filesystem::path download_imu_yaml(const std::filesystem::path& dir) {
  std::vector<std::filesystem::path> found;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (!e.is_regular_file() || e.path().extension() != ".yaml") continue;
    try {
      (void)io::read_kalibr_imu(e.path());
      found.push_back(e.path());
    } catch (const std::exception&) {  // not an IMU file: another YAML of the download
    }
  }
  return found.size() == 1 ? found.front() : std::filesystem::path();
}

GroundTruthInput read_groundtruth_input(const std::filesystem::path& dir) {
  GroundTruthInput in;
  in.mav0 = io::is_folder(dir / "mav0") ? dir / "mav0" : dir;
  if (!io::is_folder(in.mav0)) throw InputError("not a directory (expected a EuRoC mav0 folder)", {dir.string()});
  in.imu_file = in.mav0 / "imu0" / "data.csv";
  std::string download;
  if (!io::is_folder(in.mav0 / "imu0") && !io::is_folder(dir / "mav0")) {
    std::tie(in.imu_file, in.gt_file) = loose_streams(dir);
    download = " (download: " + in.imu_file.filename().string() + " + " + in.gt_file.filename().string() + ")";
  }
  if (!io::path_exists(in.imu_file)) throw InputError("missing EuRoC stream", {in.imu_file.string()});
  // The IMU's ground truth: EuRoC's state (17 columns) or a pose-only file in its place; else TUM-VI's
  // mocap0, which is the IMU pose there. (EuRoC's vicon0 is the marker body, not the IMU: not taken.)
  const std::filesystem::path candidates[] = {in.mav0 / "state_groundtruth_estimate0" / "data.csv",
                                              in.mav0 / "mocap0" / "data.csv"};
  for (const auto& f : candidates)
    if (in.gt_file.empty() && io::path_exists(f)) in.gt_file = f;
  if (in.gt_file.empty())
    throw InputError(fmt::format("missing ground truth: expected {} (EuRoC: 17 columns, or 8: time, position, "
                                 "quaternion) or {} (TUM-VI)",
                                 candidates[0].string(), candidates[1].string()),
                     {in.mav0.string()});
  in.imu = store::read_imu_csv(in.imu_file);
  in.imu_yaml = in.mav0 / "imu0" / "sensor.yaml";
  if (!download.empty()) in.imu_yaml = download_imu_yaml(dir);
  if (!in.imu_yaml.empty() && io::path_exists(in.imu_yaml)) in.imu_noise = io::read_kalibr_imu(in.imu_yaml).noise;
  store::GroundTruthFile gt = store::read_groundtruth_file(in.gt_file);
  in.layout = gt.layout + download;
  in.pose_only = gt.pose_only();
  in.states = in.pose_only ? sim::states_from_poses(gt.poses) : std::move(gt.states);
  return in;
}
}  // namespace

sim::SimRun simulate_dataset(const SimulateOptions& opt, json* effective) {
  const bool gt_mode = !opt.from_groundtruth.empty();
  if (gt_mode && (!opt.preset.empty() || !opt.config_file.empty()))
    throw InputError("--from-groundtruth cannot be combined with --preset or --config",
                     {"--from-groundtruth"});
  if (!gt_mode && opt.objects)
    throw InputError("--objects only applies to --from-groundtruth", {"--objects"});
  if (!gt_mode && opt.preset.empty() == opt.config_file.empty())
    throw InputError("give exactly one of --preset NAME, --config FILE or --from-groundtruth DIR",
                     {"roe simulate"});
  if (opt.duration_s && !(std::isfinite(*opt.duration_s) && *opt.duration_s > 0.0))
    throw InputError("must be a positive number of seconds", {"--duration"});
  if (opt.time_offset_s && !(std::abs(*opt.time_offset_s) <= 1.0))
    throw InputError("must be a number of seconds within [-1, 1]", {"--time-offset"});

  SourceRecord src;
  src.kind = "simulate";
  src.options["seed"] = std::to_string(opt.seed);
  if (opt.time_offset_s) src.options["time_offset_s"] = io::format_double(*opt.time_offset_s);
  sim::SimRun run;
  if (gt_mode) {
    const GroundTruthInput in = read_groundtruth_input(opt.from_groundtruth);
    const auto& imu = in.imu;
    const auto& gt = in.states;
    sim::FromGroundtruthConfig cfg;
    if (opt.objects) cfg.num_objects = *opt.objects;
    if (in.imu_noise) cfg.imu_noise = *in.imu_noise;
    if (opt.duration_s) throw InputError("--duration does not apply to --from-groundtruth", {"--duration"});
    if (opt.time_offset_s) cfg.time_offset_s = *opt.time_offset_s;
    try {
      run = sim::simulate_from_groundtruth(imu, gt, cfg, opt.seed);
    } catch (const ConfigError& e) {
      ErrorContext ctx = e.context();
      if (ctx.key == "objects") {
        ctx.file = "--objects";
        ctx.key.clear();
      } else {
        ctx.file = "from-groundtruth";
      }
      throw InputError(e.bare_message(), ctx);
    }
    src.kind = "simulate-from-groundtruth";
    src.path = io::provenance_path(in.mav0);
    src.options["objects"] = std::to_string(cfg.num_objects);
    src.options["imu_sha256"] = io::sha256_file(in.imu_file);
    src.options["groundtruth"] = io::provenance_path(in.gt_file);
    src.options["groundtruth_sha256"] = io::sha256_file(in.gt_file);
    src.options["groundtruth_layout"] = in.layout;
    src.options["imu_noise"] = in.imu_noise ? io::provenance_path(in.imu_yaml)
                                            : std::string("EuRoC ADIS16448 sensor.yaml values (no imu0/sensor.yaml)");
    if (in.pose_only) {
      src.options["groundtruth_velocity"] = fmt::format(
          "from the poses: slope of a least-squares quadratic over +-{} s (docs/simulator.md section 9)",
          sim::VelocityFromPosesConfig{}.half_window_s);
      src.options["groundtruth_biases"] = "unknown (written as 0 in state_groundtruth_estimate0)";
    }
    src.options["T_I_C"] = "EuRoC cam0 T_BS";
    if (effective)
      *effective = {{"from_groundtruth", in.mav0.string()}, {"objects", cfg.num_objects}, {"seed", opt.seed}};
  } else {
    std::string source;
    sim::SimConfig cfg;
    if (!opt.preset.empty()) {
      cfg = sim_config_from_preset(opt.preset);
      source = "preset " + opt.preset;
      src.options["preset"] = opt.preset;
    } else {
      cfg = sim_config_from_file(opt.config_file);
      source = opt.config_file;
      src.path = io::provenance_path(opt.config_file);
      src.sha256 = io::sha256_file(opt.config_file);
    }
    if (opt.duration_s) cfg.duration_s = *opt.duration_s;
    if (opt.time_offset_s) cfg.camera.time_offset_s = *opt.time_offset_s;
    try {
      run = sim::simulate_run(cfg, opt.seed);
    } catch (const ConfigError& e) {
      ErrorContext ctx = e.context();
      if (opt.duration_s && ctx.key == "duration_s") {  // the command line's value, not the file's
        throw InputError(e.bare_message(), {"--duration"});
      }
      ctx.file = source;
      throw ConfigError(e.bare_message(), ctx);
    } catch (const NumericError& e) {
      // A trajectory the config makes degenerate (the camera straight above its look-at point): bad
      // input, named by its key, not a failure of the data.
      throw ConfigError(e.bare_message(), {source, 0, 0, "trajectory"});
    }
    src.options["duration_s"] = fmt::format("{}", cfg.duration_s);
    const json eff = sim_config_to_json(cfg);
    src.options["config_sha256"] = io::sha256_hex(io::dump_json(eff));
    if (effective) *effective = eff;
  }
  run.dataset.manifest.sources.push_back(src);
  return run;
}

namespace {
constexpr const char* kModelsInfo = "models_info.json";  ///< --models-info: next to roe.json
}  // namespace

SimulateResult simulate(const SimulateOptions& opt, const std::filesystem::path& out) {
  io::OutputDir dir(out, opt.force, {opt.from_groundtruth, opt.config_file});  // refused before any work
  json effective;
  sim::SimRun run = simulate_dataset(opt, &effective);
  log::info("simulated {}: seed {}, {} IMU samples, {} camera frames, {} detections of {} objects",
            run.dataset.manifest.name, opt.seed, run.dataset.imu.size(), run.dataset.frames.size(),
            run.stats.detections, run.dataset.manifest.objects.size());
  std::map<int, ObjectSymmetry> symmetries;
  if (opt.models_info)
    for (auto& o : run.dataset.manifest.objects) {
      if (!o.symmetric) continue;
      o.models_info = kModelsInfo;
      o.symmetry = symmetries[o.id] = sim::simulated_symmetry(o.id);
    }
  // The file first: writing roe.json checks what it points at.
  if (!symmetries.empty()) io::write_models_info(dir.tmp() / kModelsInfo, symmetries);
  store::write_dataset_files(run.dataset, dir.tmp());
  // detections/sim/meta.json: who produced the detections and with which configuration.
  store::DetectionSetMeta meta;
  meta.producer = std::string("roe simulate ") + roe::kVersion;
  meta.frames_processed = run.stats.frames;
  meta.detections = run.stats.detections;
  meta.details = {{"seed", opt.seed}, {"config", effective}};
  store::write_detection_set_meta(dir.file("detections/sim/meta.json"), meta);
  dir.commit();
  log::info("wrote {}", out.string());

  SimulateResult r;
  r.out = out;
  r.name = run.dataset.manifest.name;
  r.seed = opt.seed;
  r.stats = run.stats;
  r.mocap_samples = run.dataset.mocap.size();
  if (!run.dataset.imu.empty())
    r.duration_s = dt_seconds(run.dataset.imu.front().t_ns, run.dataset.imu.back().t_ns);
  for (const auto& o : run.dataset.manifest.objects) r.object_ids.push_back(o.id);
  return r;
}

json SimulateResult::to_json() const {
  json per_object = json::object();
  for (const auto& [id, n] : stats.detections_per_object) per_object[std::to_string(id)] = n;
  return {{"out", out.string()},
          {"name", name},
          {"seed", seed},
          {"duration_s", duration_s},
          {"objects", object_ids},
          {"imu_samples", stats.imu_samples},
          {"frames", stats.frames},
          {"frames_with_detections", stats.frames_with_detections},
          {"detections", stats.detections},
          {"detections_per_object", per_object},
          {"outliers", stats.outliers},
          {"symmetric_flips", stats.flips},
          {"blurred_frames", stats.blurred_frames},
          {"blurred_detections", stats.blurred_detections},
          {"bad_frames", stats.bad_frames},
          {"bad_frame_detections", stats.bad_frame_detections},
          {"missed", stats.missed},
          {"mocap_samples", mocap_samples},
          {"max_speed_m_s", stats.max_speed_m_s},
          {"max_rate_deg_s", stats.max_rate_deg_s}};
}

std::string SimulateResult::to_text() const {
  std::string per;
  for (const auto& [id, n] : stats.detections_per_object) per += fmt::format(" {}:{}", id, n);
  return fmt::format(
      "wrote {} ({}, seed {})\n"
      "  {:.1f} s: {} IMU samples, {} frames ({} with detections), {} mocap poses\n"
      "  objects [{}], detections {} (per object:{})\n"
      "  outliers {}, symmetric flips {}, blurred frames {}, bad frames {}, missed {}\n"
      "  max speed {:.2f} m/s, max rate {:.1f} deg/s\n",
      out.string(), name, seed, duration_s, stats.imu_samples, stats.frames, stats.frames_with_detections,
      mocap_samples, join_ids(object_ids), stats.detections, per, stats.outliers, stats.flips,
      stats.blurred_frames, stats.bad_frames, stats.missed, stats.max_speed_m_s, stats.max_rate_deg_s);
}

}  // namespace roe::app
