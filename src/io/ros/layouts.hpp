#pragma once
// The field layouts of the ROS messages roe reads and writes, one per message type (the msg:: tags of
// include/roe/io/ros/msgs.hpp), written once for both wire formats and both directions: a layout lists
// the message's fields in wire order, and each field goes through the cursor by its C++ type, read into
// the message by a reading cursor (ros::Cursor, cdr::Cursor) or appended from it by a writer (ros::Writer,
// cdr::Writer). Alignment, byte order and the string and header encodings are the cursor's business.
//
// Field types and their primitives: ros::Header → header; std::string → str; std::string_view →
// byte_sequence (uint8[] with its length); std::uint32_t → u32; std::uint8_t, bool → u8; float → f32;
// double → f64; fixed arrays element by element; Eigen::Vector3d (Vector3, Point) → x y z;
// Eigen::Quaterniond → x y z w; ros::Transform (Pose, Transform) → position, orientation. float32 fields
// kept as doubles are marked as_f32(...); variable-length sequences go through sequence().
// Private to src/io/ros.

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "roe/io/ros/msgs.hpp"

namespace roe::io::layout {

using ros::Wire;

/// Fields of type double (or arrays of them) that the wire holds as float32.
template <class A>
struct F32 {
  A& fields;
};
template <class A>
F32<A> as_f32(A& a) {
  return {a};
}

template <class T>
struct IsArray : std::false_type {};
template <class T, std::size_t N>
struct IsArray<std::array<T, N>> : std::true_type {};

/// Moves one primitive field: `read(cursor)` into `v` with a reading cursor, `write(writer, v)` otherwise.
template <class C, class T, class Read, class Write>
void transfer(C& c, T& v, Read read, Write write) {
  if constexpr (C::kReads)
    v = static_cast<std::remove_const_t<T>>(read(c));
  else
    write(c, v);
}

template <class C, class... T>
void io(C& c, T&... fields);

/// One field, by its type (see the top of this file).
template <class C, class T>
void field(C& c, T& v) {
  using U = std::remove_const_t<T>;
  if constexpr (IsArray<U>::value) {
    for (auto& e : v) field(c, e);
  } else if constexpr (std::is_same_v<U, Eigen::Vector3d>) {
    io(c, v.x(), v.y(), v.z());
  } else if constexpr (std::is_same_v<U, Eigen::Quaterniond>) {
    io(c, v.x(), v.y(), v.z(), v.w());
  } else if constexpr (std::is_same_v<U, ros::Transform>) {
    io(c, v.t, v.q);
  } else if constexpr (std::is_same_v<U, ros::Header>) {
    transfer(c, v, [](auto& r) { return r.header(); }, [](auto& w, const auto& x) { w.header(x); });
  } else if constexpr (std::is_same_v<U, std::string>) {
    transfer(c, v, [](auto& r) { return r.str(); }, [](auto& w, const auto& x) { w.str(x); });
  } else if constexpr (std::is_same_v<U, std::string_view>) {
    transfer(c, v, [](auto& r) { return r.byte_sequence(); }, [](auto& w, auto x) { w.byte_sequence(x); });
  } else if constexpr (std::is_same_v<U, std::uint32_t>) {
    transfer(c, v, [](auto& r) { return r.u32(); }, [](auto& w, auto x) { w.u32(x); });
  } else if constexpr (std::is_same_v<U, std::uint8_t> || std::is_same_v<U, bool>) {
    transfer(c, v, [](auto& r) { return r.u8(); }, [](auto& w, auto x) { w.u8(static_cast<std::uint8_t>(x)); });
  } else if constexpr (std::is_same_v<U, float>) {
    transfer(c, v, [](auto& r) { return r.f32(); }, [](auto& w, auto x) { w.f32(x); });
  } else if constexpr (std::is_same_v<U, double>) {
    transfer(c, v, [](auto& r) { return r.f64(); }, [](auto& w, auto x) { w.f64(x); });
  } else {
    static_assert(std::is_same_v<U, double>, "no wire primitive for this field type");
  }
}

/// The fields in wire order.
template <class C, class... T>
void io(C& c, T&... fields) {
  (field(c, fields), ...);
}
template <class C, class A>
void io(C& c, F32<A> f) {
  for (auto& e : f.fields)
    transfer(c, e, [](auto& r) { return r.f32(); }, [](auto& w, double x) { w.f32(static_cast<float>(x)); });
}

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

/// A variable-length sequence: its count (reading: checked by count(), and refused beyond `max`, named
/// `what`), then each element through `element`.
template <class C, class Vec, class F>
void sequence(C& c, Vec& v, std::size_t min_bytes, F&& element,
              std::uint32_t max = std::numeric_limits<std::uint32_t>::max(), const char* what = "") {
  if constexpr (C::kReads) {
    const std::uint32_t n = count(c, min_bytes);
    if (n > max) c.fail(std::string("implausible ") + what + " " + std::to_string(n));
    v.resize(n);
  } else {
    c.u32(static_cast<std::uint32_t>(v.size()));
  }
  for (auto& e : v) element(e);
}

/// `n` float64 fields roe does not keep: read and dropped, written as zeros.
template <class C>
void unused_f64(C& c, std::size_t n) {
  if constexpr (C::kReads) {
    // Stepped over at once, failing where n calls of f64() would: the first aligns (CDR), the rest follow.
    if (n == 0) return;
    c.f64();
    const std::size_t whole = std::min(n - 1, c.remaining() / 8);
    c.bytes(8 * whole);
    if (whole < n - 1) c.f64();
  } else {
    for (std::size_t i = 0; i < n; ++i) c.f64(0.0);
  }
}

/// Whether an optional last field of `n` bytes is there: exactly `n` bytes left to read; always written.
template <class C>
bool trailing(const C& c, std::size_t n) {
  if constexpr (C::kReads)
    return c.remaining() == n;
  else
    return true;
}

// The messages: fields(tag, cursor, message), and check(tag, cursor, message) for what can only be
// checked once the whole message is read (after finish()). M is the message struct, const when written.

template <class Tag, class C, class M>
void check(Tag, const C&, const M&) {}

template <class C, class M>
void fields(ros::msg::Image, C& c, M& m) {
  io(c, m.header, m.height, m.width, m.encoding, m.is_bigendian, m.step, m.data);
  // ROS 1 bags of librealsense >= 2.49: header.version "1" (in the frame_id slot) appends float32
  // depth_units; read when exactly those 4 bytes follow (other trailing bytes are still refused by finish()).
  if constexpr (C::kWire == Wire::ros1)
    if (m.header.frame_id == ros::kRealsenseImageVersion1 && trailing(c, 4)) io(c, m.depth_units);
}

/// The data must hold step x height bytes.
template <class C>
void check(ros::msg::Image, const C& c, const ros::Image& m) {
  if (static_cast<std::uint64_t>(m.step) * m.height > m.data.size())
    c.fail("image data has " + std::to_string(m.data.size()) + " bytes, step x height = " +
           std::to_string(static_cast<std::uint64_t>(m.step) * m.height));
}

template <class C, class M>
void fields(ros::msg::CompressedImage, C& c, M& m) {
  io(c, m.header, m.format, m.data);
}

template <class C, class M>
void fields(ros::msg::CameraInfo, C& c, M& m) {
  io(c, m.header, m.height, m.width, m.distortion_model);
  sequence(c, m.D, 8, [&](auto& d) { io(c, d); }, 64, "distortion coefficient count");
  io(c, m.K, m.R, m.P, m.binning_x, m.binning_y, m.roi_x, m.roi_y, m.roi_height, m.roi_width, m.roi_do_rectify);
}

template <class C, class M>
void fields(ros::msg::Imu, C& c, M& m) {
  io(c, m.header, m.orientation, m.orientation_covariance, m.angular_velocity, m.angular_velocity_covariance,
     m.linear_acceleration, m.linear_acceleration_covariance);
}

template <class C, class M>
void fields(ros::msg::Transform, C& c, M& m) {  // geometry_msgs/Transform; Pose has the same layout
  io(c, m);
}

template <class C, class M>
void fields(ros::msg::PoseStamped, C& c, M& m) {
  io(c, m.header, m.transform);
}

template <class C, class M>
void fields(ros::msg::PoseWithCovarianceStamped, C& c, M& m) {
  fields(ros::msg::PoseStamped{}, c, m);  // and the pose covariance
  unused_f64(c, 36);
}

template <class C, class M>
void fields(ros::msg::TransformStamped, C& c, M& m) {
  io(c, m.header, m.child_frame_id, m.transform);
}

template <class C, class M>
void fields(ros::msg::Odometry, C& c, M& m) {
  fields(ros::msg::TransformStamped{}, c, m);  // the same fields first: header, child frame, pose
  unused_f64(c, 36 + 6 + 36);                  // pose covariance, twist, twist covariance
}

template <class C, class M>
void fields(ros::msg::TFMessage, C& c, M& m) {
  // A TransformStamped takes at least a header, an empty child frame id and a pose.
  sequence(c, m, C::kMinHeaderBytes + 4 + 7 * 8, [&](auto& t) { fields(ros::msg::TransformStamped{}, c, t); });
}

template <class C, class M>
void fields(ros::msg::StreamInfo, C& c, M& m) {
  io(c, m.fps, m.encoding, m.is_recommended);
}

template <class C, class M>
void fields(ros::msg::ImuIntrinsic, C& c, M& m) {
  io(c, as_f32(m.data));
  io(c, as_f32(m.noise_variances));
  io(c, as_f32(m.bias_variances));
}

template <class C, class M>
void fields(ros::msg::IMUInfo, C& c, M& m) {
  io(c, m.frame_id, m.data, m.noise_variances, m.bias_variances);
}

template <class C, class M>
void fields(ros::msg::Extrinsics, C& c, M& m) {
  io(c, m.header, m.rotation, m.translation);
}

template <class C, class M>
void fields(ros::msg::KeyValue, C& c, M& m) {
  io(c, m.key, m.value);
}

/// std_msgs/UInt32, Float32 and String: the value itself.
template <class Tag, class C, class V,
          class = std::enable_if_t<std::is_same_v<Tag, ros::msg::UInt32> || std::is_same_v<Tag, ros::msg::Float32> ||
                                   std::is_same_v<Tag, ros::msg::String>>>
void fields(Tag, C& c, V& v) {
  io(c, v);
}

}  // namespace roe::io::layout
