#pragma once
/// @file
/// The ROS message types roe imports, decode<M> and encode<M> for them in either wire format, and the
/// ROS 1 serialization: little-endian fixed-size fields, strings and variable arrays prefixed by a uint32
/// length, fixed-size arrays without prefix, time = uint32 sec + uint32 nsec (CDR: cdr.hpp).
///
/// A decoder throws roe::InputError ("message too short", "trailing bytes", ...) naming the topic and
/// the bag byte offset passed in `where`; it never reads out of bounds. Image payloads are views into
/// the message buffer (no copy).

#include <array>
#include <cstdint>
#include <cstring>
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
/// included (third-party/realsense-file/rosbag/msgs/sensor_msgs/Image.h). decode<msg::Image> reads it
/// in ROS 1 messages; encode<msg::Image> writes it for frame_id "1", as the SDK does.
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

/// The two wire formats of the messages: the ROS 1 serialization (this header's Cursor and Writer) and
/// CDR for ROS 2 (cdr.hpp).
enum class Wire { ros1, cdr };

/// The message types roe decodes and encodes: each tag names the ROS type (ROS 1 spelling, as
/// normalize_ros_type writes it) and the struct it decodes to. Each has one field layout, in
/// src/io/ros/layouts.hpp, that both wire formats' cursors read and both writers write; adding a type is a
/// tag here and a layout there.
namespace msg {
/// The struct a message type decodes to (each tag adds its ROS type name, kType).
template <class V>
struct Message {
  using Value = V;
};
// clang-format off
struct Image : Message<ros::Image> { static constexpr auto kType = "sensor_msgs/Image"; };
struct CompressedImage : Message<ros::CompressedImage> {
  static constexpr auto kType = "sensor_msgs/CompressedImage"; };
struct CameraInfo : Message<ros::CameraInfo> { static constexpr auto kType = "sensor_msgs/CameraInfo"; };
struct Imu : Message<ros::Imu> { static constexpr auto kType = "sensor_msgs/Imu"; };
struct Transform : Message<ros::Transform> { static constexpr auto kType = "geometry_msgs/Transform"; };
struct PoseStamped : Message<StampedTransform> { static constexpr auto kType = "geometry_msgs/PoseStamped"; };
struct PoseWithCovarianceStamped : Message<StampedTransform> {
  static constexpr auto kType = "geometry_msgs/PoseWithCovarianceStamped"; };
struct TransformStamped : Message<StampedTransform> {
  static constexpr auto kType = "geometry_msgs/TransformStamped"; };
struct Odometry : Message<StampedTransform> { static constexpr auto kType = "nav_msgs/Odometry"; };
struct TFMessage : Message<std::vector<StampedTransform>> {
  static constexpr auto kType = "tf2_msgs/TFMessage"; };
struct StreamInfo : Message<ros::StreamInfo> { static constexpr auto kType = "realsense_msgs/StreamInfo"; };
/// float32 fields.
struct ImuIntrinsic : Message<ros::ImuIntrinsic> {
  static constexpr auto kType = "realsense_msgs/ImuIntrinsic"; };
/// float64 fields and a frame id.
struct IMUInfo : Message<ros::ImuIntrinsic> { static constexpr auto kType = "realsense2_camera/IMUInfo"; };
struct Extrinsics : Message<ros::Extrinsics> {
  static constexpr auto kType = "realsense2_camera/Extrinsics"; };
struct KeyValue : Message<ros::KeyValue> { static constexpr auto kType = "diagnostic_msgs/KeyValue"; };
struct UInt32 : Message<std::uint32_t> { static constexpr auto kType = "std_msgs/UInt32"; };
struct Float32 : Message<float> { static constexpr auto kType = "std_msgs/Float32"; };
struct String : Message<std::string> { static constexpr auto kType = "std_msgs/String"; };
// clang-format on
}  // namespace msg

/// Decodes one serialized message of type M (a msg:: tag) in `wire` format. `where` names the source in
/// errors (e.g. "bag.bag: /topic at byte 1234").
template <class M>
typename M::Value decode(Wire wire, std::string_view bytes, const std::string& where);
/// Serializes a message of type M in `wire` format (test fixtures, benchmarks); decode<M> reads it back.
template <class M>
std::string encode(Wire wire, const typename M::Value& m);

/// Bounds-checked reader over one ROS 1 serialized message: the primitives the field layouts
/// (src/io/ros/layouts.hpp) read.
class Cursor {
 public:
  static constexpr Wire kWire = Wire::ros1;
  static constexpr bool kReads = true;
  /// The fewest bytes a std_msgs/Header takes: seq, stamp, an empty frame_id.
  static constexpr std::size_t kMinHeaderBytes = 4 + 8 + 4;

  /// `where` (named in errors) is kept by reference: it must outlive the cursor.
  Cursor(std::string_view data, const std::string& where) : d_(data), where_(where) {}
  Cursor(std::string_view data, std::string&& where) = delete;
  std::uint8_t u8() { return num<std::uint8_t>(); }
  std::uint32_t u32() { return num<std::uint32_t>(); }
  float f32() { return num<float>(); }
  double f64() { return num<double>(); }
  Timestamp time() {
    const std::uint32_t s = u32();
    const std::uint32_t ns = u32();
    return static_cast<Timestamp>(s) * kNsPerSecond + static_cast<Timestamp>(ns);
  }
  std::string str() { return std::string(bytes(u32())); }
  std::string_view bytes(std::size_t n) {
    need(n);
    std::string_view v = d_.substr(pos_, n);
    pos_ += n;
    return v;
  }
  /// uint8[] with a length prefix.
  std::string_view byte_sequence() { return bytes(u32()); }
  Header header() {
    Header h;
    h.seq = u32();
    h.stamp_ns = time();
    h.frame_id = str();
    return h;
  }
  std::size_t remaining() const { return d_.size() - pos_; }
  /// InputError unless every byte was consumed.
  void finish() const;
  [[noreturn]] void fail(const std::string& what) const;

 private:
  template <class T>
  T num() {
    need(sizeof(T));
    T v;
    std::memcpy(&v, d_.data() + pos_, sizeof(T));  // little-endian, as is every platform roe targets
    pos_ += sizeof(T);
    return v;
  }
  void need(std::size_t n) const {
    if (n > d_.size() - pos_) too_short(n);
  }
  [[noreturn]] void too_short(std::size_t n) const;
  std::string_view d_;
  std::size_t pos_ = 0;
  const std::string& where_;
};

/// Appends ROS 1 serialized fields to a byte string: the primitives the layouts write (encode<M>), and
/// for hand-made messages in tests.
class Writer {
 public:
  static constexpr Wire kWire = Wire::ros1;
  static constexpr bool kReads = false;
  static constexpr std::size_t kMinHeaderBytes = Cursor::kMinHeaderBytes;

  Writer& u8(std::uint8_t v);
  Writer& u32(std::uint32_t v);
  Writer& f32(float v);
  Writer& f64(double v);
  Writer& time(Timestamp ns);
  Writer& str(std::string_view s);
  Writer& byte_sequence(std::string_view b);
  Writer& header(const Header& h);
  const std::string& bytes() const { return out_; }

 private:
  std::string out_;
};

}  // namespace roe::io::ros
