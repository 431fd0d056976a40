#pragma once
/// @file
/// A PoET model bundle for `roe infer`: a folder with the manifest `poet_bundle.json` (schema
/// "roe-poet-bundle/1", validated strictly: unknown keys, wrong types, missing files and
/// inconsistent settings are roe::ConfigError naming the key) and the files it names. Written by
/// scripts/export_poet.py (real PoET checkpoints) or tests/models/gen_tiny_poet.py. Layout and keys:
/// docs/infer.md.

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "roe/infer/nms.hpp"
#include "roe/infer/rotation.hpp"

namespace roe::infer {

namespace fs = std::filesystem;

inline constexpr const char* kBundleSchema = "roe-poet-bundle/1";
inline constexpr const char* kBundleManifest = "poet_bundle.json";

/// Pinhole intrinsics (pixels).
struct Intrinsics {
  double fx = 0, fy = 0, cx = 0, cy = 0;
};

/// The network input: size it was trained at, channel order and normalisation
/// x = (pixel · scale − mean) / std per channel.
struct BundleImage {
  int width = 0, height = 0;
  bool rgb = true;  ///< channel order fed to the network ("RGB" or "BGR")
  double scale = 1.0 / 255.0;
  double mean[3] = {0, 0, 0};
  double std[3] = {1, 1, 1};
};

struct BundleClass {
  int id = 0;  ///< PoET class id (1-based; 0 = background)
  std::string name;
};

enum class DetectorKind { kDarknet, kExternal };

/// Darknet (YOLO) detector run through OpenCV's DNN module.
struct DarknetSpec {
  fs::path cfg, weights;
  NmsOptions nms;
  std::vector<std::string> feature_layers;  ///< OpenCV layer names tapped for the pose head
  /// Optional self-test: an image and the expected outputs of named layers.
  fs::path selftest_image;
  std::vector<std::pair<std::string, fs::path>> selftest_outputs;
  /// Optional: the detections after NMS that PoET's own detector gives on the image, float32
  /// [N, 6] rows x1, y1, x2, y2 (pixels), score, class (after class_offset), best first.
  fs::path selftest_detections;
  double selftest_atol = 1e-4;
};

enum class PoseInputs { kFeatures, kImage };

struct PoseSpec {
  fs::path file;              ///< TorchScript module
  std::string torch_version;  ///< of the exporter (informational; checked against the runtime)
  PoseInputs inputs = PoseInputs::kFeatures;
  bool aleatoric = false;     ///< also outputs log-variances of t and of the rotation (camera frame)
};

struct SelfTest {
  std::vector<fs::path> inputs;   ///< boxes, classes, then the feature maps (or the image)
  std::vector<fs::path> outputs;  ///< t, rotation (, logvar_t, logvar_r)
  double atol = 1e-5;
};

struct PoetBundle {
  fs::path dir;
  std::string model_id;
  std::string description;
  BundleImage image;
  Intrinsics train_intrinsics;
  int num_queries = 10;
  std::vector<BundleClass> classes;
  std::vector<int> symmetric;
  RotationFormat rotation = RotationFormat::k6d;
  double translation_scale = 1.0;  ///< to metres ("m" → 1, "mm" → 0.001)
  DetectorKind detector = DetectorKind::kDarknet;
  DarknetSpec darknet;
  PoseSpec pose;
  nlohmann::json provenance = nlohmann::json::object();
  SelfTest selftest;
  nlohmann::json manifest;  ///< the file as read

  /// Name of a class id ("" when unknown).
  std::string class_name(int id) const;
};

/// Reads and validates DIR/poet_bundle.json (no model is loaded).
PoetBundle read_bundle(const fs::path& dir);
/// Validates a manifest given as JSON; `dir` resolves relative file names.
PoetBundle bundle_from_json(const nlohmann::json& j, const fs::path& dir, const std::string& source);

}  // namespace roe::infer
