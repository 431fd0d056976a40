#pragma once
/// @file
/// The RealSense recording reader: which streams a RealSense bag holds (the recorder or the realsense-ros
/// layout, any bag generation; io/ros/realsense_streams.hpp decides from the topic list) and everything of
/// them but the colour images, read in one pass over the bag: the camera info, the IMU (united or accel and
/// gyro apart), the recorder's stream info, intrinsics, metadata and tf/0, and /tf_static. What the
/// samples become is decided elsewhere: the merged IMU in io/ros/imu_streams.hpp, the camera model and the
/// dataset by the importer (app/import_realsense).

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/io/ros/message_bag.hpp"
#include "roe/io/ros/msgs.hpp"
#include "roe/io/ros/realsense_streams.hpp"

namespace roe::io {

/// Everything of the chosen streams but the images. Samples are in bag order, stamped with header.stamp.
struct RealsenseRecording {
  std::optional<ros::CameraInfo> cam_info;                 ///< the first message of the camera info topic
  std::vector<std::pair<Timestamp, Eigen::Vector3d>> accel;  ///< split IMU: accel (m s^-2)
  std::vector<std::pair<Timestamp, Eigen::Vector3d>> gyro;   ///< split IMU: gyro (rad s^-1)
  std::vector<ImuSample> united;                          ///< the united IMU topic
  std::map<std::string, std::string> domain_of;           ///< metadata topic → its first timestamp_domain
  std::optional<ros::ImuIntrinsic> accel_intr, gyro_intr;
  std::uint32_t color_fps = 0, accel_fps = 0, gyro_fps = 0;  ///< recorder stream info
  std::map<std::string, ros::Transform> recorder_tf;  ///< recorder: stream label → tf/0
  std::vector<ros::StampedTransform> tf_static;       ///< realsense-ros: /tf_static
  std::string imu_frame;                              ///< header.frame_id of the united (else gyro) samples
};

/// The streams of a RealSense bag: discover_realsense_streams on the bag's topics (with the recorder
/// sensors' names read from their info topics). InputError naming the bag as that function's; a damaged
/// bag whose intact part has neither colour images nor IMU says so (nothing to salvage).
RealsenseStreams discover_realsense_bag(MessageBag& bag, const RealsenseTopicChoice& choice);

/// One pass over the streams `st` names (images excepted). InputError naming the message on a message
/// that does not decode; damage is left in bag.warnings() for the caller to judge.
RealsenseRecording read_realsense_recording(MessageBag& bag, const RealsenseStreams& st);

}  // namespace roe::io
