// ROS 2 bags written by tools nobody here wrote (../shared/data/rosbag2, see its README): a rosbag2
// MCAP of a Nav2 TurtleBot run and a rosbag2 SQLite bag of /tf. The pinned values were read with
// Foxglove's @mcap/core + @foxglove/rosmsg2-serialization and Python's sqlite3 (independent readers),
// not with roe. Skipped when ../shared is absent.
#include <catch2/catch.hpp>

#include <filesystem>
#include <map>

#include "roe/io/ros/message_bag.hpp"
#include "roe/io/ros/mcap.hpp"
#include "roe/io/ros/rosbag2.hpp"
#include "support/test_util.hpp"

namespace fs = std::filesystem;
using namespace roe;
namespace msg = roe::io::ros::msg;
using roe::io::ros::Wire;
namespace ros = roe::io::ros;

namespace {

fs::path shared(const char* rel) { return fs::path(ROE_SHARED_DATA_DIR) / rel; }

struct TopicSpan {
  std::size_t n = 0;
  Timestamp first = 0, last = 0;
};

std::map<std::string, TopicSpan> spans(io::MessageBag& b) {
  std::map<std::string, TopicSpan> s;
  std::set<std::string> all;
  for (const auto& t : b.topics()) all.insert(t.topic);
  b.for_each(all, [&](const io::BagMessage& m) {
    auto& x = s[m.topic->topic];
    if (x.n++ == 0) x.first = m.log_time_ns;
    CHECK(m.log_time_ns >= x.last);  // time order within a topic
    x.last = m.log_time_ns;
    return true;
  });
  return s;
}

}  // namespace

TEST_CASE("ros2 real: the Nav2 TurtleBot MCAP decodes with the pinned values", "[io][mcap][ros2][real]") {
  const fs::path file = shared("rosbag2/nav2_turtlebot.mcap");
  if (!fs::exists(file)) {
    WARN("skipped: " << file << " absent");
    return;
  }
  for (bool scan : {false, true}) {
    INFO((scan ? "linear scan" : "through the summary"));
    io::mcap::ReaderOptions o;
    o.force_scan = scan;
    io::mcap::Reader r(file, o);
    CHECK(r.profile() == "ros2");
    CHECK(r.summary_used() == !scan);
    CHECK_FALSE(r.damaged());
    CHECK(r.chunks().size() == 1);
    CHECK(r.channels().size() == 4);
    std::map<std::string, std::uint64_t> counts;
    for (const auto& [id, c] : r.channels()) {
      counts[c.topic] = r.message_count(id);
      CHECK(c.message_encoding == "cdr");
    }
    CHECK(counts == std::map<std::string, std::uint64_t>{{"/amcl_pose", 135}, {"/odom", 2639}, {"/tf", 5422},
                                                         {"/tf_static", 1}});
  }
  auto bag = io::open_bag(file);
  CHECK(bag->format() == "mcap");
  CHECK(bag->ros2());
  CHECK(bag->topic_type("/odom") == "nav_msgs/Odometry");
  CHECK(bag->find("/odom")->stored_type == "nav_msgs/msg/Odometry");
  CHECK(bag->topic_type("/amcl_pose") == "geometry_msgs/PoseWithCovarianceStamped");
  CHECK(bag->topic_type("/tf") == "tf2_msgs/TFMessage");
  const auto s = spans(*bag);
  CHECK(s.at("/odom").n == 2639);
  CHECK(s.at("/odom").first == 1778234353382747000);
  CHECK(s.at("/odom").last == 1778234450738021000);
  CHECK(s.at("/tf").n == 5422);
  CHECK(s.at("/tf").first == 1778234353382761000);
  CHECK(s.at("/tf").last == 1778234450738043000);
  CHECK(s.at("/amcl_pose").n == 135);
  CHECK(s.at("/amcl_pose").first == 1778234353600224000);
  CHECK(s.at("/amcl_pose").last == 1778234448539160000);
  CHECK(s.at("/tf_static").n == 1);

  std::vector<ros::StampedTransform> odom, amcl;
  std::vector<ros::StampedTransform> statics;
  bag->for_each({"/odom", "/amcl_pose", "/tf_static"}, [&](const io::BagMessage& m) {
    if (m.topic->topic == "/tf_static")
      statics = io::decode<msg::TFMessage>(m);
    else
      (m.topic->topic == "/odom" ? odom : amcl).push_back(io::decode_stamped_pose(m));
    return true;
  });
  REQUIRE(odom.size() == 2639);
  CHECK(odom.front().header.stamp_ns == 928'800'000'000);
  CHECK(odom.front().header.frame_id == "odom");
  CHECK(odom.front().child_frame_id == "base_link");
  CHECK(odom.front().transform.t.x() == Approx(-2.8019166340612314).epsilon(1e-15));
  CHECK(odom.front().transform.t.y() == Approx(1.0977901491292252).epsilon(1e-15));
  CHECK(odom.front().transform.q.z() == Approx(0.08457359616958599).epsilon(1e-15));
  CHECK(odom.front().transform.q.w() == Approx(-0.9964172353140746).epsilon(1e-15));
  CHECK(odom.back().header.stamp_ns == 1025'496'000'000);
  CHECK(odom.back().transform.t.x() == Approx(0.21005680059713844).epsilon(1e-15));
  CHECK(odom.back().transform.q.w() == Approx(-0.9503433452139315).epsilon(1e-15));
  REQUIRE(amcl.size() == 135);
  CHECK(amcl.front().header.frame_id == "map");
  CHECK(amcl.front().header.stamp_ns == 924'102'000'000);
  CHECK(amcl.front().transform.t.x() == Approx(4.36519665396771).epsilon(1e-15));
  CHECK(amcl.back().transform.q.z() == Approx(-0.1715888150847654).epsilon(1e-15));
  REQUIRE(statics.size() >= 2);
  CHECK(statics[1].header.frame_id == "base_link");
  CHECK(statics[1].child_frame_id == "bump_front_center");
  CHECK(statics[1].transform.t.x() == Approx(0.175));
  CHECK(statics[1].transform.t.z() == Approx(0.039));
}

TEST_CASE("ros2 real: the rosbag2 SQLite /tf bag, as a folder and as the .db3", "[io][rosbag2][ros2][real]") {
  const fs::path folder = shared("rosbag2/tf_example");
  if (!fs::exists(folder)) {
    WARN("skipped: " << folder << " absent");
    return;
  }
  CHECK(io::detect_bag_kind(folder) == "rosbag2-folder");
  CHECK(io::detect_bag_kind(folder / "tf_example.db3") == "sqlite3");
  const auto meta = io::rosbag2::read_metadata(folder / "metadata.yaml");
  CHECK(meta.version == 8);
  CHECK(meta.storage_identifier == "sqlite3");
  CHECK(meta.relative_file_paths == std::vector<std::string>{"tf_example.db3"});
  CHECK(meta.message_count == 518);
  io::rosbag2::SqliteReader db(folder / "tf_example.db3");
  CHECK(db.schema_version() > 0);
  for (const fs::path& p : {folder, folder / "tf_example.db3"}) {
    INFO(p);
    auto bag = io::open_bag(p);
    CHECK(bag->ros2());
    CHECK(bag->topic_type("/tf") == "tf2_msgs/TFMessage");
    CHECK(bag->message_count("/tf") == 517);
    CHECK(bag->message_count("/tf_static") == 1);
    const auto s = spans(*bag);
    CHECK(s.at("/tf").first == 1714741164196592603);
    CHECK(s.at("/tf").last == 1714741215796545476);
    CHECK(s.at("/tf_static").first == 1714741164111822142);
    std::vector<ros::StampedTransform> tf;
    bag->for_each({"/tf"}, [&](const io::BagMessage& m) {
      CHECK(m.location.rfind("messages row id ", 0) == 0);
      for (const auto& t : io::decode<msg::TFMessage>(m)) tf.push_back(t);
      return true;
    });
    REQUIRE(tf.size() == 517);
    CHECK(tf.front().header.frame_id == "odom");
    CHECK(tf.front().child_frame_id == "base_footprint");
    CHECK(tf.front().header.stamp_ns == 1714741164'177519307);
    CHECK(tf.front().transform.t.x() == Approx(1.1603796887148006).epsilon(1e-15));
    CHECK(tf.front().transform.t.y() == Approx(-2.942426888388735).epsilon(1e-15));
    CHECK(tf.front().transform.q.z() == Approx(0.6808039454578293).epsilon(1e-15));
    CHECK(tf.back().header.stamp_ns == 1714741215'784817334);
    CHECK(tf.back().transform.t.x() == Approx(0.4409785886185202).epsilon(1e-15));
    CHECK(tf.back().transform.q.w() == Approx(0.9996567762677121).epsilon(1e-15));
  }
}

TEST_CASE("ros2 real: the kind is decided by the content, not the name", "[io][ros2][real]") {
  const fs::path mcap = shared("rosbag2/nav2_turtlebot.mcap");
  if (!fs::exists(mcap)) {
    WARN("skipped: " << mcap << " absent");
    return;
  }
  test::TempDir tmp;
  fs::copy_file(mcap, tmp / "recording.db3");
  fs::copy_file(shared("rosbag2/tf_example/tf_example.db3"), tmp / "recording.mcap");
  CHECK(io::detect_bag_kind(tmp / "recording.db3") == "mcap");
  CHECK(io::detect_bag_kind(tmp / "recording.mcap") == "sqlite3");
  CHECK(io::open_bag(tmp / "recording.db3")->message_count("/odom") == 2639);
  CHECK(io::open_bag(tmp / "recording.mcap")->message_count("/tf") == 517);
}
