#include "roe/store/dataset.hpp"
#include "roe/io/models_info.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "roe/io/csv.hpp"
#include "roe/io/input.hpp"
#include "roe/io/output.hpp"
#include "roe/io/pose_json.hpp"
#include "roe/io/trajectory_io.hpp"

namespace roe::store {

// store reads and writes through io's primitives.
using io::CsvOptions;
using io::CsvReader;
using io::CsvWriter;
using io::JsonObject;
using io::OutputDir;
using io::StampKind;
using io::StampOrder;
using io::Trajectory;
using io::TrajectoryFormat;
using io::dump_json;
using io::imu_noise_to_json;
using io::is_folder;
using io::json;
using io::optional_regular_file;
using io::path_exists;
using io::pose_from_json;
using io::pose_to_json;
using io::read_file_head;
using io::read_imu_noise;
using io::read_json_file;
using io::read_models_info;
using io::read_trajectory;
using io::unit_quaternion;
using io::write_file_atomic;
namespace {

using Eigen::Quaterniond;
using Eigen::Vector3d;

// ---------------------------------------------------------------------------------------------
// Shared helpers
// ---------------------------------------------------------------------------------------------

// Tolerance on |‖q‖ − 1| in roe.json (DESIGN §3: unit quaternions).
constexpr double kManifestQuatTol = 1e-6;
// Tolerance on |‖q‖ − 1| in CSV streams: EuRoC writes 6 decimals, network outputs may be loosely
// normalised; anything further off is a wrong column or a corrupt row, not rounding.
constexpr double kCsvQuatTol = 1e-3;

Pose make_pose(const Quaterniond& q, const Vector3d& p) {
  Pose T;
  T.q = unit_quaternion(q);
  T.p = p;
  return T;
}

// Reads a quaternion from columns (in the given order of x,y,z,w file columns) and checks its norm.
Quaterniond read_quat(const CsvReader& r, std::size_t cx, std::size_t cy, std::size_t cz, std::size_t cw) {
  const Quaterniond q(r.get_double(cw), r.get_double(cx), r.get_double(cy), r.get_double(cz));
  const double n = q.norm();
  if (!(std::abs(n - 1.0) <= kCsvQuatTol))
    throw r.error(std::min({cx, cy, cz, cw}),
                  fmt::format("quaternion is not unit norm (|q| = {:.9g}); check the column order", n));
  return q;
}

Vector3d read_vec3(const CsvReader& r, std::size_t c0) {
  return Vector3d(r.get_double(c0), r.get_double(c0 + 1), r.get_double(c0 + 2));
}

// Every stream file starts its header with the stamp column; EuRoC spells it two ways.
constexpr const char* kStampNs = "timestamp [ns]|timestamp";

CsvOptions stream_options(std::vector<std::string> header,
                          StampOrder order = StampOrder::kStrictlyIncreasing) {
  CsvOptions o;
  o.expected_header = std::move(header);
  o.stamp_column = 0;
  o.stamp_kind = StampKind::kNanoseconds;
  o.stamp_order = order;
  return o;
}

void check_finite(const Vector3d& v, const char* what) {
  ROE_CHECK(v.allFinite(), std::string("non-finite ") + what + " cannot be written");
}

// Writers refuse unsorted or non-finite data: the readers would reject the file, so writing it
// is a bug in the producer.
template <typename T>
void check_sorted(const std::vector<T>& v, const fs::path& file, bool strict) {
  for (std::size_t i = 1; i < v.size(); ++i) {
    const bool ok = strict ? v[i].t_ns > v[i - 1].t_ns : v[i].t_ns >= v[i - 1].t_ns;
    ROE_CHECK(ok, fmt::format("{}: stamps not {} at element {}", file.string(),
                              strict ? "strictly increasing" : "sorted", i));
  }
}

void add_quat_wxyz(CsvWriter& w, const Quaterniond& q) { w.add(q.w()).add(q.x()).add(q.y()).add(q.z()); }
void add_vec3(CsvWriter& w, const Vector3d& v) { w.add(v.x()).add(v.y()).add(v.z()); }

// ---------------------------------------------------------------------------------------------
// roe.json
// ---------------------------------------------------------------------------------------------

Pose required_pose(JsonObject& o, const char* key) {
  const json* v = o.raw(key);
  if (!v || v->is_null()) throw ConfigError("missing required key", {o.source(), 0, 0, o.key_path(key)});
  return pose_from_json(*v, o.source(), o.key_path(key), {kManifestQuatTol, nullptr});
}

Pose optional_pose(JsonObject& o, const char* key) {
  const json* v = o.raw(key);
  if (!v || v->is_null()) return Pose::identity();
  return pose_from_json(*v, o.source(), o.key_path(key), {kManifestQuatTol, nullptr});
}

// Calls fn(element JsonObject-able json, path "key[i]") for each element of an optional array.
template <typename Fn>
void for_each_element(JsonObject& o, const char* key, Fn&& fn) {
  const json* v = o.raw(key);
  if (!v || v->is_null()) return;
  if (!v->is_array()) throw ConfigError("expected an array", {o.source(), 0, 0, o.key_path(key)});
  for (std::size_t i = 0; i < v->size(); ++i) fn((*v)[i], fmt::format("{}[{}]", o.key_path(key), i));
}

// The stamp-ordered loaders share "absent file → empty stream"; a folder, a FIFO or a symlink loop
// where the file should be is an input error (not an empty stream).
bool present(const fs::path& file) { return optional_regular_file(file, "data file"); }

const std::vector<std::string>& imu_header() {
  static const std::vector<std::string> h = {
      "timestamp [ns]",    "w_RS_S_x [rad s^-1]", "w_RS_S_y [rad s^-1]", "w_RS_S_z [rad s^-1]",
      "a_RS_S_x [m s^-2]", "a_RS_S_y [m s^-2]",   "a_RS_S_z [m s^-2]"};
  return h;
}
const std::vector<std::string>& mocap_header() {
  static const std::vector<std::string> h = {"timestamp [ns]", "p_RS_R_x [m]", "p_RS_R_y [m]", "p_RS_R_z [m]",
                                             "q_RS_w []",      "q_RS_x []",    "q_RS_y []",    "q_RS_z []"};
  return h;
}
// Exactly the EuRoC ground-truth header (state_groundtruth_estimate0), including its "#timestamp"
// without unit; written with ", " separators like the original files.
const std::vector<std::string>& groundtruth_header() {
  static const std::vector<std::string> h = {"timestamp",
                                             "p_RS_R_x [m]",
                                             "p_RS_R_y [m]",
                                             "p_RS_R_z [m]",
                                             "q_RS_w []",
                                             "q_RS_x []",
                                             "q_RS_y []",
                                             "q_RS_z []",
                                             "v_RS_R_x [m s^-1]",
                                             "v_RS_R_y [m s^-1]",
                                             "v_RS_R_z [m s^-1]",
                                             "b_w_RS_S_x [rad s^-1]",
                                             "b_w_RS_S_y [rad s^-1]",
                                             "b_w_RS_S_z [rad s^-1]",
                                             "b_a_RS_S_x [m s^-2]",
                                             "b_a_RS_S_y [m s^-2]",
                                             "b_a_RS_S_z [m s^-2]"};
  return h;
}
const std::vector<std::string>& detections_header(bool with_sigma) {
  static const std::vector<std::string> base = {"timestamp_ns", "object_id", "tx", "ty", "tz",
                                                "qx",           "qy",        "qz", "qw", "score"};
  static const std::vector<std::string> full = [] {
    auto h = base;
    for (const char* s : {"sigma_tx", "sigma_ty", "sigma_tz", "sigma_rx", "sigma_ry", "sigma_rz"})
      h.push_back(s);
    return h;
  }();
  return with_sigma ? full : base;
}

// The ground-truth header as read: EuRoC's names, or OpenVINS's (vicon2gt / ov_eval:
// `#time(ns),px,py,pz,qw,qx,qy,qz,vx,vy,vz,bwx,bwy,bwz,bax,bay,baz`, the same columns in the same order).
std::vector<std::string> groundtruth_header_read() {
  static const char* const ov[] = {"time(ns)", "px", "py", "pz", "qw", "qx", "qy", "qz", "vx",
                                   "vy",       "vz", "bwx", "bwy", "bwz", "bax", "bay", "baz"};
  std::vector<std::string> h = groundtruth_header();
  h[0] = std::string("timestamp [ns]|") + h[0];
  for (std::size_t i = 0; i < h.size(); ++i) h[i] += std::string("|") + ov[i];
  return h;
}

// Header with the first column's accepted spellings.
std::vector<std::string> with_stamp_alternatives(std::vector<std::string> h) {
  h[0] = kStampNs;
  return h;
}

// roe.json layout: keys in a fixed, readable order (then alphabetical), arrays of numbers on one
// line, two-space indent. Deterministic, so the same manifest always gives the same bytes.
int key_rank(const std::string& k) {
  static const char* order[] = {"schema",
                                "id",
                                "name",
                                "kind",
                                "path",
                                "sha256",
                                "options",
                                "symmetric",
                                "sources",
                                "imu",
                                "camera",
                                "mocap",
                                "objects",
                                "truth",
                                "rate_hz",
                                "gyro_noise_density",
                                "gyro_random_walk",
                                "accel_noise_density",
                                "accel_random_walk",
                                "width",
                                "height",
                                "fx",
                                "fy",
                                "cx",
                                "cy",
                                "distortion_model",
                                "distortion",
                                "body",
                                "T_I_C",
                                "T_B_I",
                                "T_W_O",
                                "time_offset_s",
                                "imu_noise",
                                "detection_noise",
                                "p",
                                "q"};
  for (std::size_t i = 0; i < sizeof(order) / sizeof(order[0]); ++i)
    if (k == order[i]) return static_cast<int>(i);
  return 1000;
}

void print_json(const json& j, int indent, std::string& out) {
  const std::string pad(static_cast<std::size_t>(indent) + 2, ' ');
  if (j.is_object()) {
    if (j.empty()) {
      out += "{}";
      return;
    }
    std::vector<std::string> keys;
    for (auto it = j.begin(); it != j.end(); ++it) keys.push_back(it.key());
    std::stable_sort(keys.begin(), keys.end(),
                     [](const std::string& a, const std::string& b) { return key_rank(a) < key_rank(b); });
    out += "{\n";
    for (std::size_t i = 0; i < keys.size(); ++i) {
      out += pad + dump_json(json(keys[i])) + ": ";
      print_json(j.at(keys[i]), indent + 2, out);
      out += i + 1 < keys.size() ? ",\n" : "\n";
    }
    out += std::string(static_cast<std::size_t>(indent), ' ') + "}";
  } else if (j.is_array()) {
    if (j.empty()) {
      out += "[]";
      return;
    }
    const bool flat = std::none_of(j.begin(), j.end(), [](const json& e) { return e.is_structured(); });
    if (flat) {
      out += "[";
      for (std::size_t i = 0; i < j.size(); ++i) out += (i ? ", " : "") + dump_json(j[i]);
      out += "]";
      return;
    }
    out += "[\n";
    for (std::size_t i = 0; i < j.size(); ++i) {
      out += pad;
      print_json(j[i], indent + 2, out);
      out += i + 1 < j.size() ? ",\n" : "\n";
    }
    out += std::string(static_cast<std::size_t>(indent), ' ') + "]";
  } else {
    out += dump_json(j);
  }
}

}  // namespace

// -------------------------------------------------------------------------------------------------
// Paths
// -------------------------------------------------------------------------------------------------

fs::path manifest_path(const fs::path& d) { return d / "roe.json"; }
fs::path imu_csv_path(const fs::path& d) { return d / "mav0" / "imu0" / "data.csv"; }
fs::path cam_csv_path(const fs::path& d) { return d / "mav0" / "cam0" / "data.csv"; }
fs::path cam_image_dir(const fs::path& d) { return d / "mav0" / "cam0" / "data"; }
fs::path mocap_csv_path(const fs::path& d) { return d / "mav0" / "mocap0" / "data.csv"; }
fs::path groundtruth_csv_path(const fs::path& d) {
  return d / "mav0" / "state_groundtruth_estimate0" / "data.csv";
}
fs::path detections_dir(const fs::path& d, const std::string& name) { return d / "detections" / name; }

// -------------------------------------------------------------------------------------------------
// roe.json
// -------------------------------------------------------------------------------------------------

json manifest_to_json(const DatasetManifest& m) {
  json j = json::object();
  j["schema"] = m.schema;
  j["name"] = m.name;
  json sources = json::array();
  for (const auto& s : m.sources) {
    json o = {{"kind", s.kind}, {"path", s.path}, {"sha256", s.sha256}, {"options", json::object()}};
    for (const auto& [k, v] : s.options) o["options"][k] = v;
    sources.push_back(std::move(o));
  }
  j["sources"] = std::move(sources);
  if (m.imu) {
    json imu = imu_noise_to_json(m.imu->noise);
    imu["rate_hz"] = m.imu->rate_hz;
    j["imu"] = std::move(imu);
  }
  if (m.camera) {
    const auto& c = *m.camera;
    j["camera"] = {{"width", c.width},
                   {"height", c.height},
                   {"fx", c.fx},
                   {"fy", c.fy},
                   {"cx", c.cx},
                   {"cy", c.cy},
                   {"distortion_model", c.distortion_model},
                   {"distortion", c.distortion},
                   {"T_I_C", pose_to_json(c.T_I_C)},
                   {"time_offset_s", c.time_offset_s}};
  }
  if (m.mocap) {
    j["mocap"] = {{"body", m.mocap->body},
                  {"T_B_I", pose_to_json(m.mocap->T_B_I)},
                  {"time_offset_s", m.mocap->time_offset_s}};
  }
  json objects = json::array();
  for (const auto& o : m.objects) {
    json oj = {{"id", o.id}, {"name", o.name}, {"symmetric", o.symmetric}};
    if (!o.models_info.empty()) oj["models_info"] = o.models_info;
    if (o.models_info_id >= 0) oj["models_info_id"] = o.models_info_id;
    objects.push_back(std::move(oj));
  }
  j["objects"] = std::move(objects);
  if (m.truth) {
    const auto& t = *m.truth;
    json tj = {{"T_I_C", pose_to_json(t.T_I_C)}, {"objects", json::array()}};
    // Only when there is one: datasets without a time offset keep the bytes (and readers) they had before.
    if (t.camera_time_offset_s != 0.0) tj["camera_time_offset_s"] = t.camera_time_offset_s;
    for (const auto& o : t.objects) tj["objects"].push_back({{"id", o.id}, {"T_W_O", pose_to_json(o.T_W_O)}});
    if (t.imu_noise) tj["imu_noise"] = imu_noise_to_json(*t.imu_noise);
    tj["detection_noise"] = json::object();
    for (const auto& [k, v] : t.detection_noise) tj["detection_noise"][k] = v;
    j["truth"] = std::move(tj);
  }
  return j;
}

namespace {

/// The optional section `key` read by `read` (which gets the section's JsonObject); an explicit null
/// counts as absent, not as an unknown key.
template <class T, class Read>
std::optional<T> optional_section(JsonObject& r, const char* key, Read read) {
  if (!r.has(key)) {
    (void)r.raw(key);
    return std::nullopt;
  }
  JsonObject o = r.child(key);
  T v = read(o);
  o.finish();
  return v;
}

/// The string values of the object `key` (absent: none), each checked as a string.
template <class Map, class Value>
void read_flat_object(JsonObject& r, const char* key, Map& out, Value) {
  JsonObject o = r.child(key);
  if (const json* ov = r.raw(key); ov && ov->is_object()) {
    for (auto it = ov->begin(); it != ov->end(); ++it) {
      Value v{};
      o.get(it.key().c_str(), v);
      out[it.key()] = v;
    }
  }
  o.finish();
}

SourceRecord read_source(const json& e, const std::string& source, const std::string& path) {
  JsonObject s(e, source, path);
  SourceRecord rec;
  s.require("kind", rec.kind);
  s.get("path", rec.path);
  s.get("sha256", rec.sha256);
  read_flat_object(s, "options", rec.options, std::string());
  s.finish();
  return rec;
}

ImuInfo read_imu_info(JsonObject& o) {
  ImuInfo imu;
  o.require("rate_hz", imu.rate_hz);
  if (!(std::isfinite(imu.rate_hz) && imu.rate_hz > 0.0))
    throw ConfigError("must be > 0", {o.source(), 0, 0, o.key_path("rate_hz")});
  read_imu_noise(o, imu.noise);
  return imu;
}

CameraInfo read_camera_info(JsonObject& o) {
  CameraInfo c;
  o.require("width", c.width);
  o.require("height", c.height);
  o.require("fx", c.fx);
  o.require("fy", c.fy);
  o.require("cx", c.cx);
  o.require("cy", c.cy);
  const auto positive = [&](bool ok, const char* key) {
    if (!ok) throw ConfigError("must be > 0", {o.source(), 0, 0, o.key_path(key)});
  };
  positive(c.width > 0, "width");
  positive(c.height > 0, "height");
  positive(c.fx > 0.0, "fx");
  positive(c.fy > 0.0, "fy");
  o.get("distortion_model", c.distortion_model);
  o.get("distortion", c.distortion);
  if (c.distortion_model == "none" && !c.distortion.empty())
    throw ConfigError("distortion coefficients given for distortion_model 'none'",
                      {o.source(), 0, 0, o.key_path("distortion")});
  c.T_I_C = optional_pose(o, "T_I_C");
  o.get("time_offset_s", c.time_offset_s);
  return c;
}

MocapInfo read_mocap_info(JsonObject& o) {
  MocapInfo mc;
  o.get("body", mc.body);
  mc.T_B_I = optional_pose(o, "T_B_I");
  o.get("time_offset_s", mc.time_offset_s);
  return mc;
}

/// One entry of `objects`, with the symmetries of its models_info (relative to the folder of roe.json).
ObjectInfo read_object(const json& e, const std::string& source, const std::string& path) {
  JsonObject o(e, source, path);
  ObjectInfo obj;
  o.require("id", obj.id);
  o.get("name", obj.name);
  o.get("symmetric", obj.symmetric);
  o.get("models_info", obj.models_info);
  o.get("models_info_id", obj.models_info_id);
  o.finish();
  if (!obj.models_info.empty()) {
    // The symmetries of the object's id (or models_info_id) there.
    const fs::path file = fs::path(source).parent_path() / obj.models_info;
    const auto info = read_models_info(file);
    const int key = obj.models_info_id >= 0 ? obj.models_info_id : obj.id;
    const auto it = info.find(key);
    if (it == info.end())
      throw ConfigError(fmt::format("object {} is not in {}", key, file.string()),
                        {source, 0, 0, o.key_path(obj.models_info_id >= 0 ? "models_info_id" : "models_info")});
    obj.symmetry = it->second;
  } else if (obj.models_info_id >= 0) {
    throw ConfigError("models_info_id without models_info", {source, 0, 0, o.key_path("models_info_id")});
  }
  return obj;
}

Truth read_truth(JsonObject& o) {
  Truth t;
  t.T_I_C = required_pose(o, "T_I_C");
  o.get("camera_time_offset_s", t.camera_time_offset_s);
  if (!std::isfinite(t.camera_time_offset_s))
    throw ConfigError("must be a finite number of seconds", {o.source(), 0, 0, o.key_path("camera_time_offset_s")});
  std::set<int> tids;
  for_each_element(o, "objects", [&](const json& e, const std::string& path) {
    JsonObject to(e, o.source(), path);
    TruthObject obj;
    to.require("id", obj.id);
    obj.T_W_O = required_pose(to, "T_W_O");
    to.finish();
    if (!tids.insert(obj.id).second)
      throw ConfigError(fmt::format("duplicate object id {}", obj.id), {o.source(), 0, 0, to.key_path("id")});
    t.objects.push_back(obj);
  });
  t.imu_noise = optional_section<ImuNoise>(o, "imu_noise", [](JsonObject& n) {
    ImuNoise noise;
    read_imu_noise(n, noise);
    return noise;
  });
  read_flat_object(o, "detection_noise", t.detection_noise, 0.0);
  return t;
}

}  // namespace

DatasetManifest manifest_from_json(const json& j, const std::string& source) {
  DatasetManifest m;
  JsonObject r(j, source);
  std::string schema;
  r.require("schema", schema);
  if (schema != kDatasetSchema)
    throw ConfigError(fmt::format("unsupported schema '{}' (expected '{}')", schema, kDatasetSchema),
                      {source, 0, 0, "schema"});
  m.schema = schema;
  r.get("name", m.name);
  for_each_element(r, "sources", [&](const json& e, const std::string& path) {
    m.sources.push_back(read_source(e, source, path));
  });
  m.imu = optional_section<ImuInfo>(r, "imu", read_imu_info);
  m.camera = optional_section<CameraInfo>(r, "camera", read_camera_info);
  m.mocap = optional_section<MocapInfo>(r, "mocap", read_mocap_info);
  std::set<int> ids;
  for_each_element(r, "objects", [&](const json& e, const std::string& path) {
    ObjectInfo obj = read_object(e, source, path);
    if (!ids.insert(obj.id).second)
      throw ConfigError(fmt::format("duplicate object id {}", obj.id), {source, 0, 0, path + ".id"});
    m.objects.push_back(std::move(obj));
  });
  m.truth = optional_section<Truth>(r, "truth", read_truth);
  r.finish();
  return m;
}

DatasetManifest read_manifest(const fs::path& dataset) {
  const fs::path file = manifest_path(dataset);
  if (!optional_regular_file(file, "roe.json"))
    throw InputError("not a roe dataset folder (no roe.json; create one with roe import or roe simulate)",
                     {file.string()});
  return read_json_file(file, manifest_from_json);
}

void write_manifest(const DatasetManifest& m, const fs::path& file) {
  const json j = manifest_to_json(m);
  // Never write a manifest the reader would refuse (duplicate ids, wrong schema, bad intrinsics...):
  // that is a bug in the producer, reported as such.
  try {
    (void)manifest_from_json(j, file.string());
  } catch (const ConfigError& e) {
    throw InternalError(std::string("refusing to write an invalid manifest: ") + e.what());
  }
  std::string text;
  print_json(j, 0, text);
  write_file_atomic(file, text + "\n");
}

// -------------------------------------------------------------------------------------------------
// Streams
// -------------------------------------------------------------------------------------------------

std::vector<ImuSample> read_imu_csv(const fs::path& file) {
  CsvReader r(file, stream_options(with_stamp_alternatives(imu_header())));
  std::vector<ImuSample> out;
  // Readings no MEMS IMU can give (a corrupt cell, a unit mix-up by 10⁶) are input errors here,
  // not a filter divergence later: the limits are ~30× the largest ranges of consumer and tactical
  // IMUs (±2000 °/s = 35 rad/s, ±16 g = 157 m/s²; 1000 rad/s, 5000 m/s²).
  constexpr double kMaxGyro = 1000.0, kMaxAccel = 5000.0;
  while (r.next()) {
    ImuSample s;
    s.t_ns = r.get_int64(0);
    s.gyro = read_vec3(r, 1);
    s.accel = read_vec3(r, 4);
    for (int k = 0; k < 3; ++k) {
      if (std::abs(s.gyro(k)) > kMaxGyro)
        throw r.error(1 + k, fmt::format("angular rate {} rad/s is beyond any IMU's range (|w| <= {})", s.gyro(k), kMaxGyro));
      if (std::abs(s.accel(k)) > kMaxAccel)
        throw r.error(4 + k, fmt::format("acceleration {} m/s^2 is beyond any IMU's range (|a| <= {})", s.accel(k), kMaxAccel));
    }
    out.push_back(s);
  }
  return out;
}

void write_imu_csv(const fs::path& file, const std::vector<ImuSample>& imu) {
  check_sorted(imu, file, true);
  CsvWriter w;
  w.header(imu_header(), "#");
  for (const auto& s : imu) {
    check_finite(s.gyro, "gyro");
    check_finite(s.accel, "accel");
    w.add(s.t_ns);
    add_vec3(w, s.gyro);
    add_vec3(w, s.accel);
    w.end_row();
  }
  w.write(file);
}

std::vector<CameraFrame> read_cam_csv(const fs::path& file) {
  CsvReader r(file, stream_options({kStampNs, "filename"}));
  std::vector<CameraFrame> out;
  while (r.next()) {
    CameraFrame f;
    f.t_ns = r.get_int64(0);
    f.filename = r.get_string(1);
    if (f.filename.find('/') != std::string::npos || f.filename == "." || f.filename == "..")
      throw r.error(1, "filename must be a plain name inside cam0/data/: '" + f.filename + "'");
    out.push_back(std::move(f));
  }
  return out;
}

void write_cam_csv(const fs::path& file, const std::vector<CameraFrame>& frames) {
  check_sorted(frames, file, true);
  CsvWriter w;
  w.header({"timestamp [ns]", "filename"}, "#");
  for (const auto& f : frames) w.add(f.t_ns).add(f.filename).end_row();
  w.write(file);
}

std::vector<StampedPose> read_mocap_csv(const fs::path& file) {
  CsvReader r(file, stream_options(with_stamp_alternatives(mocap_header())));
  std::vector<StampedPose> out;
  while (r.next()) {
    StampedPose s;
    s.t_ns = r.get_int64(0);
    s.T = make_pose(read_quat(r, 5, 6, 7, 4), read_vec3(r, 1));
    out.push_back(s);
  }
  return out;
}

void write_mocap_csv(const fs::path& file, const std::vector<StampedPose>& poses) {
  check_sorted(poses, file, true);
  CsvWriter w;
  w.header(mocap_header(), "#");
  for (const auto& s : poses) {
    check_finite(s.T.p, "position");
    w.add(s.t_ns);
    add_vec3(w, s.T.p);
    add_quat_wxyz(w, s.T.q);
    w.end_row();
  }
  w.write(file);
}

std::vector<ImuState> read_groundtruth_csv(const fs::path& file) {
  CsvReader r(file, stream_options(groundtruth_header_read()));
  std::vector<ImuState> out;
  while (r.next()) {
    ImuState s;
    s.t_ns = r.get_int64(0);
    s.T_W_I = make_pose(read_quat(r, 5, 6, 7, 4), read_vec3(r, 1));
    s.v_W_I = read_vec3(r, 8);
    s.b_g = read_vec3(r, 11);
    s.b_a = read_vec3(r, 14);
    out.push_back(s);
  }
  return out;
}

GroundTruthFile read_groundtruth_file(const fs::path& file) {
  // The first line that is not blank decides: 17 comma-separated cells are EuRoC's state.
  const std::string head = read_file_head(file, 1 << 16);
  std::size_t pos = head.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;
  while (pos < head.size() && (head[pos] == '\n' || head[pos] == '\r' || head[pos] == ' ')) ++pos;
  const std::string first = head.substr(pos, head.find('\n', pos) - pos);
  GroundTruthFile out;
  if (std::count(first.begin(), first.end(), ',') + 1 == static_cast<std::ptrdiff_t>(groundtruth_header().size())) {
    out.states = read_groundtruth_csv(file);
    out.layout = "euroc-state";
    return out;
  }
  const Trajectory tr = read_trajectory(file, TrajectoryFormat::kAuto);
  for (std::size_t i = 0; i < tr.size(); ++i) out.poses.push_back({tr.t_ns[i], tr.poses[i]});
  // Sorted; a repeated stamp keeps its first pose (as every roe reader of pose files).
  std::stable_sort(out.poses.begin(), out.poses.end(), [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });
  const std::size_t n = out.poses.size();
  out.poses.erase(std::unique(out.poses.begin(), out.poses.end(),
                              [](const auto& a, const auto& b) { return a.t_ns == b.t_ns; }),
                  out.poses.end());
  out.duplicate_stamps = n - out.poses.size();
  out.layout = to_string(tr.format);
  return out;
}

void write_groundtruth_csv(const fs::path& file, const std::vector<ImuState>& states) {
  check_sorted(states, file, true);
  // The EuRoC spelling: "#timestamp, p_RS_R_x [m], ..." (", " between names).
  CsvWriter w;
  const auto& h = groundtruth_header();
  std::vector<std::string> spaced = h;
  for (std::size_t i = 1; i < spaced.size(); ++i) spaced[i] = " " + spaced[i];
  w.header(spaced, "#");
  for (const auto& s : states) {
    check_finite(s.T_W_I.p, "position");
    check_finite(s.v_W_I, "velocity");
    check_finite(s.b_g, "gyro bias");
    check_finite(s.b_a, "accel bias");
    w.add(s.t_ns);
    add_vec3(w, s.T_W_I.p);
    add_quat_wxyz(w, s.T_W_I.q);
    add_vec3(w, s.v_W_I);
    add_vec3(w, s.b_g);
    add_vec3(w, s.b_a);
    w.end_row();
  }
  w.write(file);
}

std::vector<Detection> read_detections_csv(const fs::path& file) {
  // The header decides whether the six sigma columns are present.
  CsvOptions o;
  o.stamp_column = 0;
  o.stamp_order = StampOrder::kNonDecreasing;
  CsvReader r(file, o);
  const bool with_sigma = r.header().size() == detections_header(true).size();
  const auto& expected = detections_header(with_sigma);
  for (std::size_t c = 0; c < std::min(expected.size(), r.header().size()); ++c) {
    if (r.header()[c] != expected[c])
      throw InputError(
          fmt::format("unexpected header: column is '{}', expected '{}'", r.header()[c], expected[c]),
          {file.string(), r.header_line(), static_cast<std::int64_t>(c + 1)});
  }
  if (r.header().size() != expected.size())
    throw InputError(
        fmt::format("unexpected header: {} columns, expected {} (or {} with the six sigma columns)",
                    r.header().size(), detections_header(false).size(), detections_header(true).size()),
        {file.string(), r.header_line(),
         static_cast<std::int64_t>(std::min(r.header().size(), expected.size()) + 1)});

  std::vector<Detection> out;
  std::set<int> ids_at_stamp;
  Timestamp stamp = 0;
  while (r.next()) {
    Detection d;
    d.t_ns = r.get_int64(0);
    d.object_id = r.get_int(1);
    if (d.object_id < 0) throw r.error(1, "object_id must be >= 0");
    if (out.empty() || d.t_ns != stamp) {
      ids_at_stamp.clear();
      stamp = d.t_ns;
    }
    if (!ids_at_stamp.insert(d.object_id).second)
      throw r.error(1, fmt::format("duplicate detection of object {} at timestamp {}", d.object_id, d.t_ns));
    d.T_C_O = make_pose(read_quat(r, 5, 6, 7, 8), read_vec3(r, 2));
    d.score = r.get_double_or_nan(9);
    if (with_sigma) {
      std::size_t empty = 0;
      for (std::size_t c = 10; c < 16; ++c) empty += r.is_empty(c) ? 1 : 0;
      if (empty != 0 && empty != 6) throw r.row_error("sigma columns must be all empty or all given");
      if (empty == 0) {
        Vector6d s;
        for (int k = 0; k < 6; ++k) {
          s[k] = r.get_double(10 + k);
          if (!(s[k] > 0.0)) throw r.error(10 + k, "sigma must be > 0");
        }
        d.sigma = s;
      }
    }
    out.push_back(d);
  }
  return out;
}

void write_detections_csv(const fs::path& file, const std::vector<Detection>& detections) {
  check_sorted(detections, file, false);
  const bool with_sigma = std::any_of(detections.begin(), detections.end(),
                                      [](const Detection& d) { return d.sigma.has_value(); });
  CsvWriter w;
  w.header(detections_header(with_sigma));
  for (std::size_t i = 0; i < detections.size(); ++i) {
    const auto& d = detections[i];
    for (std::size_t k = 0; k < i && detections[i - 1 - k].t_ns == d.t_ns; ++k)
      ROE_CHECK(
          detections[i - 1 - k].object_id != d.object_id,
          fmt::format("{}: duplicate detection of object {} at {}", file.string(), d.object_id, d.t_ns));
    check_finite(d.T_C_O.p, "translation");
    ROE_CHECK(!std::isinf(d.score), "infinite detection score");
    w.add(d.t_ns).add(d.object_id);
    add_vec3(w, d.T_C_O.p);
    w.add(d.T_C_O.q.x()).add(d.T_C_O.q.y()).add(d.T_C_O.q.z()).add(d.T_C_O.q.w());
    if (std::isnan(d.score))
      w.add_empty();
    else
      w.add(d.score);
    if (with_sigma) {
      for (int k = 0; k < 6; ++k) {
        if (d.sigma) {
          ROE_CHECK(std::isfinite((*d.sigma)[k]) && (*d.sigma)[k] > 0.0, "sigma must be finite and > 0");
          w.add((*d.sigma)[k]);
        } else {
          w.add_empty();
        }
      }
    }
    w.end_row();
  }
  w.write(file);
}

// -------------------------------------------------------------------------------------------------
// Whole folder
// -------------------------------------------------------------------------------------------------

Dataset read_dataset(const fs::path& dataset, const DatasetParts& parts) {
  std::error_code ec;
  if (!is_folder(dataset))
    throw InputError(path_exists(dataset) ? "not a folder, expected a dataset folder" : "dataset folder not found",
                     {dataset.string()});
  Dataset d;
  d.manifest = read_manifest(dataset);
  if (parts.imu && present(imu_csv_path(dataset))) d.imu = read_imu_csv(imu_csv_path(dataset));
  if (parts.frames && present(cam_csv_path(dataset))) d.frames = read_cam_csv(cam_csv_path(dataset));
  if (parts.mocap && present(mocap_csv_path(dataset))) d.mocap = read_mocap_csv(mocap_csv_path(dataset));
  if (parts.groundtruth && present(groundtruth_csv_path(dataset)))
    d.groundtruth = read_groundtruth_csv(groundtruth_csv_path(dataset));
  if (parts.detections) {
    std::vector<std::string> available;
    const fs::path root = dataset / "detections";
    if (is_folder(root)) {
      for (const auto& e : fs::directory_iterator(root, ec))
        if (is_folder(e.path()) && present(e.path() / "detections.csv"))
          available.push_back(e.path().filename().string());
    }
    std::sort(available.begin(), available.end());  // deterministic order
    std::vector<std::string> names = parts.detection_names.empty() ? available : parts.detection_names;
    for (const auto& n : names) {
      if (std::find(available.begin(), available.end(), n) == available.end()) {
        std::string list;
        for (const auto& a : available) list += (list.empty() ? "" : ", ") + a;
        throw InputError(fmt::format("no detections named '{}' in this dataset (available: {})", n,
                                     list.empty() ? "none" : list),
                         {detections_dir(dataset, n).string()});
      }
      d.detections[n] = read_detections_csv(detections_dir(dataset, n) / "detections.csv");
    }
  }
  return d;
}

void write_dataset_files(const Dataset& d, const fs::path& root) {
  if (!d.imu.empty()) write_imu_csv(imu_csv_path(root), d.imu);
  if (!d.frames.empty()) write_cam_csv(cam_csv_path(root), d.frames);
  if (!d.mocap.empty()) write_mocap_csv(mocap_csv_path(root), d.mocap);
  if (!d.groundtruth.empty()) write_groundtruth_csv(groundtruth_csv_path(root), d.groundtruth);
  for (const auto& [name, dets] : d.detections) {
    ROE_CHECK(!name.empty() && name.find('/') == std::string::npos && name != "." && name != "..",
              "invalid detection set name '" + name + "'");
    // An empty set is still written (header only): "ran, found nothing" differs from "not run".
    write_detections_csv(detections_dir(root, name) / "detections.csv", dets);
  }
  write_manifest(d.manifest, manifest_path(root));
}

void write_dataset(const Dataset& d, const fs::path& dataset, bool force) {
  OutputDir out(dataset, force);
  write_dataset_files(d, out.tmp());
  out.commit();
}

// -------------------------------------------------------------------------------------------------
// detections/<name>/meta.json

fs::path detection_set_meta_path(const fs::path& dataset, const std::string& name) {
  return detections_dir(dataset, name) / "meta.json";
}

io::json detection_set_meta_to_json(const DetectionSetMeta& m) {
  io::json j = m.details.is_object() ? m.details : io::json::object();
  j["producer"] = m.producer;
  j["frames_processed"] = m.frames_processed;
  if (!m.roe_version.empty()) j["roe_version"] = m.roe_version;
  if (m.detections) j["detections"] = *m.detections;
  if (!m.score.empty()) j["score"] = m.score;
  if (!m.sigma.empty()) j["sigma"] = m.sigma;
  return j;
}

DetectionSetMeta detection_set_meta_from_json(const io::json& j, const std::string& source) {
  if (!j.is_object()) throw ConfigError("expected a JSON object (a detection set's meta.json)", {source});
  DetectionSetMeta m;
  io::JsonObject o(j, source);
  o.require("producer", m.producer);
  o.require("frames_processed", m.frames_processed);
  o.get("roe_version", m.roe_version);
  std::size_t n = 0;
  if (o.has("detections")) {
    o.get("detections", n);
    m.detections = n;
  }
  o.get("score", m.score);
  o.get("sigma", m.sigma);
  for (const auto& [key, value] : j.items())
    if (key != "producer" && key != "frames_processed" && key != "roe_version" && key != "detections" &&
        key != "score" && key != "sigma")
      m.details[key] = value;
  return m;
}

void write_detection_set_meta(const fs::path& file, const DetectionSetMeta& m) {
  io::write_file_atomic(file, io::dump_json(detection_set_meta_to_json(m), 2) + "\n");
}

std::optional<DetectionSetMeta> read_detection_set_meta(const fs::path& dataset, const std::string& name) {
  const fs::path file = detection_set_meta_path(dataset, name);
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) return std::nullopt;
  return io::read_json_file(file, detection_set_meta_from_json);
}

}  // namespace roe::store
