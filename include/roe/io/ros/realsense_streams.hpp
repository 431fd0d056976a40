#pragma once
/// @file
/// Which topics of a bag are a RealSense's colour image, camera info, IMU (united or split) and
/// static transforms: one pure function of the bag's (topic, type) list for every bag generation
/// (ROS 1 and ROS 2), tested without a bag. Two layouts:
///  - the RealSense SDK recorder: /device_D/sensor_S/<Kind>_<i>/... (Color_0/image/data,
///    Accel_0/imu/data, .../info/camera_info, .../tf/0, .../imu_intrinsic, .../image/metadata);
///  - realsense-ros (ROS 1 2.x and ROS 2 4.x, any namespace, e.g. /camera or /camera/camera):
///    <ns>/color/image_raw (or image_rect_raw, or their /compressed), <ns>/color/camera_info,
///    <ns>/imu (unite_imu_method) or <ns>/accel/sample + <ns>/gyro/sample, <ns>/{accel,gyro}/imu_info,
///    and /tf_static for the extrinsics.
/// Types are the normalised ones (io::normalize_ros_type: "sensor_msgs/Imu").

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/io/ros/msgs.hpp"

namespace roe::io {

struct TopicType {
  std::string topic, type;
};

/// Topics the user chose (--color-topic, --accel-topic, --gyro-topic, --imu-topic); "" = find.
struct RealsenseTopicChoice {
  std::string color_topic, accel_topic, gyro_topic, imu_topic;
};

/// A stream of the recorder layout: /device_D/sensor_S/<Kind>_<i>.
struct RecorderStream {
  std::string prefix;  ///< "/device_0/sensor_1/Color_0"
  std::string sensor;  ///< "/device_0/sensor_1"
  std::string kind;    ///< "Color"
  std::string label;   ///< "Color_0"
};
std::optional<RecorderStream> recorder_stream(const std::string& topic);
/// Whether `topic` is a recorder sensor's info topic (/device_D/sensor_S/info); its sensor prefix.
std::optional<std::string> recorder_sensor_info(const std::string& topic);

struct RealsenseStreams {
  std::string layout;  ///< "recorder" | "realsense-ros"
  std::string color_topic, camera_info_topic;
  std::string accel_topic, gyro_topic, imu_topic;  ///< imu_topic: united (gyro + accel per message)
  std::string accel_intr_topic, gyro_intr_topic;   ///< recorder imu_intrinsic / realsense-ros imu_info
  std::string tf_static_topic;                     ///< realsense-ros: "/tf_static" when the bag has it
  // Recorder layout only: StreamInfo (fps) and per-frame metadata (timestamp_domain) topics.
  std::string color_info_topic, metadata_topic, accel_info_topic, gyro_info_topic, accel_meta_topic,
      gyro_meta_topic;
  std::vector<std::string> image_topics;      ///< every Image/CompressedImage topic (for messages)
  std::vector<std::string> imu_typed_topics;  ///< every sensor_msgs/Imu topic
  std::vector<std::string> warnings;          ///< choices made among several candidates
};

/// Decides the streams. `sensor_names` maps a recorder sensor prefix to its "Name" (read from its
/// info topic; only the recorder layout needs it). InputError (without a file: the caller adds it)
/// for a chosen topic that is not in the list or has the wrong type, and when neither a colour image
/// nor an IMU stream is found (listing every topic with its type).
RealsenseStreams discover_realsense_streams(const std::vector<TopicType>& topics, const RealsenseTopicChoice& choice,
                                            const std::map<std::string, std::string>& sensor_names = {});

/// T_target_source from a set of static transforms (tf: header.frame_id = parent, child_frame_id =
/// child, transform = T_parent_child), through their common root; nullopt when the two frames are not
/// connected. A frame equal to itself gives the identity.
std::optional<Pose> static_transform(const std::vector<ros::StampedTransform>& tfs, const std::string& target,
                                     const std::string& source);

}  // namespace roe::io
