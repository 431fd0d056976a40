#pragma once
/// @file
/// Pose topics of ROS bags read as motion-capture data (io::MocapData, mocap_formats.hpp): what
/// `roe import mocap BAG --topic T` and `roe eval BAG:TOPIC` read.

#include <filesystem>
#include <string>

#include "roe/io/mocap_formats.hpp"

namespace roe::io {

/// Pose messages of one topic in a ROS 1 or ROS 2 bag (any kind io::open_bag reads), stamped with
/// header.stamp (record time when the stamp is zero). For tf2_msgs/TFMessage topics (/tf),
/// `child_frame` and `parent_frame` select the transform (required when the topic carries several).
/// A damaged bag (truncated, corrupt chunk, missing split file) is an InputError naming the byte
/// offset (or table row) unless `salvage`, which keeps what is intact (with warnings).
MocapData read_bag_poses(const fs::path& bag, const std::string& topic, const std::string& child_frame = "",
                         bool salvage = false, const std::string& parent_frame = "");

}  // namespace roe::io
