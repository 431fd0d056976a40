#pragma once
/// @file
/// One message-level interface over every bag roe reads, so importers do not care which generation a
/// bag is: ROS 1 bags (ros1_bag.hpp), MCAP files (mcap.hpp; rosbag2's default storage, CDR or ROS 1
/// messages), rosbag2 SQLite databases (.db3) and rosbag2 folders (metadata.yaml with split files and
/// file- or message-level zstd compression). The kind is decided by the content (magic bytes, or a
/// folder holding metadata.yaml), never by the file name.
///
/// Topic types are normalised to the ROS 1 spelling ("sensor_msgs/msg/Imu" → "sensor_msgs/Imu"), and
/// the decoders below pick the ROS 1 or the CDR decoder from the topic's message encoding.
/// Damage is reported as for ROS 1 bags: warnings with a location ("byte N" in a file, "messages row
/// id N" in a database); a caller decides whether damage is an error (importers: unless --salvage).

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/io/ros/msgs.hpp"

namespace roe::io {

namespace fs = std::filesystem;

struct BagTopic {
  std::string topic;
  std::string type;         ///< normalised: "sensor_msgs/Imu"
  std::string stored_type;  ///< as the bag spells it: "sensor_msgs/msg/Imu"
  std::string encoding;     ///< message serialisation: "ros1" | "cdr" | what the bag says
  std::uint64_t count = 0;  ///< messages (index, statistics or metadata)
};

struct BagMessage {
  const BagTopic* topic = nullptr;
  Timestamp log_time_ns = 0;  ///< the bag's receive/record time (not header.stamp)
  std::string_view data;      ///< the serialized message, valid during the callback
  std::string file;           ///< the file holding it
  std::string location;       ///< "chunk at byte N" | "byte N" | "messages row id N"
  /// "FILE: TOPIC (LOCATION)" for error messages.
  std::string where() const;
};

struct BagWarning {
  std::string file;
  std::string location;  ///< "byte N" | "messages row id N" | ""
  std::string message;
  bool damage = true;           ///< false for notes that mean no data loss
  bool index_fallback = false;  ///< an index/summary was unusable and the reader scanned instead
  /// "LOCATION: MESSAGE" (the file is named separately by the caller's error context).
  std::string text() const;
};

struct BagOpenOptions {
  /// Ignore indexes and summaries and scan the records (tests).
  bool force_scan = false;
  /// Go on past a missing split file of a folder (--salvage): it becomes a damage warning.
  bool allow_missing_files = false;
};

class MessageBag {
 public:
  virtual ~MessageBag() = default;
  /// The path as given (file or folder).
  const std::string& name() const { return name_; }
  /// "ros1", "mcap", "sqlite3", or "rosbag2 folder (mcap|sqlite3[, zstd file|message compression])".
  const std::string& format() const { return format_; }
  /// Whether this is a ROS 2 bag (MCAP or SQLite storage).
  virtual bool ros2() const = 0;
  const std::vector<BagTopic>& topics() const { return topics_; }
  const BagTopic* find(const std::string& topic) const;
  /// Normalised type of a topic ("" when absent).
  std::string topic_type(const std::string& topic) const;
  std::uint64_t message_count(const std::string& topic) const;
  /// Calls `fn` for every message on `topics`, in log-time order within each file (files of a split
  /// bag in order); `fn` returns false to stop. Damage is skipped with a warning.
  virtual void for_each(const std::set<std::string>& topics, const std::function<bool(const BagMessage&)>& fn,
                        const ProgressCallback& progress = {}) = 0;
  virtual std::vector<BagWarning> warnings() const = 0;
  bool damaged() const;
  /// Damage warnings, the most specific first (record-level before index fallbacks).
  std::vector<BagWarning> damage() const;
  /// "LOCATION: MESSAGE" of the most specific damage ("" when none).
  std::string first_damage() const;
  /// "LOCATION: MESSAGE; K problem(s)": the most specific damage and how many there are ("" when none).
  std::string damage_summary() const;
  /// "\nproblems found:" and every damage on a line of its own, in file order, when there are several
  /// ("" otherwise).
  std::string damage_listing() const;
  /// "\n  /topic (type)" for each topic, for error messages listing what the bag holds.
  std::string topic_listing() const;

 protected:
  std::string name_, format_;
  std::vector<BagTopic> topics_;
};

/// "ros1", "mcap", "sqlite3", "rosbag2-folder", "zstd" (a zstd-compressed file) or "" (unknown), from
/// the content: the first bytes of a file; for a folder, metadata.yaml or (without one) the MCAP or SQLite
/// bag files in it, as open_bag reads them.
std::string detect_bag_kind(const fs::path& path);
/// Opens any bag roe reads. InputError naming the path when it is not a bag roe knows.
std::unique_ptr<MessageBag> open_bag(const fs::path& path, const BagOpenOptions& options = {});
/// sha256 of a bag file, or of a rosbag2 folder (metadata.yaml followed by each data file's sha256).
std::string bag_sha256(const fs::path& path);

/// "sensor_msgs/msg/Imu" → "sensor_msgs/Imu"; other spellings unchanged.
std::string normalize_ros_type(const std::string& type);

/// The wire format of a message, from its topic's message encoding ("ros1" or "cdr"); InputError naming
/// BagMessage::where() for another encoding (json, protobuf, ...): refused, never guessed at.
ros::Wire message_wire(const BagMessage& m);
/// Decodes a message of type M (a ros::msg tag) in its topic's wire format. InputError names
/// BagMessage::where().
template <class M>
typename M::Value decode(const BagMessage& m) {
  return ros::decode<M>(message_wire(m), m.data, m.where());
}
/// PoseStamped, TransformStamped, PoseWithCovarianceStamped or Odometry, by the topic's type.
ros::StampedTransform decode_stamped_pose(const BagMessage& m);
/// Whether decode_stamped_pose or decode<ros::msg::TFMessage> reads this (normalised) type.
bool is_pose_type(const std::string& type);

}  // namespace roe::io
