#pragma once
/// @file
/// The skeleton both chunked bag readers stand on (ROS 1 bags, ros1_bag.hpp; MCAP, mcap.hpp): a byte
/// source with its name and options, the offset-tagged warnings (one per problem, however often it is
/// met), and the time-ordered k-way merge of chunks. Each format keeps what is its own: the record
/// layout, the index or summary, how a chunk is decompressed and which of its records are messages.
///
/// The merge: chunks that hold a selected message are read in order of their start time; a chunk's
/// messages wait in a heap (sharing the chunk's buffer) until no later chunk can hold an earlier one,
/// i.e. up to the next chunk's start time, so messages come out in time order (ties in file order)
/// with one chunk in memory plus those that overlap it in time. Beyond options().max_chunk_bytes of
/// waiting chunks, what waits goes out at once with a note (the order may then break).

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <queue>
#include <string>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/io/ros/byte_source.hpp"

namespace roe::io {

struct ChunkedReaderOptions {
  /// Ignore the index (ROS 1) or summary (MCAP) even when intact and scan every record (tests, and
  /// files whose index is suspected to be wrong).
  bool force_scan = false;
  /// Largest uncompressed chunk accepted (a corrupt size field or a decompression bomb must not cost more
  /// memory): 0 is io::chunk_decompression_limit(file size) (compression.hpp: 4× the file, within
  /// [64 MiB, 256 MiB]). The k-way merge of chunks that overlap in time holds at most this many bytes of
  /// decompressed chunks waiting for their turn (beyond, it emits what waits, with a warning).
  std::uint64_t max_chunk_bytes = 0;
};

/// The decompressed chunks a merge holds while their messages wait for their turn: hold() takes a chunk's
/// bytes and counts them until the last message view of it is dropped, so the merge can bound what it keeps
/// (ChunkedReaderOptions::max_chunk_bytes) even when a file's chunks all overlap.
class HeldChunks {
 public:
  std::shared_ptr<const std::string> hold(std::string bytes);
  std::uint64_t bytes() const { return *total_; }

 private:
  std::shared_ptr<std::uint64_t> total_ = std::make_shared<std::uint64_t>(0);
};

/// Messages of type `View` (valid while their chunk is held) handed to `fn` in time order.
template <class View>
class TimeOrderedMerge {
 public:
  TimeOrderedMerge(const std::function<bool(const View&)>& fn, const ProgressCallback& progress, std::size_t total)
      : fn_(fn), progress_(progress), total_(total) {}
  /// Keeps a chunk's bytes alive while its messages wait.
  std::shared_ptr<const std::string> hold(std::string bytes) { return held_.hold(std::move(bytes)); }
  /// A message at time `t` whose view points into `chunk`.
  void push(Timestamp t, std::shared_ptr<const std::string> chunk, const View& v) {
    heap_.push({t, seq_++, std::move(chunk), v});
  }
  /// Hands out the waiting messages earlier than `limit` (all of them when `all`), until fn says stop.
  void emit_until(Timestamp limit, bool all) {
    while (!stop_ && !heap_.empty() && (all || heap_.top().t < limit)) {
      if (!fn_(heap_.top().view)) stop_ = true;
      heap_.pop();
      ++done_;
      if (progress_) progress_(std::min(done_, total_), total_);
    }
  }
  bool stopped() const { return stop_; }
  /// What the waiting messages hold: their chunks' bytes and the heap itself.
  std::uint64_t waiting_bytes() const { return held_.bytes() + heap_.size() * sizeof(Pending); }

 private:
  struct Pending {
    Timestamp t;
    std::uint64_t seq;
    std::shared_ptr<const std::string> chunk;
    View view;
  };
  struct Later {
    bool operator()(const Pending& a, const Pending& b) const { return a.t != b.t ? a.t > b.t : a.seq > b.seq; }
  };
  std::function<bool(const View&)> fn_;
  ProgressCallback progress_;
  std::size_t total_ = 0, done_ = 0;
  std::uint64_t seq_ = 0;
  bool stop_ = false;
  HeldChunks held_;
  std::priority_queue<Pending, std::vector<Pending>, Later> heap_;
};

/// The common part of the ROS 1 and MCAP readers (the two Reader classes derive from it).
class ChunkedReader {
 public:
  const std::string& name() const { return name_; }
  std::uint64_t file_size() const;
  const ChunkedReaderOptions& options() const { return options_; }
  /// Problems skipped while opening and reading (grows while iterating; a damaged chunk read by several
  /// iterations is listed once).
  const std::vector<OffsetWarning>& warnings() const { return warnings_; }
  /// Whether any warning reports damage (data that could not be read).
  bool damaged() const;
  /// The damage warnings, the most specific first: problems found in the records themselves (a truncated
  /// record, a chunk that fails to decompress) before the index-level ones that only made the reader fall
  /// back to a scan (OffsetWarning::index_fallback); otherwise in the order found.
  std::vector<OffsetWarning> damage() const;
  /// "byte N: message" of the first damage warning (empty when none).
  std::string first_damage() const;

 protected:
  /// A file (InputError naming it when it cannot be read), or bytes held in memory named `name`.
  /// max_chunk_bytes 0 becomes chunk_decompression_limit(size).
  ChunkedReader(const std::filesystem::path& file, ChunkedReaderOptions options);
  ChunkedReader(std::string bytes, std::string name, ChunkedReaderOptions options);
  ~ChunkedReader();
  ChunkedReader(ChunkedReader&&) noexcept;
  ChunkedReader& operator=(ChunkedReader&&) noexcept;

  /// Records a problem at byte `offset` of the file, once (a damaged chunk is met by every iteration
  /// that reads it). `index_fallback`: the index/summary was unusable and the reader scans instead.
  void warn(std::uint64_t offset, std::string message, bool damage = true, bool index_fallback = false);
  /// A damage that makes the reader give up its index or summary and scan the records.
  void warn_fallback(std::uint64_t offset, std::string message) { warn(offset, std::move(message), true, true); }

  /// The loop of every iteration: `chunks` (those holding a selected message) in order of start time,
  /// `read(chunk)` pushing the chunk's selected messages into `merge`, which hands them out between
  /// chunks as far as no later chunk can precede them. Chunk needs `offset` and `start_ns`.
  template <class Chunk, class View>
  void merge_chunks(std::vector<const Chunk*> chunks, TimeOrderedMerge<View>& merge,
                    const std::function<void(const Chunk&)>& read) {
    std::stable_sort(chunks.begin(), chunks.end(), [](const Chunk* a, const Chunk* b) { return a->start_ns < b->start_ns; });
    bool over_budget = false;
    for (std::size_t k = 0; k < chunks.size() && !merge.stopped(); ++k) {
      read(*chunks[k]);
      const bool last = k + 1 == chunks.size();
      merge.emit_until(last ? std::numeric_limits<Timestamp>::max() : chunks[k + 1]->start_ns, last);
      // Chunks overlapping in time wait together; beyond one chunk's limit of them, what waits goes out now.
      if (merge.waiting_bytes() > options_.max_chunk_bytes) {
        if (!over_budget) warn_over_budget(chunks[k]->offset);
        over_budget = true;
        merge.emit_until(0, true);
      }
    }
    merge.emit_until(0, true);
  }

  std::string name_;
  std::unique_ptr<ByteSource> src_;
  ChunkedReaderOptions options_;
  std::vector<OffsetWarning> warnings_;

 private:
  void warn_over_budget(std::uint64_t offset);
};

}  // namespace roe::io
