#pragma once
/// @file
/// `roe import poet RESULTS_JSON --into DATASET [--name poet]`: detections from PoET's own Python
/// inference (its results.json, notes/poet.md §2) → DATASET/detections/<name>/{detections.csv,
/// meta.json}, plus a source record in roe.json.
///
/// Image ids → frames (cam0/data.csv): an id matches a frame when it equals PoET's id of the frame's
/// file name (text between the first '_' and the last '.'), the file's stem, or the frame's ns
/// timestamp. An id matching two frames, or two ids matching one frame, is an InputError (PoET
/// overwrites colliding ids, so which image the entry belongs to is unknown). Ids matching no frame
/// are skipped with a warning (InputError when none matches). Without cam0/data.csv, ids must be ns
/// timestamps.
///
/// Classes → object ids: --class-map FILE ({"<poet class>": <object id>}) when given; otherwise by
/// name (PoET class names from --classes FILE, default YCB-V) against roe.json's objects, ignoring
/// case and a leading "NNN_" number; with no objects in roe.json, object id = PoET class.
///
/// Per frame, detections keep PoET's order (detector score). Dropped with a count: non-finite t/rot
/// (bare NaN tokens), classes with no object, and repeated objects in one frame (the first = highest
/// detector score is kept: detections.csv holds one row per (frame, object)). The score column is
/// left empty: PoET's results.json has no score. Per-detection uncertainty (aleatoric log-variances or a
/// 6x6 covariance, io/poet_results.hpp) goes into the sigma columns (docs/import.md, "PoET uncertainty").

#include <filesystem>
#include <map>
#include <set>
#include <optional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "roe/core/dataset.hpp"

namespace roe::app {

/// PoET class id → dataset object id, shared by `roe import poet` and `roe infer`:
/// an explicit map file ({"<poet class>": <object id>}) when given; otherwise by name against the
/// manifest's objects (case-insensitive, a leading "NNN_" ignored); with no objects in the
/// manifest, the class id itself.
class ClassMapper {
 public:
  /// `class_names[c]` = name of PoET class c ("" unknown). `manifest_file` names roe.json in errors.
  ClassMapper(const DatasetManifest& manifest, std::vector<std::string> class_names, const std::string& class_map_file,
              std::string manifest_file);
  /// nullopt when the class maps to no object. InputError when a name matches several objects.
  std::optional<int> object_of(int poet_class);
  /// The mapping actually used so far.
  const std::map<int, int>& used() const { return used_; }

  /// What the per-frame mapping dropped, over all frames.
  struct Dropped {
    std::size_t unmapped = 0;                  ///< detections whose class maps to no object
    std::size_t duplicate = 0;                 ///< a second detection of an object in one frame
    std::map<int, std::size_t> unmapped_by_class;
  };
  /// The one rule of roe import poet and roe infer for a frame's detections, in the network's order (best
  /// first): the object of class `poet_class`, or nullopt (counted in `dropped`) when the class maps to no
  /// object or `frame_objects` (the objects this frame already has) holds it.
  std::optional<int> frame_object(int poet_class, std::set<int>& frame_objects, Dropped& dropped);
  bool by_name() const { return by_name_; }
  bool identity() const { return identity_; }

 private:
  const DatasetManifest& manifest_;
  std::vector<std::string> names_;
  std::string manifest_file_;
  bool explicit_ = false, by_name_ = false, identity_ = false;
  std::map<int, int> explicit_map_;
  std::map<int, std::optional<int>> resolved_;
  std::map<int, int> used_;
};

/// Case-insensitive name match ignoring a leading "NNN_" ("002_master_chef_can" = "Master_Chef_Can").
bool same_object_name(const std::string& a, const std::string& b);

struct ImportPoetOptions {
  std::string name = "poet";      ///< detections/<name>
  std::string rotation = "auto";  ///< auto | matrix | quat_wxyz
  std::string classes_file;       ///< PoET class-info JSON ({"1": "002_master_chef_can", ...})
  std::string class_map_file;     ///< explicit {"<poet class>": <object id>}
  bool force = false;             ///< replace an existing detections/<name>
};

struct ImportPoetSummary {
  std::filesystem::path output_dir;
  std::size_t images_in_file = 0;
  std::size_t images_matched = 0;
  std::size_t images_unknown = 0;       ///< ids matching no frame (skipped)
  std::size_t empty_images = 0;         ///< matched frames with no detection
  std::size_t detections_in_file = 0;
  std::size_t detections_written = 0;
  std::size_t dropped_non_finite = 0;
  std::size_t dropped_unmapped_class = 0;
  std::size_t dropped_duplicate = 0;
  std::size_t quaternion_rotations = 0;
  std::size_t sigma_from_log_variances = 0;  ///< written detections with σ from PoET's aleatoric heads
  std::size_t sigma_from_covariance = 0;     ///< written detections with σ from a 6x6 covariance
  double max_abs_correlation_dropped = 0.0;  ///< largest |ρ| of those covariances (not in the σ columns)
  std::map<int, int> class_map;         ///< PoET class → object id actually used
  std::vector<std::string> unknown_ids; ///< first few unmatched ids
  std::vector<std::string> warnings;
  nlohmann::json to_json() const;
};

ImportPoetSummary import_poet(const std::filesystem::path& results_json, const std::filesystem::path& dataset,
                              const ImportPoetOptions& options);

}  // namespace roe::app
