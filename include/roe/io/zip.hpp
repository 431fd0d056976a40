#pragma once
/// @file
/// ZIP archives as evo keeps its results (Python's zipfile): read with members stored or deflated, written
/// with members stored, as zipfile.ZipFile(path, "w") writes them. No ZIP64, encryption or multi-disk
/// archives: those are refused by name. Bounded: a member is at most kMaxZipMember bytes once
/// decompressed and at most 1000× its compressed size, the whole archive at most kMaxZipTotal.

#include <cstddef>
#include <string>
#include <vector>

namespace roe::io {

inline constexpr std::size_t kMaxZipMember = 256u << 20;  ///< 256 MiB
inline constexpr std::size_t kMaxZipTotal = 256u << 20;

struct ZipMember {
  std::string name;
  std::string data;
};

/// The members of the archive `bytes` in the order of its central directory, each checked against its
/// CRC-32. InputError naming `source` and the byte offset of what is wrong.
std::vector<ZipMember> read_zip(const std::string& bytes, const std::string& source);
/// The archive's bytes: every member stored (method 0), DOS time 1980-01-01 00:00 (reproducible bytes).
std::string write_zip(const std::vector<ZipMember>& members);

}  // namespace roe::io
