// libFuzzer target for roe's CDR (XCDR1) decoders of the ROS 2 messages it imports (docs/import.md,
// "Fuzzing"). The first input byte picks the message type, the rest is the serialized message.
// Contract under test: every decoder returns or throws roe::InputError; never reads out of bounds,
// never allocates more than the message justifies.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "roe/core/error.hpp"
#include "roe/io/ros/cdr.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  namespace cdr = roe::io::cdr;
  const std::string_view msg(reinterpret_cast<const char*>(data) + 1, size - 1);
  const std::string w = "fuzz";
  try {
    switch (data[0] % 9) {
      case 0: cdr::decode_image(msg, w); break;
      case 1: cdr::decode_compressed_image(msg, w); break;
      case 2: cdr::decode_camera_info(msg, w); break;
      case 3: cdr::decode_imu(msg, w); break;
      case 4: cdr::decode_pose_stamped(msg, w); break;
      case 5: cdr::decode_pose_with_covariance_stamped(msg, w); break;
      case 6: cdr::decode_transform_stamped(msg, w); break;
      case 7: cdr::decode_odometry(msg, w); break;
      default: cdr::decode_tf_message(msg, w); break;
    }
  } catch (const roe::InputError&) {
  }
  return 0;
}
