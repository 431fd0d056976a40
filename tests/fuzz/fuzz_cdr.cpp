// libFuzzer target for roe's CDR (XCDR1) decoders of the ROS 2 messages it imports (docs/import.md,
// "Fuzzing"). The first input byte picks the message type, the rest is the serialized message.
// Contract under test: every decoder returns or throws roe::InputError; never reads out of bounds,
// never allocates more than the message justifies.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "roe/core/error.hpp"
#include "roe/io/ros/msgs.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  namespace ros = roe::io::ros;
  namespace msg = ros::msg;
  using ros::Wire;
  const std::string_view bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  const std::string w = "fuzz";
  try {
    switch (data[0] % 9) {
      case 0: ros::decode<msg::Image>(Wire::cdr, bytes, w); break;
      case 1: ros::decode<msg::CompressedImage>(Wire::cdr, bytes, w); break;
      case 2: ros::decode<msg::CameraInfo>(Wire::cdr, bytes, w); break;
      case 3: ros::decode<msg::Imu>(Wire::cdr, bytes, w); break;
      case 4: ros::decode<msg::PoseStamped>(Wire::cdr, bytes, w); break;
      case 5: ros::decode<msg::PoseWithCovarianceStamped>(Wire::cdr, bytes, w); break;
      case 6: ros::decode<msg::TransformStamped>(Wire::cdr, bytes, w); break;
      case 7: ros::decode<msg::Odometry>(Wire::cdr, bytes, w); break;
      default: ros::decode<msg::TFMessage>(Wire::cdr, bytes, w); break;
    }
  } catch (const roe::InputError&) {
  }
  return 0;
}
