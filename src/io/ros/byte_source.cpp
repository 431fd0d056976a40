// File and memory byte sources (include/roe/io/ros/byte_source.hpp).
#include "roe/io/ros/byte_source.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "roe/core/error.hpp"
#include "roe/io/input.hpp"

namespace roe::io {
namespace {
namespace fs = std::filesystem;

// Regular files only (io/input.hpp): a FIFO or a device is refused before anything is read.
class FileSource final : public ByteSource {
 public:
  explicit FileSource(const fs::path& p) : file_(p, "bag") {}
  std::uint64_t size() const override { return file_.size(); }
  std::size_t read_at(std::uint64_t offset, void* out, std::size_t n) const override {
    return file_.read_at(offset, out, n);
  }

 private:
  InputFile file_;
};

class MemorySource final : public ByteSource {
 public:
  explicit MemorySource(std::string b) : bytes_(std::move(b)) {}
  std::uint64_t size() const override { return bytes_.size(); }
  std::size_t read_at(std::uint64_t offset, void* out, std::size_t n) const override {
    if (offset >= bytes_.size()) return 0;
    n = std::min<std::size_t>(n, bytes_.size() - offset);
    std::memcpy(out, bytes_.data() + offset, n);
    return n;
  }

 private:
  std::string bytes_;
};

}  // namespace

std::unique_ptr<ByteSource> open_file_source(const fs::path& file) { return std::make_unique<FileSource>(file); }
std::unique_ptr<ByteSource> memory_source(std::string bytes) { return std::make_unique<MemorySource>(std::move(bytes)); }

}  // namespace roe::io
