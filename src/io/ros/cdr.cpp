// CDR (XCDR1) decoders of the ROS 2 messages roe imports (include/roe/io/ros/cdr.hpp).
#include "roe/io/ros/cdr.hpp"

#include <cstring>

#include "layouts.hpp"

namespace roe::io::cdr {

Cursor::Cursor(std::string_view msg, std::string where) : d_(msg), where_(std::move(where)) {
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

void Cursor::need(std::size_t n) const {
  if (n > d_.size() - pos_) fail("message too short (needs " + std::to_string(n) + " more bytes)");
}

void Cursor::align(std::size_t n) {
  const std::size_t off = (pos_ - 4) % n;
  if (off) {
    need(n - off);
    pos_ += n - off;
  }
}

template <class T>
T Cursor::raw() {
  align(sizeof(T));
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

std::uint8_t Cursor::u8() { return raw<std::uint8_t>(); }
std::uint32_t Cursor::u32() { return raw<std::uint32_t>(); }
std::int32_t Cursor::i32() { return raw<std::int32_t>(); }
double Cursor::f64() { return raw<double>(); }

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

ros::Image decode_image(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  ros::Image m = layout::image(c);
  c.finish();
  layout::check_image_size(c, m);
  return m;
}

ros::CompressedImage decode_compressed_image(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  ros::CompressedImage m = layout::compressed_image(c);
  c.finish();
  return m;
}

ros::CameraInfo decode_camera_info(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  ros::CameraInfo m = layout::camera_info(c);
  c.finish();
  return m;
}

ros::Imu decode_imu(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  ros::Imu m = layout::imu(c);
  c.finish();
  return m;
}

ros::StampedTransform decode_pose_stamped(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  ros::StampedTransform m = layout::pose_stamped(c);
  c.finish();
  return m;
}

ros::StampedTransform decode_pose_with_covariance_stamped(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  ros::StampedTransform m = layout::pose_with_covariance_stamped(c);
  c.finish();
  return m;
}

ros::StampedTransform decode_transform_stamped(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  ros::StampedTransform m = layout::transform_stamped(c);
  c.finish();
  return m;
}

ros::StampedTransform decode_odometry(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  ros::StampedTransform m = layout::odometry(c);
  c.finish();
  return m;
}

std::vector<ros::StampedTransform> decode_tf_message(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  // A TransformStamped takes at least 8 (stamp) + 4 + 4 (two empty strings) + 56 (pose) bytes.
  const std::uint32_t n = layout::count(c, 72);
  std::vector<ros::StampedTransform> out(n);
  for (auto& m : out) m = layout::transform_stamped(c);
  c.finish();
  return out;
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
Writer& Writer::vec3(const Eigen::Vector3d& v) { return f64(v.x()).f64(v.y()).f64(v.z()); }
Writer& Writer::quat_xyzw(const Eigen::Quaterniond& q) { return f64(q.x()).f64(q.y()).f64(q.z()).f64(q.w()); }

std::string encode_imu(const ros::Imu& m) {
  Writer w;
  w.header(m.header).quat_xyzw(m.orientation);
  for (double d : m.orientation_covariance) w.f64(d);
  w.vec3(m.angular_velocity);
  for (double d : m.angular_velocity_covariance) w.f64(d);
  w.vec3(m.linear_acceleration);
  for (double d : m.linear_acceleration_covariance) w.f64(d);
  return w.bytes();
}

std::string encode_camera_info(const ros::CameraInfo& m) {
  Writer w;
  w.header(m.header).u32(m.height).u32(m.width).str(m.distortion_model).u32(static_cast<std::uint32_t>(m.D.size()));
  for (double d : m.D) w.f64(d);
  for (double d : m.K) w.f64(d);
  for (double d : m.R) w.f64(d);
  for (double d : m.P) w.f64(d);
  w.u32(m.binning_x).u32(m.binning_y).u32(m.roi_x).u32(m.roi_y).u32(m.roi_height).u32(m.roi_width);
  return w.u8(m.roi_do_rectify ? 1 : 0).bytes();
}

std::string encode_pose_stamped(const ros::StampedTransform& m) {
  Writer w;
  w.header(m.header).vec3(m.transform.t).quat_xyzw(m.transform.q);
  return w.bytes();
}

std::string encode_tf_message(const std::vector<ros::StampedTransform>& m) {
  Writer w;
  w.u32(static_cast<std::uint32_t>(m.size()));
  for (const auto& t : m) w.header(t.header).str(t.child_frame_id).vec3(t.transform.t).quat_xyzw(t.transform.q);
  return w.bytes();
}

}  // namespace roe::io::cdr
