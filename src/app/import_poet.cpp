#include "roe/app/import_poet.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <functional>
#include <set>

#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"
#include "roe/io/poet_results.hpp"
#include "roe/version.hpp"

namespace roe::app {
namespace fs = std::filesystem;
namespace {

// "002_Master_Chef_Can" and "master_chef_can" compare equal: lower case, leading "NNN_" removed.
std::string normalize_name(const std::string& s) {
  std::size_t i = 0;
  while (i < s.size() && std::isdigit(static_cast<unsigned char>(s[i]))) ++i;
  std::string out = (i > 0 && i < s.size() && s[i] == '_') ? s.substr(i + 1) : s;
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

bool all_digits(const std::string& s) {
  return !s.empty() && s.size() <= 19 && std::all_of(s.begin(), s.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); });
}

std::map<int, int> read_class_map(const fs::path& file) {
  const io::json j = io::parse_json_file(file);
  if (!j.is_object()) throw ConfigError("a class map must be an object {\"<poet class>\": <object id>}", {file.string()});
  std::map<int, int> m;
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string& k = it.key();
    if (!all_digits(k) || k.size() > 6) throw ConfigError("class-map keys must be PoET class ids (\"5\")", {file.string(), 0, 0, k});
    if (!it->is_number_integer()) throw ConfigError("class-map values must be integer object ids", {file.string(), 0, 0, k});
    m[std::stoi(k)] = it->get<int>();
  }
  return m;
}

}  // namespace

bool same_object_name(const std::string& a, const std::string& b) { return normalize_name(a) == normalize_name(b); }

ClassMapper::ClassMapper(const DatasetManifest& manifest, std::vector<std::string> class_names, const std::string& class_map_file,
                         std::string manifest_file)
    : manifest_(manifest), names_(std::move(class_names)), manifest_file_(std::move(manifest_file)) {
  if (!class_map_file.empty()) {
    explicit_ = true;
    explicit_map_ = read_class_map(class_map_file);
    // A map onto objects roe.json does not declare would only fail later, in roe run.
    if (!manifest.objects.empty()) {
      std::set<int> declared;
      for (const auto& o : manifest.objects) declared.insert(o.id);
      for (const auto& [cls, id] : explicit_map_)
        if (!declared.count(id))
          throw ConfigError(fmt::format("class {} is mapped to object id {}, which {} does not declare (objects: {})",
                                        cls, id, manifest_file_.empty() ? "roe.json" : manifest_file_,
                                        fmt::join(declared, ", ")),
                            {class_map_file, 0, 0, std::to_string(cls)});
    }
  } else if (!manifest.objects.empty()) {
    by_name_ = true;
  } else {
    identity_ = true;
  }
}

std::optional<int> ClassMapper::frame_object(int poet_class, std::set<int>& frame_objects, Dropped& dropped) {
  const auto obj = object_of(poet_class);
  if (!obj) {
    ++dropped.unmapped;
    ++dropped.unmapped_by_class[poet_class];
    return std::nullopt;
  }
  if (!frame_objects.insert(*obj).second) {
    ++dropped.duplicate;
    return std::nullopt;
  }
  return obj;
}

std::optional<int> ClassMapper::object_of(int cls) {
  auto it = resolved_.find(cls);
  if (it != resolved_.end()) return it->second;
  std::optional<int> id;
  if (explicit_) {
    auto e = explicit_map_.find(cls);
    if (e != explicit_map_.end()) id = e->second;
  } else if (by_name_) {
    const std::string cname = cls >= 0 && static_cast<std::size_t>(cls) < names_.size() ? names_[static_cast<std::size_t>(cls)] : "";
    if (!cname.empty()) {
      for (const auto& o : manifest_.objects) {
        if (!o.name.empty() && same_object_name(o.name, cname)) {
          if (id)
            throw InputError("class " + std::to_string(cls) + " (" + cname + ") matches several objects of roe.json by name; pass --class-map",
                             {manifest_file_});
          id = o.id;
        }
      }
    }
  } else {
    id = cls;
  }
  resolved_[cls] = id;
  if (id) used_[cls] = *id;
  return id;
}

nlohmann::json ImportPoetSummary::to_json() const {
  nlohmann::json cm = nlohmann::json::object();
  for (const auto& [c, o] : class_map) cm[std::to_string(c)] = o;
  return {{"output", output_dir.string()},
          {"images_in_file", images_in_file},
          {"images_matched", images_matched},
          {"images_unknown", images_unknown},
          {"unknown_ids", unknown_ids},
          {"empty_images", empty_images},
          {"detections_in_file", detections_in_file},
          {"detections_written", detections_written},
          {"dropped_non_finite", dropped_non_finite},
          {"dropped_unmapped_class", dropped_unmapped_class},
          {"dropped_duplicate_object", dropped_duplicate},
          {"quaternion_rotations", quaternion_rotations},
          {"sigma_from_log_variances", sigma_from_log_variances},
          {"sigma_from_covariance", sigma_from_covariance},
          {"max_abs_correlation_dropped", max_abs_correlation_dropped},
          {"class_map", cm},
          {"warnings", warnings}};
}

namespace {

using Warn = std::function<void(const std::string&)>;
/// The results' images that denote a frame of the dataset, with the frame's stamp, sorted by time.
using MatchedImages = std::vector<std::pair<Timestamp, const io::PoetImageResult*>>;

/// Image ids → frames: by cam.csv's stamp, file name or PoET's image id; without cam.csv ids are ns
/// stamps. Two ids for one frame, or one id for two frames, are input errors; unknown ids are skipped.
MatchedImages match_images(const io::PoetResults& results, const fs::path& results_json, const fs::path& dataset,
                           ImportPoetSummary& s, const Warn& warn) {
  const fs::path cam_csv = store::cam_csv_path(dataset);
  const bool have_frames = io::path_exists(cam_csv);
  std::vector<CameraFrame> frames;
  if (have_frames) frames = store::read_cam_csv(cam_csv);
  // key → frame indices it may denote (a set: one frame may offer the same key by several rules).
  std::map<std::string, std::set<std::size_t>> by_key;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    by_key[std::to_string(frames[i].t_ns)].insert(i);
    if (!frames[i].filename.empty()) {
      by_key[io::poet_image_id(frames[i].filename)].insert(i);
      by_key[fs::path(frames[i].filename).stem().string()].insert(i);
    }
  }
  if (!have_frames) warn(cam_csv.string() + " does not exist: image ids are taken as ns timestamps");

  std::map<Timestamp, std::pair<std::string, std::int64_t>> used;  // frame stamp → (id, line)
  MatchedImages matched;
  s.images_in_file = results.images.size();
  for (const auto& img : results.images) {
    Timestamp t_ns = 0;
    bool found = false;
    if (have_frames) {
      auto it = by_key.find(img.id);
      if (it != by_key.end()) {
        if (it->second.size() > 1) {
          std::string names;
          for (std::size_t i : it->second) names += (names.empty() ? "" : ", ") + frames[i].filename;
          throw InputError("image id \"" + img.id + "\" matches several frames of " + cam_csv.string() + " (" + names +
                               "); PoET overwrites colliding ids, so the frame of this entry is unknown",
                           {results_json.string(), img.line, img.column, img.id});
        }
        t_ns = frames[*it->second.begin()].t_ns;
        found = true;
      }
    } else if (all_digits(img.id)) {
      try {
        t_ns = std::stoll(img.id);
        found = true;
      } catch (const std::out_of_range&) {
      }
    }
    if (!found) {
      ++s.images_unknown;
      if (s.unknown_ids.size() < 10) s.unknown_ids.push_back(img.id);
      continue;
    }
    auto [uit, inserted] = used.emplace(t_ns, std::make_pair(img.id, img.line));
    if (!inserted)
      throw InputError("image ids \"" + uit->second.first + "\" (line " + std::to_string(uit->second.second) +
                           ") and \"" + img.id + "\" denote the same frame " + std::to_string(t_ns),
                       {results_json.string(), img.line, img.column, img.id});
    matched.emplace_back(t_ns, &img);
  }
  s.images_matched = matched.size();
  if (s.images_unknown > 0) {
    std::string ids;
    for (const auto& u : s.unknown_ids) ids += (ids.empty() ? "" : ", ") + u;
    warn(std::to_string(s.images_unknown) + " image id(s) of " + results_json.string() + " match no frame and were skipped (" +
         ids + (s.images_unknown > s.unknown_ids.size() ? ", ..." : "") + ")");
  }
  if (results.images.empty())  // images with no detection are kept ("ran, found nothing"); no image at all is not a result
    throw InputError("the file lists no image: nothing to import (PoET's results.json has one entry per image)",
                     {results_json.string()});
  if (matched.empty())
    throw InputError("none of the " + std::to_string(results.images.size()) + " image ids matches a frame of " +
                         (have_frames ? cam_csv.string() : std::string("the dataset (ids must be ns timestamps)")) +
                         " (first: \"" + results.images.front().id + "\")",
                     {results_json.string()});
  std::sort(matched.begin(), matched.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  return matched;
}

/// The matched images' detections as roe detections: classes mapped to objects (one per object and
/// frame), non-finite entries dropped, σ from PoET's uncertainty; counts in `s`.
std::vector<Detection> convert_detections(const MatchedImages& matched, ClassMapper& mapper, ImportPoetSummary& s,
                                          ClassMapper::Dropped& dropped) {
  std::vector<Detection> out;
  for (const auto& [t_ns, img] : matched) {
    if (img->detections.empty()) ++s.empty_images;
    std::set<int> seen;
    for (const auto& d : img->detections) {
      ++s.detections_in_file;
      if (d.rot_was_quaternion) ++s.quaternion_rotations;
      if (!d.finite) {
        ++s.dropped_non_finite;
        continue;
      }
      const auto obj = mapper.frame_object(d.class_id, seen, dropped);
      if (!obj) continue;
      Detection det;
      det.t_ns = t_ns;
      det.object_id = *obj;
      det.T_C_O = Pose(Eigen::Matrix3d(d.R_C_O), d.t);
      if (d.score) det.score = *d.score;
      det.sigma = d.sigma;
      if (d.uncertainty == io::PoetRawDetection::Uncertainty::kLogVariance) ++s.sigma_from_log_variances;
      if (d.uncertainty == io::PoetRawDetection::Uncertainty::kCovariance) {
        ++s.sigma_from_covariance;
        s.max_abs_correlation_dropped = std::max(s.max_abs_correlation_dropped, d.max_abs_correlation);
      }
      out.push_back(det);
    }
  }
  s.dropped_unmapped_class = dropped.unmapped;
  s.dropped_duplicate = dropped.duplicate;
  s.class_map = mapper.used();
  s.detections_written = out.size();
  return out;
}

/// What the conversion dropped or could not carry, said once each (and no class matching by name at all
/// is an error: nothing would be imported).
void conversion_warnings(const ImportPoetSummary& s, const ClassMapper& mapper, const ClassMapper::Dropped& dropped,
                         const DatasetManifest& manifest, const fs::path& dataset, const Warn& warn) {
  if (mapper.by_name() && s.class_map.empty() && s.dropped_unmapped_class > 0)
    throw InputError("no PoET class matches an object of roe.json by name (objects: " +
                         std::to_string(manifest.objects.size()) + "); pass --class-map FILE or --classes FILE",
                     {store::manifest_path(dataset).string()});
  if (s.dropped_non_finite) warn(std::to_string(s.dropped_non_finite) + " detection(s) with non-finite t or rot (NaN/Infinity) dropped");
  for (const auto& [c, n] : dropped.unmapped_by_class)
    warn(std::to_string(n) + " detection(s) of PoET class " + std::to_string(c) + " map to no object and were dropped");
  if (s.dropped_duplicate)
    warn(std::to_string(s.dropped_duplicate) + " repeated detection(s) of an object in one frame dropped (the first, highest detector score, is kept)");
  const std::size_t with_sigma = s.sigma_from_log_variances + s.sigma_from_covariance;
  const std::size_t n = s.detections_written;
  if (with_sigma > 0 && with_sigma < n)
    warn(std::to_string(n - with_sigma) + " of " + std::to_string(n) +
         " written detection(s) carry no uncertainty (empty sigma columns): the filter uses its fixed σ for them");
  if (s.sigma_from_covariance > 0 && s.max_abs_correlation_dropped > 0.1)
    warn(fmt::format("the covariances have correlations up to |ρ| = {:.3f} between axes; the sigma columns keep "
                     "each axis's marginal σ and drop them (docs/import.md, \"PoET uncertainty\")",
                     s.max_abs_correlation_dropped));
}

/// Writes the detection set (detections.csv, meta.json) and records the import in roe.json, replacing
/// an earlier import under the same name; both change together or neither does.
void write_import(const fs::path& results_json, const fs::path& dataset, const ImportPoetOptions& opt,
                  DatasetManifest& manifest, const std::vector<Detection>& out, ImportPoetSummary& s) {
  const std::string sha = io::sha256_file(results_json);
  io::OutputDir dir(store::detections_dir(dataset, opt.name), opt.force, {results_json});
  store::write_detections_csv(dir.file("detections.csv"), out);
  store::DetectionSetMeta meta;
  meta.producer = "roe import poet";
  meta.roe_version = kVersion;
  meta.frames_processed = s.images_matched;
  meta.score = "empty: PoET's results.json has no detection score";
  meta.sigma = s.sigma_from_log_variances + s.sigma_from_covariance == 0
                   ? "none: the entries carry no uncertainty"
                   : "camera frame, m and rad (rotation error about the camera axes, R_meas = Exp(n) R); "
                     "sigma = exp(s/2) of PoET's aleatoric log-variances s = log(sigma^2), or sqrt of a 6x6 "
                     "covariance's diagonal (its correlations dropped)";
  meta.details = {
      {"source", {{"path", results_json.string()}, {"sha256", sha}, {"format", "poet results.json"}}},
      {"options",
       {{"name", opt.name}, {"rotation", opt.rotation}, {"classes", opt.classes_file}, {"class_map", opt.class_map_file}}},
      {"summary", s.to_json()}};
  meta.details["summary"].erase("output");
  store::write_detection_set_meta(dir.file("meta.json"), meta);

  // Record the import in roe.json (replacing an earlier import into the same detections name).
  SourceRecord rec;
  rec.kind = "poet";
  rec.path = io::provenance_path(results_json);
  rec.sha256 = sha;
  rec.options = {{"name", opt.name}, {"rotation", opt.rotation}};
  if (!opt.classes_file.empty()) rec.options["classes"] = opt.classes_file;
  if (!opt.class_map_file.empty()) rec.options["class_map"] = opt.class_map_file;
  auto& src = manifest.sources;
  src.erase(std::remove_if(src.begin(), src.end(),
                           [&](const SourceRecord& r) {
                             auto it = r.options.find("name");
                             return r.kind == "poet" && it != r.options.end() && it->second == opt.name;
                           }),
            src.end());
  src.push_back(rec);
  // The detections folder and roe.json change together: roe.json is written (staged) first, so a
  // failure there leaves both as they were; then the folder is moved into place and roe.json after it.
  io::StagedFiles staged;
  store::write_manifest(manifest, staged.stage(store::manifest_path(dataset)));
  {
    const io::DeferSignals defer;  // a Ctrl-C waits until both are in place
    dir.commit();
    staged.commit();
  }
  s.output_dir = dir.final_dir();
}

}  // namespace

ImportPoetSummary import_poet(const fs::path& results_json, const fs::path& dataset, const ImportPoetOptions& opt) {
  if (!io::is_plain_name(opt.name))
    throw InputError("--name must be a plain folder name, got \"" + opt.name + "\"");
  const auto rot_format = io::parse_poet_rotation_format(opt.rotation, "--rotation");
  DatasetManifest manifest = store::read_manifest(dataset);  // checks that the dataset is there
  // roe.json is read again under the dataset's lock before it is changed (a concurrent import).
  const io::FolderLock lock(dataset);
  manifest = store::read_manifest(dataset);
  const io::PoetResults results = io::read_poet_results(results_json, rot_format);

  ImportPoetSummary s;
  const Warn warn = [&s](const std::string& w) {
    log::warn("{}", w);
    s.warnings.push_back(w);
  };
  const MatchedImages matched = match_images(results, results_json, dataset, s, warn);
  ClassMapper mapper(manifest, opt.classes_file.empty() ? io::ycbv_class_names() : io::read_poet_class_names(opt.classes_file),
                     opt.class_map_file, store::manifest_path(dataset).string());
  if (mapper.identity()) warn("roe.json lists no objects: object ids are PoET's class ids");
  ClassMapper::Dropped dropped;
  const std::vector<Detection> out = convert_detections(matched, mapper, s, dropped);
  conversion_warnings(s, mapper, dropped, manifest, dataset, warn);
  write_import(results_json, dataset, opt, manifest, out, s);
  return s;
}

}  // namespace roe::app
