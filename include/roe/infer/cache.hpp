#pragma once
/// @file
/// The per-frame detection cache of `roe infer`: DATASET/cache/infer/<model_id>/<config_hash>/frames.jsonl.
/// One JSON line per computed frame, keyed by the SHA-256 of the image file's bytes (plus the
/// external boxes of that frame, when used); the folder is keyed by model id and config hash, so a
/// line is reused only for the same image, model and configuration. Lines are appended and flushed
/// as frames finish, so an interrupted run keeps its work; a torn last line (or any unreadable
/// line) is ignored with a count. The first line is a header naming the schema, model and hash.

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "roe/infer/model.hpp"

namespace roe::infer {

inline constexpr const char* kCacheSchema = "roe-infer-cache/1";

struct CachedFrame {
  std::string key;
  Timestamp t_ns = 0;  ///< informational (the same image may appear at several stamps)
  double ms = 0.0;     ///< time it took to compute
  std::vector<PoseDetection> detections;
};

class DetectionCache {
 public:
  /// Opens (creating folders) and loads the cache file. A header of another model/config or
  /// schema makes the file start over.
  DetectionCache(std::filesystem::path file, std::string model_id, std::string config_hash);
  const CachedFrame* find(const std::string& key) const;
  /// Appends one frame and flushes the file.
  void append(const CachedFrame& frame);
  std::size_t size() const { return frames_.size(); }
  std::size_t ignored_lines() const { return ignored_; }
  const std::filesystem::path& file() const { return file_; }

 private:
  std::filesystem::path file_;
  std::map<std::string, CachedFrame> frames_;
  std::ofstream out_;
  std::size_t ignored_ = 0;
};

/// JSON forms (used by the cache; exposed for tests).
nlohmann::json frame_to_json(const CachedFrame& f);
CachedFrame frame_from_json(const nlohmann::json& j);

}  // namespace roe::infer
