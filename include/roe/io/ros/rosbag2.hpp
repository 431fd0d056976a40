#pragma once
/// @file
/// rosbag2 storage that is not MCAP: the SQLite3 database (.db3) and the bag folder's metadata.yaml.
///
/// SQLite: read with libsqlite3, opened read-only and immutable (no journal, no lock, no write). Every
/// schema rosbag2 has used is accepted: `topics(id, name, type, serialization_format
/// [, offered_qos_profiles] [, type_description_hash])`, `messages(id, topic_id, timestamp, data)`,
/// optionally `schema(schema_version, ros_distro)` and `message_definitions(...)` (not needed: roe
/// decodes by type name). A database without `topics` and `messages` is not a rosbag2 bag.
///
/// metadata.yaml (`rosbag2_bagfile_information`, versions 1 to 9): storage_identifier,
/// relative_file_paths (split files, in order), compression_format ("" or zstd), compression_mode
/// ("", FILE or MESSAGE), topics_with_message_count. Keys roe does not need are ignored (rosbag2 adds
/// some with every release).

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "roe/core/types.hpp"

namespace roe::io::rosbag2 {

namespace fs = std::filesystem;

struct SqliteTopic {
  std::int64_t id = 0;
  std::string name, type, serialization_format;
  std::uint64_t count = 0;
};

struct SqliteWarning {
  std::int64_t row_id = 0;  ///< messages.id after which the problem was met (0: before any row)
  std::string message;
};

class SqliteReader {
 public:
  /// InputError naming the file when it is not an SQLite database or not a rosbag2 one.
  explicit SqliteReader(const fs::path& file);
  ~SqliteReader();
  SqliteReader(const SqliteReader&) = delete;
  SqliteReader& operator=(const SqliteReader&) = delete;

  const std::string& name() const { return name_; }
  /// schema.schema_version, or 0 when the database has no schema table (rosbag2 before Foxy's last).
  int schema_version() const { return schema_version_; }
  const std::vector<SqliteTopic>& topics() const { return topics_; }
  /// Rows of `topic_ids` in (timestamp, id) order; fn(topic_id, timestamp, data, row_id) returns false
  /// to stop. A database error mid-way becomes a warning naming the last row read.
  void for_each(const std::set<std::int64_t>& topic_ids,
                const std::function<bool(std::int64_t, Timestamp, std::string_view, std::int64_t)>& fn);
  const std::vector<SqliteWarning>& warnings() const { return warnings_; }

 private:
  struct Db;
  std::unique_ptr<Db> db_;
  std::string name_;
  int schema_version_ = 0;
  std::vector<SqliteTopic> topics_;
  std::vector<SqliteWarning> warnings_;
};

struct Metadata {
  int version = 0;
  std::string storage_identifier;           ///< "sqlite3" | "mcap"
  std::vector<std::string> relative_file_paths;
  std::string compression_format;           ///< "" | "zstd"
  std::string compression_mode;             ///< "" | "FILE" | "MESSAGE"
  struct Topic {
    std::string name, type, serialization_format;
    std::uint64_t count = 0;
  };
  std::vector<Topic> topics;
  std::uint64_t message_count = 0;
};

/// Parses a folder's metadata.yaml. InputError naming the file and key on malformed content, an
/// unknown compression format or mode, or a path that leaves the folder.
Metadata read_metadata(const fs::path& metadata_yaml);

}  // namespace roe::io::rosbag2
