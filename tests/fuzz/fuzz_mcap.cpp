// libFuzzer target for roe's MCAP reader and, through it, the CDR decoders (docs/import.md, "Fuzzing").
// Contract under test: for ANY input bytes, opening (through the summary and by a linear scan) and
// iterating an MCAP file either succeeds or throws roe::InputError; no crash, no sanitizer report, no
// unbounded allocation, no hang.
#include <cstddef>
#include <cstdint>
#include <string>

#include "roe/core/error.hpp"
#include "roe/io/ros/msgs.hpp"
#include "roe/io/ros/mcap.hpp"

namespace {
void decode(const std::string& schema, std::string_view data) {
  namespace ros = roe::io::ros;
  namespace msg = ros::msg;
  using ros::Wire;
  const std::string w = "fuzz";
  try {
    if (schema == "sensor_msgs/msg/Image") ros::decode<msg::Image>(Wire::cdr, data, w);
    else if (schema == "sensor_msgs/msg/CompressedImage") ros::decode<msg::CompressedImage>(Wire::cdr, data, w);
    else if (schema == "sensor_msgs/msg/CameraInfo") ros::decode<msg::CameraInfo>(Wire::cdr, data, w);
    else if (schema == "sensor_msgs/msg/Imu") ros::decode<msg::Imu>(Wire::cdr, data, w);
    else if (schema == "nav_msgs/msg/Odometry") ros::decode<msg::Odometry>(Wire::cdr, data, w);
    else ros::decode<msg::TFMessage>(Wire::cdr, data, w);
  } catch (const roe::InputError&) {
  }
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  for (bool scan : {false, true}) {
    try {
      roe::io::mcap::ReaderOptions o;
      o.force_scan = scan;
      o.max_chunk_bytes = 8u << 20;
      roe::io::mcap::Reader r(std::string(reinterpret_cast<const char*>(data), size), "fuzz", o);
      for (const auto& [id, c] : r.channels()) (void)r.message_count(id);
      r.for_each([](const roe::io::mcap::Channel&) { return true; },
                 [&](const roe::io::mcap::MessageView& m) {
                   decode(r.schema_name(*m.channel), m.data);
                   return true;
                 });
    } catch (const roe::InputError&) {
    }
  }
  return 0;
}
