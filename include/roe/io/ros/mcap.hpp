#pragma once
/// @file
/// A read-only MCAP reader (https://mcap.dev/spec, format version 0), written for roe on libzstd and
/// liblz4 so that ROS 2 recordings (rosbag2's default storage since Iron) import without ROS.
///
/// File layout: magic "\x89MCAP0\r\n", records, magic. A record is opcode u8, content length u64,
/// content (little-endian; strings u32-length-prefixed; maps and arrays u32-byte-length-prefixed):
///   0x01 header (profile, library)        0x02 footer (summary_start, summary_offset_start, summary_crc)
///   0x03 schema (id u16, name, encoding, data)
///   0x04 channel (id u16, schema_id u16, topic, message_encoding, metadata)
///   0x05 message (channel_id u16, sequence u32, log_time u64, publish_time u64, data = the rest)
///   0x06 chunk (start, end, uncompressed_size u64, uncompressed_crc u32, compression "", "zstd" or "lz4",
///        records u64-length-prefixed: schema, channel and message records)
///   0x07 message index (channel_id, [(log_time, offset in the chunk)])   0x08 chunk index
///   0x09 attachment  0x0A attachment index  0x0B statistics  0x0C metadata  0x0D metadata index
///   0x0E summary offset  0x0F data end. Unknown opcodes are skipped (the spec reserves them).
///
/// Reading: with an intact footer and summary (its CRC checked when set) the chunk indexes give
/// every chunk's offset, time range and channels, so iterating some topics reads only the chunks that
/// hold them. Without a summary, or when it is damaged, the data section is scanned record by record.
/// Memory: one chunk at a time (plus the chunks whose time ranges overlap it during the time-ordered
/// merge), never the file. A chunk's uncompressed CRC is checked when set.
///
/// Robustness as for ROS 1 bags (ros1_bag.hpp): only a file that is not MCAP at all (wrong magic,
/// unreadable) is an InputError; truncated records, chunks that fail to decompress or whose CRC or
/// length lies are skipped with a warning giving the byte offset (warnings(), damaged()).

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

namespace roe::io::mcap {

namespace fs = std::filesystem;

struct Schema {
  std::uint16_t id = 0;
  std::string name;      ///< e.g. "sensor_msgs/msg/Imu"
  std::string encoding;  ///< e.g. "ros2msg"
  std::string data;
};

struct Channel {
  std::uint16_t id = 0;
  std::uint16_t schema_id = 0;
  std::string topic;
  std::string message_encoding;  ///< e.g. "cdr"
  std::map<std::string, std::string> metadata;
};

/// One chunk (from the chunk index, or from the scan).
struct ChunkInfo {
  std::uint64_t offset = 0;        ///< file offset of the chunk record (its opcode)
  Timestamp start_ns = 0, end_ns = 0;
  std::map<std::uint16_t, std::uint64_t> counts;  ///< messages per channel (known or counted)
  bool channels_known = false;     ///< counts lists every channel that has messages in the chunk
  /// A message outside any chunk (unchunked files): the chunk is this one record.
  bool loose_message = false;
};

struct MessageView {
  const Channel* channel = nullptr;
  std::uint32_t sequence = 0;
  Timestamp log_time_ns = 0;
  Timestamp publish_time_ns = 0;
  std::string_view data;          ///< valid only during the callback
  std::uint64_t chunk_offset = 0; ///< file offset of the chunk (or of the message record)
};

/// force_scan ignores the summary even when intact and scans the data section.
using ReaderOptions = ChunkedReaderOptions;

class Reader : public ChunkedReader {
 public:
  /// Opens an MCAP file. InputError if it cannot be read or does not start with the MCAP magic.
  explicit Reader(const fs::path& file, ReaderOptions options = {});
  /// A file held in memory; `name` is used in messages.
  Reader(std::string bytes, std::string name, ReaderOptions options = {});

  const std::string& profile() const { return profile_; }
  const std::string& library() const { return library_; }
  /// Whether the summary section was used (false: linear scan).
  bool summary_used() const { return summary_used_; }
  const std::map<std::uint16_t, Channel>& channels() const { return channels_; }
  const std::map<std::uint16_t, Schema>& schemas() const { return schemas_; }
  const std::vector<ChunkInfo>& chunks() const { return chunks_; }
  /// Schema name of a channel ("" when it has none).
  std::string schema_name(const Channel& c) const;
  /// Messages on a channel (statistics, message indexes or the scan's count).
  std::uint64_t message_count(std::uint16_t channel_id) const;

  /// Calls `fn` for every message of the channels `select` accepts, in log-time order (ties keep file
  /// order). `fn` returns false to stop. Damaged chunks are skipped with a warning.
  void for_each(const std::function<bool(const Channel&)>& select, const std::function<bool(const MessageView&)>& fn,
                const ProgressCallback& progress = {});

 private:
  struct Impl;
  void open();
  bool read_summary();
  void scan();
  /// The chunk's uncompressed records, from out[begin] on (uncompressed chunks stay in their record
  /// buffer: no copy); false + warning when unreadable.
  bool load_chunk(const ChunkInfo& c, std::string& out, std::size_t& begin);
  /// Adds the schema/channel records found in a record block (a chunk's records).
  void learn_records(std::string_view records, std::uint64_t where, ChunkInfo* count_into);

  std::string profile_, library_;
  bool summary_used_ = false;
  std::map<std::uint16_t, Channel> channels_;
  std::map<std::uint16_t, Schema> schemas_;
  std::vector<ChunkInfo> chunks_;
  std::map<std::uint16_t, std::uint64_t> stat_counts_;
  bool have_stat_counts_ = false;
};

/// The 8 magic bytes that start and end every MCAP file.
inline constexpr std::string_view kMagic{"\x89MCAP0\r\n", 8};

/// CRC-32 (IEEE 802.3, zlib's crc32) of `data`, continuing from `crc` (0 to start).
std::uint32_t crc32(std::string_view data, std::uint32_t crc = 0);

}  // namespace roe::io::mcap
