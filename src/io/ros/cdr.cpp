// The CDR (XCDR1) cursor and writer (include/roe/io/ros/cdr.hpp).
#include "roe/io/ros/cdr.hpp"

#include <cstring>

#include "layouts.hpp"

namespace roe::io::cdr {

Cursor::Cursor(std::string_view msg, const std::string& where) : d_(msg), where_(where) {
  if (msg.size() < 4) {
    pos_ = 0;
    fail("shorter than the 4-byte CDR encapsulation header");
  }
  const auto b0 = static_cast<std::uint8_t>(msg[0]), b1 = static_cast<std::uint8_t>(msg[1]);
  if (b0 != 0 || b1 > 1) {
    pos_ = 0;
    fail("encapsulation " + std::to_string(b0) + "," + std::to_string(b1) +
         " is not plain CDR (0,0 big-endian or 0,1 little-endian)");
  }
  big_ = b1 == 0;
}

void Cursor::fail(const std::string& what) const {
  throw InputError(where_ + ": malformed CDR message: " + what + " (at message byte " + std::to_string(pos_) + " of " +
                   std::to_string(d_.size()) + ")");
}

void Cursor::too_short(std::size_t n) const {
  fail("message too short (needs " + std::to_string(n) + " more bytes)");
}

std::string Cursor::str() {
  const std::uint32_t n = u32();
  if (n > remaining())
    fail("string length " + std::to_string(n) + " exceeds the message (" + std::to_string(remaining()) +
         " bytes left)");
  if (n == 0) return {};  // some serializers write an empty string without its NUL
  const std::string_view s = d_.substr(pos_, n);
  if (s.back() != '\0') fail("string of length " + std::to_string(n) + " is not NUL-terminated");
  pos_ += n;
  return std::string(s.substr(0, n - 1));
}

std::string_view Cursor::byte_sequence() {
  const std::uint32_t n = layout::count(*this, 1);
  const std::string_view v = d_.substr(pos_, n);
  pos_ += n;
  return v;
}

ros::Header Cursor::header() {
  ros::Header h;
  const std::int32_t sec = i32();
  const std::uint32_t nsec = u32();
  if (nsec >= kNsPerSecond) fail("header.stamp.nanosec " + std::to_string(nsec) + " is not below 1e9");
  h.stamp_ns = static_cast<Timestamp>(sec) * kNsPerSecond + static_cast<Timestamp>(nsec);
  h.frame_id = str();
  return h;
}

void Cursor::finish() const {
  if (remaining() > 3) fail(std::to_string(remaining()) + " unexpected trailing bytes");
}

// ---------------------------------------------------------------------------------------------
// Writer
// ---------------------------------------------------------------------------------------------
Writer::Writer() : out_(std::string("\x00\x01\x00\x00", 4)) {}
void Writer::align(std::size_t n) {
  while ((out_.size() - 4) % n) out_.push_back('\0');
}
Writer& Writer::u8(std::uint8_t v) {
  out_.push_back(static_cast<char>(v));
  return *this;
}
Writer& Writer::u32(std::uint32_t v) {
  align(4);
  out_.append(reinterpret_cast<const char*>(&v), 4);
  return *this;
}
Writer& Writer::i32(std::int32_t v) { return u32(static_cast<std::uint32_t>(v)); }
Writer& Writer::f32(float v) {
  align(4);
  out_.append(reinterpret_cast<const char*>(&v), 4);
  return *this;
}
Writer& Writer::f64(double v) {
  align(8);
  out_.append(reinterpret_cast<const char*>(&v), 8);
  return *this;
}
Writer& Writer::str(std::string_view s) {
  u32(static_cast<std::uint32_t>(s.size() + 1));
  out_.append(s.data(), s.size());
  out_.push_back('\0');
  return *this;
}
Writer& Writer::byte_sequence(std::string_view b) {
  u32(static_cast<std::uint32_t>(b.size()));
  out_.append(b.data(), b.size());
  return *this;
}
Writer& Writer::header(const ros::Header& h) {
  const Timestamp s = h.stamp_ns >= 0 ? h.stamp_ns / kNsPerSecond : -((-h.stamp_ns + kNsPerSecond - 1) / kNsPerSecond);
  i32(static_cast<std::int32_t>(s));
  u32(static_cast<std::uint32_t>(h.stamp_ns - s * kNsPerSecond));
  return str(h.frame_id);
}

}  // namespace roe::io::cdr
