#pragma once
/// @file
/// PoET's own inference output, `results.json` (aau-cns/poet `inference_tools/inference_engine.py`),
/// read as it really is (notes/poet.md §2):
///   {"<img_id>": {"0": {"t": [x,y,z], "rot": [[..],[..],[..]] | [w,x,y,z], "box": [cx,cy,w,h],
///                       "class": 5}, "1": {...}}, "<img_id2>": {}}
///  - img_id is cut from the image file name (see poet_image_id),
///  - detection keys are strings "0", "1", ... in detector-score order,
///  - t is in metres, rot maps object → camera (x_C = R x_O + t), a 4-list is a w-first quaternion,
///  - box is normalised cx, cy, w, h; class is 1-based (YCB-V 1..21),
///  - Python's json.dump may write the bare tokens NaN, Infinity and -Infinity, which strict JSON
///    parsers (nlohmann) reject: this reader has its own tokenizer that accepts them.
/// There is no score, no time and no model information in the file.
///
/// Optional per-detection uncertainty (docs/import.md, "PoET uncertainty"): PoET's aleatoric heads (aau-cns/poet,
/// `--aleatoric`) output per axis a log-variance s = log σ², `pred_translation_aleatoric` (t, log m²) and
/// `pred_rotation_aleatoric` (rotation error v = Log(R_pred R_trueᵀ) about the camera axes, log rad²);
/// a results.json entry may carry them under those names or as `t_aleatoric` / `rot_aleatoric`, or a
/// full 6x6 covariance `cov` (= `covariance`) of (t, v) in m², m·rad, rad².

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "roe/core/types.hpp"

namespace roe::io {

/// How `rot` is written: decided per entry from its shape (kAuto), or required to be one form.
enum class PoetRotationFormat { kAuto, kMatrix, kQuatWxyz };

/// Parses "auto", "matrix" or "quat_wxyz" (roe::InputError otherwise, naming `what`).
PoetRotationFormat parse_poet_rotation_format(const std::string& s, const std::string& what);

/// One entry "<index>": {...} of one image.
struct PoetRawDetection {
  int index = 0;                                       ///< the string key as an integer (score rank)
  Eigen::Vector3d t = Eigen::Vector3d::Zero();         ///< metres; may hold NaN/Inf as written
  Eigen::Matrix3d R_C_O = Eigen::Matrix3d::Identity(); ///< orthonormalised when finite
  bool rot_was_quaternion = false;
  bool finite = true;                                  ///< false if t or rot held NaN/Inf
  Eigen::Vector4d box = Eigen::Vector4d::Constant(std::numeric_limits<double>::quiet_NaN());
  int class_id = 0;                                    ///< 1-based PoET class
  std::optional<double> score;                         ///< only if a fork wrote "score"
  /// Where the uncertainty came from: none, log-variances (PoET's aleatoric heads), or a 6x6 covariance.
  enum class Uncertainty { kNone, kLogVariance, kCovariance } uncertainty = Uncertainty::kNone;
  /// σ in the camera frame, tx, ty, tz (m), rx, ry, rz (rad), as the sigma columns of detections.csv:
  /// exp(s/2) of the log-variances, or the square roots of the covariance's diagonal. Unset without
  /// uncertainty and for a detection whose pose is not finite (it is dropped).
  std::optional<Vector6d> sigma;
  /// A covariance's largest |correlation| off the diagonal: what the per-axis σ columns cannot hold.
  double max_abs_correlation = 0.0;
  std::int64_t line = 0, column = 0;                   ///< where the entry starts in the file
};

/// One top-level key.
struct PoetImageResult {
  std::string id;
  std::vector<PoetRawDetection> detections;  ///< sorted by index
  std::int64_t line = 0, column = 0;
};

struct PoetResults {
  std::vector<PoetImageResult> images;  ///< in file order
};

/// Per-image limits of a results.json (docs/infer.md, "Per-image limits"): the file is read one image's entry
/// at a time, so memory is bounded by the largest entry; an entry with more detections, or more JSON values in
/// all (a detection with a 6x6 covariance is about 80), is refused with its line and column. PoET writes at
/// most one detection per query of its transformer (tens), far below these.
constexpr std::size_t kMaxPoetDetectionsPerImage = 10'000;
constexpr std::size_t kMaxPoetValuesPerImage = 1'000'000;

/// Parses the text of a results.json. `source` names it in errors (roe::InputError with line and
/// column): syntax errors, wrong shapes, non-integer indices or classes, class < 1, duplicate keys
/// (top-level duplicates are colliding image ids, which Python would have silently overwritten),
/// unknown keys, finite rotations that are not rotations (|RᵀR − I| > 1e-3 or det < 0), quaternions
/// far from unit norm (|‖q‖ − 1| > 1e-3); and for the uncertainty keys: a wrong shape, a non-number,
/// NaN/Inf, a log-variance outside [−600, 600] (σ² would under/overflow), one of the two log-variance
/// vectors without the other, two spellings of one key, log-variances and a covariance together, a
/// covariance diagonal ≤ 0, a covariance that is not symmetric (|C_ij − C_ji| > 1e-5·√(C_ii C_jj)) or
/// not positive semi-definite (correlation-matrix eigenvalue < −1e-6). Values of a detection whose
/// t or rot is not finite are checked for shape only (the detection is dropped).
PoetResults parse_poet_results(const std::string& text, const std::string& source,
                               PoetRotationFormat format = PoetRotationFormat::kAuto);
PoetResults read_poet_results(const std::filesystem::path& file,
                              PoetRotationFormat format = PoetRotationFormat::kAuto);

/// PoET's image id of a file name, Python's name[name.find('_') + 1 : name.rfind('.')]: the text
/// between the first '_' and the last '.'; without an underscore, the stem. "1662634121000000000.png"
/// → "1662634121000000000", "rgb_000123.png" → "000123", "cam_rgb_17.png" → "rgb_17"; without a dot
/// the slice drops the last character ("frame17" → "frame1"), as PoET does.
std::string poet_image_id(const std::string& filename);

/// YCB-V class names, index = 1-based PoET class id (index 0 = "background"); 22 entries.
const std::vector<std::string>& ycbv_class_names();

/// Reads a PoET class-info JSON ({"1": "002_master_chef_can", ...}): index = class id, "" where
/// a class id is not listed. Errors name the file and key.
std::vector<std::string> read_poet_class_names(const std::filesystem::path& file);

}  // namespace roe::io
