#pragma once
/// @file
/// A read-only reader for ROS1 bag files, format version 2.0 (http://wiki.ros.org/Bags/Format/2.0),
/// written for roe on liblz4 and libbz2 so that importing needs no ROS installation.
///
/// File layout: the magic line "#ROSBAG V2.0\n", then records. A record is
///   int32 header_len, header = sequence of (int32 len, "name=value"), int32 data_len, data.
/// The header field "op" (one byte) gives the record kind:
///   0x03 bag header  (index_pos u64, conn_count i32, chunk_count i32)
///   0x05 chunk       (compression "none"|"lz4"|"bz2", size u32 = uncompressed size); the data holds
///                    connection (0x07) and message data (0x02) records
///   0x04 index data  (ver 1, conn i32, count i32); data = count x (time u64, offset u32 in the chunk)
///   0x07 connection  (conn i32, topic); data = a header with topic/type/md5sum/message_definition
///   0x02 message     (conn i32, time u64 = sec u32 + nsec u32)
///   0x06 chunk info  (ver 1, chunk_pos u64, start_time, end_time, count); data = (conn, count) pairs
/// The index section at index_pos holds every connection record and one chunk-info per chunk.
///
/// Robustness (DESIGN §7): opening never reads past the end of the file. An index that is missing or
/// inconsistent makes the reader fall back to a sequential scan of the records. Truncated records,
/// chunks that fail to decompress and malformed records inside chunks are skipped with a warning
/// giving the byte offset (warnings()); what is intact is still read. Only a file that is not a bag
/// at all (wrong magic, unreadable) is an InputError.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/io/ros/chunked_reader.hpp"

namespace roe::io::ros1 {

namespace fs = std::filesystem;

/// One connection (a topic with its message type) of a bag.
struct Connection {
  std::uint32_t id = 0;
  std::string topic;
  std::string type;     ///< e.g. "sensor_msgs/Imu"
  std::string md5sum;
  std::string message_definition;
  std::string callerid;
  bool latching = false;
};

/// A message as handed to the iteration callback. `data` is valid only during the callback.
struct MessageView {
  const Connection* connection = nullptr;
  Timestamp record_time_ns = 0;   ///< the bag (record) time, not header.stamp
  std::string_view data;          ///< the serialized message
  std::uint64_t chunk_offset = 0; ///< file offset of the chunk that holds it (for messages)
};

/// A problem that was skipped over, with the byte offset in the file where it was found.
using Warning = io::OffsetWarning;

/// Summary of one chunk (from the index, or from the sequential scan).
struct ChunkInfo {
  std::uint64_t offset = 0;       ///< file offset of the chunk record
  std::uint64_t data_offset = 0;  ///< file offset of the chunk's (compressed) data
  std::uint32_t data_size = 0;    ///< compressed size
  std::uint32_t uncompressed_size = 0;
  std::string compression;        ///< "none", "lz4" or "bz2"
  Timestamp start_ns = 0, end_ns = 0;
  std::map<std::uint32_t, std::uint32_t> counts;  ///< messages per connection id
  bool times_known = false;
};

/// force_scan ignores the index section even when present and scans every record.
using ReaderOptions = ChunkedReaderOptions;

class Reader : public ChunkedReader {
 public:
  /// Opens a bag file. InputError if the file cannot be read or is not a ROS bag v2.0.
  explicit Reader(const fs::path& file, ReaderOptions options = {});
  /// A bag held in memory; `name` is used in messages.
  Reader(std::string bytes, std::string name, ReaderOptions options = {});

  /// Whether the index section was used (false: sequential scan).
  bool indexed() const { return indexed_; }
  const std::vector<Connection>& connections() const { return connections_; }
  const std::vector<ChunkInfo>& chunks() const { return chunks_; }
  /// The distinct topics, sorted.
  std::vector<std::string> topics() const;
  /// Type of a topic ("" when absent).
  std::string topic_type(const std::string& topic) const;
  /// Number of messages on a topic according to the index or scan.
  std::size_t message_count(const std::string& topic) const;
  /// Total number of messages.
  std::size_t message_count() const;
  /// Calls `fn` for every message whose topic passes `select`, in record-time order (ties keep
  /// file order). `fn` may return false to stop early. Damaged chunks are skipped with a warning.
  void for_each(const std::function<bool(const Connection&)>& select,
                const std::function<bool(const MessageView&)>& fn, const ProgressCallback& progress = {});
  /// Convenience: messages of the given topics.
  void for_each_topic(const std::vector<std::string>& topics,
                      const std::function<bool(const MessageView&)>& fn,
                      const ProgressCallback& progress = {});

 private:
  void open();
  bool read_index(std::uint64_t index_pos, std::int32_t chunk_count);
  void scan();
  /// Decompressed chunk bytes; empty + warning on failure.
  bool load_chunk(const ChunkInfo& c, std::string& out);
  void add_connection(Connection c);

  bool indexed_ = false;
  std::vector<Connection> connections_;
  std::map<std::uint32_t, std::size_t> conn_index_;  // id → position in connections_
  std::vector<ChunkInfo> chunks_;
};

}  // namespace roe::io::ros1
