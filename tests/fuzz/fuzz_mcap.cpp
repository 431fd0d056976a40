// libFuzzer target for roe's MCAP reader and, through it, the CDR decoders (docs/import.md, "Fuzzing").
// Contract under test: for ANY input bytes, opening (through the summary and by a linear scan) and
// iterating an MCAP file either succeeds or throws roe::InputError; no crash, no sanitizer report, no
// unbounded allocation, no hang.
#include <cstddef>
#include <cstdint>
#include <string>

#include "roe/core/error.hpp"
#include "roe/io/ros/cdr.hpp"
#include "roe/io/ros/mcap.hpp"

namespace {
void decode(const std::string& schema, std::string_view data) {
  namespace cdr = roe::io::cdr;
  const std::string w = "fuzz";
  try {
    if (schema == "sensor_msgs/msg/Image") cdr::decode_image(data, w);
    else if (schema == "sensor_msgs/msg/CompressedImage") cdr::decode_compressed_image(data, w);
    else if (schema == "sensor_msgs/msg/CameraInfo") cdr::decode_camera_info(data, w);
    else if (schema == "sensor_msgs/msg/Imu") cdr::decode_imu(data, w);
    else if (schema == "nav_msgs/msg/Odometry") cdr::decode_odometry(data, w);
    else cdr::decode_tf_message(data, w);
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
