#pragma once
/// @file
/// zstd (libzstd) for the ROS 2 readers: MCAP chunks, rosbag2 message- and file-level compression.
/// LZ4 frames are in rosbag.hpp (bag::lz4_decompress), shared by ROS 1 bags and MCAP chunks.

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
/// Streams a zstd-compressed file (rosbag2 file-level compression) into `out` with bounded memory.
/// InputError naming `in` and the compressed byte offset on corrupt or truncated data.
void zstd_decompress_file(const std::filesystem::path& in, const std::filesystem::path& out);

}  // namespace roe::io
