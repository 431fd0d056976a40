#pragma once
/// @file
/// `roe infer DATASET --model BUNDLE_DIR [--name NAME]`: PoET inference in C++ over the dataset's
/// frames (mav0/cam0/data.csv + images) → DATASET/detections/<name>/{detections.csv, meta.json}.
/// Frames are cached per (image content hash, model id, config hash) under
/// DATASET/cache/infer/<model_id>/<config_hash>/ so re-runs compute only new frames.

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "roe/core/types.hpp"

namespace roe::app {

struct InferOptions {
  std::string model_dir;          ///< bundle folder (poet_bundle.json)
  std::string name;               ///< detections/<name>; default: the bundle's model_id
  std::string frames;             ///< "A:B" 0-based frame index range (B exclusive), "" = all
  int every = 1;                  ///< keep every N-th frame of the range
  std::string warp = "auto";      ///< virtual-camera warp: auto | on | off
  std::string device = "auto";    ///< LibTorch device: auto | cpu | cuda
  int threads = 0;                ///< LibTorch intra-op threads on the CPU; 0 = one per hardware thread
  std::string boxes_file;         ///< external boxes CSV (timestamp_ns,class,x1,y1,x2,y2,score)
  std::string class_map_file;     ///< {"<poet class>": <object id>}; default: by name
  bool use_cache = true;          ///< false: recompute every selected frame (replacing their cache entries)
  bool force = false;             ///< replace an existing detections/<name>
};

struct InferSummary {
  std::filesystem::path output_dir;
  std::filesystem::path cache_file;
  std::string model_id, config_hash, device;
  std::size_t frames_in_dataset = 0, frames_selected = 0, frames_computed = 0, frames_reused = 0;
  std::size_t detections_written = 0, dropped_unmapped_class = 0, dropped_duplicate = 0, dropped_invalid = 0;
  double mean_ms_computed = 0.0;  ///< mean wall time of the frames computed in this run
  bool warp = false;
  nlohmann::json selftest;
  std::vector<std::string> warnings;
  nlohmann::json to_json() const;
};

/// Parses "A:B", "A:", ":B" or "A" (one frame) into [begin, end) over n frames. InputError on
/// malformed or empty ranges.
std::pair<std::size_t, std::size_t> parse_frame_range(const std::string& spec, std::size_t n);

InferSummary run_infer(const std::filesystem::path& dataset, const InferOptions& options,
                       const ProgressCallback& progress = {});

}  // namespace roe::app
