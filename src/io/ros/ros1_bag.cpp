// ROS bag v2.0 reader (see include/roe/io/ros/ros1_bag.hpp for the format summary).
#include "roe/io/ros/ros1_bag.hpp"

#include <bzlib.h>
#include <fmt/format.h>
#include <lz4frame.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <queue>
#include <set>

#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/io/ros/compression.hpp"
#include "roe/io/input.hpp"

namespace roe::io::bag {
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
// Compression
// ---------------------------------------------------------------------------------------------
bool lz4_decompress(std::string_view in, std::size_t expected_size, std::string& out) {
  // The output grows with what the decoder actually produces (doubling up to expected_size), so a
  // corrupt size field on a tiny chunk costs nothing: no up-front zero-filled allocation.
  out.clear();
  out.resize(std::min<std::size_t>(expected_size, 1u << 16));
  LZ4F_dctx* ctx = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION))) return false;
  std::size_t in_pos = 0, out_pos = 0;
  bool ok = true;
  while (true) {
    if (out_pos == out.size() && out.size() < expected_size)
      out.resize(std::min<std::size_t>(expected_size, 2 * out.size()));
    std::size_t src_size = in.size() - in_pos;
    std::size_t dst_size = out.size() - out_pos;
    const std::size_t r = LZ4F_decompress(ctx, out.data() + out_pos, &dst_size, in.data() + in_pos,
                                          &src_size, nullptr);
    if (LZ4F_isError(r)) {
      ok = false;
      break;
    }
    in_pos += src_size;
    out_pos += dst_size;
    if (r == 0) break;  // frame complete
    if (src_size == 0 && dst_size == 0 && (in_pos == in.size() || out_pos == expected_size)) {
      ok = false;  // input exhausted before the end of the frame, or more output than announced
      break;
    }
  }
  LZ4F_freeDecompressionContext(ctx);
  return ok && out_pos == expected_size;
}

std::string lz4_compress(std::string_view in) {
  LZ4F_preferences_t prefs;
  std::memset(&prefs, 0, sizeof prefs);
  prefs.frameInfo.contentChecksumFlag = LZ4F_contentChecksumEnabled;
  std::string out(LZ4F_compressFrameBound(in.size(), &prefs), '\0');
  const std::size_t n = LZ4F_compressFrame(out.data(), out.size(), in.data(), in.size(), &prefs);
  if (LZ4F_isError(n)) throw InternalError(std::string("LZ4 compression failed: ") + LZ4F_getErrorName(n));
  out.resize(n);
  return out;
}

bool bz2_decompress(std::string_view in, std::size_t expected_size, std::string& out) {
  // Streaming, with the output grown as it is produced (see lz4_decompress).
  if (in.size() > std::numeric_limits<unsigned>::max()) return false;
  out.clear();
  out.resize(std::min<std::size_t>(expected_size, 1u << 16));
  bz_stream s;
  std::memset(&s, 0, sizeof s);
  if (BZ2_bzDecompressInit(&s, 0, 0) != BZ_OK) return false;
  s.next_in = const_cast<char*>(in.data());  // libbz2 takes non-const pointers but does not write
  s.avail_in = static_cast<unsigned>(in.size());
  std::size_t out_pos = 0;
  bool ok = false;
  while (true) {
    if (out_pos == out.size() && out.size() < expected_size)
      out.resize(std::min<std::size_t>(expected_size, 2 * out.size()));
    const std::size_t room = std::min<std::size_t>(out.size() - out_pos, std::numeric_limits<unsigned>::max());
    s.next_out = out.data() + out_pos;
    s.avail_out = static_cast<unsigned>(room);
    const int r = BZ2_bzDecompress(&s);
    out_pos += room - s.avail_out;
    if (r == BZ_STREAM_END) {
      ok = out_pos == expected_size;
      break;
    }
    if (r != BZ_OK) break;
    if (room - s.avail_out == 0 && (s.avail_in == 0 || out_pos == expected_size)) break;  // stuck
  }
  BZ2_bzDecompressEnd(&s);
  return ok;
}

std::string bz2_compress(std::string_view in) {
  unsigned len = static_cast<unsigned>(in.size() + in.size() / 100 + 600);
  std::string out(len, '\0');
  const int r = BZ2_bzBuffToBuffCompress(out.data(), &len, const_cast<char*>(in.data()),
                                         static_cast<unsigned>(in.size()), 9, 0, 30);
  if (r != BZ_OK) throw InternalError("bz2 compression failed");
  out.resize(len);
  return out;
}

// ---------------------------------------------------------------------------------------------
// Reader
// ---------------------------------------------------------------------------------------------
Reader::Reader(const fs::path& file, ReaderOptions options)
    : name_(file.string()), src_(open_file_source(file)), options_(options) {
  open();
}

Reader::Reader(std::string bytes, std::string name, ReaderOptions options)
    : name_(std::move(name)), src_(memory_source(std::move(bytes))), options_(options) {
  open();
}

Reader::~Reader() = default;
Reader::Reader(Reader&&) noexcept = default;
Reader& Reader::operator=(Reader&&) noexcept = default;

std::uint64_t Reader::file_size() const { return src_->size(); }

void Reader::warn(std::uint64_t offset, std::string message, bool damage) {
  // A damaged chunk is met again by every iteration that reads it: one problem, one warning.
  for (const auto& w : warnings_)
    if (w.offset == offset && w.message == message) return;
  log::debug("{}: byte {}: {}", name_, offset, message);
  warnings_.push_back({offset, std::move(message), damage});
}

void Reader::warn_fallback(std::uint64_t offset, std::string message) {
  warn(offset, message);
  for (auto& w : warnings_)
    if (w.offset == offset && w.message == message) w.index_fallback = true;
}

std::vector<Warning> Reader::damage() const {
  std::vector<Warning> d;
  for (const auto& w : warnings_)
    if (w.damage) d.push_back(w);
  std::stable_partition(d.begin(), d.end(), [](const Warning& w) { return !w.index_fallback; });
  return d;
}

bool Reader::damaged() const {
  for (const auto& w : warnings_)
    if (w.damage) return true;
  return false;
}

std::string Reader::first_damage() const {
  for (const auto& w : warnings_)
    if (w.damage) return "byte " + std::to_string(w.offset) + ": " + w.message;
  return {};
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
  if (options_.max_chunk_bytes == 0) options_.max_chunk_bytes = chunk_decompression_limit(src_->size());
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
  // Chunks that hold any selected message, ordered by start time.
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
  std::stable_sort(order.begin(), order.end(),
                   [](const ChunkInfo* a, const ChunkInfo* b) { return a->start_ns < b->start_ns; });

  // k-way merge: messages of a chunk are buffered (sharing the chunk's buffer) until no later
  // chunk can hold an earlier message, i.e. up to the next chunk's start time.
  struct Pending {
    Timestamp t;
    std::uint64_t seq;
    std::shared_ptr<const std::string> buf;
    std::string_view data;
    const Connection* conn;
    std::uint64_t chunk_offset;
  };
  auto later = [](const Pending& a, const Pending& b) { return a.t != b.t ? a.t > b.t : a.seq > b.seq; };
  std::priority_queue<Pending, std::vector<Pending>, decltype(later)> heap(later);
  std::uint64_t seq = 0;
  std::size_t done = 0;
  bool stop = false;
  auto emit_until = [&](Timestamp limit, bool all) {
    while (!stop && !heap.empty() && (all || heap.top().t < limit)) {
      const Pending& p = heap.top();
      MessageView v{p.conn, p.t, p.data, p.chunk_offset};
      if (!fn(v)) stop = true;
      heap.pop();
      ++done;
      if (progress) progress(std::min(done, total), total);
    }
  };
  HeldChunks held;
  bool over_budget = false;
  for (std::size_t k = 0; k < order.size() && !stop; ++k) {
    const ChunkInfo& c = *order[k];
    std::string bytes;
    const bool loaded = load_chunk(c, bytes);
    const auto buf = held.hold(std::move(bytes));
    if (loaded) {
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
            if (ids.count(id)) {
              auto it = conn_index_.find(id);
              heap.push({t, seq++, buf, r.data, &connections_[it->second], c.offset});
            }
          } else {
            warn(c.offset, "message record without conn/time fields at uncompressed offset " +
                               std::to_string(p) + " skipped");
          }
        }
        p = r.next;
      }
    }
    const Timestamp next_start =
        k + 1 < order.size() ? order[k + 1]->start_ns : std::numeric_limits<Timestamp>::max();
    emit_until(next_start, k + 1 == order.size());
    // Chunks overlapping in time wait together; beyond one chunk's limit of them, what waits goes out now.
    if (held.bytes() + heap.size() * sizeof(Pending) > options_.max_chunk_bytes) {
      if (!over_budget)
        warn(c.offset, fmt::format("chunks overlapping in time hold more than {} decompressed bytes: messages "
                                   "from here on may be out of time order", options_.max_chunk_bytes),
             false);
      over_budget = true;
      emit_until(0, true);
    }
  }
  emit_until(0, true);
}

}  // namespace roe::io::bag
