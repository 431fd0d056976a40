#pragma once
/// @file
/// Safe output: nothing half-written, nothing overwritten by accident (DESIGN §7).
///  - OutputDir: a new output folder is built in a temporary sibling folder and renamed into place
///    by commit(); an existing non-empty folder is refused unless `force` is set (then it is
///    replaced only at commit time). If commit() is never reached the temporary folder is removed.
///  - write_file_atomic: one file via a temporary name in the same folder + rename.

#include <filesystem>
#include <string>
#include <string_view>

namespace roe::io {

namespace fs = std::filesystem;

class OutputDir {
 public:
  /// Throws roe::InputError if `final_dir` exists, is non-empty and force is false, or exists and is
  /// not a directory.
  OutputDir(fs::path final_dir, bool force);
  ~OutputDir();
  OutputDir(const OutputDir&) = delete;
  OutputDir& operator=(const OutputDir&) = delete;

  /// The temporary folder files are written into.
  const fs::path& tmp() const { return tmp_; }
  /// The final folder (valid after commit()).
  const fs::path& final_dir() const { return final_; }
  /// Path of `rel` inside the temporary folder; creates its parent folders.
  fs::path file(const fs::path& rel) const;
  /// Moves the finished folder into place (replacing an existing one when forced).
  void commit();

 private:
  fs::path final_;
  fs::path tmp_;
  bool force_;
  bool committed_ = false;
};

/// Writes `content` to `path` through a temporary file in the same folder and a rename.
/// Refuses to replace an existing file unless `overwrite` is true (roe::InputError).
void write_file_atomic(const fs::path& path, std::string_view content, bool overwrite = true);

/// Reads a whole file; roe::InputError naming the file when it cannot be read.
std::string read_file(const fs::path& path);

/// Lower-case hex SHA-256 of a file's bytes (OpenSSL libcrypto).
std::string sha256_file(const fs::path& path);
/// Lower-case hex SHA-256 of a byte string.
std::string sha256_hex(std::string_view bytes);

}  // namespace roe::io
