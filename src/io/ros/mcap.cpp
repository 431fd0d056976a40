// MCAP reader (see include/roe/io/ros/mcap.hpp for the format summary).
#include "roe/io/ros/mcap.hpp"

#include <algorithm>
#include <array>
#include <cstring>
#include <limits>
#include <optional>
#include <utility>
#include <set>

#include <fmt/format.h>

#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/io/ros/compression.hpp"

namespace roe::io::mcap {
namespace {

enum Op : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kStatistics = 0x0B,
  kDataEnd = 0x0F,
};

constexpr std::uint64_t kRecordPrefix = 9;                    // opcode u8 + length u64
constexpr std::uint64_t kFooterRecord = kRecordPrefix + 20;   // footer content: u64 u64 u32
constexpr std::uint64_t kMaxSummaryBytes = 256ull << 20;      // a summary is a few bytes per chunk
constexpr std::uint64_t kMessageHeaderBytes = 2 + 4 + 8 + 8;  // channel, sequence, log and publish time

/// Bounded little-endian reader over one record's content: any read past the end clears ok().
class Rd {
 public:
  explicit Rd(std::string_view d) : d_(d) {}
  bool ok() const { return ok_; }
  std::size_t pos() const { return p_; }
  std::size_t left() const { return d_.size() - p_; }
  template <class T>
  T num() {
    T v{};
    if (!need(sizeof(T))) return v;
    std::memcpy(&v, d_.data() + p_, sizeof(T));  // MCAP is little-endian, as is every platform roe targets
    p_ += sizeof(T);
    return v;
  }
  std::string_view bytes(std::uint64_t n) {
    if (!need(n)) return {};
    const std::string_view v = d_.substr(p_, static_cast<std::size_t>(n));
    p_ += static_cast<std::size_t>(n);
    return v;
  }
  std::string str() { return std::string(bytes(num<std::uint32_t>())); }
  std::string_view rest() { return bytes(left()); }

 private:
  bool need(std::uint64_t n) {
    if (!ok_ || n > left()) ok_ = false;
    return ok_;
  }
  std::string_view d_;
  std::size_t p_ = 0;
  bool ok_ = true;
};

Timestamp ns(std::uint64_t t) {
  return static_cast<Timestamp>(std::min<std::uint64_t>(t, std::numeric_limits<Timestamp>::max()));
}

bool parse_schema(std::string_view content, Schema& s) {
  Rd r(content);
  s.id = r.num<std::uint16_t>();
  s.name = r.str();
  s.encoding = r.str();
  s.data = std::string(r.bytes(r.num<std::uint32_t>()));
  return r.ok();
}

bool parse_channel(std::string_view content, Channel& c) {
  Rd r(content);
  c.id = r.num<std::uint16_t>();
  c.schema_id = r.num<std::uint16_t>();
  c.topic = r.str();
  c.message_encoding = r.str();
  Rd m(r.bytes(r.num<std::uint32_t>()));
  while (r.ok() && m.ok() && m.left() > 0) {
    std::string k = m.str();
    std::string v = m.str();
    if (m.ok()) c.metadata[std::move(k)] = std::move(v);
  }
  return r.ok() && m.ok() && !c.topic.empty();
}

struct MessageHead {
  std::uint16_t channel = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time = 0, publish_time = 0;
  std::string_view data;
};

bool parse_message(std::string_view content, MessageHead& m) {
  Rd r(content);
  m.channel = r.num<std::uint16_t>();
  m.sequence = r.num<std::uint32_t>();
  m.log_time = r.num<std::uint64_t>();
  m.publish_time = r.num<std::uint64_t>();
  m.data = r.rest();
  return r.ok();
}

/// Slicing-by-8 tables of the reflected CRC-32 polynomial 0xEDB88320 (8 bytes per step).
const std::array<std::array<std::uint32_t, 256>, 8>& crc_tables() {
  static const auto tables = [] {
    std::array<std::array<std::uint32_t, 256>, 8> t{};
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[0][i] = c;
    }
    for (std::uint32_t i = 0; i < 256; ++i)
      for (int k = 1; k < 8; ++k) t[k][i] = (t[k - 1][i] >> 8) ^ t[0][t[k - 1][i] & 0xFFu];
    return t;
  }();
  return tables;
}

std::string op_name(int op) { return fmt::format("0x{:02x}", op); }

/// Walks a block of records (opcode u8, length u64, content: a chunk's records, or the summary section):
/// fn(opcode, content, offset in the block) for each in turn while fn returns true. Returns the offset of
/// a record that runs past the end of the block, if one does (the walk stops there).
template <class F>
std::optional<std::uint64_t> for_each_record(std::string_view records, F&& fn) {
  std::uint64_t p = 0;
  while (p < records.size()) {
    Rd r(records.substr(static_cast<std::size_t>(p)));
    const auto op = r.num<std::uint8_t>();
    const auto len = r.num<std::uint64_t>();
    const std::string_view content = r.bytes(len);
    if (!r.ok()) return p;
    if (!fn(op, content, p)) break;
    p += kRecordPrefix + len;
  }
  return std::nullopt;
}

/// A Chunk Index record of the summary: the chunk's time span and place, and the offset of each
/// channel's message index. False when it is malformed or points outside the data section.
bool parse_chunk_index(std::string_view content, std::uint64_t summary_start, ChunkInfo& ci,
                       std::map<std::uint16_t, std::uint64_t>& offs) {
  Rd c(content);
  ci.start_ns = ns(c.num<std::uint64_t>());
  ci.end_ns = ns(c.num<std::uint64_t>());
  ci.offset = c.num<std::uint64_t>();
  const auto chunk_len = c.num<std::uint64_t>();
  Rd m(c.bytes(c.num<std::uint32_t>()));
  while (c.ok() && m.ok() && m.left() > 0) {
    const auto ch = m.num<std::uint16_t>();
    const auto off = m.num<std::uint64_t>();
    if (m.ok()) offs[ch] = off;
  }
  c.num<std::uint64_t>();  // message_index_length
  c.str();                 // compression (read again from the chunk itself)
  if (!(c.ok() && m.ok() && ci.offset >= 8 && chunk_len <= summary_start && ci.offset <= summary_start - chunk_len))
    return false;
  for (const auto& kv : offs) ci.counts[kv.first] = 0;
  ci.channels_known = !offs.empty();
  return true;
}

/// A Statistics record: the message count and the count per channel. False when it is malformed.
bool parse_statistics(std::string_view content, std::uint64_t& messages, std::map<std::uint16_t, std::uint64_t>& counts) {
  Rd s(content);
  messages = s.num<std::uint64_t>();
  s.num<std::uint16_t>();
  s.num<std::uint32_t>();
  s.num<std::uint32_t>();
  s.num<std::uint32_t>();
  s.num<std::uint32_t>();
  s.num<std::uint64_t>();
  s.num<std::uint64_t>();
  Rd m(s.bytes(s.num<std::uint32_t>()));
  while (s.ok() && m.ok() && m.left() > 0) {
    const auto ch = m.num<std::uint16_t>();
    const auto n = m.num<std::uint64_t>();
    if (m.ok()) counts[ch] = n;
  }
  return s.ok() && m.ok();
}

}  // namespace

std::uint32_t crc32(std::string_view data, std::uint32_t crc) {
  const auto& t = crc_tables();
  crc = ~crc;
  const auto* p = reinterpret_cast<const unsigned char*>(data.data());
  std::size_t n = data.size();
  while (n >= 8) {  // little-endian host (as everywhere roe runs)
    std::uint32_t lo, hi;
    std::memcpy(&lo, p, 4);
    std::memcpy(&hi, p + 4, 4);
    lo ^= crc;
    crc = t[7][lo & 0xFF] ^ t[6][(lo >> 8) & 0xFF] ^ t[5][(lo >> 16) & 0xFF] ^ t[4][lo >> 24] ^ t[3][hi & 0xFF] ^
          t[2][(hi >> 8) & 0xFF] ^ t[1][(hi >> 16) & 0xFF] ^ t[0][hi >> 24];
    p += 8;
    n -= 8;
  }
  while (n--) crc = t[0][(crc ^ *p++) & 0xFFu] ^ (crc >> 8);
  return ~crc;
}

Reader::Reader(const fs::path& file, ReaderOptions options) : ChunkedReader(file, options) { open(); }

Reader::Reader(std::string bytes, std::string name, ReaderOptions options)
    : ChunkedReader(std::move(bytes), std::move(name), options) {
  open();
}

std::string Reader::schema_name(const Channel& c) const {
  const auto it = schemas_.find(c.schema_id);
  return it == schemas_.end() ? std::string() : it->second.name;
}

std::uint64_t Reader::message_count(std::uint16_t channel_id) const {
  if (have_stat_counts_) {
    const auto it = stat_counts_.find(channel_id);
    return it == stat_counts_.end() ? 0 : it->second;
  }
  std::uint64_t n = 0;
  for (const auto& c : chunks_) {
    const auto it = c.counts.find(channel_id);
    if (it != c.counts.end()) n += it->second;
  }
  return n;
}

void Reader::open() {
  char magic[8];
  if (src_->read_at(0, magic, 8) != 8 || std::string_view(magic, 8) != kMagic)
    throw InputError("not an MCAP file (wrong magic at byte 0; expected \\x89MCAP0\\r\\n)", {name_});
  // Header record.
  char pre[kRecordPrefix];
  std::uint64_t hlen = 0;
  if (src_->read_at(8, pre, kRecordPrefix) == kRecordPrefix && static_cast<std::uint8_t>(pre[0]) == kHeader &&
      (std::memcpy(&hlen, pre + 1, 8), hlen <= src_->size() - 8 - kRecordPrefix) && hlen < (1u << 20)) {
    std::string h(static_cast<std::size_t>(hlen), '\0');
    src_->read_at(8 + kRecordPrefix, h.data(), h.size());
    Rd r(h);
    profile_ = r.str();
    library_ = r.str();
    if (!r.ok()) warn(8, "malformed header record");
  } else {
    warn(8, "the first record is not a readable MCAP header record");
  }
  if (!options_.force_scan && read_summary()) {
    summary_used_ = true;
    return;
  }
  channels_.clear();
  schemas_.clear();
  chunks_.clear();
  stat_counts_.clear();
  have_stat_counts_ = false;
  scan();
}

bool Reader::read_summary() {
  const std::uint64_t size = src_->size();
  const auto fallback = [&](std::uint64_t at, const std::string& why) {
    warn_fallback(at, why + "; scanning the data section");
    return false;
  };
  if (size < 8 + kFooterRecord + 8) return fallback(size, "file too short for a footer (truncated?)");
  char tail[8];
  src_->read_at(size - 8, tail, 8);
  if (std::string_view(tail, 8) != kMagic) return fallback(size - 8, "no MCAP magic at the end of the file (truncated?)");
  const std::uint64_t footer_pos = size - 8 - kFooterRecord;
  std::string footer(kFooterRecord, '\0');
  src_->read_at(footer_pos, footer.data(), footer.size());
  Rd f(footer);
  const auto op = f.num<std::uint8_t>();
  const auto flen = f.num<std::uint64_t>();
  const auto summary_start = f.num<std::uint64_t>();
  const auto summary_offset_start = f.num<std::uint64_t>();
  const auto summary_crc = f.num<std::uint32_t>();
  if (op != kFooter || flen != 20) return fallback(footer_pos, "malformed footer record");
  if (summary_start == 0) {
    warn(footer_pos, "the file has no summary section; scanning the data section", false);
    return false;
  }
  if (summary_start < 8 || summary_start > footer_pos || footer_pos - summary_start > kMaxSummaryBytes)
    return fallback(footer_pos, fmt::format("footer gives an impossible summary start {}", summary_start));
  if (summary_offset_start != 0 && (summary_offset_start < summary_start || summary_offset_start > footer_pos))
    return fallback(footer_pos, fmt::format("footer gives an impossible summary offset start {}", summary_offset_start));
  std::string summary(static_cast<std::size_t>(footer_pos - summary_start), '\0');
  if (src_->read_at(summary_start, summary.data(), summary.size()) != summary.size())
    return fallback(summary_start, "summary section unreadable");
  if (summary_crc != 0) {
    const std::uint32_t c = crc32(std::string_view(footer).substr(0, kRecordPrefix + 16), crc32(summary));
    if (c != summary_crc)
      return fallback(summary_start,
                      fmt::format("summary CRC mismatch (stored {:08x}, computed {:08x})", summary_crc, c));
  }
  const std::uint64_t end = summary_offset_start ? summary_offset_start - summary_start : summary.size();
  std::vector<ChunkInfo> chunks;
  bool have_stats = false;
  std::uint64_t stat_messages = 0;
  std::vector<std::map<std::uint16_t, std::uint64_t>> index_offsets;
  std::optional<std::pair<std::uint64_t, std::string>> unusable;  // where the summary fails, and why
  const auto runs_past = for_each_record(
      std::string_view(summary).substr(0, static_cast<std::size_t>(end)),
      [&](std::uint8_t rop, std::string_view content, std::uint64_t p) {
        bool ok = true;
        if (rop == kSchema) {
          Schema s;
          ok = parse_schema(content, s);
          if (ok) schemas_[s.id] = std::move(s);
        } else if (rop == kChannel) {
          Channel c;
          ok = parse_channel(content, c);
          if (ok) channels_[c.id] = std::move(c);
        } else if (rop == kChunkIndex) {
          ChunkInfo ci;
          std::map<std::uint16_t, std::uint64_t> offs;
          if (!parse_chunk_index(content, summary_start, ci, offs)) {
            unusable = {p, "chunk index record points outside the data section"};
            return false;
          }
          chunks.push_back(std::move(ci));
          index_offsets.push_back(std::move(offs));
        } else if (rop == kStatistics) {
          ok = parse_statistics(content, stat_messages, stat_counts_);
          have_stats = ok;
        }
        if (!ok) unusable = {p, "malformed summary record (opcode " + op_name(rop) + ")"};
        return ok;
      });
  if (runs_past) return fallback(summary_start + *runs_past, "summary record runs past the summary section");
  if (unusable) return fallback(summary_start + unusable->first, unusable->second);
  if (chunks.empty() && (!have_stats || stat_messages > 0)) {
    warn(summary_start, "the summary has no chunk index (unchunked file); scanning the data section", false);
    return false;
  }
  // Per-chunk message counts from the message index records when the statistics do not give them.
  if (!have_stats) {
    for (std::size_t k = 0; k < chunks.size(); ++k) {
      for (auto& [ch, off] : index_offsets[k]) {
        char b[kRecordPrefix + 2 + 4];
        if (off > size - sizeof b || src_->read_at(off, b, sizeof b) != sizeof b ||
            static_cast<std::uint8_t>(b[0]) != kMessageIndex)
          return fallback(off, "message index record listed in the summary is unreadable");
        std::uint32_t bytes = 0;
        std::memcpy(&bytes, b + kRecordPrefix + 2, 4);
        chunks[k].counts[ch] = bytes / 16;
      }
    }
  }
  have_stat_counts_ = have_stats;
  std::stable_sort(chunks.begin(), chunks.end(), [](const ChunkInfo& a, const ChunkInfo& b) { return a.offset < b.offset; });
  chunks_ = std::move(chunks);
  return true;
}

void Reader::learn_records(std::string_view records, std::uint64_t where, ChunkInfo* count_into) {
  const auto runs_past = for_each_record(records, [&](std::uint8_t op, std::string_view content, std::uint64_t p) {
    if (op == kSchema) {
      Schema s;
      if (parse_schema(content, s)) schemas_.emplace(s.id, std::move(s));
      else warn(where, fmt::format("inside chunk at uncompressed offset {}: malformed schema record", p));
    } else if (op == kChannel) {
      Channel c;
      if (parse_channel(content, c)) channels_.emplace(c.id, std::move(c));
      else warn(where, fmt::format("inside chunk at uncompressed offset {}: malformed channel record", p));
    } else if (op == kMessage && count_into) {
      MessageHead m;
      if (parse_message(content, m)) count_into->counts[m.channel] += 1;
    }
    return true;
  });
  if (runs_past)
    warn(where, fmt::format("inside chunk at uncompressed offset {}: record runs past the end of the chunk", *runs_past));
}

void Reader::scan() {
  const std::uint64_t size = src_->size();
  std::uint64_t pos = 8;
  std::ptrdiff_t last_chunk = -1;
  std::vector<bool> indexed;  // per chunk: message index records seen
  std::string buf;
  while (pos < size) {
    char pre[kRecordPrefix];
    if (size - pos < kRecordPrefix || src_->read_at(pos, pre, kRecordPrefix) != kRecordPrefix) {
      if (size - pos == 8) {  // the closing magic
        char tail[8];
        src_->read_at(pos, tail, 8);
        if (std::string_view(tail, 8) == kMagic) break;
      }
      warn(pos, fmt::format("truncated record (no opcode and length); the rest of the file ({} bytes) is ignored",
                            size - pos));
      break;
    }
    const auto op = static_cast<std::uint8_t>(pre[0]);
    std::uint64_t len = 0;
    std::memcpy(&len, pre + 1, 8);
    if (len > size - pos - kRecordPrefix) {
      warn(pos, fmt::format("record (opcode {}) of length {} runs past the end of the file ({} bytes left); the rest "
                            "of the file is ignored",
                            op_name(op), len, size - pos - kRecordPrefix));
      break;
    }
    const std::uint64_t cpos = pos + kRecordPrefix;
    const auto read_content = [&](std::uint64_t n) {
      buf.resize(static_cast<std::size_t>(n));
      return src_->read_at(cpos, buf.data(), buf.size()) == buf.size();
    };
    if (op == kFooter) break;
    if (op == kSchema || op == kChannel) {
      if (len > (64u << 20) || !read_content(len)) {
        warn(pos, "implausible schema/channel record skipped");
      } else if (op == kSchema) {
        Schema s;
        if (parse_schema(buf, s)) schemas_.emplace(s.id, std::move(s));
        else warn(pos, "malformed schema record ignored");
      } else {
        Channel c;
        if (parse_channel(buf, c)) channels_.emplace(c.id, std::move(c));
        else warn(pos, "malformed channel record ignored");
      }
    } else if (op == kMessage) {
      MessageHead m;
      if (len < kMessageHeaderBytes || !read_content(kMessageHeaderBytes) || !parse_message(buf, m)) {
        warn(pos, "malformed message record ignored");
      } else {
        ChunkInfo c;
        c.offset = pos;
        c.start_ns = c.end_ns = ns(m.log_time);
        c.counts[m.channel] = 1;
        c.channels_known = true;
        c.loose_message = true;
        chunks_.push_back(std::move(c));
        indexed.push_back(true);
        last_chunk = -1;
      }
    } else if (op == kChunk) {
      if (len < 8 + 8 + 8 + 4 || !read_content(16)) {
        warn(pos, "chunk record too short; chunk skipped");
        last_chunk = -1;
      } else {
        Rd r(buf);
        ChunkInfo c;
        c.offset = pos;
        c.start_ns = ns(r.num<std::uint64_t>());
        c.end_ns = ns(r.num<std::uint64_t>());
        chunks_.push_back(std::move(c));
        indexed.push_back(false);
        last_chunk = static_cast<std::ptrdiff_t>(chunks_.size()) - 1;
      }
    } else if (op == kMessageIndex) {
      if (last_chunk >= 0 && len >= 6 && read_content(6)) {
        Rd r(buf);
        const auto ch = r.num<std::uint16_t>();
        const auto bytes = r.num<std::uint32_t>();
        if (bytes % 16 == 0 && bytes <= len - 6) {
          if (bytes) chunks_[static_cast<std::size_t>(last_chunk)].counts[ch] += bytes / 16;
          indexed[static_cast<std::size_t>(last_chunk)] = true;
        } else {
          warn(pos, "malformed message index record ignored");
        }
      }
    }
    // Header, attachments, metadata, indexes, statistics, data end and unknown opcodes: skipped.
    pos = cpos + len;
  }
  // Chunks whose channels are not all known (their channel records live inside them) or that have no
  // message index: decompress them to learn channels and counts.
  for (std::size_t k = 0; k < chunks_.size(); ++k) {
    auto& c = chunks_[k];
    if (c.loose_message) continue;
    bool known = indexed[k];
    for (const auto& kv : c.counts) known = known && channels_.count(kv.first);
    if (known) {
      c.channels_known = true;
      continue;
    }
    std::size_t begin = 0;
    if (!load_chunk(c, buf, begin)) continue;
    learn_records(std::string_view(buf).substr(begin), c.offset, indexed[k] ? nullptr : &c);
    c.channels_known = true;
  }
}

bool Reader::load_chunk(const ChunkInfo& c, std::string& out, std::size_t& begin) {
  begin = 0;
  const std::uint64_t size = src_->size();
  char pre[kRecordPrefix];
  if (c.offset > size || size - c.offset < kRecordPrefix || src_->read_at(c.offset, pre, kRecordPrefix) != kRecordPrefix ||
      static_cast<std::uint8_t>(pre[0]) != kChunk) {
    warn(c.offset, "no chunk record at this offset; chunk skipped");
    return false;
  }
  std::uint64_t len = 0;
  std::memcpy(&len, pre + 1, 8);
  if (len > size - c.offset - kRecordPrefix) {
    warn(c.offset, fmt::format("chunk record of length {} runs past the end of the file; chunk skipped", len));
    return false;
  }
  if (len > options_.max_chunk_bytes + 4096) {
    warn(c.offset, fmt::format("chunk record of {} bytes exceeds the {}-byte limit; chunk skipped", len,
                               options_.max_chunk_bytes));
    return false;
  }
  std::string raw(static_cast<std::size_t>(len), '\0');
  if (src_->read_at(c.offset + kRecordPrefix, raw.data(), raw.size()) != raw.size()) {
    warn(c.offset, "chunk data could not be read; chunk skipped");
    return false;
  }
  Rd r(raw);
  r.num<std::uint64_t>();
  r.num<std::uint64_t>();
  const auto usize = r.num<std::uint64_t>();
  const auto crc = r.num<std::uint32_t>();
  const std::string compression = r.str();
  const auto rlen = r.num<std::uint64_t>();
  if (!r.ok() || rlen != r.left()) {
    warn(c.offset, fmt::format("chunk records length {} disagrees with the record length ({} bytes left); chunk "
                               "skipped",
                               rlen, r.left()));
    return false;
  }
  const std::string_view records = r.rest();
  if (usize > options_.max_chunk_bytes) {
    warn(c.offset, fmt::format("chunk claims an uncompressed size of {} bytes, more than the {}-byte limit for this "
                               "file (docs/import.md, \"Limits\"); chunk skipped",
                               usize, options_.max_chunk_bytes));
    return false;
  }
  if (compression.empty()) {
    if (usize != records.size()) {
      warn(c.offset, fmt::format("uncompressed chunk: size field {} differs from its {} record bytes; chunk skipped",
                                 usize, records.size()));
      return false;
    }
    // The records are used where they lie in the record buffer: no copy of the chunk.
    begin = static_cast<std::size_t>(records.data() - raw.data());
    out = std::move(raw);
  } else if (compression == "zstd") {
    if (!zstd_decompress(records, static_cast<std::size_t>(usize), out)) {
      warn(c.offset, "zstd chunk fails to decompress to its announced size; chunk skipped");
      return false;
    }
  } else if (compression == "lz4") {
    if (!lz4_decompress(records, static_cast<std::size_t>(usize), out)) {
      warn(c.offset, "lz4 chunk fails to decompress to its announced size; chunk skipped");
      return false;
    }
  } else {
    warn(c.offset, "unknown chunk compression \"" + compression + "\" (MCAP allows \"\", zstd, lz4); chunk skipped");
    return false;
  }
  if (crc != 0) {
    const std::uint32_t got = crc32(std::string_view(out).substr(begin));
    if (got != crc) {
      warn(c.offset, fmt::format("chunk CRC mismatch (stored {:08x}, computed {:08x}); chunk skipped", crc, got));
      return false;
    }
  }
  return true;
}

void Reader::for_each(const std::function<bool(const Channel&)>& select,
                      const std::function<bool(const MessageView&)>& fn, const ProgressCallback& progress) {
  std::set<std::uint16_t> ids;
  for (const auto& [id, c] : channels_)
    if (select(c)) ids.insert(id);
  std::size_t total = 0;
  for (auto id : ids) total += static_cast<std::size_t>(message_count(id));
  std::vector<const ChunkInfo*> order;
  for (const auto& ch : chunks_) {
    bool wanted = !ch.channels_known;
    for (const auto& kv : ch.counts) wanted = wanted || ids.count(kv.first);
    if (wanted) order.push_back(&ch);
  }
  TimeOrderedMerge<MessageView> merge(fn, progress, total);
  auto push = [&](const MessageHead& m, const std::shared_ptr<const std::string>& buf, std::uint64_t where) {
    const auto it = channels_.find(m.channel);
    if (it == channels_.end() || !ids.count(m.channel)) return;
    const MessageView v{&it->second, m.sequence, ns(m.log_time), ns(m.publish_time), m.data, where};
    merge.push(v.log_time_ns, buf, v);
  };
  merge_chunks<ChunkInfo>(order, merge, [&](const ChunkInfo& c) {
    if (c.loose_message) {
      std::string bytes;
      char pre[kRecordPrefix];
      std::uint64_t len = 0;
      src_->read_at(c.offset, pre, kRecordPrefix);
      std::memcpy(&len, pre + 1, 8);
      bytes.resize(static_cast<std::size_t>(len));  // bounded by the file size (checked by the scan)
      const bool read = src_->read_at(c.offset + kRecordPrefix, bytes.data(), bytes.size()) == bytes.size();
      const auto buf = merge.hold(std::move(bytes));
      MessageHead m;
      if (read && parse_message(*buf, m))
        push(m, buf, c.offset);
      else
        warn(c.offset, "message record unreadable; skipped");
      return;
    }
    std::string bytes;
    std::size_t begin = 0;
    if (!load_chunk(c, bytes, begin)) return;
    const auto buf = merge.hold(std::move(bytes));
    const std::string_view records = std::string_view(*buf).substr(begin);
    const auto runs_past = for_each_record(records, [&](std::uint8_t op, std::string_view content, std::uint64_t p) {
      if (op == kMessage) {
        MessageHead m;
        if (parse_message(content, m)) push(m, buf, c.offset);
        else warn(c.offset, fmt::format("inside chunk at uncompressed offset {}: malformed message record", p));
      } else if (op == kChannel && !channels_.count(Rd(content).num<std::uint16_t>())) {
        // A channel first defined inside this chunk (a file read through a partial summary).
        Channel ch;
        if (parse_channel(content, ch) && select(ch)) ids.insert(ch.id);
        if (!ch.topic.empty()) channels_.emplace(ch.id, std::move(ch));
      }
      return true;
    });
    if (runs_past)
      warn(c.offset, fmt::format("inside chunk at uncompressed offset {}: record runs past the end of the chunk; "
                                 "rest of the chunk skipped",
                                 *runs_past));
  });
}

}  // namespace roe::io::mcap
