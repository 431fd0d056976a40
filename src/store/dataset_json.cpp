// roe.json and detections/<name>/meta.json (store/dataset.hpp): one field mapping per block, walked by the
// writer and by the strict reader (json_fields.hpp), so each key is spelled once, here; roe.json's printer
// (a fixed key order, arrays of numbers on one line) is the other thing this file owns.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "json_fields.hpp"
#include "roe/io/input.hpp"
#include "roe/io/models_info.hpp"
#include "roe/io/output.hpp"
#include "roe/io/pose_json.hpp"
#include "roe/store/dataset.hpp"

namespace roe::store {

using io::dump_json;
using io::imu_noise_to_json;
using io::json;
using io::JsonObject;
using io::optional_regular_file;
using io::pose_from_json;
using io::pose_to_json;
using io::read_imu_noise;
using io::read_json_file;
using io::read_models_info;
using io::write_file_atomic;

namespace {

// Tolerance on |‖q‖ − 1| in roe.json (DESIGN §3: unit quaternions).
constexpr double kManifestQuatTol = 1e-6;

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
// roe.json
// -------------------------------------------------------------------------------------------------

namespace {

using json_fields::Problem;

/// roe.json's dialect: strict (an unknown key is an error, with io::JsonObject's hints), an absent or null
/// optional key keeps its default; errors are ConfigErrors naming the file and the key path. Poses are
/// unit to kManifestQuatTol, the IMU noise in io's form.
struct ManifestJson : json_fields::StrictDialect {
  static json write_leaf(const Pose& T) { return pose_to_json(T); }
  static void read_leaf(const json& x, Pose& T, const std::string& file, const std::string& path) {
    T = pose_from_json(x, file, path, {kManifestQuatTol, nullptr});
  }
  static json write_leaf(const ImuNoise& n) { return imu_noise_to_json(n); }
  static void read_leaf(const json& x, ImuNoise& n, const std::string& file, const std::string& path) {
    if (!x.is_object()) fail(file, path, Problem::kNotObject, {});
    JsonObject o(x, file, path);
    read_imu_noise(o, n);
    o.finish();
  }
};

/// The rule of a rate, a size or a focal length (a NaN is refused too).
const auto positive = [](const auto& v) { return std::string(v > 0 ? "" : "must be > 0"); };

template <class A>
void fields(A& a, SourceRecord& s) {
  a("kind", s.kind), a.opt("path", s.path), a.opt("sha256", s.sha256), a.opt("options", s.options);
}

template <class A>
void fields(A& a, ImuInfo& imu) {
  a("rate_hz", imu.rate_hz, positive);
  a.merge([&](json& j) { j.update(imu_noise_to_json(imu.noise)); }, [&](JsonObject& o) { read_imu_noise(o, imu.noise); });
}

template <class A>
void fields(A& a, CameraInfo& c) {
  a("width", c.width, positive), a("height", c.height, positive), a("fx", c.fx, positive), a("fy", c.fy, positive);
  a("cx", c.cx), a("cy", c.cy), a.opt("distortion_model", c.distortion_model);
  a.opt("distortion", c.distortion, true, [&](const std::vector<double>& d) {
    return std::string(c.distortion_model != "none" || d.empty() ? "" : "distortion coefficients given for distortion_model 'none'");
  });
  a.opt("T_I_C", c.T_I_C), a.opt("time_offset_s", c.time_offset_s);
}

template <class A>
void fields(A& a, MocapInfo& mc) {
  a.opt("body", mc.body), a.opt("T_B_I", mc.T_B_I), a.opt("time_offset_s", mc.time_offset_s);
}

/// The symmetries of an object's models_info (relative to the folder of roe.json `file`), at its id there.
void read_symmetry(ObjectInfo& obj, const std::string& file, const std::string& models_info_path,
                   const std::string& models_info_id_path) {
  if (!obj.models_info.empty()) {
    const fs::path info_file = fs::path(file).parent_path() / obj.models_info;
    const auto info = read_models_info(info_file);
    const int key = obj.models_info_id >= 0 ? obj.models_info_id : obj.id;
    const auto it = info.find(key);
    if (it == info.end())
      throw ConfigError(fmt::format("object {} is not in {}", key, info_file.string()),
                        {file, 0, 0, obj.models_info_id >= 0 ? models_info_id_path : models_info_path});
    obj.symmetry = it->second;
  } else if (obj.models_info_id >= 0) {
    throw ConfigError("models_info_id without models_info", {file, 0, 0, models_info_id_path});
  }
}

template <class A>
void fields(A& a, ObjectInfo& o) {
  static constexpr const char* kModelsInfo = "models_info";
  static constexpr const char* kModelsInfoId = "models_info_id";
  a("id", o.id), a.opt("name", o.name), a.opt("symmetric", o.symmetric);
  a.opt(kModelsInfo, o.models_info, !o.models_info.empty());
  a.opt(kModelsInfoId, o.models_info_id, o.models_info_id >= 0);
  if constexpr (A::kReading) read_symmetry(o, a.file(), a.at(kModelsInfo), a.at(kModelsInfoId));
}

template <class A>
void fields(A& a, TruthObject& o) {
  a("id", o.id), a("T_W_O", o.T_W_O);
}

/// An id given twice in the array `key` of objects with an "id": refused at the second one's id.
template <class A, class Object>
void check_unique_ids(A& a, const char* key, const std::vector<Object>& objects) {
  if constexpr (A::kReading) {
    std::set<int> ids;
    for (std::size_t i = 0; i < objects.size(); ++i)
      if (!ids.insert(objects[i].id).second)
        throw ConfigError(fmt::format("duplicate object id {}", objects[i].id),
                          {a.file(), 0, 0, fmt::format("{}[{}].id", a.at(key), i)});
  }
}

template <class A>
void fields(A& a, Truth& t) {
  static constexpr const char* kObjects = "objects";
  a("T_I_C", t.T_I_C);
  // Only when there is one: datasets without a time offset keep the bytes (and readers) they had before.
  a.opt("camera_time_offset_s", t.camera_time_offset_s, t.camera_time_offset_s != 0.0, [](double s) {
    return std::string(std::isfinite(s) ? "" : "must be a finite number of seconds");
  });
  a.opt(kObjects, t.objects);
  check_unique_ids(a, kObjects, t.objects);
  a.omittable("imu_noise", t.imu_noise), a.opt("detection_noise", t.detection_noise);
}

template <class A>
void fields(A& a, DatasetManifest& m) {
  a("schema", m.schema, [](const std::string& s) {
    return s == kDatasetSchema ? std::string() : fmt::format("unsupported schema '{}' (expected '{}')", s, kDatasetSchema);
  });
  a.opt("name", m.name), a.opt("sources", m.sources);
  a.omittable("imu", m.imu), a.omittable("camera", m.camera), a.omittable("mocap", m.mocap);
  static constexpr const char* kObjects = "objects";
  a.opt(kObjects, m.objects);
  check_unique_ids(a, kObjects, m.objects);
  a.omittable("truth", m.truth);
}

}  // namespace

json manifest_to_json(const DatasetManifest& m) { return json_fields::write<ManifestJson>(m); }

DatasetManifest manifest_from_json(const json& j, const std::string& source) {
  DatasetManifest m;
  json_fields::read<ManifestJson>(j, m, source);
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

namespace {

/// meta.json's dialect: the typed keys strictly, the producer's other keys kept as they are (`details`).
struct DetectionSetMetaJson : json_fields::StrictDialect {
  static constexpr bool kStrictKeys = false;  // every other key is the producer's record
};

template <class A>
void fields(A& a, DetectionSetMeta& m) {
  a("producer", m.producer), a("frames_processed", m.frames_processed);
  a.opt("roe_version", m.roe_version, !m.roe_version.empty()), a.omittable("detections", m.detections);
  a.opt("score", m.score, !m.score.empty()), a.opt("sigma", m.sigma, !m.sigma.empty());
  a.rest(m.details);
}

}  // namespace

io::json detection_set_meta_to_json(const DetectionSetMeta& m) { return json_fields::write<DetectionSetMetaJson>(m); }

DetectionSetMeta detection_set_meta_from_json(const io::json& j, const std::string& source) {
  if (!j.is_object()) throw ConfigError("expected a JSON object (a detection set's meta.json)", {source});
  DetectionSetMeta m;
  json_fields::read<DetectionSetMetaJson>(j, m, source);
  return m;
}

void write_detection_set_meta(const fs::path& file, const DetectionSetMeta& m) {
  io::write_file_atomic(file, io::dump_json(detection_set_meta_to_json(m), 2) + "\n");
}


}  // namespace roe::store
