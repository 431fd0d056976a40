// ZIP read (stored, deflated) and write (stored), PKWARE APPNOTE 6.3: local headers, central directory,
// end of central directory record.
#include "roe/io/zip.hpp"

#include <cstdint>
#include <zlib.h>

#include "roe/core/error.hpp"

namespace roe::io {
namespace {

constexpr std::uint32_t kLocalSig = 0x04034b50, kCentralSig = 0x02014b50, kEndSig = 0x06054b50;

std::uint32_t le(const std::string& b, std::size_t at, int n) {
  std::uint32_t v = 0;
  for (int i = n - 1; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(b[at + static_cast<std::size_t>(i)]);
  return v;
}

void put(std::string& out, std::uint32_t v, int n) {
  for (int i = 0; i < n; ++i) out += static_cast<char>((v >> (8 * i)) & 0xFF);
}

[[noreturn]] void bad(const std::string& source, std::size_t offset, const std::string& msg) {
  throw InputError("not a readable ZIP archive: " + msg + " (byte offset " + std::to_string(offset) + ")", {source});
}

std::uint32_t crc32_of(const std::string& d) {
  uLong c = crc32(0L, Z_NULL, 0);
  std::size_t at = 0;
  while (at < d.size()) {  // zlib's length is a uInt
    const auto n = static_cast<uInt>(std::min<std::size_t>(d.size() - at, 1u << 30));
    c = crc32(c, reinterpret_cast<const Bytef*>(d.data() + at), n);
    at += n;
  }
  return static_cast<std::uint32_t>(c);
}

std::string inflate_raw(const std::string& in, std::size_t expected, const std::string& source, std::size_t offset) {
  std::string out(expected, '\0');
  z_stream z{};
  if (inflateInit2(&z, -MAX_WBITS) != Z_OK) throw InternalError("zlib inflateInit2 failed");
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
  z.avail_in = static_cast<uInt>(in.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  const int rc = inflate(&z, Z_FINISH);
  const std::size_t produced = out.size() - z.avail_out;
  inflateEnd(&z);
  if (rc != Z_STREAM_END || produced != expected)
    bad(source, offset, "a deflated member does not inflate to its declared size");
  return out;
}

/// The end of central directory record: the last signature within the 64 KiB comment window.
std::size_t find_end_record(const std::string& b, const std::string& source) {
  if (b.size() < 22) bad(source, 0, "shorter than an end of central directory record");
  const std::size_t lowest = b.size() >= 22 + 0xFFFF ? b.size() - 22 - 0xFFFF : 0;
  for (std::size_t at = b.size() - 22 + 1; at-- > lowest;)
    if (le(b, at, 4) == kEndSig) return at;
  bad(source, b.size(), "no end of central directory record");
}

}  // namespace

std::vector<ZipMember> read_zip(const std::string& b, const std::string& source) {
  const std::size_t end = find_end_record(b, source);
  if (le(b, end + 4, 2) != 0 || le(b, end + 6, 2) != 0) bad(source, end, "multi-disk archives are not supported");
  const std::size_t count = le(b, end + 10, 2), cd_size = le(b, end + 12, 4), cd_at = le(b, end + 16, 4);
  if (count == 0xFFFF || cd_at == 0xFFFFFFFF) bad(source, end, "ZIP64 archives are not supported");
  if (cd_at > end || cd_size > end - cd_at) bad(source, end, "the central directory lies outside the file");
  std::vector<ZipMember> members;
  std::size_t at = cd_at, total = 0;
  for (std::size_t i = 0; i < count; ++i) {
    if (at + 46 > end || le(b, at, 4) != kCentralSig) bad(source, at, "a central directory entry is damaged");
    const std::uint32_t flags = le(b, at + 8, 2), method = le(b, at + 10, 2), crc = le(b, at + 16, 4);
    const std::size_t csize = le(b, at + 20, 4), usize = le(b, at + 24, 4);
    const std::size_t nlen = le(b, at + 28, 2), xlen = le(b, at + 30, 2), clen = le(b, at + 32, 2);
    const std::size_t local = le(b, at + 42, 4);
    if (at + 46 + nlen > end) bad(source, at, "a central directory entry is damaged");
    ZipMember m;
    m.name = b.substr(at + 46, nlen);
    if (flags & 1) bad(source, at, "member " + m.name + " is encrypted");
    if (usize > kMaxZipMember || (total += usize) > kMaxZipTotal)
      bad(source, at, "member " + m.name + " is larger than roe reads (" + std::to_string(kMaxZipMember >> 20) + " MiB)");
    if (method == 8 && usize > 1000 * std::max<std::size_t>(csize, 1))
      bad(source, at, "member " + m.name + " claims to inflate more than 1000-fold");
    if (local + 30 > cd_at || le(b, local, 4) != kLocalSig) bad(source, local, "the local header of " + m.name + " is damaged");
    const std::size_t data_at = local + 30 + le(b, local + 26, 2) + le(b, local + 28, 2);
    if (data_at > cd_at || csize > cd_at - data_at) bad(source, local, "the data of " + m.name + " lies outside the file");
    const std::string raw = b.substr(data_at, csize);
    if (method == 0) {
      if (csize != usize) bad(source, at, "stored member " + m.name + " has two sizes");
      m.data = raw;
    } else if (method == 8) {
      m.data = inflate_raw(raw, usize, source, data_at);
    } else {
      bad(source, at, "member " + m.name + " uses compression method " + std::to_string(method) +
                          " (roe reads stored and deflated members)");
    }
    if (crc32_of(m.data) != crc) bad(source, data_at, "member " + m.name + " fails its CRC-32");
    members.push_back(std::move(m));
    at += 46 + nlen + xlen + clen;
  }
  return members;
}

std::string write_zip(const std::vector<ZipMember>& members) {
  std::string out, central;
  for (const auto& m : members) {
    ROE_CHECK(m.data.size() < 0xFFFFFFFFu && m.name.size() < 0xFFFF, "zip: member too large for a ZIP without ZIP64");
    const std::uint32_t crc = crc32_of(m.data), size = static_cast<std::uint32_t>(m.data.size());
    const auto offset = static_cast<std::uint32_t>(out.size());
    const auto header = [&](std::string& s, bool is_central) {
      put(s, is_central ? kCentralSig : kLocalSig, 4);
      if (is_central) put(s, 20, 2);  // made by: version 2.0
      put(s, 20, 2);                   // needed to extract: 2.0
      put(s, 0, 2);                    // flags
      put(s, 0, 2);                    // method: stored
      put(s, 0, 2);                    // time 00:00
      put(s, (0 << 9) | (1 << 5) | 1, 2);  // date 1980-01-01
      put(s, crc, 4);
      put(s, size, 4);
      put(s, size, 4);
      put(s, static_cast<std::uint32_t>(m.name.size()), 2);
      put(s, 0, 2);  // extra length
      if (is_central) {
        put(s, 0, 2);  // comment length
        put(s, 0, 2);  // disk
        put(s, 0, 2);  // internal attributes
        put(s, 0, 4);  // external attributes
        put(s, offset, 4);
      }
      s += m.name;
    };
    header(out, false);
    out += m.data;
    header(central, true);
  }
  const auto cd_at = static_cast<std::uint32_t>(out.size());
  out += central;
  put(out, kEndSig, 4);
  put(out, 0, 2);
  put(out, 0, 2);
  put(out, static_cast<std::uint32_t>(members.size()), 2);
  put(out, static_cast<std::uint32_t>(members.size()), 2);
  put(out, static_cast<std::uint32_t>(central.size()), 4);
  put(out, cd_at, 4);
  put(out, 0, 2);
  return out;
}

}  // namespace roe::io
