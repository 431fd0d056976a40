#include "roe/infer/bundle.hpp"

#include <cmath>
#include <set>

#include "roe/core/error.hpp"
#include "roe/io/json.hpp"

namespace roe::infer {
namespace {

using io::JsonObject;

[[noreturn]] void bad(const JsonObject& o, const std::string& key, const std::string& msg) {
  throw ConfigError(msg, {o.source(), 0, 0, o.key_path(key)});
}

fs::path existing_file(JsonObject& o, const char* key, const fs::path& dir, bool required) {
  std::string rel;
  if (required) o.require(key, rel);
  else o.get(key, rel);
  if (rel.empty()) {
    if (required) bad(o, key, "must name a file");
    return {};
  }
  const fs::path p = fs::path(rel).is_absolute() ? fs::path(rel) : dir / rel;
  std::error_code ec;
  if (!fs::is_regular_file(p, ec)) bad(o, key, "file not found: " + p.string());
  return p;
}

double positive(JsonObject& o, const char* key) {
  double v = 0;
  o.require(key, v);
  if (!std::isfinite(v) || v <= 0) bad(o, key, "must be a positive number");
  return v;
}

double unit_interval(JsonObject& o, const char* key, double def) {
  double v = def;
  o.get(key, v);
  if (!(v >= 0.0 && v <= 1.0)) bad(o, key, "must be in [0, 1]");
  return v;
}

}  // namespace

std::string PoetBundle::class_name(int id) const {
  for (const auto& c : classes)
    if (c.id == id) return c.name;
  return "";
}

namespace {

void read_image(JsonObject& r, PoetBundle& b) {
  auto im = r.child("image");
  if (!r.has("image")) bad(r, "image", "missing required key");
  im.require("width", b.image.width);
  im.require("height", b.image.height);
  if (b.image.width <= 0 || b.image.width > 16384) bad(im, "width", "must be a positive image width");
  if (b.image.height <= 0 || b.image.height > 16384) bad(im, "height", "must be a positive image height");
  std::string color = "RGB";
  im.get("color", color);
  if (color != "RGB" && color != "BGR") bad(im, "color", "must be \"RGB\" or \"BGR\"");
  b.image.rgb = color == "RGB";
  im.get("scale", b.image.scale);
  if (!std::isfinite(b.image.scale) || b.image.scale <= 0) bad(im, "scale", "must be a positive number");
  std::vector<double> mean{0, 0, 0}, stdv{1, 1, 1};
  im.get("mean", mean);
  im.get("std", stdv);
  if (mean.size() != 3) bad(im, "mean", "must have 3 values (per channel)");
  if (stdv.size() != 3) bad(im, "std", "must have 3 values (per channel)");
  for (int c = 0; c < 3; ++c) {
    if (!std::isfinite(mean[c])) bad(im, "mean", "must be finite");
    if (!std::isfinite(stdv[c]) || stdv[c] <= 0) bad(im, "std", "must be positive");
    b.image.mean[c] = mean[c];
    b.image.std[c] = stdv[c];
  }
  im.finish();
}

void read_train_intrinsics(JsonObject& r, PoetBundle& b) {
  if (!r.has("train_intrinsics")) bad(r, "train_intrinsics", "missing required key");
  auto k = r.child("train_intrinsics");
  b.train_intrinsics.fx = positive(k, "fx");
  b.train_intrinsics.fy = positive(k, "fy");
  k.require("cx", b.train_intrinsics.cx);
  k.require("cy", b.train_intrinsics.cy);
  if (!std::isfinite(b.train_intrinsics.cx)) bad(k, "cx", "must be finite");
  if (!std::isfinite(b.train_intrinsics.cy)) bad(k, "cy", "must be finite");
  k.finish();
}

/// "classes" (1-based, unique ids and names) and "symmetric" (a subset of the ids).
void read_classes(JsonObject& r, PoetBundle& b, const std::string& source) {
  const nlohmann::json* classes = r.raw("classes");
  if (!classes || !classes->is_array() || classes->empty()) bad(r, "classes", "must be a non-empty list of {\"id\", \"name\"}");
  std::set<int> ids;
  std::set<std::string> names;
  for (std::size_t i = 0; i < classes->size(); ++i) {
    JsonObject c((*classes)[i], source, "classes[" + std::to_string(i) + "]");
    BundleClass bc;
    c.require("id", bc.id);
    c.require("name", bc.name);
    c.finish();
    if (bc.id < 1) bad(c, "id", "class ids are 1-based (0 is PoET's background)");
    if (!ids.insert(bc.id).second) bad(c, "id", "duplicate class id " + std::to_string(bc.id));
    if (bc.name.empty()) bad(c, "name", "must not be empty");
    if (!names.insert(bc.name).second) bad(c, "name", "duplicate class name \"" + bc.name + "\"");
    b.classes.push_back(bc);
  }
  r.get("symmetric", b.symmetric);
  for (int s : b.symmetric)
    if (!ids.count(s)) bad(r, "symmetric", "lists " + std::to_string(s) + ", which is not a class id");
}

/// "rotation" and "translation_unit": how the pose head's outputs are read.
void read_output_format(JsonObject& r, PoetBundle& b) {
  std::string rot;
  r.require("rotation", rot);
  const auto rf = parse_rotation_format(rot);
  if (!rf) bad(r, "rotation", "must be \"6d\", \"quat_wxyz\" or \"matrix\", got \"" + rot + "\"");
  b.rotation = *rf;
  std::string unit = "m";
  r.get("translation_unit", unit);
  if (unit == "m") b.translation_scale = 1.0;
  else if (unit == "mm") b.translation_scale = 1e-3;
  else bad(r, "translation_unit", "must be \"m\" or \"mm\"");
}

void read_pose_head(JsonObject& r, PoetBundle& b, const fs::path& dir) {
  if (!r.has("pose")) bad(r, "pose", "missing required key");
  auto p = r.child("pose");
  b.pose.file = existing_file(p, "file", dir, true);
  p.get("torch_version", b.pose.torch_version);
  std::string inputs = "features";
  p.get("inputs", inputs);
  if (inputs == "features") b.pose.inputs = PoseInputs::kFeatures;
  else if (inputs == "image") b.pose.inputs = PoseInputs::kImage;
  else bad(p, "inputs", "must be \"features\" (detector feature maps) or \"image\"");
  p.get("aleatoric", b.pose.aleatoric);
  p.finish();
}

/// detector.selftest of a darknet detector: an image and the tapped layers' reference outputs.
void read_darknet_selftest(JsonObject& d, DarknetSpec& s, const fs::path& dir) {
  auto st = d.child("selftest");
  s.selftest_image = existing_file(st, "image", dir, true);
  auto outs = st.child("outputs");
  const nlohmann::json* raw = st.raw("outputs");
  if (!raw || !raw->is_object() || raw->empty()) bad(st, "outputs", "must map layer names to .npy files");
  for (auto it = raw->begin(); it != raw->end(); ++it) {
    const fs::path f = existing_file(outs, it.key().c_str(), dir, true);
    s.selftest_outputs.emplace_back(it.key(), f);
  }
  if (st.has("detections")) s.selftest_detections = existing_file(st, "detections", dir, true);
  st.get("atol", s.selftest_atol);
  if (!(s.selftest_atol > 0)) bad(st, "atol", "must be positive");
  st.finish();
}

void read_darknet(JsonObject& d, PoetBundle& b, const fs::path& dir, const std::string& source) {
  b.detector = DetectorKind::kDarknet;
  auto& s = b.darknet;
  s.cfg = existing_file(d, "cfg", dir, true);
  s.weights = existing_file(d, "weights", dir, true);
  s.nms.conf_thresh = unit_interval(d, "conf_thresh", 0.4);
  s.nms.iou_thresh = unit_interval(d, "iou_thresh", 0.5);
  int max_det = 300;
  d.get("max_detections", max_det);
  if (max_det < 1) bad(d, "max_detections", "must be at least 1");
  s.nms.max_detections = static_cast<std::size_t>(max_det);
  d.get("multi_label", s.nms.multi_label);
  d.get("class_aware", s.nms.class_aware);
  d.get("class_offset", s.nms.class_offset);
  d.get("feature_layers", s.feature_layers);
  if (b.pose.inputs == PoseInputs::kFeatures && s.feature_layers.empty())
    bad(d, "feature_layers", "must name the tapped layers when pose.inputs is \"features\"");
  if (b.image.width % 32 != 0 || b.image.height % 32 != 0)
    throw ConfigError("a YOLO (darknet) detector needs an image size divisible by 32, got " +
                          std::to_string(b.image.width) + "x" + std::to_string(b.image.height),
                      {source, 0, 0, "image"});
  if (d.has("selftest")) read_darknet_selftest(d, s, dir);
}

void read_detector(JsonObject& r, PoetBundle& b, const fs::path& dir, const std::string& source) {
  if (!r.has("detector")) bad(r, "detector", "missing required key");
  auto d = r.child("detector");
  std::string kind;
  d.require("kind", kind);
  if (kind == "darknet") {
    read_darknet(d, b, dir, source);
  } else if (kind == "external") {
    b.detector = DetectorKind::kExternal;
    if (b.pose.inputs != PoseInputs::kImage)
      throw ConfigError("an external detector gives boxes only: pose.inputs must be \"image\"", {source, 0, 0, "pose.inputs"});
  } else {
    bad(d, "kind", "must be \"darknet\" or \"external\", got \"" + kind + "\"");
  }
  d.finish();
}

/// The pose head's self-test: .npy inputs and outputs, as many as the head's inputs and outputs.
void read_selftest(JsonObject& r, PoetBundle& b, const fs::path& dir) {
  if (!r.has("selftest")) bad(r, "selftest", "missing required key (roe checks the pose head on load)");
  auto st = r.child("selftest");
  const nlohmann::json* in = st.raw("inputs");
  const nlohmann::json* out = st.raw("outputs");
  auto files = [&](const nlohmann::json* list, const char* key) {
    std::vector<fs::path> v;
    if (!list || !list->is_array()) bad(st, key, "must be a list of .npy files");
    for (std::size_t i = 0; i < list->size(); ++i) {
      if (!(*list)[i].is_string()) bad(st, key, "must be a list of .npy files");
      fs::path p = (*list)[i].get<std::string>();
      if (p.is_relative()) p = dir / p;
      std::error_code ec;
      if (!fs::is_regular_file(p, ec)) bad(st, std::string(key) + "[" + std::to_string(i) + "]", "file not found: " + p.string());
      v.push_back(p);
    }
    return v;
  };
  b.selftest.inputs = files(in, "inputs");
  b.selftest.outputs = files(out, "outputs");
  st.get("atol", b.selftest.atol);
  if (!(b.selftest.atol > 0)) bad(st, "atol", "must be positive");
  st.finish();
  const std::size_t n_in = 2 + (b.pose.inputs == PoseInputs::kImage ? 1 : b.darknet.feature_layers.size());
  if (b.selftest.inputs.size() != n_in)
    bad(st, "inputs", "needs " + std::to_string(n_in) + " files (boxes, classes, " +
                          (b.pose.inputs == PoseInputs::kImage ? "image" : "one per feature layer") + ")");
  const std::size_t n_out = b.pose.aleatoric ? 4 : 2;
  if (b.selftest.outputs.size() != n_out)
    bad(st, "outputs", "needs " + std::to_string(n_out) + " files (t, rotation" + (b.pose.aleatoric ? ", logvar_t, logvar_r)" : ")"));
}

}  // namespace

PoetBundle bundle_from_json(const nlohmann::json& j, const fs::path& dir, const std::string& source) {
  PoetBundle b;
  b.dir = dir;
  b.manifest = j;
  JsonObject r(j, source);
  std::string schema;
  r.require("schema", schema);
  if (schema != kBundleSchema)
    bad(r, "schema", "unsupported bundle schema \"" + schema + "\" (this roe reads \"" + kBundleSchema + "\")");
  r.require("model_id", b.model_id);
  if (b.model_id.empty() || b.model_id.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789._-") != std::string::npos ||
      b.model_id[0] == '.')
    bad(r, "model_id", "must be a non-empty name of letters, digits, '.', '_' or '-' (it names cache and output folders)");
  r.get("description", b.description);
  read_image(r, b);
  read_train_intrinsics(r, b);
  r.require("num_queries", b.num_queries);
  if (b.num_queries < 1 || b.num_queries > 1000) bad(r, "num_queries", "must be in 1..1000");
  read_classes(r, b, source);
  read_output_format(r, b);
  read_pose_head(r, b, dir);
  read_detector(r, b, dir, source);
  if (const nlohmann::json* prov = r.raw("provenance")) {
    if (!prov->is_object()) bad(r, "provenance", "must be an object");
    b.provenance = *prov;
  }
  read_selftest(r, b, dir);
  r.finish();
  return b;
}

PoetBundle read_bundle(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw InputError("model bundle folder not found", {dir.string()});
  const fs::path manifest = dir / kBundleManifest;
  if (!fs::is_regular_file(manifest, ec))
    throw InputError(std::string("not a roe model bundle: ") + kBundleManifest + " is missing", {dir.string()});
  return bundle_from_json(io::parse_json_file(manifest), dir, manifest.string());
}

}  // namespace roe::infer
