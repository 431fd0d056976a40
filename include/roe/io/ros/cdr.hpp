#pragma once
/// @file
/// The CDR serialization of the ROS 2 messages roe imports (OMG XCDR1, as rmw and
/// rosbag2 store them): a 4-byte encapsulation header (0x00 0x01 little-endian, 0x00 0x00 big-endian,
/// then two option bytes), then the fields, each primitive aligned to its own size (8 for float64)
/// counted from the end of the encapsulation header; strings are a uint32 length that counts a
/// terminating NUL, then the bytes and the NUL; sequences a uint32 count then the elements; fixed
/// arrays have no prefix; builtin_interfaces/Time is int32 sec + uint32 nanosec; std_msgs/Header has
/// no seq. decode<M>(Wire::cdr, ...) (msgs.hpp) reads these with the same field layouts and into the
/// same structs as the ROS 1 messages (Header::seq = 0).
///
/// Every decoder throws roe::InputError naming `where` and the message byte offset on a short
/// message, a string or sequence length beyond the message, a missing NUL, or more than 3 trailing
/// bytes (serializers may pad the end to 4 bytes); it never reads out of bounds and never allocates
/// more than the message size justifies.

#include <cstring>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "roe/io/ros/msgs.hpp"

namespace roe::io::cdr {

/// Bounds-checked CDR reader over one serialized message (encapsulation header included): the
/// primitives the field layouts (src/io/ros/layouts.hpp) read.
class Cursor {
 public:
  static constexpr ros::Wire kWire = ros::Wire::cdr;
  static constexpr bool kReads = true;
  /// The fewest bytes a std_msgs/Header takes: stamp and an empty frame_id.
  static constexpr std::size_t kMinHeaderBytes = 8 + 4;

  /// InputError when the message has no plain CDR encapsulation header. `where` (named in errors) is kept
  /// by reference: it must outlive the cursor.
  Cursor(std::string_view msg, const std::string& where);
  Cursor(std::string_view msg, std::string&& where) = delete;
  bool big_endian() const { return big_; }
  std::uint8_t u8() { return raw<std::uint8_t>(); }
  std::uint32_t u32() { return raw<std::uint32_t>(); }
  std::int32_t i32() { return raw<std::int32_t>(); }
  float f32() { return raw<float>(); }
  double f64() { return raw<double>(); }
  std::string str();
  /// The next `n` bytes (no alignment).
  std::string_view bytes(std::size_t n) {
    need(n);
    const std::string_view v = d_.substr(pos_, n);
    pos_ += n;
    return v;
  }
  /// uint8[] sequence: a view into the message.
  std::string_view byte_sequence();
  ros::Header header();
  std::size_t remaining() const { return d_.size() - pos_; }
  /// InputError unless at most 3 (padding) bytes are left.
  void finish() const;
  [[noreturn]] void fail(const std::string& what) const;

 private:
  void need(std::size_t n) const {
    if (n > d_.size() - pos_) too_short(n);
  }
  [[noreturn]] void too_short(std::size_t n) const;
  template <class T>
  T raw() {
    // Aligned to its size, counted from the end of the encapsulation header.
    const std::size_t off = (pos_ - 4) % sizeof(T);
    if (off) {
      need(sizeof(T) - off);
      pos_ += sizeof(T) - off;
    }
    need(sizeof(T));
    unsigned char b[sizeof(T)];
    std::memcpy(b, d_.data() + pos_, sizeof(T));
    if (big_)
      for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
    pos_ += sizeof(T);
    T v;
    std::memcpy(&v, b, sizeof(T));
    return v;
  }
  std::string_view d_;
  std::size_t pos_ = 4;
  bool big_ = false;
  const std::string& where_;
};

/// Appends CDR little-endian fields: the primitives the layouts write (encode<M>), and for hand-made
/// messages in tests and benchmarks (the committed ROS 2 fixtures are written by an independent
/// serializer, tests/fixtures/ros2/make_fixtures.mjs).
class Writer {
 public:
  static constexpr ros::Wire kWire = ros::Wire::cdr;
  static constexpr bool kReads = false;
  static constexpr std::size_t kMinHeaderBytes = Cursor::kMinHeaderBytes;

  Writer();
  Writer& u8(std::uint8_t v);
  Writer& u32(std::uint32_t v);
  Writer& i32(std::int32_t v);
  Writer& f32(float v);
  Writer& f64(double v);
  Writer& str(std::string_view s);
  Writer& byte_sequence(std::string_view b);
  Writer& header(const ros::Header& h);
  const std::string& bytes() const { return out_; }

 private:
  void align(std::size_t n);
  std::string out_;
};

}  // namespace roe::io::cdr
