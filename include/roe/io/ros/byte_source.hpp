#pragma once
/// @file
/// Random-access byte sources and offset-tagged warnings shared by roe's binary container readers
/// (ROS 1 bags, MCAP): a file read with pread (never mapped or slurped, so memory stays bounded by
/// what a reader asks for) or a buffer in memory (tests, fuzzing).

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

namespace roe::io {

/// Where the bytes come from.
class ByteSource {
 public:
  virtual ~ByteSource() = default;
  virtual std::uint64_t size() const = 0;
  /// Reads up to n bytes at offset; returns the number read (less at the end of the source).
  virtual std::size_t read_at(std::uint64_t offset, void* out, std::size_t n) const = 0;
};

/// A file opened read-only; InputError naming the file when it cannot be opened.
std::unique_ptr<ByteSource> open_file_source(const std::filesystem::path& file);
/// Bytes held in memory.
std::unique_ptr<ByteSource> memory_source(std::string bytes);

/// A problem a container reader skipped over, with the byte offset in the file where it was found.
struct OffsetWarning {
  std::uint64_t offset = 0;
  std::string message;
  bool damage = true;  ///< false for notes that do not mean lost data (e.g. "bag is not indexed")
  /// The index/summary was unusable, so the reader scanned the records instead: the symptom of a
  /// damage that the scan's own warnings (a truncated record, ...) name more precisely.
  bool index_fallback = false;
};

}  // namespace roe::io
