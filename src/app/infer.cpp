#include "roe/app/infer.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <map>
#include <set>

#include "roe/app/import_poet.hpp"
#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/infer/bundle.hpp"
#include "roe/infer/cache.hpp"
#include "roe/infer/model.hpp"
#include "roe/infer/pose_head.hpp"
#include "roe/io/csv.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/output.hpp"
#include "roe/version.hpp"

namespace roe::app {
namespace fs = std::filesystem;
namespace {

// External boxes: timestamp_ns,class,x1,y1,x2,y2,score (pixels of the dataset image; score may be empty).
// Classes must be the bundle's: the pose head indexes its class-specific outputs with them.
std::map<Timestamp, std::vector<infer::BoxDetection>> read_boxes_csv(const fs::path& file, const infer::PoetBundle& bundle) {
  std::set<int> ids;
  for (const auto& c : bundle.classes) ids.insert(c.id);
  std::string known;
  if (!ids.empty() && *ids.rbegin() - *ids.begin() + 1 == static_cast<int>(ids.size())) {
    known = std::to_string(*ids.begin()) + ".." + std::to_string(*ids.rbegin());
  } else {
    for (int id : ids) known += (known.empty() ? "" : ", ") + std::to_string(id);
  }
  io::CsvOptions o;
  o.expected_header = {"timestamp_ns|timestamp [ns]|timestamp", "class", "x1", "y1", "x2", "y2", "score"};
  o.stamp_column = 0;
  o.stamp_order = io::StampOrder::kNonDecreasing;
  io::CsvReader r(file, o);
  std::map<Timestamp, std::vector<infer::BoxDetection>> out;
  while (r.next()) {
    infer::BoxDetection b;
    const Timestamp t = r.get_int64(0);
    b.class_id = r.get_int(1);
    if (b.class_id < 1) throw r.error(1, "class must be a 1-based PoET class id");
    if (!ids.count(b.class_id))
      throw r.error(1, "class " + std::to_string(b.class_id) + " is not a class of model " + bundle.model_id + " (its classes: " +
                           known + ")");
    b.x1 = r.get_double(2);
    b.y1 = r.get_double(3);
    b.x2 = r.get_double(4);
    b.y2 = r.get_double(5);
    if (!(b.x2 > b.x1)) throw r.error(4, "x2 must be greater than x1");
    if (!(b.y2 > b.y1)) throw r.error(5, "y2 must be greater than y1");
    b.score = r.get_double_or_nan(6);
    out[t].push_back(b);
  }
  return out;
}

std::string boxes_key(const std::vector<infer::BoxDetection>& boxes) {
  std::string s;
  for (const auto& b : boxes)
    s += fmt::format("{},{},{},{},{},{};", b.class_id, b.x1, b.y1, b.x2, b.y2, b.score);
  return s;
}

}  // namespace

std::pair<std::size_t, std::size_t> parse_frame_range(const std::string& spec, std::size_t n) {
  if (spec.empty()) return {0, n};
  auto num = [&](const std::string& s) -> std::size_t {
    if (s.empty() || s.size() > 12 || s.find_first_not_of("0123456789") != std::string::npos)
      throw InputError("--frames must be A:B with 0-based frame indices (B exclusive), A:, :B or A; got \"" + spec + "\"");
    return static_cast<std::size_t>(std::stoull(s));
  };
  std::size_t a = 0, b = n;
  const auto colon = spec.find(':');
  if (colon == std::string::npos) {
    a = num(spec);
    b = a + 1;
  } else {
    if (colon > 0) a = num(spec.substr(0, colon));
    if (colon + 1 < spec.size()) b = num(spec.substr(colon + 1));
  }
  b = std::min(b, n);
  if (a >= b) throw InputError("--frames " + spec + " selects no frame (the dataset has " + std::to_string(n) + ")");
  return {a, b};
}

nlohmann::json InferSummary::to_json() const {
  return {{"output", output_dir.string()},
          {"cache", cache_file.string()},
          {"model_id", model_id},
          {"config_hash", config_hash},
          {"device", device},
          {"warp", warp},
          {"frames_in_dataset", frames_in_dataset},
          {"frames_selected", frames_selected},
          {"frames_computed", frames_computed},
          {"frames_reused", frames_reused},
          {"detections_written", detections_written},
          {"dropped_unmapped_class", dropped_unmapped_class},
          {"dropped_duplicate_object", dropped_duplicate},
          {"dropped_invalid_pose", dropped_invalid},
          {"mean_ms_computed", mean_ms_computed},
          {"selftest", selftest},
          {"warnings", warnings}};
}

namespace {

using Warn = std::function<void(const std::string&)>;
using BoxesByStamp = std::map<Timestamp, std::vector<infer::BoxDetection>>;

/// Every selected frame must have its image: an InputError naming the first missing one otherwise.
void check_selected_images(const std::vector<CameraFrame>& frames, const std::vector<std::size_t>& sel,
                           const fs::path& img_dir, const fs::path& cam_csv) {
  std::size_t missing = 0;
  const CameraFrame* first_missing = nullptr;
  std::error_code ec;
  for (std::size_t i : sel) {
    if (!frames[i].filename.empty() && fs::is_regular_file(img_dir / frames[i].filename, ec)) continue;
    if (!missing++) first_missing = &frames[i];
  }
  if (!missing) return;
  const std::string what = first_missing->filename.empty()
                               ? "frame " + std::to_string(first_missing->t_ns) + " has no image file name"
                               : "frame " + std::to_string(first_missing->t_ns) + ": " +
                                     (img_dir / first_missing->filename).string() + " is missing";
  throw InputError(std::to_string(missing) + " of the " + std::to_string(sel.size()) + " selected frame(s) have no image (" +
                       what + "); a dataset without images (e.g. from roe simulate) cannot be inferred",
                   {cam_csv.string()});
}

/// The external boxes against the frames: none matching a selected frame is an error, boxes at stamps of no
/// frame a warning.
void check_boxes_match(const BoxesByStamp& ext, const std::vector<CameraFrame>& frames,
                       const std::vector<std::size_t>& sel, const fs::path& cam_csv, const std::string& boxes_file,
                       const Warn& warn) {
  std::set<Timestamp> in_dataset, selected;
  for (const auto& f : frames) in_dataset.insert(f.t_ns);
  for (std::size_t i : sel) selected.insert(frames[i].t_ns);
  std::size_t stamps_unknown = 0, rows_unknown = 0, stamps_selected = 0, stamps_elsewhere = 0;
  for (const auto& [t, b] : ext) {
    if (selected.count(t)) ++stamps_selected;
    else if (in_dataset.count(t)) ++stamps_elsewhere;
    else {
      ++stamps_unknown;
      rows_unknown += b.size();
    }
  }
  if (ext.empty()) throw InputError("the boxes file has no rows: no frame would get a detection", {boxes_file});
  if (stamps_selected == 0) {
    std::string msg = "none of the " + std::to_string(ext.size()) + " timestamp(s) of the boxes matches " +
                      (sel.size() < frames.size() ? "a selected frame" : "a frame of the dataset");
    if (stamps_elsewhere)
      msg += " (" + std::to_string(stamps_elsewhere) + " match frames outside --frames/--every)";
    else
      msg += "; the boxes span " + std::to_string(ext.begin()->first) + ".." + std::to_string(ext.rbegin()->first) +
             " ns, the frames " + std::to_string(frames.front().t_ns) + ".." + std::to_string(frames.back().t_ns) +
             " ns (timestamp_ns must equal the stamps of " + cam_csv.filename().string() + ")";
    throw InputError(msg, {boxes_file});
  }
  if (stamps_unknown)
    warn(std::to_string(rows_unknown) + " box(es) at " + std::to_string(stamps_unknown) + " timestamp(s) of " + boxes_file +
         " match no frame of the dataset and were ignored");
}

/// The camera the model warps from: roe.json's, or (without one) the size of the first selected image.
void set_model_camera(infer::PoetModel& model, const DatasetManifest& manifest, const fs::path& dataset,
                      const fs::path& first_image, const Warn& warn) {
  if (manifest.camera && manifest.camera->width > 0) {
    const auto& c = *manifest.camera;
    if (c.distortion_model != "none" && !c.distortion.empty() &&
        std::any_of(c.distortion.begin(), c.distortion.end(), [](double d) { return d != 0.0; }))
      warn("roe.json's camera has distortion " + c.distortion_model + "; roe infer assumes undistorted (processed) images");
    model.set_camera(c.width, c.height, infer::Intrinsics{c.fx, c.fy, c.cx, c.cy});
    return;
  }
  const std::string bytes = io::read_file(first_image);
  const infer::HostTensor probe = [&] {
    try {
      return model.preprocess(bytes, first_image.string());
    } catch (const InputError&) {
      throw InputError("roe.json has no camera and the images are not at the model's size; add the camera intrinsics so "
                       "that roe can warp them", {store::manifest_path(dataset).string()});
    }
  }();
  model.set_camera(static_cast<int>(probe.shape[3]), static_cast<int>(probe.shape[2]), std::nullopt);
  warn("roe.json has no camera: the images are used as they are (no virtual-camera warp)");
}

/// What shapes the output besides the images: every file of the bundle that matters, the camera/warp and
/// the device. Its hash names the cache.
nlohmann::json output_config(const infer::PoetBundle& bundle, const infer::PoetModel& model, const InferOptions& opt) {
  nlohmann::json cfg = {{"bundle_manifest_sha256", io::sha256_hex(io::dump_json(bundle.manifest))},
                        {"pose_head_sha256", io::sha256_file(bundle.pose.file)},
                        {"camera", model.camera_json()},
                        {"device", opt.device == "auto" ? std::string("auto") : opt.device},
                        {"external_boxes", !opt.boxes_file.empty()},
                        {"cache_schema", infer::kCacheSchema}};
  if (bundle.detector == infer::DetectorKind::kDarknet) {
    cfg["detector_cfg_sha256"] = io::sha256_file(bundle.darknet.cfg);
    cfg["detector_weights_sha256"] = io::sha256_file(bundle.darknet.weights);
  }
  return cfg;
}

/// Class names indexed by PoET class id (gaps empty), for the mapping to dataset objects.
std::vector<std::string> class_names_by_id(const infer::PoetBundle& bundle) {
  std::vector<std::string> names;
  for (const auto& c : bundle.classes) {
    if (static_cast<std::size_t>(c.id) >= names.size()) names.resize(static_cast<std::size_t>(c.id) + 1);
    names[static_cast<std::size_t>(c.id)] = c.name;
  }
  return names;
}

/// The detections of all selected frames and what the loop counted.
struct FrameResults {
  std::vector<Detection> detections;
  nlohmann::json per_frame = nlohmann::json::array();
  std::vector<double> computed_ms;
  ClassMapper::Dropped dropped;  ///< detections without an object, second detections of one
};

/// One frame's cache entry: reused when the cache has its key, computed (and appended) otherwise.
infer::CachedFrame frame_entry(infer::PoetModel& model, infer::DetectionCache& cache, const CameraFrame& f,
                               const fs::path& img, const BoxesByStamp* ext, bool use_cache, bool& reused) {
  const std::string bytes = io::read_file(img);
  std::string key = io::sha256_hex(bytes);
  const std::vector<infer::BoxDetection>* boxes = nullptr;
  static const std::vector<infer::BoxDetection> kNone;
  if (ext) {
    auto it = ext->find(f.t_ns);
    boxes = it == ext->end() ? &kNone : &it->second;
    key = io::sha256_hex(key + "|" + boxes_key(*boxes));
  }
  const infer::CachedFrame* hit = use_cache ? cache.find(key) : nullptr;
  reused = hit != nullptr;
  if (hit) return *hit;
  const auto r = model.infer(bytes, boxes, img.string());
  infer::CachedFrame cf;
  cf.key = key;
  cf.t_ns = f.t_ns;
  cf.ms = r.timings.total_ms;
  cf.detections = r.detections;
  cf.dropped_invalid = r.dropped_invalid;
  cache.append(cf);
  return cf;
}

/// The frame's detections mapped to dataset objects (one per object, the first, i.e. highest-scoring).
void map_frame_detections(const infer::CachedFrame& cf, Timestamp t_ns, ClassMapper& mapper, FrameResults& r) {
  std::set<int> seen;
  for (const auto& d : cf.detections) {
    const auto obj = mapper.frame_object(d.class_id, seen, r.dropped);
    if (!obj) continue;
    Detection det;
    det.t_ns = t_ns;
    det.object_id = *obj;
    det.T_C_O = d.T_C_O;
    det.score = d.score;
    det.sigma = d.sigma;
    r.detections.push_back(det);
  }
}

struct FrameLoop {
  infer::PoetModel& model;
  infer::DetectionCache& cache;
  ClassMapper& mapper;
  const BoxesByStamp* ext;  ///< external boxes, or null
  bool use_cache;
};

FrameResults infer_frames(const FrameLoop& loop, const std::vector<CameraFrame>& frames,
                          const std::vector<std::size_t>& sel, const fs::path& img_dir, InferSummary& s,
                          const ProgressCallback& progress) {
  FrameResults r;
  if (progress) progress(0, sel.size());
  for (std::size_t k = 0; k < sel.size(); ++k) {
    const CameraFrame& f = frames[sel[k]];
    bool reused = false;
    const infer::CachedFrame cf =
        frame_entry(loop.model, loop.cache, f, img_dir / f.filename, loop.ext, loop.use_cache, reused);
    if (reused) {
      ++s.frames_reused;
    } else {
      r.computed_ms.push_back(cf.ms);
      ++s.frames_computed;
    }
    s.dropped_invalid += cf.dropped_invalid;
    map_frame_detections(cf, f.t_ns, loop.mapper, r);
    r.per_frame.push_back({{"t_ns", f.t_ns}, {"ms", cf.ms}, {"cached", reused}, {"detections", cf.detections.size()}});
    if (progress) progress(k + 1, sel.size());
  }
  return r;
}

/// The warnings about what the loop dropped.
void warn_dropped(const FrameResults& r, const InferSummary& s, const infer::PoetBundle& bundle, const Warn& warn) {
  for (const auto& [c, n] : r.dropped.unmapped_by_class)
    warn(std::to_string(n) + " detection(s) of class " + std::to_string(c) + " (" + bundle.class_name(c) +
         ") map to no object of roe.json and were dropped");
  if (s.dropped_invalid)
    warn(std::to_string(s.dropped_invalid) +
         " pose(s) the model returned with a degenerate rotation or a non-finite translation were dropped");
  if (s.dropped_duplicate)
    warn(std::to_string(s.dropped_duplicate) + " repeated detection(s) of an object in one frame dropped (the highest score is kept)");
}

/// detections/<name>/meta.json.
store::DetectionSetMeta detection_set_meta(const InferSummary& s, const InferOptions& opt, const infer::PoetBundle& bundle,
                                           const infer::PoetModel& model, const nlohmann::json& cfg,
                                           const ClassMapper& mapper, const FrameResults& r,
                                           std::size_t frames_processed) {
  nlohmann::json class_map = nlohmann::json::object();
  for (const auto& [c, o] : mapper.used()) class_map[std::to_string(c)] = o;
  store::DetectionSetMeta meta;
  meta.producer = "roe infer";
  meta.roe_version = kVersion;
  meta.frames_processed = frames_processed;
  meta.score = "detector confidence (objectness x class probability) of the box the pose belongs to";
  meta.details = {{"model",
                   {{"model_id", bundle.model_id},
                    {"bundle", fs::absolute(opt.model_dir).lexically_normal().string()},
                    {"provenance", bundle.provenance},
                    {"libtorch", infer::PoseHead::runtime_version()},
                    {"device", s.device},
                    {"pose_head_optimized", model.pose_head_optimized()},
                    {"cpu_threads", infer::PoseHead::threads()}}},
                  {"config_hash", s.config_hash},
                  {"config", cfg},
                  {"options",
                   {{"frames", opt.frames}, {"every", opt.every}, {"warp", opt.warp}, {"boxes", opt.boxes_file},
                    {"class_map", opt.class_map_file}, {"use_cache", opt.use_cache}, {"threads", opt.threads}}},
                  {"class_map", class_map},
                  {"selftest", s.selftest},
                  {"frames_computed", s.frames_computed},
                  {"frames_reused", s.frames_reused},
                  {"mean_ms_computed", s.mean_ms_computed},
                  {"per_frame", r.per_frame},
                  {"warnings", s.warnings}};
  return meta;
}

/// The output set's name, checked: a plain folder name.
std::string detection_set_name(const InferOptions& opt, const infer::PoetBundle& bundle) {
  const std::string name = opt.name.empty() ? bundle.model_id : opt.name;
  if (!io::is_plain_name(name)) throw InputError("--name must be a plain folder name, got \"" + name + "\"");
  return name;
}

/// What can be refused before the bundle is read.
void check_options(const InferOptions& opt) {
  if (opt.every < 1) throw InputError("--every must be at least 1");
  if (opt.model_dir.empty()) throw InputError("--model BUNDLE_DIR is required");
}

/// What can be refused once the bundle is read, before the model is loaded.
void check_bundle_usable(const infer::PoetBundle& bundle, const InferOptions& opt) {
  if (!infer::PoseHead::available())
    throw InputError("this roe was built without LibTorch, so `roe infer` cannot run PoET; rebuild with libtorch-dev "
                     "(cmake -DROE_WITH_TORCH=ON), or run PoET's own inference and `roe import poet`");
  if (bundle.detector == infer::DetectorKind::kExternal && opt.boxes_file.empty())
    throw InputError("model " + bundle.model_id + " has an external detector: give the boxes with --boxes FILE");
}

}  // namespace

InferSummary run_infer(const fs::path& dataset, const InferOptions& opt, const ProgressCallback& progress) {
  InferSummary s;
  const Warn warn = [&s](const std::string& w) {
    log::warn("{}", w);
    s.warnings.push_back(w);
  };
  check_options(opt);
  DatasetManifest manifest = store::read_manifest(dataset);
  const fs::path cam_csv = store::cam_csv_path(dataset);
  if (!io::path_exists(cam_csv)) throw InputError("the dataset has no frames (missing " + cam_csv.string() + ")", {dataset.string()});
  const std::vector<CameraFrame> frames = store::read_cam_csv(cam_csv);
  s.frames_in_dataset = frames.size();
  if (frames.empty()) throw InputError("the dataset has no frames", {cam_csv.string()});

  infer::PoetBundle bundle = infer::read_bundle(opt.model_dir);
  const std::string name = detection_set_name(opt, bundle);
  check_bundle_usable(bundle, opt);
  // The output set: an existing one is refused (without --force) before any frame is computed; the
  // folder itself is created only at the end (an interrupted run leaves no temporary folder).
  io::OutputDir::check(store::detections_dir(dataset, name), opt.force, {opt.model_dir, opt.boxes_file});

  // Selection, and everything that can be checked before the model is loaded and a frame computed.
  const auto [first, last] = parse_frame_range(opt.frames, frames.size());
  std::vector<std::size_t> sel;
  for (std::size_t i = first; i < last; i += static_cast<std::size_t>(opt.every)) sel.push_back(i);
  s.frames_selected = sel.size();
  const fs::path img_dir = store::cam_image_dir(dataset);
  check_selected_images(frames, sel, img_dir, cam_csv);
  BoxesByStamp ext;
  if (!opt.boxes_file.empty()) {
    ext = read_boxes_csv(opt.boxes_file, bundle);
    check_boxes_match(ext, frames, sel, cam_csv, opt.boxes_file, warn);
  }

  infer::ModelOptions mo;
  mo.warp = opt.warp;
  mo.device = opt.device;
  mo.tuning.threads = opt.threads;
  infer::PoetModel model(bundle, mo);
  s.model_id = bundle.model_id;
  s.selftest = model.selftest_report().to_json();
  s.device = model.device();
  set_model_camera(model, manifest, dataset, sel.empty() ? fs::path() : img_dir / frames[sel.front()].filename, warn);
  s.warp = model.warping();

  const nlohmann::json cfg = output_config(bundle, model, opt);
  s.config_hash = io::sha256_hex(io::dump_json(cfg)).substr(0, 16);
  infer::DetectionCache cache(dataset / "cache" / "infer" / bundle.model_id / s.config_hash / "frames.jsonl", bundle.model_id,
                              s.config_hash);
  s.cache_file = cache.file();
  ClassMapper mapper(manifest, class_names_by_id(bundle), opt.class_map_file, store::manifest_path(dataset).string());
  if (mapper.identity()) warn("roe.json lists no objects: object ids are the model's class ids");

  const FrameLoop loop{model, cache, mapper, opt.boxes_file.empty() ? nullptr : &ext, opt.use_cache};
  const FrameResults r = infer_frames(loop, frames, sel, img_dir, s, progress);
  s.dropped_unmapped_class = r.dropped.unmapped;
  s.dropped_duplicate = r.dropped.duplicate;
  cache.compact();  // one line per frame: entries recomputed by this run (--no-cache) replace the old ones
  warn_dropped(r, s, bundle, warn);
  s.detections_written = r.detections.size();
  double sum = 0;
  for (double v : r.computed_ms) sum += v;
  s.mean_ms_computed = r.computed_ms.empty() ? 0.0 : sum / static_cast<double>(r.computed_ms.size());

  io::OutputDir dir(store::detections_dir(dataset, name), opt.force, {opt.model_dir, opt.boxes_file});
  store::write_detections_csv(dir.file("detections.csv"), r.detections);
  store::write_detection_set_meta(dir.file("meta.json"),
                                  detection_set_meta(s, opt, bundle, model, cfg, mapper, r, sel.size()));
  dir.commit();
  s.output_dir = dir.final_dir();
  return s;
}

}  // namespace roe::app
