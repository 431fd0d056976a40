// The RealSense recording reader (include/roe/io/ros/realsense_recording.hpp): which streams a bag holds and
// everything of them but the images, in one pass.
#include "roe/io/ros/realsense_recording.hpp"

#include <set>

#include "roe/core/error.hpp"

namespace roe::io {
namespace {

namespace msg = ros::msg;

/// The RealSense recorder's and realsense2_camera's own types (StreamInfo, ImuIntrinsic, IMUInfo,
/// KeyValue, Transform) come in ROS 1 bags: read in the ROS 1 wire format.
template <class M>
typename M::Value decode_ros1(const BagMessage& m) {
  return ros::decode<M>(ros::Wire::ros1, m.data, m.where());
}

/// Recorder layout: sensor prefix → its "Name" (diagnostic_msgs/KeyValue on /device_D/sensor_S/info).
std::map<std::string, std::string> read_sensor_names(MessageBag& bag) {
  std::set<std::string> info;
  for (const auto& t : bag.topics())
    if (recorder_sensor_info(t.topic) && t.type == "diagnostic_msgs/KeyValue" && t.encoding == "ros1")
      info.insert(t.topic);
  std::map<std::string, std::string> names;
  bag.for_each(info, [&](const BagMessage& m) {
    const auto kv = decode_ros1<msg::KeyValue>(m);
    if (kv.key == "Name") names[*recorder_sensor_info(m.topic->topic)] = kv.value;
    return true;
  });
  return names;
}

}  // namespace

RealsenseStreams discover_realsense_bag(MessageBag& bag, const RealsenseTopicChoice& choice) {
  std::vector<TopicType> tt;
  bool recorder = false;
  for (const auto& t : bag.topics()) {
    tt.push_back({t.topic, t.type});
    recorder = recorder || recorder_stream(t.topic).has_value();
  }
  try {
    return discover_realsense_streams(tt, choice, recorder ? read_sensor_names(bag) : std::map<std::string, std::string>{});
  } catch (const InputError& e) {
    if (bag.damaged() && e.bare_message().rfind("no colour image and no IMU stream", 0) == 0)
      // e.g. cut inside its first chunk: the topics are in the part that is lost
      throw InputError("the bag is damaged (" + bag.damage_summary() +
                           ") and its intact part has no colour image and no IMU stream: nothing to import, "
                           "even with --salvage" + bag.damage_listing(),
                       {bag.name()});
    throw InputError(e.bare_message(), {bag.name()});
  }
}

RealsenseRecording read_realsense_recording(MessageBag& bag, const RealsenseStreams& st) {
  RealsenseRecording d;
  std::set<std::string> topics = {st.camera_info_topic, st.color_info_topic, st.metadata_topic,  st.accel_topic,
                                  st.gyro_topic,        st.imu_topic,        st.accel_info_topic, st.gyro_info_topic,
                                  st.accel_intr_topic,  st.gyro_intr_topic,  st.accel_meta_topic, st.gyro_meta_topic,
                                  st.tf_static_topic};
  // Every recorder stream's tf/0 for the extrinsics record.
  for (const auto& t : bag.topics()) {
    const auto s = recorder_stream(t.topic);
    if (s && t.topic == s->prefix + "/tf/0" && t.type == "geometry_msgs/Transform") topics.insert(t.topic);
  }
  topics.erase("");
  bag.for_each(topics, [&](const BagMessage& m) {
    const std::string& t = m.topic->topic;
    if (t == st.camera_info_topic) {
      if (!d.cam_info) d.cam_info = decode<msg::CameraInfo>(m);
    } else if (t == st.imu_topic) {  // before accel/gyro: a united topic given as one of them too
      const auto imu = decode<msg::Imu>(m);
      d.united.push_back({imu.header.stamp_ns, imu.angular_velocity, imu.linear_acceleration});
      if (d.imu_frame.empty()) d.imu_frame = imu.header.frame_id;
    } else if (t == st.accel_topic || t == st.gyro_topic) {
      const auto imu = decode<msg::Imu>(m);
      if (t == st.accel_topic) d.accel.emplace_back(imu.header.stamp_ns, imu.linear_acceleration);
      if (t == st.gyro_topic) d.gyro.emplace_back(imu.header.stamp_ns, imu.angular_velocity);
      if (t == st.gyro_topic && st.imu_topic.empty() && d.imu_frame.empty()) d.imu_frame = imu.header.frame_id;
    } else if (t == st.tf_static_topic) {
      for (auto& tr : decode<msg::TFMessage>(m)) d.tf_static.push_back(std::move(tr));
    } else if (t == st.metadata_topic || t == st.accel_meta_topic || t == st.gyro_meta_topic) {
      const auto kv = decode_ros1<msg::KeyValue>(m);
      if (kv.key == "timestamp_domain" && !d.domain_of.count(t)) d.domain_of[t] = kv.value;
    } else if (t == st.color_info_topic) {
      d.color_fps = decode_ros1<msg::StreamInfo>(m).fps;
    } else if (t == st.accel_info_topic || t == st.gyro_info_topic) {
      (t == st.accel_info_topic ? d.accel_fps : d.gyro_fps) = decode_ros1<msg::StreamInfo>(m).fps;
    } else if (t == st.accel_intr_topic || t == st.gyro_intr_topic) {
      const auto ii = m.topic->type == msg::ImuIntrinsic::kType ? decode_ros1<msg::ImuIntrinsic>(m)
                                                                   : decode_ros1<msg::IMUInfo>(m);
      (t == st.accel_intr_topic ? d.accel_intr : d.gyro_intr) = ii;
    } else {
      const auto s = recorder_stream(t);
      if (s && !d.recorder_tf.count(s->label)) d.recorder_tf[s->label] = decode_ros1<msg::Transform>(m);
    }
    return true;
  });
  return d;
}

}  // namespace roe::io
