#pragma once
/// @file
/// Opening the files a user names (docs/import.md, "Which paths roe reads").
///
/// Every input roe reads is a regular file (or a symlink to one). A folder, a FIFO, a character or
/// block device (`/dev/zero`, `/dev/stdin`), a socket, a symlink loop or a dangling symlink is an
/// InputError naming the path and what is there instead, raised before a byte is read: nothing blocks
/// on a FIFO without a writer and nothing grows without bound on an endless device. There is no `-`
/// for stdin: roe needs to know an input's size before reading it (and several readers read a file
/// twice, to detect its format and then to parse it).
///
/// Memory bound: read_file allocates exactly the size the file had when it was opened (fstat), never
/// more; bytes appended while it reads are not read. The readers on top of it (JSON, YAML, PoET
/// results) hold that text plus their parsed rows, so their peak memory is a small multiple of the
/// file's size (docs/import.md gives the factors). CSV tables and trajectory files opened by path are
/// parsed as they are read (io::CsvReader, 1 MiB at a time, up to the size at open time), and ROS bags
/// are read in place (pread), one chunk at a time.
///
/// Every query here uses the non-throwing std::filesystem forms: a problem with the path itself (a
/// loop, a permission) is an InputError, never a std::filesystem::filesystem_error.

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace roe::io {

namespace fs = std::filesystem;

/// What is at a path, after following symlinks.
enum class PathKind {
  kMissing,    ///< nothing (no such file or folder)
  kRegular,    ///< a regular file
  kDirectory,  ///< a folder
  kSpecial,    ///< a FIFO, device or socket
  kBroken,     ///< the path cannot be resolved: a symlink loop, a dangling symlink, no permission, ...
};

struct PathProbe {
  PathKind kind = PathKind::kMissing;
  std::uintmax_t size = 0;  ///< bytes, for a regular file
  std::string what;         ///< for kSpecial and kBroken: what is there ("a FIFO", "a symlink loop ...")
};

/// Looks at `path` without throwing and without opening it.
PathProbe probe_path(const fs::path& path);

/// Throws InputError naming `path` unless it is a regular file; returns its size. `role` names what
/// was expected ("file", "roe.json", "IMU file") in the message.
std::uintmax_t require_regular_file(const fs::path& path, const std::string& role = "file");

/// For an input that may be absent: false when nothing is there, true for a regular file, and an
/// InputError when something else is there (a folder where data.csv should be is not "no data").
bool optional_regular_file(const fs::path& path, const std::string& role = "file");

/// Whether `path` is a folder; false when absent; InputError when it cannot be resolved (a symlink loop).
bool is_folder(const fs::path& path);

/// Whether anything is at `path` (following symlinks); InputError when it cannot be resolved.
bool path_exists(const fs::path& path);

/// A name that is one folder or file name and nothing more: not empty, not "." or "..", no '/' and no control
/// character. Names read from options or user-editable files (a detection set, a sweep's job id) are checked
/// with it before they become a path, so they can never point outside the folder they are joined to.
bool is_plain_name(std::string_view name);

/// An open regular file: the descriptor and its size at open time. Opened with O_NONBLOCK and checked
/// with fstat, so a path swapped for a FIFO between the check and the open cannot block either.
class InputFile {
 public:
  explicit InputFile(const fs::path& path, const std::string& role = "file");
  ~InputFile();
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;

  int fd() const { return fd_; }
  std::uint64_t size() const { return size_; }
  const std::string& path() const { return path_; }
  /// Reads up to `n` bytes at `offset` (never past size()); InputError on a read error.
  std::size_t read_at(std::uint64_t offset, void* out, std::size_t n) const;

 private:
  std::string path_;
  int fd_ = -1;
  std::uint64_t size_ = 0;
};

/// Reads a whole regular file (see the memory bound above); InputError naming the file otherwise.
std::string read_file(const fs::path& path);

/// The first `max_bytes` bytes of a regular file (fewer when it is shorter).
std::string read_file_head(const fs::path& path, std::size_t max_bytes);

/// Bytes of a UTF-8 byte order mark at the start of `text` (3 or 0). Every text reader (CSV, JSON,
/// YAML, trajectories, format detection) skips one; UTF-16 and UTF-32 are not text roe reads.
inline std::size_t utf8_bom_length(std::string_view text) {
  return text.size() >= 3 && text.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;
}

/// Lower-case hex SHA-256 of a regular file's bytes (OpenSSL libcrypto).
std::string sha256_file(const fs::path& path);

}  // namespace roe::io
