// One message-level interface over ROS 1 bags, MCAP, rosbag2 SQLite and rosbag2 folders
// (include/roe/io/ros/message_bag.hpp).
#include "roe/io/ros/message_bag.hpp"

#include <algorithm>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <random>

#include <fmt/format.h>

#include "roe/core/error.hpp"
#include "roe/io/ros/compression.hpp"
#include "roe/io/ros/mcap.hpp"
#include "roe/io/output.hpp"
#include "roe/io/ros/ros1_bag.hpp"
#include "roe/io/ros/rosbag2.hpp"

namespace roe::io {

std::string BagMessage::where() const {
  return fmt::format("{}: {} ({})", file, topic ? topic->topic : std::string("?"), location);
}

std::string BagWarning::text() const { return location.empty() ? message : location + ": " + message; }

const BagTopic* MessageBag::find(const std::string& topic) const {
  for (const auto& t : topics_)
    if (t.topic == topic) return &t;
  return nullptr;
}

std::string MessageBag::topic_type(const std::string& topic) const {
  const BagTopic* t = find(topic);
  return t ? t->type : std::string();
}

std::uint64_t MessageBag::message_count(const std::string& topic) const {
  const BagTopic* t = find(topic);
  return t ? t->count : 0;
}

bool MessageBag::damaged() const {
  for (const auto& w : warnings())
    if (w.damage) return true;
  return false;
}

std::vector<BagWarning> MessageBag::damage() const {
  std::vector<BagWarning> d;
  for (const auto& w : warnings())
    if (w.damage) d.push_back(w);
  std::stable_partition(d.begin(), d.end(), [](const BagWarning& w) { return !w.index_fallback; });
  return d;
}

std::string MessageBag::first_damage() const {
  const auto d = damage();
  return d.empty() ? std::string() : (d.front().file != name_ ? d.front().file + ": " : "") + d.front().text();
}

std::string MessageBag::damage_summary() const {
  const auto d = damage();
  if (d.empty()) return {};
  return first_damage() + "; " + std::to_string(d.size()) + " problem(s)";
}

std::string MessageBag::damage_listing() const {
  if (damage().size() < 2) return {};
  std::string s = "\nproblems found:";
  for (const auto& w : warnings())
    if (w.damage) s += "\n  " + (w.file != name_ ? w.file + ": " : std::string()) + w.text();
  return s;
}

std::string MessageBag::topic_listing() const {
  std::string s;
  for (const auto& t : topics_) s += "\n  " + t.topic + " (" + t.type + ")";
  return s.empty() ? std::string(" none") : s;
}

std::string normalize_ros_type(const std::string& type) {
  const std::size_t a = type.find('/');
  if (a == std::string::npos) return type;
  const std::size_t b = type.find('/', a + 1);
  if (b == std::string::npos || type.compare(a + 1, b - a - 1, "msg") != 0) return type;
  return type.substr(0, a) + type.substr(b);
}

namespace {

std::vector<BagWarning> offset_warnings(const std::string& file, const std::vector<OffsetWarning>& ws) {
  std::vector<BagWarning> out;
  for (const auto& w : ws) out.push_back({file, "byte " + std::to_string(w.offset), w.message, w.damage, w.index_fallback});
  return out;
}

/// Positions of topics_ by name.
std::map<std::string, std::size_t> topic_index(const std::vector<BagTopic>& topics) {
  std::map<std::string, std::size_t> m;
  for (std::size_t i = 0; i < topics.size(); ++i) m[topics[i].topic] = i;
  return m;
}

/// What the ROS 1 and MCAP bags share over their chunked readers: the reader, the topic index, the warnings
/// and the step from a reader's message to a BagMessage.
template <class Reader>
class ChunkedBag : public MessageBag {
 public:
  std::vector<BagWarning> warnings() const override { return offset_warnings(name_, r_.warnings()); }

 protected:
  ChunkedBag(const fs::path& file, const BagOpenOptions& o, const char* format) : r_(file, {o.force_scan}) {
    name_ = file.string();
    format_ = format;
  }
  /// `m` (its file set) filled in for a message of `topic` and handed to `fn`; a topic not listed (an MCAP
  /// channel met only inside a chunk) is passed over.
  bool deliver(BagMessage& m, const std::string& topic, Timestamp t, std::string_view data, std::uint64_t chunk,
               const std::function<bool(const BagMessage&)>& fn) const {
    const auto it = index_.find(topic);
    if (it == index_.end()) return true;
    m.topic = &topics_[it->second];
    m.log_time_ns = t;
    m.data = data;
    m.location = "chunk at byte " + std::to_string(chunk);
    return fn(m);
  }

  Reader r_;
  std::map<std::string, std::size_t> index_;  // topics_ by name
};

class Ros1Bag final : public ChunkedBag<ros1::Reader> {
 public:
  Ros1Bag(const fs::path& file, const BagOpenOptions& o) : ChunkedBag(file, o, "ros1") {
    for (const auto& t : r_.topics()) {
      const std::string type = r_.topic_type(t);
      topics_.push_back({t, normalize_ros_type(type), type, "ros1", r_.message_count(t)});
    }
    index_ = topic_index(topics_);
  }
  bool ros2() const override { return false; }
  void for_each(const std::set<std::string>& topics, const std::function<bool(const BagMessage&)>& fn,
                const ProgressCallback& progress) override {
    BagMessage m;
    m.file = name_;
    r_.for_each_topic(
        {topics.begin(), topics.end()},
        [&](const ros1::MessageView& v) {
          return deliver(m, v.connection->topic, v.record_time_ns, v.data, v.chunk_offset, fn);
        },
        progress);
  }
};

class McapBag final : public ChunkedBag<mcap::Reader> {
 public:
  McapBag(const fs::path& file, const BagOpenOptions& o) : ChunkedBag(file, o, "mcap") {
    for (const auto& [id, c] : r_.channels()) {
      auto it = index_.find(c.topic);
      if (it == index_.end()) {
        const std::string type = r_.schema_name(c);
        it = index_.emplace(c.topic, topics_.size()).first;
        topics_.push_back({c.topic, normalize_ros_type(type), type, c.message_encoding, 0});
      }
      topics_[it->second].count += r_.message_count(id);
    }
  }
  bool ros2() const override { return r_.profile() != "ros1"; }
  void for_each(const std::set<std::string>& topics, const std::function<bool(const BagMessage&)>& fn,
                const ProgressCallback& progress) override {
    BagMessage m;
    m.file = name_;
    r_.for_each([&](const mcap::Channel& c) { return topics.count(c.topic) != 0; },
                [&](const mcap::MessageView& v) {
                  return deliver(m, v.channel->topic, v.log_time_ns, v.data, v.chunk_offset, fn);
                },
                progress);
  }
};

class SqliteBag final : public MessageBag {
 public:
  explicit SqliteBag(const fs::path& file) : r_(file) {
    name_ = file.string();
    format_ = "sqlite3";
    for (const auto& t : r_.topics()) {
      index_[t.id] = topics_.size();
      topics_.push_back({t.name, normalize_ros_type(t.type), t.type, t.serialization_format, t.count});
    }
  }
  bool ros2() const override { return true; }
  void for_each(const std::set<std::string>& topics, const std::function<bool(const BagMessage&)>& fn,
                const ProgressCallback& progress) override {
    std::set<std::int64_t> ids;
    std::size_t total = 0, done = 0;
    for (const auto& t : r_.topics())
      if (topics.count(t.name)) {
        ids.insert(t.id);
        total += t.count;
      }
    BagMessage m;
    m.file = name_;
    r_.for_each(ids, [&](std::int64_t topic_id, Timestamp t, std::string_view data, std::int64_t row) {
      m.topic = &topics_[index_.at(topic_id)];
      m.log_time_ns = t;
      m.data = data;
      m.location = "messages row id " + std::to_string(row);
      if (progress) progress(++done, total);
      return fn(m);
    });
  }
  std::vector<BagWarning> warnings() const override {
    std::vector<BagWarning> out;
    for (const auto& w : r_.warnings())
      out.push_back({name_, w.row_id ? "messages row id " + std::to_string(w.row_id) : "table messages", w.message});
    return out;
  }

 private:
  rosbag2::SqliteReader r_;
  std::map<std::int64_t, std::size_t> index_;
};

/// A temporary folder removed with its content when destroyed (decompressed copies of files).
class TempDir {
 public:
  TempDir() {
    std::random_device rd;
    const fs::path base = fs::temp_directory_path();
    for (int i = 0; i < 100; ++i) {
      const fs::path p = base / fmt::format("roe-bag-{:08x}", rd());
      std::error_code ec;
      if (fs::create_directory(p, ec)) {
        path_ = p;
        cleanup_.emplace(p);  // INT, TERM, HUP: removed before the process dies
        return;
      }
    }
    throw InputError("cannot create a temporary folder for a decompressed bag file", {base.string()});
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);  // path-checked: the folder the constructor created
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
  std::optional<SignalCleanup> cleanup_;
};

std::unique_ptr<MessageBag> open_file(const fs::path& file, const BagOpenOptions& o, const std::string& kind);

/// A rosbag2 folder (metadata.yaml, or the bag files in name order), or a lone zstd-compressed file.
class FolderBag final : public MessageBag {
 public:
  FolderBag(const fs::path& name, const std::vector<fs::path>& files, const std::string& compression_mode,
            const BagOpenOptions& o, std::string format, const rosbag2::Metadata* meta)
      : message_zstd_(compression_mode == "MESSAGE") {
    name_ = name.string();
    format_ = std::move(format);
    for (const auto& f : files) {
      std::error_code ec;
      if (!fs::exists(f, ec)) {
        if (!o.allow_missing_files)
          throw InputError("split file " + f.filename().string() + " listed in metadata.yaml is missing (use "
                               "--salvage to read the others)",
                           {f.string()});
        own_.push_back({f.string(), "", "split file listed in metadata.yaml is missing; its messages are lost"});
        continue;
      }
      fs::path readable = f;
      if (compression_mode == "FILE") {
        if (!tmp_) tmp_ = std::make_unique<TempDir>();
        readable = tmp_->path() / f.filename().replace_extension("");
        const std::uintmax_t compressed = fs::file_size(f, ec);
        zstd_decompress_file(f, readable, file_decompression_limit(ec ? 0 : compressed));
      }
      const std::string kind = detect_bag_kind(readable);
      if (kind != "mcap" && kind != "sqlite3")
        throw InputError("not an MCAP or rosbag2 SQLite file (by its content)" +
                             std::string(compression_mode == "FILE" ? ", after zstd decompression" : ""),
                         {f.string()});
      parts_.push_back(open_file(readable, o, kind));
      part_names_.push_back(f.string());
      const std::uintmax_t size = fs::file_size(readable, ec);
      message_limits_.push_back(chunk_decompression_limit(ec ? 0 : size));
    }
    if (parts_.empty()) throw InputError("no bag file of this rosbag2 folder could be opened", {name_});
    for (const auto& p : parts_)
      for (const auto& t : p->topics()) {
        auto it = index_.find(t.topic);
        if (it == index_.end()) {
          it = index_.emplace(t.topic, topics_.size()).first;
          topics_.push_back(t);
          topics_.back().count = 0;
        }
        topics_[it->second].count += t.count;
      }
    // metadata.yaml may list a topic that has no message in the files read (e.g. a lost split file).
    if (meta)
      for (const auto& t : meta->topics)
        if (!index_.count(t.name)) {
          index_.emplace(t.name, topics_.size());
          topics_.push_back({t.name, normalize_ros_type(t.type), t.type, t.serialization_format, 0});
        }
  }
  bool ros2() const override { return true; }
  void for_each(const std::set<std::string>& topics, const std::function<bool(const BagMessage&)>& fn,
                const ProgressCallback& progress) override {
    std::string buf;
    bool stop = false;
    std::size_t total = 0, done = 0;
    for (const auto& t : topics) total += message_count(t);
    for (std::size_t k = 0; k < parts_.size() && !stop; ++k) {
      parts_[k]->for_each(topics, [&](const BagMessage& pm) {
        BagMessage m = pm;
        m.topic = &topics_[index_.at(pm.topic->topic)];
        m.file = part_names_[k];
        if (message_zstd_) {
          if (!zstd_decompress_any(pm.data, static_cast<std::size_t>(message_limits_[k]), buf)) {
            own_.push_back({m.file, m.location,
                            fmt::format("message of {} fails to decompress (zstd message compression) within the "
                                        "{}-byte limit; skipped",
                                        pm.topic->topic, message_limits_[k])});
            return true;
          }
          m.data = buf;
        }
        if (progress) progress(++done, total);
        stop = !fn(m);
        return !stop;
      });
    }
  }
  std::vector<BagWarning> warnings() const override {
    std::vector<BagWarning> out = own_;
    for (std::size_t k = 0; k < parts_.size(); ++k)
      for (auto w : parts_[k]->warnings()) {
        w.file = part_names_[k];
        out.push_back(std::move(w));
      }
    return out;
  }

 private:
  bool message_zstd_ = false;
  std::unique_ptr<TempDir> tmp_;  // declared before parts_: the files are closed before it is removed
  std::vector<std::unique_ptr<MessageBag>> parts_;
  std::vector<std::string> part_names_;
  std::vector<std::uint64_t> message_limits_;  ///< chunk_decompression_limit of each part
  std::map<std::string, std::size_t> index_;
  std::vector<BagWarning> own_;
};

std::unique_ptr<MessageBag> open_file(const fs::path& file, const BagOpenOptions& o, const std::string& kind) {
  if (kind == "ros1") return std::make_unique<Ros1Bag>(file, o);
  if (kind == "mcap") return std::make_unique<McapBag>(file, o);
  if (kind == "sqlite3") return std::make_unique<SqliteBag>(file);
  throw InternalError("open_file: kind " + kind);
}

/// Bag files of a folder without metadata.yaml, in name order.
std::vector<fs::path> bag_files_in(const fs::path& dir) {
  std::vector<fs::path> files;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string k = e.is_regular_file() ? detect_bag_kind(e.path()) : std::string();
    if (k == "mcap" || k == "sqlite3") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace

std::string detect_bag_kind(const fs::path& path) {
  std::error_code ec;
  // A rosbag2 folder: metadata.yaml, or (as open_bag reads it) MCAP or SQLite bag files without one.
  if (fs::is_directory(path, ec))
    return fs::exists(path / "metadata.yaml", ec) || !bag_files_in(path).empty() ? "rosbag2-folder" : "";
  std::ifstream f(path, std::ios::binary);
  char b[16] = {};
  f.read(b, sizeof b);
  const std::string_view head(b, static_cast<std::size_t>(f.gcount()));
  if (head.substr(0, 9) == "#ROSBAG V") return "ros1";
  if (head.substr(0, 8) == mcap::kMagic) return "mcap";
  if (head == std::string_view("SQLite format 3\0", 16)) return "sqlite3";
  if (head.substr(0, 4) == std::string_view("\x28\xB5\x2F\xFD", 4)) return "zstd";
  return "";
}

std::unique_ptr<MessageBag> open_bag(const fs::path& path, const BagOpenOptions& o) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError("no such bag file or folder", {path.string()});
  if (fs::is_directory(path, ec)) {
    if (fs::exists(path / "metadata.yaml", ec)) {
      const auto meta = rosbag2::read_metadata(path / "metadata.yaml");
      std::vector<fs::path> files;
      for (const auto& f : meta.relative_file_paths) files.push_back(path / f);
      std::string fmt_ = "rosbag2 folder (" + (meta.storage_identifier.empty() ? "?" : meta.storage_identifier);
      if (!meta.compression_mode.empty())
        fmt_ += ", " + meta.compression_format + " " + (meta.compression_mode == "FILE" ? "file" : "message") +
                " compression";
      return std::make_unique<FolderBag>(path, files, meta.compression_mode, o, fmt_ + ")", &meta);
    }
    const auto files = bag_files_in(path);
    if (files.empty())
      throw InputError("a folder without metadata.yaml and without MCAP or rosbag2 SQLite files: not a bag",
                       {path.string()});
    auto b = std::make_unique<FolderBag>(path, files, "", o, "rosbag2 folder without metadata.yaml", nullptr);
    return b;
  }
  const std::string kind = detect_bag_kind(path);
  if (kind == "zstd")
    return std::make_unique<FolderBag>(path, std::vector<fs::path>{path}, "FILE", o, "zstd-compressed rosbag2 file",
                                       nullptr);
  if (kind.empty())
    throw InputError("not a bag roe reads (wrong magic at byte 0: not a ROS 1 bag \"#ROSBAG V2.0\", MCAP, rosbag2 "
                     "SQLite database or zstd-compressed rosbag2 file)",
                     {path.string()});
  return open_file(path, o, kind);
}

std::string bag_sha256(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_directory(path, ec)) return sha256_file(path);
  std::string acc;
  std::vector<fs::path> files;
  if (fs::exists(path / "metadata.yaml", ec)) {
    files.push_back(path / "metadata.yaml");
    for (const auto& f : rosbag2::read_metadata(path / "metadata.yaml").relative_file_paths)
      if (fs::exists(path / f, ec)) files.push_back(path / f);
  } else {
    files = bag_files_in(path);
  }
  for (const auto& f : files) acc += f.filename().string() + " " + sha256_file(f) + "\n";
  return sha256_hex(acc);
}

// ---------------------------------------------------------------------------------------------
// Decoders
// ---------------------------------------------------------------------------------------------
ros::Wire message_wire(const BagMessage& m) {
  const std::string& enc = m.topic->encoding;
  if (enc == "ros1") return ros::Wire::ros1;
  if (enc == "cdr") return ros::Wire::cdr;
  throw InputError(m.where() + ": message encoding \"" + enc + "\" is not one roe decodes (ros1, cdr)");
}

bool is_pose_type(const std::string& t) {
  namespace msg = ros::msg;
  return t == msg::PoseStamped::kType || t == msg::TransformStamped::kType ||
         t == msg::PoseWithCovarianceStamped::kType || t == msg::Odometry::kType ||
         t == msg::TFMessage::kType;
}

ros::StampedTransform decode_stamped_pose(const BagMessage& m) {
  namespace msg = ros::msg;
  const std::string& t = m.topic->type;
  if (t == msg::PoseStamped::kType) return decode<msg::PoseStamped>(m);
  if (t == msg::TransformStamped::kType) return decode<msg::TransformStamped>(m);
  if (t == msg::PoseWithCovarianceStamped::kType) return decode<msg::PoseWithCovarianceStamped>(m);
  if (t == msg::Odometry::kType) return decode<msg::Odometry>(m);
  throw InputError(m.where() + ": type " + t + " is not a stamped pose");
}

}  // namespace roe::io
