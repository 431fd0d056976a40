// ROS1 message (de)serialization for the types roe imports.
#include "roe/io/ros/msgs.hpp"

#include <cstring>

#include "layouts.hpp"

namespace roe::io::ros {

// ---------------------------------------------------------------------------------------------
// Cursor
// ---------------------------------------------------------------------------------------------
void Cursor::fail(const std::string& what) const {
  throw InputError(where_ + ": malformed message: " + what + " (at message byte " + std::to_string(pos_) +
                   " of " + std::to_string(d_.size()) + ")");
}

void Cursor::need(std::size_t n) const {
  if (n > d_.size() - pos_) fail("message too short (needs " + std::to_string(n) + " more bytes)");
}

std::uint8_t Cursor::u8() {
  need(1);
  return static_cast<std::uint8_t>(d_[pos_++]);
}
std::uint32_t Cursor::u32() {
  need(4);
  std::uint32_t v;
  std::memcpy(&v, d_.data() + pos_, 4);
  pos_ += 4;
  return v;
}
std::int32_t Cursor::i32() { return static_cast<std::int32_t>(u32()); }
float Cursor::f32() {
  need(4);
  float v;
  std::memcpy(&v, d_.data() + pos_, 4);
  pos_ += 4;
  return v;
}
double Cursor::f64() {
  need(8);
  double v;
  std::memcpy(&v, d_.data() + pos_, 8);
  pos_ += 8;
  return v;
}
Timestamp Cursor::time() {
  const std::uint32_t s = u32();
  const std::uint32_t ns = u32();
  return static_cast<Timestamp>(s) * kNsPerSecond + static_cast<Timestamp>(ns);
}
std::string_view Cursor::bytes(std::size_t n) {
  need(n);
  std::string_view v = d_.substr(pos_, n);
  pos_ += n;
  return v;
}
std::string Cursor::str() {
  const std::uint32_t n = u32();
  return std::string(bytes(n));
}
std::string_view Cursor::byte_sequence() { return bytes(u32()); }
Header Cursor::header() {
  Header h;
  h.seq = u32();
  h.stamp_ns = time();
  h.frame_id = str();
  return h;
}
void Cursor::finish() const {
  if (pos_ != d_.size()) fail(std::to_string(d_.size() - pos_) + " unexpected trailing bytes");
}

// ---------------------------------------------------------------------------------------------
// Decoders
// ---------------------------------------------------------------------------------------------
Header decode_header_only(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  return c.header();
}

Image decode_image(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  Image m = layout::image(c);
  // librealsense >= 2.49: header.version "1" (in the frame_id slot) appends float32 depth_units.
  // Exactly those 4 bytes are accepted; any other trailing bytes are still refused by finish().
  if (m.header.frame_id == kRealsenseImageVersion1 && c.remaining() == 4) m.depth_units = c.f32();
  c.finish();
  layout::check_image_size(c, m);
  return m;
}

CompressedImage decode_compressed_image(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  CompressedImage m = layout::compressed_image(c);
  c.finish();
  return m;
}

CameraInfo decode_camera_info(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  CameraInfo m = layout::camera_info(c);
  c.finish();
  return m;
}

Imu decode_imu(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  Imu m = layout::imu(c);
  c.finish();
  return m;
}

Transform decode_transform(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  Transform t = layout::pose(c);
  c.finish();
  return t;
}

StampedTransform decode_pose_stamped(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  StampedTransform m = layout::pose_stamped(c);
  c.finish();
  return m;
}

StampedTransform decode_pose_with_covariance_stamped(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  StampedTransform m = layout::pose_with_covariance_stamped(c);
  c.finish();
  return m;
}

StampedTransform decode_transform_stamped(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  StampedTransform m = layout::transform_stamped(c);
  c.finish();
  return m;
}

StampedTransform decode_odometry(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  StampedTransform m = layout::odometry(c);
  c.finish();
  return m;
}

std::vector<StampedTransform> decode_tf_message(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  // Each TransformStamped has at least 4+8+4+4+56 bytes: impossible counts are refused before reserving.
  const std::uint32_t n = layout::count(c, 76);
  std::vector<StampedTransform> out(n);
  for (auto& m : out) m = layout::transform_stamped(c);
  c.finish();
  return out;
}

StreamInfo decode_stream_info(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  StreamInfo m;
  m.fps = c.u32();
  m.encoding = c.str();
  m.is_recommended = c.u8() != 0;
  c.finish();
  return m;
}

ImuIntrinsic decode_rs_imu_intrinsic(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  ImuIntrinsic m;
  for (auto& v : m.data) v = c.f32();
  for (auto& v : m.noise_variances) v = c.f32();
  for (auto& v : m.bias_variances) v = c.f32();
  c.finish();
  return m;
}

ImuIntrinsic decode_rs2_imu_info(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  ImuIntrinsic m;
  m.frame_id = c.str();
  for (auto& v : m.data) v = c.f64();
  for (auto& v : m.noise_variances) v = c.f64();
  for (auto& v : m.bias_variances) v = c.f64();
  c.finish();
  return m;
}

Extrinsics decode_rs2_extrinsics(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  Extrinsics m;
  m.header = c.header();
  layout::f64_array(c, m.rotation);
  layout::f64_array(c, m.translation);
  c.finish();
  return m;
}

KeyValue decode_key_value(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  KeyValue kv;
  kv.key = c.str();
  kv.value = c.str();
  c.finish();
  return kv;
}

std::uint32_t decode_uint32(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  const std::uint32_t v = c.u32();
  c.finish();
  return v;
}

float decode_float32(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  const float v = c.f32();
  c.finish();
  return v;
}

std::string decode_string(std::string_view msg, const std::string& where) {
  Cursor c(msg, where);
  std::string s = c.str();
  c.finish();
  return s;
}

// ---------------------------------------------------------------------------------------------
// Writer / encoders
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
Writer& Writer::vec3(const Eigen::Vector3d& v) { return f64(v.x()).f64(v.y()).f64(v.z()); }
Writer& Writer::quat_xyzw(const Eigen::Quaterniond& q) { return f64(q.x()).f64(q.y()).f64(q.z()).f64(q.w()); }

std::string encode_image(const Image& m) {
  Writer w;
  w.header(m.header).u32(m.height).u32(m.width).str(m.encoding).u8(m.is_bigendian).u32(m.step).byte_sequence(m.data);
  if (m.header.frame_id == kRealsenseImageVersion1) w.f32(m.depth_units);  // librealsense >= 2.49
  return w.bytes();
}
std::string encode_compressed_image(const CompressedImage& m) {
  Writer w;
  w.header(m.header).str(m.format).byte_sequence(m.data);
  return w.bytes();
}
std::string encode_camera_info(const CameraInfo& m) {
  Writer w;
  w.header(m.header).u32(m.height).u32(m.width).str(m.distortion_model).u32(static_cast<std::uint32_t>(m.D.size()));
  for (double d : m.D) w.f64(d);
  for (double d : m.K) w.f64(d);
  for (double d : m.R) w.f64(d);
  for (double d : m.P) w.f64(d);
  w.u32(m.binning_x).u32(m.binning_y).u32(m.roi_x).u32(m.roi_y).u32(m.roi_height).u32(m.roi_width).u8(
      m.roi_do_rectify ? 1 : 0);
  return w.bytes();
}
std::string encode_imu(const Imu& m) {
  Writer w;
  w.header(m.header).quat_xyzw(m.orientation);
  for (double d : m.orientation_covariance) w.f64(d);
  w.vec3(m.angular_velocity);
  for (double d : m.angular_velocity_covariance) w.f64(d);
  w.vec3(m.linear_acceleration);
  for (double d : m.linear_acceleration_covariance) w.f64(d);
  return w.bytes();
}
std::string encode_transform(const Transform& t) {
  Writer w;
  w.vec3(t.t).quat_xyzw(t.q);
  return w.bytes();
}
std::string encode_pose_stamped(const StampedTransform& m) {
  Writer w;
  w.header(m.header).vec3(m.transform.t).quat_xyzw(m.transform.q);
  return w.bytes();
}
std::string encode_transform_stamped(const StampedTransform& m) {
  Writer w;
  w.header(m.header).str(m.child_frame_id).vec3(m.transform.t).quat_xyzw(m.transform.q);
  return w.bytes();
}
std::string encode_odometry(const StampedTransform& m) {
  Writer w;
  w.header(m.header).str(m.child_frame_id).vec3(m.transform.t).quat_xyzw(m.transform.q);
  for (int i = 0; i < 36 + 6 + 36; ++i) w.f64(0.0);
  return w.bytes();
}
std::string encode_stream_info(const StreamInfo& m) {
  Writer w;
  w.u32(m.fps).str(m.encoding).u8(m.is_recommended ? 1 : 0);
  return w.bytes();
}
std::string encode_rs_imu_intrinsic(const ImuIntrinsic& m) {
  Writer w;
  for (double d : m.data) w.f32(static_cast<float>(d));
  for (double d : m.noise_variances) w.f32(static_cast<float>(d));
  for (double d : m.bias_variances) w.f32(static_cast<float>(d));
  return w.bytes();
}
std::string encode_key_value(const KeyValue& m) {
  Writer w;
  w.str(m.key).str(m.value);
  return w.bytes();
}
std::string encode_uint32(std::uint32_t v) {
  Writer w;
  w.u32(v);
  return w.bytes();
}

}  // namespace roe::io::ros
