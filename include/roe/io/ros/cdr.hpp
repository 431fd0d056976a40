#pragma once
/// @file
/// Decoders of the ROS 2 messages roe imports, from their CDR serialization (OMG XCDR1, as rmw and
/// rosbag2 store them): a 4-byte encapsulation header (0x00 0x01 little-endian, 0x00 0x00 big-endian,
/// then two option bytes), then the fields, each primitive aligned to its own size (8 for float64)
/// counted from the end of the encapsulation header; strings are a uint32 length that counts a
/// terminating NUL, then the bytes and the NUL; sequences a uint32 count then the elements; fixed
/// arrays have no prefix; builtin_interfaces/Time is int32 sec + uint32 nanosec; std_msgs/Header has
/// no seq. The results are the same structs as the ROS 1 decoders' (ros_msgs.hpp; Header::seq = 0).
///
/// Every decoder throws roe::InputError naming `where` and the message byte offset on a short
/// message, a string or sequence length beyond the message, a missing NUL, or more than 3 trailing
/// bytes (serializers may pad the end to 4 bytes); it never reads out of bounds and never allocates
/// more than the message size justifies.

#include <string>
#include <string_view>
#include <vector>

#include "roe/io/ros/msgs.hpp"

namespace roe::io::cdr {

/// Bounds-checked CDR reader over one serialized message (encapsulation header included): the
/// primitives; the messages' field layouts are shared with the ROS 1 decoders (src/io/ros/layouts.hpp).
class Cursor {
 public:
  Cursor(std::string_view msg, std::string where);
  bool big_endian() const { return big_; }
  std::uint8_t u8();
  std::uint32_t u32();
  std::int32_t i32();
  double f64();
  std::string str();
  /// uint8[] sequence: a view into the message.
  std::string_view byte_sequence();
  ros::Header header();
  std::size_t remaining() const { return d_.size() - pos_; }
  /// InputError unless at most 3 (padding) bytes are left.
  void finish() const;
  [[noreturn]] void fail(const std::string& what) const;

 private:
  void align(std::size_t n);
  void need(std::size_t n) const;
  template <class T>
  T raw();
  std::string_view d_;
  std::size_t pos_ = 4;
  bool big_ = false;
  std::string where_;
};

ros::Image decode_image(std::string_view msg, const std::string& where);
ros::CompressedImage decode_compressed_image(std::string_view msg, const std::string& where);
ros::CameraInfo decode_camera_info(std::string_view msg, const std::string& where);
ros::Imu decode_imu(std::string_view msg, const std::string& where);
ros::StampedTransform decode_pose_stamped(std::string_view msg, const std::string& where);
ros::StampedTransform decode_pose_with_covariance_stamped(std::string_view msg, const std::string& where);
ros::StampedTransform decode_transform_stamped(std::string_view msg, const std::string& where);
ros::StampedTransform decode_odometry(std::string_view msg, const std::string& where);
std::vector<ros::StampedTransform> decode_tf_message(std::string_view msg, const std::string& where);

/// Appends CDR little-endian fields (test fixtures and benchmarks; the committed ROS 2 fixtures are
/// written by an independent serializer, tests/fixtures/ros2/make_fixtures.mjs).
class Writer {
 public:
  Writer();
  Writer& u8(std::uint8_t v);
  Writer& u32(std::uint32_t v);
  Writer& i32(std::int32_t v);
  Writer& f64(double v);
  Writer& str(std::string_view s);
  Writer& byte_sequence(std::string_view b);
  Writer& header(const ros::Header& h);
  Writer& vec3(const Eigen::Vector3d& v);
  Writer& quat_xyzw(const Eigen::Quaterniond& q);
  const std::string& bytes() const { return out_; }

 private:
  void align(std::size_t n);
  std::string out_;
};

std::string encode_imu(const ros::Imu& m);
std::string encode_camera_info(const ros::CameraInfo& m);
std::string encode_pose_stamped(const ros::StampedTransform& m);
std::string encode_tf_message(const std::vector<ros::StampedTransform>& m);

}  // namespace roe::io::cdr
