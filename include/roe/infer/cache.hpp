#pragma once
/// @file
/// The per-frame detection cache of `roe infer`: DATASET/cache/infer/<model_id>/<config_hash>/frames.jsonl.
/// One JSON line per computed frame, keyed by the SHA-256 of the image file's bytes (plus the
/// external boxes of that frame, when used); the folder is keyed by model id and config hash, so a
/// line is reused only for the same image, model and configuration. Lines are appended and flushed
/// as frames finish, so an interrupted run keeps its work; a torn last line (or any unreadable
/// line) is ignored with a count. The first line is a header naming the schema, model and hash.
/// The file is created lazily by the first append. A recomputed frame (`roe infer --no-cache`)
/// is appended again and replaces the older line when the run finishes (compact()), so the file
/// holds one line per key.

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "roe/infer/model.hpp"

namespace roe::infer {

/// Version 2: the YOLO boxes are decoded with PoET's rule (decode_yolo_head); frames cached by
/// version 1 (OpenCV's Region decoding) are computed again.
inline constexpr const char* kCacheSchema = "roe-infer-cache/2";

struct CachedFrame {
  std::string key;
  Timestamp t_ns = 0;  ///< informational (the same image may appear at several stamps)
  double ms = 0.0;     ///< time it took to compute
  std::size_t dropped_invalid = 0;  ///< poses the model returned degenerate (absent in older lines: 0)
  std::vector<PoseDetection> detections;
};

class DetectionCache {
 public:
  /// Loads the cache file when it exists. Nothing is written (no folder, no file) until the first
  /// append(), so a run that fails before computing a frame leaves no trace. A header of another
  /// model/config or schema makes the file start over at the first append.
  DetectionCache(std::filesystem::path file, std::string model_id, std::string config_hash);
  const CachedFrame* find(const std::string& key) const;
  /// Appends one frame and flushes the file (creating folders and file on first use). A frame
  /// whose key is already there replaces it: in memory at once, in the file at compact().
  void append(const CachedFrame& frame);
  /// Rewrites the file (atomically) with one line per key, when it holds replaced entries or
  /// unreadable lines; a no-op otherwise. Call it when a run has finished.
  void compact();
  std::size_t size() const { return frames_.size(); }
  std::size_t ignored_lines() const { return ignored_; }
  /// Lines of the file superseded by a later line with the same key (removed by compact()).
  std::size_t stale_lines() const { return stale_; }
  const std::filesystem::path& file() const { return file_; }

 private:
  void open_for_append();
  std::filesystem::path file_;
  nlohmann::json header_;
  std::map<std::string, CachedFrame> frames_;
  std::vector<std::string> order_;  ///< keys in the order of their first line
  std::ofstream out_;
  std::size_t ignored_ = 0, stale_ = 0;
  bool exists_ = false;   ///< the file exists with our header (or was created by us)
  bool restart_ = false;  ///< the file is foreign: truncate it at the first append
  bool torn_ = false;     ///< the file does not end with a newline
};

/// JSON forms (used by the cache; exposed for tests).
nlohmann::json frame_to_json(const CachedFrame& f);
CachedFrame frame_from_json(const nlohmann::json& j);

}  // namespace roe::infer
