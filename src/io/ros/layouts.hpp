#pragma once
// The field layouts of the ROS messages roe imports, written once for both wire formats: the ROS 1
// serialization (ros::Cursor, msgs.cpp) and CDR for ROS 2 (cdr::Cursor, cdr.cpp). A cursor reads the
// primitives in its format (alignment, byte order, string and header encodings are its business):
// u8, u32, f64, str, header, byte_sequence (uint8[] with its length), remaining() and fail(what).
// Private to src/io.

#include <array>
#include <cstdint>
#include <string>

#include "roe/io/ros/msgs.hpp"

namespace roe::io::layout {

/// A sequence's element count, refused when that many elements of at least `min_bytes` each cannot fit in
/// the bytes left (before anything is reserved for them).
template <class C>
std::uint32_t count(C& c, std::size_t min_bytes) {
  const std::uint32_t n = c.u32();
  if (static_cast<std::uint64_t>(n) * min_bytes > c.remaining())
    c.fail("sequence length " + std::to_string(n) + " exceeds the message (" + std::to_string(c.remaining()) +
           " bytes left)");
  return n;
}

template <class C>
Eigen::Vector3d vec3(C& c) {  // geometry_msgs/Vector3, Point
  Eigen::Vector3d v;
  v.x() = c.f64();
  v.y() = c.f64();
  v.z() = c.f64();
  return v;
}

template <class C>
Eigen::Quaterniond quat_xyzw(C& c) {  // geometry_msgs/Quaternion
  const double x = c.f64(), y = c.f64(), z = c.f64(), w = c.f64();
  return Eigen::Quaterniond(w, x, y, z);
}

template <class C, std::size_t N>
void f64_array(C& c, std::array<double, N>& a) {
  for (auto& v : a) v = c.f64();
}

template <class C>
void skip_f64(C& c, int n) {
  for (int i = 0; i < n; ++i) c.f64();
}

template <class C>
ros::Transform pose(C& c) {  // geometry_msgs/Pose or Transform: a vector and a quaternion
  ros::Transform t;
  t.t = vec3(c);
  t.q = quat_xyzw(c);
  return t;
}

/// sensor_msgs/Image up to its data (the ROS 1 RealSense extension that may follow is msgs.cpp's).
template <class C>
ros::Image image(C& c) {
  ros::Image m;
  m.header = c.header();
  m.height = c.u32();
  m.width = c.u32();
  m.encoding = c.str();
  m.is_bigendian = c.u8();
  m.step = c.u32();
  m.data = c.byte_sequence();
  return m;
}

/// After finish(): the data must hold step x height bytes.
template <class C>
void check_image_size(const C& c, const ros::Image& m) {
  if (static_cast<std::uint64_t>(m.step) * m.height > m.data.size())
    c.fail("image data has " + std::to_string(m.data.size()) + " bytes, step x height = " +
           std::to_string(static_cast<std::uint64_t>(m.step) * m.height));
}

template <class C>
ros::CompressedImage compressed_image(C& c) {
  ros::CompressedImage m;
  m.header = c.header();
  m.format = c.str();
  m.data = c.byte_sequence();
  return m;
}

template <class C>
ros::CameraInfo camera_info(C& c) {
  ros::CameraInfo m;
  m.header = c.header();
  m.height = c.u32();
  m.width = c.u32();
  m.distortion_model = c.str();
  const std::uint32_t nd = count(c, 8);
  if (nd > 64) c.fail("implausible distortion coefficient count " + std::to_string(nd));
  m.D.resize(nd);
  for (auto& d : m.D) d = c.f64();
  f64_array(c, m.K);
  f64_array(c, m.R);
  f64_array(c, m.P);
  m.binning_x = c.u32();
  m.binning_y = c.u32();
  m.roi_x = c.u32();
  m.roi_y = c.u32();
  m.roi_height = c.u32();
  m.roi_width = c.u32();
  m.roi_do_rectify = c.u8() != 0;
  return m;
}

template <class C>
ros::Imu imu(C& c) {
  ros::Imu m;
  m.header = c.header();
  m.orientation = quat_xyzw(c);
  f64_array(c, m.orientation_covariance);
  m.angular_velocity = vec3(c);
  f64_array(c, m.angular_velocity_covariance);
  m.linear_acceleration = vec3(c);
  f64_array(c, m.linear_acceleration_covariance);
  return m;
}

template <class C>
ros::StampedTransform pose_stamped(C& c) {
  ros::StampedTransform m;
  m.header = c.header();
  m.transform = pose(c);
  return m;
}

template <class C>
ros::StampedTransform pose_with_covariance_stamped(C& c) {
  ros::StampedTransform m = pose_stamped(c);
  skip_f64(c, 36);
  return m;
}

/// geometry_msgs/TransformStamped, also the element of tf2_msgs/TFMessage.
template <class C>
ros::StampedTransform transform_stamped(C& c) {
  ros::StampedTransform m;
  m.header = c.header();
  m.child_frame_id = c.str();
  m.transform = pose(c);
  return m;
}

template <class C>
ros::StampedTransform odometry(C& c) {
  ros::StampedTransform m = transform_stamped(c);  // the same fields first: header, child frame, pose
  skip_f64(c, 36 + 6 + 36);                        // pose covariance, twist, twist covariance
  return m;
}

}  // namespace roe::io::layout
