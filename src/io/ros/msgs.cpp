// decode<M> and encode<M> over the field layouts (include/roe/io/ros/msgs.hpp), and the ROS 1 cursor and
// writer.
#include "roe/io/ros/msgs.hpp"

#include "layouts.hpp"
#include "roe/io/ros/cdr.hpp"

namespace roe::io::ros {

// ---------------------------------------------------------------------------------------------
// decode<M>, encode<M>: one layout per message type, read by either wire's cursor, written by its writer
// ---------------------------------------------------------------------------------------------
namespace {

template <class M, class Reader>
typename M::Value decode_with(std::string_view bytes, const std::string& where) {
  Reader c(bytes, where);
  typename M::Value m{};
  layout::fields(M{}, c, m);
  c.finish();
  layout::check(M{}, c, m);
  return m;
}

template <class M, class Out>
std::string encode_with(const typename M::Value& m) {
  Out w;
  layout::fields(M{}, w, m);
  return w.bytes();
}

}  // namespace

template <class M>
typename M::Value decode(Wire wire, std::string_view bytes, const std::string& where) {
  return wire == Wire::ros1 ? decode_with<M, Cursor>(bytes, where)
                            : decode_with<M, cdr::Cursor>(bytes, where);
}

template <class M>
std::string encode(Wire wire, const typename M::Value& m) {
  return wire == Wire::ros1 ? encode_with<M, Writer>(m) : encode_with<M, cdr::Writer>(m);
}

// The message types of msgs.hpp (their decode and encode are defined here only).
// clang-format off
#define ROE_ROS_MESSAGE(M)                                                 \
  template M::Value decode<M>(Wire, std::string_view, const std::string&); \
  template std::string encode<M>(Wire, const M::Value&);
ROE_ROS_MESSAGE(msg::Image) ROE_ROS_MESSAGE(msg::CompressedImage) ROE_ROS_MESSAGE(msg::CameraInfo)
ROE_ROS_MESSAGE(msg::Imu) ROE_ROS_MESSAGE(msg::Transform) ROE_ROS_MESSAGE(msg::PoseStamped)
ROE_ROS_MESSAGE(msg::PoseWithCovarianceStamped) ROE_ROS_MESSAGE(msg::TransformStamped)
ROE_ROS_MESSAGE(msg::Odometry) ROE_ROS_MESSAGE(msg::TFMessage) ROE_ROS_MESSAGE(msg::StreamInfo)
ROE_ROS_MESSAGE(msg::ImuIntrinsic) ROE_ROS_MESSAGE(msg::IMUInfo) ROE_ROS_MESSAGE(msg::Extrinsics)
ROE_ROS_MESSAGE(msg::KeyValue) ROE_ROS_MESSAGE(msg::UInt32) ROE_ROS_MESSAGE(msg::Float32) ROE_ROS_MESSAGE(msg::String)
#undef ROE_ROS_MESSAGE
// clang-format on

// ---------------------------------------------------------------------------------------------
// Cursor
// ---------------------------------------------------------------------------------------------
void Cursor::fail(const std::string& what) const {
  throw InputError(where_ + ": malformed message: " + what + " (at message byte " + std::to_string(pos_) +
                   " of " + std::to_string(d_.size()) + ")");
}

void Cursor::too_short(std::size_t n) const {
  fail("message too short (needs " + std::to_string(n) + " more bytes)");
}

void Cursor::finish() const {
  if (pos_ != d_.size()) fail(std::to_string(d_.size() - pos_) + " unexpected trailing bytes");
}

// ---------------------------------------------------------------------------------------------
// Writer
// ---------------------------------------------------------------------------------------------
Writer& Writer::u8(std::uint8_t v) {
  out_.push_back(static_cast<char>(v));
  return *this;
}
Writer& Writer::u32(std::uint32_t v) {
  out_.append(reinterpret_cast<const char*>(&v), 4);
  return *this;
}
Writer& Writer::f32(float v) {
  out_.append(reinterpret_cast<const char*>(&v), 4);
  return *this;
}
Writer& Writer::f64(double v) {
  out_.append(reinterpret_cast<const char*>(&v), 8);
  return *this;
}
Writer& Writer::time(Timestamp ns) {
  u32(static_cast<std::uint32_t>(ns / kNsPerSecond));
  return u32(static_cast<std::uint32_t>(ns % kNsPerSecond));
}
Writer& Writer::str(std::string_view s) {
  u32(static_cast<std::uint32_t>(s.size()));
  out_.append(s.data(), s.size());
  return *this;
}
Writer& Writer::byte_sequence(std::string_view b) { return str(b); }
Writer& Writer::header(const Header& h) { return u32(h.seq).time(h.stamp_ns).str(h.frame_id); }

}  // namespace roe::io::ros
