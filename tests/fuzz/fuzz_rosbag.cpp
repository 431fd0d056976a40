// libFuzzer target for roe's ROS bag reader and message decoders (see docs/import.md, "Fuzzing").
// Contract under test: for ANY input bytes, opening and iterating a bag either succeeds or throws
// roe::InputError; no crash, no sanitizer report, no unbounded allocation, no hang.
#include <cstddef>
#include <cstdint>
#include <string>

#include "roe/core/error.hpp"
#include "roe/io/ros/msgs.hpp"
#include "roe/io/ros/ros1_bag.hpp"

namespace {
void decode(const roe::io::ros1::MessageView& m) {
  namespace ros = roe::io::ros;
  namespace msg = ros::msg;
  using ros::Wire;
  const std::string& t = m.connection->type;
  const std::string w = "fuzz";
  try {
    if (t == "sensor_msgs/Image") ros::decode<msg::Image>(Wire::ros1, m.data, w);
    else if (t == "sensor_msgs/CompressedImage") ros::decode<msg::CompressedImage>(Wire::ros1, m.data, w);
    else if (t == "sensor_msgs/CameraInfo") ros::decode<msg::CameraInfo>(Wire::ros1, m.data, w);
    else if (t == "sensor_msgs/Imu") ros::decode<msg::Imu>(Wire::ros1, m.data, w);
    else if (t == "geometry_msgs/Transform") ros::decode<msg::Transform>(Wire::ros1, m.data, w);
    else if (t == "geometry_msgs/PoseStamped") ros::decode<msg::PoseStamped>(Wire::ros1, m.data, w);
    else if (t == "geometry_msgs/TransformStamped") ros::decode<msg::TransformStamped>(Wire::ros1, m.data, w);
    else if (t == "nav_msgs/Odometry") ros::decode<msg::Odometry>(Wire::ros1, m.data, w);
    else if (t == "tf2_msgs/TFMessage") ros::decode<msg::TFMessage>(Wire::ros1, m.data, w);
    else if (t == "realsense_msgs/StreamInfo") ros::decode<msg::StreamInfo>(Wire::ros1, m.data, w);
    else if (t == "realsense_msgs/ImuIntrinsic") ros::decode<msg::ImuIntrinsic>(Wire::ros1, m.data, w);
    else if (t == "diagnostic_msgs/KeyValue") ros::decode<msg::KeyValue>(Wire::ros1, m.data, w);
    else {
      // Unknown types: exercise every decoder on the bytes anyway.
      try { ros::decode<msg::Imu>(Wire::ros1, m.data, w); } catch (const roe::InputError&) {}
      try { ros::decode<msg::CameraInfo>(Wire::ros1, m.data, w); } catch (const roe::InputError&) {}
      try { ros::decode<msg::Image>(Wire::ros1, m.data, w); } catch (const roe::InputError&) {}
      try { ros::decode<msg::TFMessage>(Wire::ros1, m.data, w); } catch (const roe::InputError&) {}
      try { ros::decode<msg::Odometry>(Wire::ros1, m.data, w); } catch (const roe::InputError&) {}
    }
  } catch (const roe::InputError&) {
  }
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  for (bool scan : {false, true}) {
    try {
      roe::io::ros1::ReaderOptions o;
      o.force_scan = scan;
      o.max_chunk_bytes = 8u << 20;
      roe::io::ros1::Reader r(std::string(reinterpret_cast<const char*>(data), size), "fuzz", o);
      (void)r.topics();
      (void)r.message_count();
      r.for_each([](const roe::io::ros1::Connection&) { return true; },
                 [](const roe::io::ros1::MessageView& m) {
                   decode(m);
                   return true;
                 });
    } catch (const roe::InputError&) {
    }
  }
  return 0;
}
