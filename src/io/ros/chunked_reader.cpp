// The skeleton of the chunked bag readers (include/roe/io/ros/chunked_reader.hpp).
#include "roe/io/ros/chunked_reader.hpp"

#include <fmt/format.h>

#include "roe/core/log.hpp"
#include "roe/io/ros/compression.hpp"

namespace roe::io {

std::shared_ptr<const std::string> HeldChunks::hold(std::string bytes) {
  struct Node {
    std::string bytes;
    std::shared_ptr<std::uint64_t> total;
    Node(std::string b, std::shared_ptr<std::uint64_t> t) : bytes(std::move(b)), total(std::move(t)) {
      *total += bytes.size();
    }
    ~Node() { *total -= bytes.size(); }
    Node(const Node&) = delete;
    Node& operator=(const Node&) = delete;
  };
  auto node = std::make_shared<Node>(std::move(bytes), total_);
  return std::shared_ptr<const std::string>(node, &node->bytes);
}

ChunkedReader::ChunkedReader(const std::filesystem::path& file, ChunkedReaderOptions options)
    : name_(file.string()), src_(open_file_source(file)), options_(options) {
  if (options_.max_chunk_bytes == 0) options_.max_chunk_bytes = chunk_decompression_limit(src_->size());
}

ChunkedReader::ChunkedReader(std::string bytes, std::string name, ChunkedReaderOptions options)
    : name_(std::move(name)), src_(memory_source(std::move(bytes))), options_(options) {
  if (options_.max_chunk_bytes == 0) options_.max_chunk_bytes = chunk_decompression_limit(src_->size());
}

ChunkedReader::~ChunkedReader() = default;
ChunkedReader::ChunkedReader(ChunkedReader&&) noexcept = default;
ChunkedReader& ChunkedReader::operator=(ChunkedReader&&) noexcept = default;

std::uint64_t ChunkedReader::file_size() const { return src_->size(); }

void ChunkedReader::warn(std::uint64_t offset, std::string message, bool damage, bool index_fallback) {
  for (auto& w : warnings_)
    if (w.offset == offset && w.message == message) {
      w.index_fallback = w.index_fallback || index_fallback;
      return;
    }
  log::debug("{}: byte {}: {}", name_, offset, message);
  warnings_.push_back({offset, std::move(message), damage, index_fallback});
}

void ChunkedReader::warn_over_budget(std::uint64_t offset) {
  warn(offset, fmt::format("chunks overlapping in time hold more than {} decompressed bytes: messages from here on "
                           "may be out of time order",
                           options_.max_chunk_bytes),
       false);
}

bool ChunkedReader::damaged() const {
  return std::any_of(warnings_.begin(), warnings_.end(), [](const OffsetWarning& w) { return w.damage; });
}

std::vector<OffsetWarning> ChunkedReader::damage() const {
  std::vector<OffsetWarning> d;
  for (const auto& w : warnings_)
    if (w.damage) d.push_back(w);
  std::stable_partition(d.begin(), d.end(), [](const OffsetWarning& w) { return !w.index_fallback; });
  return d;
}

std::string ChunkedReader::first_damage() const {
  for (const auto& w : warnings_)
    if (w.damage) return "byte " + std::to_string(w.offset) + ": " + w.message;
  return {};
}

}  // namespace roe::io
