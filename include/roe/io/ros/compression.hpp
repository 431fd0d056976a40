#pragma once
/// @file
/// The decompressors of the bag readers: zstd (libzstd) for MCAP chunks and rosbag2 message- and
/// file-level compression, LZ4 frames (liblz4) for ROS 1 and MCAP chunks, bzip2 (libbz2) for ROS 1 chunks.

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace roe::io {

/// Decompresses one or more zstd frames into exactly `expected_size` bytes; false on any error
/// (corrupt data, more or less output than announced). The output grows with what is produced, so a
/// lying size costs no up-front allocation.
bool zstd_decompress(std::string_view in, std::size_t expected_size, std::string& out);
/// Decompresses zstd frames whose size is not known in advance (rosbag2 message-level compression),
/// refusing more than `max_size` bytes; false on any error.
bool zstd_decompress_any(std::string_view in, std::size_t max_size, std::string& out);
/// Compresses (tests, benchmarks, fixtures).
std::string zstd_compress(std::string_view in, int level = 1);
/// Streams a zstd-compressed file (rosbag2 file-level compression) into `out` with bounded memory, writing
/// at most `max_bytes` (InputError beyond, so a 200 KB zstd bomb cannot fill the disk). InputError naming `in`
/// and the compressed byte offset on corrupt or truncated data.
void zstd_decompress_file(const std::filesystem::path& in, const std::filesystem::path& out, std::uint64_t max_bytes);

/// Decompresses an LZ4 frame (rosbag's roslz4 and MCAP write the standard LZ4 frame format) into exactly
/// `expected_size` bytes; false on any error. The output grows with what is produced, as for zstd.
bool lz4_decompress(std::string_view in, std::size_t expected_size, std::string& out);
/// Decompresses a bzip2 stream (ROS 1 chunks) into exactly `expected_size` bytes; false on any error.
bool bz2_decompress(std::string_view in, std::size_t expected_size, std::string& out);
/// Compresses (tests, benchmarks, fixtures).
std::string lz4_compress(std::string_view in);
std::string bz2_compress(std::string_view in);

/// The most a zstd-compressed rosbag2 file may decompress to (docs/import.md, "Limits"):
/// max(kMinFileDecompressionLimit, kFileDecompressionRatio × its compressed size). A bag file must be
/// decompressed whole (SQLite reads a file), so the limit scales with the input; real .db3 and .mcap files
/// compress 2–6× (the shared tf_example.db3 5.4× with zstd -3).
inline constexpr std::uint64_t kMinFileDecompressionLimit = 256ull << 20;
inline constexpr std::uint64_t kFileDecompressionRatio = 16;
std::uint64_t file_decompression_limit(std::uint64_t compressed_size);

/// The most one compressed chunk of a bag (MCAP chunk, ROS 1 chunk) or one compressed rosbag2 message may
/// decompress to in memory, for a bag file of `file_size` bytes (docs/import.md, "Limits"): 4× the file,
/// but at least 64 MiB (a small real file's chunk compresses up to 8×: the shared nav2_turtlebot.mcap holds
/// 2.9 MB in a 0.5 MB file) and at most 256 MiB. A chunk that claims more is skipped with a warning.
inline constexpr std::uint64_t kMinChunkLimit = 64ull << 20;
inline constexpr std::uint64_t kMaxChunkLimit = 256ull << 20;
std::uint64_t chunk_decompression_limit(std::uint64_t file_size);

}  // namespace roe::io
