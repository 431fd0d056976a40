// Pose topics of ROS 1 and ROS 2 bags as motion-capture data (include/roe/io/ros/bag_poses.hpp).
#include "roe/io/ros/bag_poses.hpp"

#include <algorithm>
#include <cmath>
#include <set>

#include <fmt/format.h>

#include "roe/core/error.hpp"
#include "roe/io/ros/message_bag.hpp"
#include "roe/io/ros/msgs.hpp"
#include "roe/io/ros/tf_buffer.hpp"

namespace roe::io {

namespace {
/// A pose topic that is not given or not in the bag: the bag's pose topics, every topic, and both spellings.
[[noreturn]] void refuse_topic(const MessageBag& reader, const std::string& topic) {
  const std::string bag_word = reader.ros2() ? "the ROS 2 bag" : "the bag";
  std::string list;
  for (const auto& t : reader.topics())
    if (is_pose_type(t.type)) list += "\n  " + t.topic + " [" + t.type + "]";
  const std::string where = reader.damaged() ? "the intact part of " + bag_word : bag_word;
  std::string msg = (topic.empty() ? std::string("no topic given: name a pose topic (roe eval BAG:TOPIC, e.g. "
                                                 "BAG:/odom or BAG:/tf:PARENT.CHILD; roe import mocap --topic T)")
                                   : "topic \"" + topic + "\" is not in " + where) +
                    "; pose topics in " + where + ":" + (list.empty() ? std::string(" none") : list) +
                    "\nall topics:" + reader.topic_listing();
  if (reader.damaged())
    msg += "\nthe bag is damaged (" + reader.first_damage() + "); --salvage cannot recover what is lost";
  throw InputError(msg, {reader.name()});
}

/// After reading: a damaged bag is an error unless `salvage`.
void refuse_damage(const MessageBag& reader, bool salvage) {
  if (reader.damaged() && !salvage)
    throw InputError("the bag is damaged (" + reader.first_damage() +
                         "); use --salvage to import the poses that are intact",
                     {reader.name()});
}

/// PARENT -> CHILD through the tf tree of `topic` and, implicitly, /tf_static (as evo and tf2 read a
/// bag): TfBuffer::trajectory, stamped with header.stamp (the record time when it is zero).
void read_tf_chain(MessageBag& reader, const std::string& topic, const std::string& parent,
                   const std::string& child, MocapData& out) {
  TfBuffer buffer(reader.name());
  std::set<std::string> topics{topic};
  const std::string kStatic = "/tf_static";
  if (topic != kStatic && reader.topic_type(kStatic) == "tf2_msgs/TFMessage") topics.insert(kStatic);
  bool zero_stamps = false;
  reader.for_each(topics, [&](const BagMessage& m) {
    const bool is_static = m.topic->topic == kStatic;
    if (!is_static) ++out.rows;
    for (auto& tr : decode<ros::msg::TFMessage>(m)) {
      if (tr.header.stamp_ns == 0 && !is_static) {
        tr.header.stamp_ns = m.log_time_ns;
        zero_stamps = true;
      }
      buffer.add(tr, is_static, m.topic->topic + " " + m.where());
    }
    return true;
  });
  out.poses = buffer.trajectory(parent, child);
  out.body = child;
  out.parent_frame = parent;
  if (zero_stamps) out.warnings.push_back("transforms with header.stamp = 0 use the bag record time");
}
}  // namespace

MocapData read_bag_poses(const fs::path& bag_file, const std::string& topic, const std::string& child_frame,
                         bool salvage, const std::string& parent_frame) {
  MocapData out;
  out.length_unit = "m";
  out.rotation_type = "Quaternion";
  BagOpenOptions bo;
  bo.allow_missing_files = salvage;
  const auto reader = open_bag(bag_file, bo);
  out.format = reader->ros2() ? "rosbag2" : "rosbag";
  const std::string type = reader->topic_type(topic);
  if (topic.empty() || type.empty()) refuse_topic(*reader, topic);
  if (!is_pose_type(type))
    throw InputError("topic " + topic + " has type " + type +
                         " (supported: PoseStamped, TransformStamped, PoseWithCovarianceStamped, Odometry, TFMessage)",
                     {reader->name()});
  const bool tf = type == "tf2_msgs/TFMessage";
  if (!tf && !parent_frame.empty())
    throw InputError("--parent selects a transform of a tf2_msgs/TFMessage topic; " + topic + " has type " + type,
                     {reader->name()});
  out.body = topic;
  if (tf && !parent_frame.empty() && !child_frame.empty()) {
    read_tf_chain(*reader, topic, parent_frame, child_frame, out);
    refuse_damage(*reader, salvage);
    for (const auto& w : reader->warnings()) out.warnings.push_back(fmt::format("{}: {}", w.file, w.text()));
    return out;
  }
  std::set<std::pair<std::string, std::string>> pairs;  // (parent, child) seen on a tf topic
  std::vector<std::pair<Timestamp, ros::StampedTransform>> msgs;
  reader->for_each({topic}, [&](const BagMessage& m) {
    ++out.rows;
    if (tf) {
      for (auto& tr : decode<ros::msg::TFMessage>(m)) {
        pairs.insert({tr.header.frame_id, tr.child_frame_id});
        if ((child_frame.empty() || tr.child_frame_id == child_frame) &&
            (parent_frame.empty() || tr.header.frame_id == parent_frame))
          msgs.emplace_back(m.log_time_ns, tr);
      }
      return true;
    }
    msgs.emplace_back(m.log_time_ns, decode_stamped_pose(m));
    return true;
  });
  refuse_damage(*reader, salvage);
  if (tf) {
    std::set<std::pair<std::string, std::string>> chosen;
    for (const auto& pc : pairs)
      if ((child_frame.empty() || pc.second == child_frame) && (parent_frame.empty() || pc.first == parent_frame))
        chosen.insert(pc);
    std::string list;
    for (const auto& [p, c] : pairs) list += "\n  " + p + " -> " + c;
    if (chosen.empty())
      throw InputError("no transform " + (parent_frame.empty() ? std::string("*") : parent_frame) + " -> " +
                           (child_frame.empty() ? std::string("*") : child_frame) + " on " + topic +
                           "; transforms (parent -> child) on it:" + (list.empty() ? std::string(" none") : list),
                       {reader->name()});
    if (chosen.size() > 1) {
      std::set<std::string> children;
      for (const auto& pc : chosen) children.insert(pc.second);
      throw InputError("topic " + topic + (children.size() > 1 ? " carries several child frames" : " carries several parent frames") +
                           "; choose one: BAG:" + topic + ":PARENT.CHILD (roe eval; any chain through " + topic +
                           " and /tf_static) or --parent PARENT --child CHILD (roe import mocap):" + list,
                       {reader->name()});
    }
    out.body = chosen.begin()->second;
    out.parent_frame = chosen.begin()->first;
  }
  bool zero_stamps = false;
  std::size_t index = 0;
  for (const auto& [rec, st] : msgs) {
    ++index;
    const Timestamp t = st.header.stamp_ns != 0 ? st.header.stamp_ns : rec;
    zero_stamps = zero_stamps || st.header.stamp_ns == 0;
    // ROS time counts from the epoch (as the CSV importers refuse negative times, so does a bag).
    if (t < 0)
      throw InputError(fmt::format("{}: message {}: negative header stamp ({} ns); ROS stamps count from 1970",
                                   topic, index, t),
                       {reader->name()});
    const auto& q = st.transform.q;
    const double n = q.norm();
    if (!(std::abs(n - 1.0) <= kMocapUnitQuatTolerance) || !st.transform.t.allFinite())
      throw InputError(fmt::format("{}: message {} (stamp {} ns): {}", topic, index, t,
                                   st.transform.t.allFinite() ? fmt::format("quaternion is not unit norm (|q| = {:.6g})", n)
                                                              : std::string("non-finite position")),
                       {reader->name()});
    out.poses.push_back({t, Pose(q.normalized(), st.transform.t)});
    if (!tf && out.parent_frame.empty()) out.parent_frame = st.header.frame_id;
  }
  if (zero_stamps) out.warnings.push_back("messages with header.stamp = 0 use the bag record time");
  std::stable_sort(out.poses.begin(), out.poses.end(), [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });
  const std::size_t n = out.poses.size();
  out.poses.erase(std::unique(out.poses.begin(), out.poses.end(), [](const auto& a, const auto& b) { return a.t_ns == b.t_ns; }),
                  out.poses.end());
  out.duplicates = n - out.poses.size();
  if (out.duplicates) out.warnings.push_back(fmt::format("{} poses with a repeated stamp dropped", out.duplicates));
  for (const auto& w : reader->warnings())
    out.warnings.push_back(fmt::format("{}: {}", w.file, w.text()));
  return out;
}

}  // namespace roe::io
