// ROS bag v2.0 reader (see include/roe/io/ros/ros1_bag.hpp for the format summary).
#include "roe/io/ros/ros1_bag.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <set>

#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/io/ros/compression.hpp"
#include "roe/io/input.hpp"

namespace roe::io::ros1 {
namespace {

constexpr char kMagic[] = "#ROSBAG V2.0\n";
constexpr std::size_t kMagicLen = 13;
// Upper bound on a record header; real ones are < 1 kB (connection headers live in the data part).
constexpr std::uint32_t kMaxHeaderLen = 1u << 20;

enum Op : std::uint8_t {
  kOpMessage = 0x02,
  kOpBagHeader = 0x03,
  kOpIndexData = 0x04,
  kOpChunk = 0x05,
  kOpChunkInfo = 0x06,
  kOpConnection = 0x07,
};

std::uint32_t le32(const char* p) {
  std::uint32_t v;
  std::memcpy(&v, p, 4);  // bags are little-endian, as is every platform roe targets
  return v;
}
std::uint64_t le64(const char* p) {
  std::uint64_t v;
  std::memcpy(&v, p, 8);
  return v;
}
Timestamp bag_time(const char* p) {
  // time = uint32 sec, uint32 nsec
  return static_cast<Timestamp>(le32(p)) * kNsPerSecond + static_cast<Timestamp>(le32(p + 4));
}

/// Parsed record header fields.
struct Header {
  std::map<std::string, std::string_view> fields;
  bool has(const char* k) const { return fields.count(k) != 0; }
  std::string_view get(const char* k) const {
    auto it = fields.find(k);
    return it == fields.end() ? std::string_view() : it->second;
  }
  int op() const {
    auto v = get("op");
    return v.size() == 1 ? static_cast<std::uint8_t>(v[0]) : -1;
  }
  bool u32(const char* k, std::uint32_t& out) const {
    auto v = get(k);
    if (v.size() != 4) return false;
    out = le32(v.data());
    return true;
  }
  bool u64(const char* k, std::uint64_t& out) const {
    auto v = get(k);
    if (v.size() != 8) return false;
    out = le64(v.data());
    return true;
  }
  bool time(const char* k, Timestamp& out) const {
    auto v = get(k);
    if (v.size() != 8) return false;
    out = bag_time(v.data());
    return true;
  }
};

/// Splits a header block into fields; false when malformed.
bool parse_header(std::string_view block, Header& h) {
  h.fields.clear();
  std::size_t pos = 0;
  while (pos < block.size()) {
    if (block.size() - pos < 4) return false;
    const std::uint32_t len = le32(block.data() + pos);
    pos += 4;
    if (len > block.size() - pos) return false;
    std::string_view field = block.substr(pos, len);
    pos += len;
    const std::size_t eq = field.find('=');
    if (eq == std::string_view::npos || eq == 0) return false;
    h.fields[std::string(field.substr(0, eq))] = field.substr(eq + 1);
  }
  return true;
}

/// A record located in a byte buffer (inside a chunk).
struct BufRecord {
  Header header;
  std::string_view data;
  std::size_t next = 0;
};

/// Parses the record at `pos` in `buf`; empty optional-like false on malformed/truncated input.
bool parse_buf_record(std::string_view buf, std::size_t pos, BufRecord& r, std::string& why) {
  if (buf.size() - pos < 4) {
    why = "truncated record header length";
    return false;
  }
  const std::uint32_t hlen = le32(buf.data() + pos);
  if (hlen > buf.size() - pos - 4) {
    why = "record header runs past the end";
    return false;
  }
  if (!parse_header(buf.substr(pos + 4, hlen), r.header)) {
    why = "malformed record header";
    return false;
  }
  const std::size_t dpos = pos + 4 + hlen;
  if (buf.size() - dpos < 4) {
    why = "truncated record data length";
    return false;
  }
  const std::uint32_t dlen = le32(buf.data() + dpos);
  if (dlen > buf.size() - dpos - 4) {
    why = "record data runs past the end";
    return false;
  }
  r.data = buf.substr(dpos + 4, dlen);
  r.next = dpos + 4 + dlen;
  return true;
}

bool parse_connection(const Header& h, std::string_view data, Connection& c) {
  std::uint32_t id = 0;
  if (!h.u32("conn", id)) return false;
  c.id = id;
  c.topic = std::string(h.get("topic"));
  Header d;
  if (!parse_header(data, d)) return false;
  if (d.has("topic") && c.topic.empty()) c.topic = std::string(d.get("topic"));
  c.type = std::string(d.get("type"));
  c.md5sum = std::string(d.get("md5sum"));
  c.message_definition = std::string(d.get("message_definition"));
  c.callerid = std::string(d.get("callerid"));
  c.latching = d.get("latching") == "1";
  return !c.topic.empty();
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Reader
// ---------------------------------------------------------------------------------------------
Reader::Reader(const fs::path& file, ReaderOptions options) : ChunkedReader(file, options) { open(); }

Reader::Reader(std::string bytes, std::string name, ReaderOptions options)
    : ChunkedReader(std::move(bytes), std::move(name), options) {
  open();
}

void Reader::add_connection(Connection c) {
  auto it = conn_index_.find(c.id);
  if (it != conn_index_.end()) return;  // connections are repeated in chunks and in the index
  conn_index_[c.id] = connections_.size();
  connections_.push_back(std::move(c));
}

namespace {
/// Reads a record header at `pos` of the file: header fields into `h` (storage in `hbuf`), the data
/// length and the data offset. Returns an empty string on success, otherwise why it failed.
std::string read_file_record_header(const ByteSource& src, std::uint64_t pos, std::string& hbuf, Header& h,
                                    std::uint32_t& data_len, std::uint64_t& data_pos) {
  const std::uint64_t size = src.size();
  char b4[4];
  if (pos + 4 > size || src.read_at(pos, b4, 4) != 4) return "truncated record (no header length)";
  const std::uint32_t hlen = le32(b4);
  if (hlen > kMaxHeaderLen) return "record header length " + std::to_string(hlen) + " is implausible";
  if (pos + 4 + hlen + 4 > size) return "truncated record (header runs past the end of the file)";
  hbuf.resize(hlen);
  if (src.read_at(pos + 4, hbuf.data(), hlen) != hlen) return "read error in record header";
  if (!parse_header(hbuf, h)) return "malformed record header";
  if (src.read_at(pos + 4 + hlen, b4, 4) != 4) return "truncated record (no data length)";
  data_len = le32(b4);
  data_pos = pos + 8 + hlen;
  if (data_pos + data_len > size) return "truncated record (data runs past the end of the file)";
  return {};
}
}  // namespace

void Reader::open() {
  char magic[kMagicLen];
  if (src_->read_at(0, magic, kMagicLen) != kMagicLen || std::memcmp(magic, kMagic, kMagicLen) != 0) {
    if (src_->size() >= 9 && std::memcmp(magic, "#ROSBAG V", 9) == 0)
      throw InputError("unsupported ROS bag version (only V2.0 is supported): \"" +
                           std::string(magic, magic + std::min<std::size_t>(12, src_->size())) + "\"",
                       {name_});
    throw InputError("not a ROS bag v2.0 file (wrong magic at byte 0; expected \"#ROSBAG V2.0\")", {name_});
  }
  // Bag header record.
  std::string hbuf;
  Header h;
  std::uint32_t dlen = 0;
  std::uint64_t dpos = 0;
  const std::string why = read_file_record_header(*src_, kMagicLen, hbuf, h, dlen, dpos);
  std::uint64_t index_pos = 0;
  std::uint32_t chunk_count = 0;
  if (!why.empty() || h.op() != kOpBagHeader) {
    warn_fallback(kMagicLen, why.empty() ? "first record is not a bag header" : "bag header: " + why);
  } else {
    h.u64("index_pos", index_pos);
    h.u32("chunk_count", chunk_count);
  }
  if (!options_.force_scan && index_pos > kMagicLen && index_pos < src_->size() &&
      read_index(index_pos, static_cast<std::int32_t>(chunk_count))) {
    indexed_ = true;
    return;
  }
  if (!options_.force_scan) {
    if (index_pos == 0)
      warn(kMagicLen, "bag is not indexed (index_pos = 0); scanning the records sequentially", false);
    else if (index_pos >= src_->size())
      warn_fallback(kMagicLen, "index position " + std::to_string(index_pos) +
                          " is past the end of the file (truncated bag?); scanning the records sequentially");
  }
  connections_.clear();
  conn_index_.clear();
  chunks_.clear();
  scan();
}

bool Reader::read_index(std::uint64_t index_pos, std::int32_t chunk_count) {
  // The index section: connection records followed by chunk-info records, up to the end of the file.
  std::vector<ChunkInfo> chunks;
  std::string hbuf, dbuf;
  Header h;
  std::uint64_t pos = index_pos;
  while (pos < src_->size()) {
    std::uint32_t dlen = 0;
    std::uint64_t dpos = 0;
    const std::string why = read_file_record_header(*src_, pos, hbuf, h, dlen, dpos);
    if (!why.empty()) {
      warn_fallback(pos, "index section: " + why + "; scanning the records sequentially");
      return false;
    }
    dbuf.resize(dlen);
    src_->read_at(dpos, dbuf.data(), dlen);
    if (h.op() == kOpConnection) {
      Connection c;
      if (!parse_connection(h, dbuf, c)) {
        warn_fallback(pos, "index section: malformed connection record; scanning the records sequentially");
        return false;
      }
      add_connection(std::move(c));
    } else if (h.op() == kOpChunkInfo) {
      ChunkInfo ci;
      std::uint32_t n = 0;
      if (!h.u64("chunk_pos", ci.offset) || !h.time("start_time", ci.start_ns) ||
          !h.time("end_time", ci.end_ns) || !h.u32("count", n) || dlen < 8ull * n) {
        warn_fallback(pos, "index section: malformed chunk info record; scanning the records sequentially");
        return false;
      }
      for (std::uint32_t i = 0; i < n; ++i) ci.counts[le32(dbuf.data() + 8 * i)] = le32(dbuf.data() + 8 * i + 4);
      ci.times_known = true;
      chunks.push_back(std::move(ci));
    } else {
      warn_fallback(pos, "index section: unexpected record (op " + std::to_string(h.op()) +
                    "); scanning the records sequentially");
      return false;
    }
    pos = dpos + dlen;
  }
  if (chunk_count >= 0 && chunks.size() != static_cast<std::size_t>(chunk_count)) {
    warn_fallback(index_pos, "index section lists " + std::to_string(chunks.size()) + " chunks, bag header says " +
                        std::to_string(chunk_count) + "; scanning the records sequentially");
    return false;
  }
  // Resolve every chunk record's header (compression, sizes, data position).
  for (auto& c : chunks) {
    std::uint32_t dlen = 0;
    std::uint64_t dpos = 0;
    const std::string why = read_file_record_header(*src_, c.offset, hbuf, h, dlen, dpos);
    std::uint32_t usize = 0;
    if (!why.empty() || h.op() != kOpChunk || !h.u32("size", usize)) {
      warn_fallback(c.offset, "chunk listed in the index is unreadable (" + (why.empty() ? "not a chunk record" : why) +
                         "); scanning the records sequentially");
      return false;
    }
    c.compression = std::string(h.get("compression"));
    c.data_offset = dpos;
    c.data_size = dlen;
    c.uncompressed_size = usize;
  }
  std::stable_sort(chunks.begin(), chunks.end(),
                   [](const ChunkInfo& a, const ChunkInfo& b) { return a.offset < b.offset; });
  chunks_ = std::move(chunks);
  return true;
}

void Reader::scan() {
  // Sequential scan of the top-level records. Chunks are located; their per-connection counts and
  // time range come from the index-data records that follow them, or, when those are missing, from
  // decompressing the chunk (which also yields the connections stored inside it).
  std::string hbuf, dbuf;
  Header h;
  std::uint64_t pos = kMagicLen;
  ChunkInfo* last_chunk = nullptr;
  const std::uint64_t size = src_->size();
  while (pos < size) {
    std::uint32_t dlen = 0;
    std::uint64_t dpos = 0;
    const std::string why = read_file_record_header(*src_, pos, hbuf, h, dlen, dpos);
    if (!why.empty()) {
      warn(pos, why + "; the rest of the file (" + std::to_string(size - pos) + " bytes) is ignored");
      break;
    }
    const int op = h.op();
    if (op == kOpChunk) {
      ChunkInfo c;
      c.offset = pos;
      c.data_offset = dpos;
      c.data_size = dlen;
      c.compression = std::string(h.get("compression"));
      if (!h.u32("size", c.uncompressed_size)) {
        warn(pos, "chunk record without a valid size field; chunk skipped");
        last_chunk = nullptr;
      } else {
        chunks_.push_back(std::move(c));
        last_chunk = &chunks_.back();
      }
    } else if (op == kOpIndexData) {
      std::uint32_t conn = 0, count = 0, ver = 0;
      if (last_chunk && h.u32("ver", ver) && ver == 1 && h.u32("conn", conn) && h.u32("count", count) &&
          dlen >= 12ull * count) {
        dbuf.resize(dlen);
        src_->read_at(dpos, dbuf.data(), dlen);
        for (std::uint32_t i = 0; i < count; ++i) {
          const Timestamp t = bag_time(dbuf.data() + 12 * i);
          if (!last_chunk->times_known) {
            last_chunk->start_ns = last_chunk->end_ns = t;
            last_chunk->times_known = true;
          }
          last_chunk->start_ns = std::min(last_chunk->start_ns, t);
          last_chunk->end_ns = std::max(last_chunk->end_ns, t);
        }
        last_chunk->counts[conn] += count;
      } else if (!last_chunk) {
        // Index data of a skipped chunk: nothing to attach it to.
      } else {
        warn(pos, "malformed index data record ignored");
      }
    } else if (op == kOpConnection) {
      dbuf.resize(dlen);
      src_->read_at(dpos, dbuf.data(), dlen);
      Connection c;
      if (parse_connection(h, dbuf, c)) add_connection(std::move(c));
      else warn(pos, "malformed connection record ignored");
    } else if (op == kOpBagHeader || op == kOpChunkInfo) {
      // Nothing needed: the scan rebuilds this information.
    } else if (op == kOpMessage) {
      warn(pos, "message record outside a chunk ignored");
    } else {
      warn(pos, "unknown record op " + std::to_string(op) + " ignored");
    }
    pos = dpos + dlen;
  }
  // Chunks without index data (unindexed or truncated bags): decompress to learn their content.
  std::string buf;
  for (auto& c : chunks_) {
    if (c.times_known) {
      // Connections are needed even for indexed chunks when the index section is missing.
      bool all_known = true;
      for (const auto& kv : c.counts) all_known = all_known && conn_index_.count(kv.first);
      if (all_known) continue;
    }
    if (!load_chunk(c, buf)) continue;
    const bool had_times = c.times_known;
    std::size_t p = 0;
    BufRecord r;
    std::string why;
    while (p < buf.size()) {
      if (!parse_buf_record(buf, p, r, why)) {
        warn(c.offset, "inside chunk at uncompressed offset " + std::to_string(p) + ": " + why);
        break;
      }
      if (r.header.op() == kOpConnection) {
        Connection conn;
        if (parse_connection(r.header, r.data, conn)) add_connection(std::move(conn));
      } else if (r.header.op() == kOpMessage && !had_times) {
        std::uint32_t id = 0;
        Timestamp t = 0;
        if (r.header.u32("conn", id) && r.header.time("time", t)) {
          if (!c.times_known) {
            c.start_ns = c.end_ns = t;
            c.times_known = true;
          }
          c.start_ns = std::min(c.start_ns, t);
          c.end_ns = std::max(c.end_ns, t);
          c.counts[id] += 1;
        }
      }
      p = r.next;
    }
  }
}

bool Reader::load_chunk(const ChunkInfo& c, std::string& out) {
  std::string raw(c.data_size, '\0');
  if (src_->read_at(c.data_offset, raw.data(), c.data_size) != c.data_size) {
    warn(c.offset, "chunk data could not be read; chunk skipped");
    return false;
  }
  if (c.compression == "none") {
    if (c.uncompressed_size != c.data_size)
      warn(c.offset, "uncompressed chunk: size field " + std::to_string(c.uncompressed_size) +
                         " differs from the data length " + std::to_string(c.data_size) + "; using the data");
    out = std::move(raw);
    return true;
  }
  // Guard against absurd sizes from corrupt headers before allocating.
  if (c.uncompressed_size > options_.max_chunk_bytes) {
    warn(c.offset, "chunk claims an uncompressed size of " + std::to_string(c.uncompressed_size) +
                       " bytes, more than the " + std::to_string(options_.max_chunk_bytes) +
                       "-byte limit for this file (docs/import.md, \"Limits\"); chunk skipped");
    return false;
  }
  if (c.compression == "lz4") {
    if (!lz4_decompress(raw, c.uncompressed_size, out)) {
      warn(c.offset, "LZ4 chunk fails to decompress; chunk skipped");
      return false;
    }
    return true;
  }
  if (c.compression == "bz2") {
    if (!bz2_decompress(raw, c.uncompressed_size, out)) {
      warn(c.offset, "bz2 chunk fails to decompress; chunk skipped");
      return false;
    }
    return true;
  }
  warn(c.offset, "unknown chunk compression \"" + c.compression + "\"; chunk skipped");
  return false;
}

std::vector<std::string> Reader::topics() const {
  std::set<std::string> s;
  for (const auto& c : connections_) s.insert(c.topic);
  return {s.begin(), s.end()};
}

std::string Reader::topic_type(const std::string& topic) const {
  for (const auto& c : connections_)
    if (c.topic == topic) return c.type;
  return {};
}

std::size_t Reader::message_count(const std::string& topic) const {
  std::set<std::uint32_t> ids;
  for (const auto& c : connections_)
    if (c.topic == topic) ids.insert(c.id);
  std::size_t n = 0;
  for (const auto& ch : chunks_)
    for (const auto& kv : ch.counts)
      if (ids.count(kv.first)) n += kv.second;
  return n;
}

std::size_t Reader::message_count() const {
  std::size_t n = 0;
  for (const auto& ch : chunks_)
    for (const auto& kv : ch.counts) n += kv.second;
  return n;
}

void Reader::for_each_topic(const std::vector<std::string>& topics,
                            const std::function<bool(const MessageView&)>& fn,
                            const ProgressCallback& progress) {
  const std::set<std::string> want(topics.begin(), topics.end());
  for_each([&](const Connection& c) { return want.count(c.topic) != 0; }, fn, progress);
}

void Reader::for_each(const std::function<bool(const Connection&)>& select,
                      const std::function<bool(const MessageView&)>& fn, const ProgressCallback& progress) {
  std::set<std::uint32_t> ids;
  for (const auto& c : connections_)
    if (select(c)) ids.insert(c.id);
  // Chunks that hold any selected message.
  std::vector<const ChunkInfo*> order;
  std::size_t total = 0;
  for (const auto& ch : chunks_) {
    std::size_t n = 0;
    for (const auto& kv : ch.counts)
      if (ids.count(kv.first)) n += kv.second;
    if (n > 0) {
      order.push_back(&ch);
      total += n;
    }
  }
  TimeOrderedMerge<MessageView> merge(fn, progress, total);
  merge_chunks<ChunkInfo>(order, merge, [&](const ChunkInfo& c) {
    std::string bytes;
    const bool loaded = load_chunk(c, bytes);
    const auto buf = merge.hold(std::move(bytes));
    if (!loaded) return;
    std::size_t p = 0;
    BufRecord r;
    std::string why;
    while (p < buf->size()) {
      if (!parse_buf_record(*buf, p, r, why)) {
        warn(c.offset, "inside chunk at uncompressed offset " + std::to_string(p) + ": " + why +
                           "; rest of the chunk skipped");
        break;
      }
      if (r.header.op() == kOpMessage) {
        std::uint32_t id = 0;
        Timestamp t = 0;
        if (r.header.u32("conn", id) && r.header.time("time", t)) {
          if (ids.count(id)) merge.push(t, buf, {&connections_[conn_index_.at(id)], t, r.data, c.offset});
        } else {
          warn(c.offset, "message record without conn/time fields at uncompressed offset " + std::to_string(p) +
                             " skipped");
        }
      }
      p = r.next;
    }
  });
}

}  // namespace roe::io::ros1
