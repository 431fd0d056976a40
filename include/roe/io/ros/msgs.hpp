#pragma once
/// @file
/// Decoders (and, for test fixtures, encoders) of the ROS1 message types roe imports, from the ROS1
/// serialization: little-endian fixed-size fields, strings and variable arrays prefixed by a uint32
/// length, fixed-size arrays without prefix, time = uint32 sec + uint32 nsec.
///
/// A decoder throws roe::InputError ("message too short", "trailing bytes", ...) naming the topic and
/// the bag byte offset passed in `where`; it never reads out of bounds. Image payloads are views into
/// the message buffer (no copy).

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "roe/core/error.hpp"
#include "roe/core/types.hpp"

namespace roe::io::ros {

/// std_msgs/Header.
struct Header {
  std::uint32_t seq = 0;
  Timestamp stamp_ns = 0;
  std::string frame_id;
};

/// sensor_msgs/Image (data is a view into the message).
///
/// librealsense >= 2.49 extends it in its recorder bags: when header.version (serialized in the
/// frame_id slot) is "1", a float32 `depth_units` follows `data` in every video frame, colour
/// included (third-party/realsense-file/rosbag/msgs/sensor_msgs/Image.h). decode_image reads it;
/// encode_image writes it for frame_id "1", as the SDK does.
struct Image {
  Header header;
  std::uint32_t height = 0, width = 0;
  std::string encoding;
  std::uint8_t is_bigendian = 0;
  std::uint32_t step = 0;
  std::string_view data;
  float depth_units = 0.0f;  ///< librealsense header.version "1" only (0 otherwise)
};

/// header.version of librealsense's extended sensor_msgs/Image (see Image).
inline constexpr const char* kRealsenseImageVersion1 = "1";

/// sensor_msgs/CompressedImage.
struct CompressedImage {
  Header header;
  std::string format;
  std::string_view data;
};

/// sensor_msgs/CameraInfo (roi and binning kept for completeness).
struct CameraInfo {
  Header header;
  std::uint32_t height = 0, width = 0;
  std::string distortion_model;
  std::vector<double> D;
  std::array<double, 9> K{}, R{};
  std::array<double, 12> P{};
  std::uint32_t binning_x = 0, binning_y = 0;
  std::uint32_t roi_x = 0, roi_y = 0, roi_height = 0, roi_width = 0;
  bool roi_do_rectify = false;
};

/// sensor_msgs/Imu.
struct Imu {
  Header header;
  Eigen::Quaterniond orientation = Eigen::Quaterniond(0, 0, 0, 0);
  std::array<double, 9> orientation_covariance{};
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();
  std::array<double, 9> angular_velocity_covariance{};
  Eigen::Vector3d linear_acceleration = Eigen::Vector3d::Zero();
  std::array<double, 9> linear_acceleration_covariance{};
};

/// geometry_msgs/Transform or Pose content (translation/position + rotation/orientation).
struct Transform {
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q = Eigen::Quaterniond(1, 0, 0, 0);  ///< as stored (not normalised)
};

/// geometry_msgs/PoseStamped, TransformStamped, PoseWithCovarianceStamped, nav_msgs/Odometry:
/// a stamped pose with the frames it relates.
struct StampedTransform {
  Header header;
  std::string child_frame_id;  ///< empty for PoseStamped
  Transform transform;
};

/// realsense_msgs/StreamInfo.
struct StreamInfo {
  std::uint32_t fps = 0;
  std::string encoding;
  bool is_recommended = false;
};

/// realsense_msgs/ImuIntrinsic (float32 fields) or realsense2_camera/IMUInfo (float64 fields):
/// data = 3x4 row-major [scale and cross-axis | bias].
struct ImuIntrinsic {
  std::string frame_id;  ///< IMUInfo only
  std::array<double, 12> data{};
  std::array<double, 3> noise_variances{};
  std::array<double, 3> bias_variances{};
};

/// realsense2_camera/Extrinsics: R column-major (as in rs2_extrinsics), t.
struct Extrinsics {
  Header header;
  std::array<double, 9> rotation{};
  std::array<double, 3> translation{};
};

struct KeyValue {
  std::string key, value;
};

/// Bounds-checked reader over one serialized message: the primitives; the messages' field layouts are
/// shared with the ROS 2 decoders (src/io/ros/layouts.hpp).
class Cursor {
 public:
  Cursor(std::string_view data, std::string where) : d_(data), where_(std::move(where)) {}
  std::uint8_t u8();
  std::uint32_t u32();
  std::int32_t i32();
  float f32();
  double f64();
  Timestamp time();
  std::string str();
  std::string_view bytes(std::size_t n);
  /// uint8[] with a length prefix.
  std::string_view byte_sequence();
  Header header();
  std::size_t remaining() const { return d_.size() - pos_; }
  /// InputError unless every byte was consumed.
  void finish() const;
  [[noreturn]] void fail(const std::string& what) const;

 private:
  void need(std::size_t n) const;
  std::string_view d_;
  std::size_t pos_ = 0;
  std::string where_;
};

// Decoders. `where` names the source in errors (e.g. "bag.bag: /topic at byte 1234").
Header decode_header_only(std::string_view msg, const std::string& where);
Image decode_image(std::string_view msg, const std::string& where);
CompressedImage decode_compressed_image(std::string_view msg, const std::string& where);
CameraInfo decode_camera_info(std::string_view msg, const std::string& where);
Imu decode_imu(std::string_view msg, const std::string& where);
Transform decode_transform(std::string_view msg, const std::string& where);  ///< geometry_msgs/Transform
StampedTransform decode_pose_stamped(std::string_view msg, const std::string& where);
StampedTransform decode_pose_with_covariance_stamped(std::string_view msg, const std::string& where);
StampedTransform decode_transform_stamped(std::string_view msg, const std::string& where);
StampedTransform decode_odometry(std::string_view msg, const std::string& where);
std::vector<StampedTransform> decode_tf_message(std::string_view msg, const std::string& where);
StreamInfo decode_stream_info(std::string_view msg, const std::string& where);
ImuIntrinsic decode_rs_imu_intrinsic(std::string_view msg, const std::string& where);
ImuIntrinsic decode_rs2_imu_info(std::string_view msg, const std::string& where);
Extrinsics decode_rs2_extrinsics(std::string_view msg, const std::string& where);
KeyValue decode_key_value(std::string_view msg, const std::string& where);
std::uint32_t decode_uint32(std::string_view msg, const std::string& where);
float decode_float32(std::string_view msg, const std::string& where);
std::string decode_string(std::string_view msg, const std::string& where);

/// Appends ROS1-serialized fields to a byte string (used by the test fixtures' bag writer).
class Writer {
 public:
  Writer& u8(std::uint8_t v);
  Writer& u32(std::uint32_t v);
  Writer& f32(float v);
  Writer& f64(double v);
  Writer& time(Timestamp ns);
  Writer& str(std::string_view s);
  Writer& byte_sequence(std::string_view b);
  Writer& header(const Header& h);
  Writer& vec3(const Eigen::Vector3d& v);
  Writer& quat_xyzw(const Eigen::Quaterniond& q);
  const std::string& bytes() const { return out_; }

 private:
  std::string out_;
};

std::string encode_image(const Image& m);
std::string encode_compressed_image(const CompressedImage& m);
std::string encode_camera_info(const CameraInfo& m);
std::string encode_imu(const Imu& m);
std::string encode_transform(const Transform& t);
std::string encode_pose_stamped(const StampedTransform& m);
std::string encode_transform_stamped(const StampedTransform& m);
std::string encode_odometry(const StampedTransform& m);
std::string encode_stream_info(const StreamInfo& m);
std::string encode_rs_imu_intrinsic(const ImuIntrinsic& m);
std::string encode_key_value(const KeyValue& m);
std::string encode_uint32(std::uint32_t v);

}  // namespace roe::io::ros
