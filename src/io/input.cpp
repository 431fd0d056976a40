// Opening user-named input files: regular files only, sizes known before reading (io/input.hpp).
#include "roe/io/input.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <new>
#include <cstring>

#include "roe/core/error.hpp"

namespace roe::io {
namespace {

std::string special_kind(fs::file_type t) {
  switch (t) {
    case fs::file_type::fifo:
      return "a FIFO (named pipe)";
    case fs::file_type::character:
      return "a character device";
    case fs::file_type::block:
      return "a block device";
    case fs::file_type::socket:
      return "a socket";
    default:
      return "not a regular file";
  }
}

std::string special_kind(mode_t m) {
  if (S_ISFIFO(m)) return special_kind(fs::file_type::fifo);
  if (S_ISCHR(m)) return special_kind(fs::file_type::character);
  if (S_ISBLK(m)) return special_kind(fs::file_type::block);
  if (S_ISSOCK(m)) return special_kind(fs::file_type::socket);
  if (S_ISDIR(m)) return "a folder";
  return "not a regular file";
}

std::string broken_kind(const fs::path& path, const std::error_code& ec) {
  if (ec.value() == ELOOP) return "a symlink loop (too many levels of symbolic links)";
  std::error_code lec;
  if (ec.value() == ENOENT && fs::is_symlink(fs::symlink_status(path, lec)))
    return "a dangling symlink (its target does not exist)";
  return "not accessible: " + ec.message();
}

}  // namespace

PathProbe probe_path(const fs::path& path) {
  PathProbe p;
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec && st.type() != fs::file_type::not_found) {
    p.kind = PathKind::kBroken;
    p.what = broken_kind(path, ec);
    return p;
  }
  switch (st.type()) {
    case fs::file_type::not_found: {
      std::error_code lec;
      if (fs::is_symlink(fs::symlink_status(path, lec))) {
        p.kind = PathKind::kBroken;
        p.what = broken_kind(path, std::make_error_code(std::errc::no_such_file_or_directory));
      }
      return p;  // kMissing otherwise
    }
    case fs::file_type::regular:
      p.kind = PathKind::kRegular;
      p.size = fs::file_size(path, ec);
      if (ec) {
        p.kind = PathKind::kBroken;
        p.what = broken_kind(path, ec);
      }
      return p;
    case fs::file_type::directory:
      p.kind = PathKind::kDirectory;
      p.what = "a folder";
      return p;
    default:
      p.kind = PathKind::kSpecial;
      p.what = special_kind(st.type());
      return p;
  }
}

std::uintmax_t require_regular_file(const fs::path& path, const std::string& role) {
  const PathProbe p = probe_path(path);
  switch (p.kind) {
    case PathKind::kRegular:
      return p.size;
    case PathKind::kMissing:
      throw InputError("no such " + role, {path.string()});
    case PathKind::kDirectory:
      throw InputError("is a folder, expected a " + role + " (a regular file)", {path.string()});
    case PathKind::kSpecial:
      throw InputError("is " + p.what + ", expected a " + role + " (roe reads regular files only)", {path.string()});
    case PathKind::kBroken:
      break;
  }
  throw InputError("cannot read the " + role + ": " + p.what, {path.string()});
}

bool optional_regular_file(const fs::path& path, const std::string& role) {
  if (probe_path(path).kind == PathKind::kMissing) return false;
  (void)require_regular_file(path, role);
  return true;
}

bool is_folder(const fs::path& path) {
  const PathProbe p = probe_path(path);
  if (p.kind == PathKind::kBroken) throw InputError("cannot use this path: " + p.what, {path.string()});
  return p.kind == PathKind::kDirectory;
}

bool is_plain_name(std::string_view name) {
  if (name.empty() || name == "." || name == "..") return false;
  for (const char c : name)
    if (c == '/' || static_cast<unsigned char>(c) < 0x20 || c == 0x7f) return false;
  return true;
}

bool path_exists(const fs::path& path) {
  const PathProbe p = probe_path(path);
  if (p.kind == PathKind::kBroken) throw InputError("cannot use this path: " + p.what, {path.string()});
  return p.kind != PathKind::kMissing;
}

InputFile::InputFile(const fs::path& path, const std::string& role) : path_(path.string()) {
  (void)require_regular_file(path, role);
  // O_NONBLOCK: should the path have become a FIFO since the check, open() returns at once.
  fd_ = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd_ < 0) throw InputError(std::string("cannot open the " + role + ": ") + std::strerror(errno), {path_});
  struct stat st {};
  if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) {
    const std::string what = special_kind(st.st_mode);
    ::close(fd_);
    throw InputError("is " + what + ", expected a " + role + " (roe reads regular files only)", {path_});
  }
  size_ = static_cast<std::uint64_t>(st.st_size);
}

InputFile::~InputFile() {
  if (fd_ >= 0) ::close(fd_);
}

std::size_t InputFile::read_at(std::uint64_t offset, void* out, std::size_t n) const {
  if (offset >= size_) return 0;
  if (n > size_ - offset) n = static_cast<std::size_t>(size_ - offset);
  std::size_t done = 0;
  while (done < n) {
    const ssize_t r = ::pread(fd_, static_cast<char*>(out) + done, n - done, static_cast<off_t>(offset + done));
    if (r < 0) {
      if (errno == EINTR) continue;
      throw InputError(std::string("read error: ") + std::strerror(errno), {path_});
    }
    if (r == 0) break;  // the file shrank meanwhile
    done += static_cast<std::size_t>(r);
  }
  return done;
}

std::string read_file(const fs::path& path) { return read_file_head(path, static_cast<std::size_t>(-1)); }

std::string read_file_head(const fs::path& path, std::size_t max_bytes) {
  const InputFile f(path);
  const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(f.size(), max_bytes));
  std::string text;
  try {
    text.resize(n);
  } catch (const std::bad_alloc&) {
    throw InputError("the file (" + std::to_string(f.size()) + " bytes) does not fit in memory", {f.path()});
  }
  text.resize(f.read_at(0, text.data(), text.size()));
  return text;
}

}  // namespace roe::io
