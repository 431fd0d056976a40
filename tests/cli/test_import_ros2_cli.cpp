// End-to-end: ROS 2 bags (the real ones in ../shared/data/rosbag2) through `roe import mocap` and
// `roe eval`. Skipped when ../shared is absent.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "support/test_util.hpp"

namespace fs = std::filesystem;

namespace {
fs::path shared(const char* rel) { return fs::path(ROE_SHARED_DATA_DIR) / rel; }
std::size_t data_rows(const fs::path& csv) {
  std::ifstream f(csv);
  std::string line;
  std::size_t n = 0;
  while (std::getline(f, line))
    if (!line.empty() && line[0] != '#') ++n;
  return n;
}
}  // namespace

TEST_CASE("roe import mocap: the TurtleBot /odom (MCAP) and the SQLite /tf import, and roe eval accepts them",
          "[cli][import][ros2][real]") {
  const fs::path mcap = shared("rosbag2/nav2_turtlebot.mcap"), folder = shared("rosbag2/tf_example");
  if (!fs::exists(mcap)) {
    WARN("skipped: " << mcap << " absent");
    return;
  }
  roe::test::TempDir tmp("roe_test_ros2_cli");
  const std::string odom_ds = (tmp / "odom").string(), tf_ds = (tmp / "tf").string();
  fs::create_directories(odom_ds);
  fs::create_directories(tf_ds);

  // nav_msgs/msg/Odometry from the MCAP.
  auto r = roe::test::run_roe("--json import mocap " + mcap.string() + " --into " + odom_ds + " --topic /odom", false);
  REQUIRE(r.code == 0);
  auto j = nlohmann::json::parse(r.out);
  CHECK(j["format"] == "rosbag2");
  CHECK(j["rows"] == 2639);
  CHECK(j["poses"].get<int>() > 2600);
  CHECK(data_rows(fs::path(odom_ds) / "mav0/mocap0/data.csv") == j["poses"].get<std::size_t>());
  const auto man = nlohmann::json::parse(std::ifstream(fs::path(odom_ds) / "roe.json"));
  CHECK(man["sources"][0]["kind"] == "ros2-bag");
  CHECK(man["sources"][0]["options"]["parent_frame"] == "odom");

  // /tf from the SQLite folder: odom -> base_footprint, named by --parent and --child.
  r = roe::test::run_roe("--json import mocap " + folder.string() + " --into " + tf_ds +
                             " --topic /tf --parent odom --child base_footprint",
                         false);
  REQUIRE(r.code == 0);
  j = nlohmann::json::parse(r.out);
  CHECK(j["body"] == "base_footprint");
  CHECK(j["rows"] == 517);
  CHECK(j["poses"] == 517);
  // A frame pair that is not on the topic lists those that are.
  r = roe::test::run_roe("--force import mocap " + folder.string() + " --into " + tf_ds + " --topic /tf --parent map");
  CHECK(r.code == 2);
  CHECK(r.out.find("odom -> base_footprint") != std::string::npos);
  // A topic roe cannot use lists the bag's topics with their types.
  r = roe::test::run_roe("--force import mocap " + mcap.string() + " --into " + tf_ds + " --topic /nope");
  CHECK(r.code == 2);
  CHECK(r.out.find("/amcl_pose (geometry_msgs/PoseWithCovarianceStamped)") != std::string::npos);

  // roe eval accepts both trajectories (the dataset as ground truth, its own poses as estimate).
  for (const auto& ds : {odom_ds, tf_ds}) {
    const std::string est = (fs::path(ds) / "mav0/mocap0/data.csv").string();
    r = roe::test::run_roe("--json eval " + est + " --gt " + ds + " --no-out", false);
    REQUIRE(r.code == 0);
    j = nlohmann::json::parse(r.out);
    CHECK(j["association"]["n_matched"].get<int>() > 500);
    CHECK(j["ape_trans_m"]["rmse"].get<double>() < 1e-6);
  }
}

TEST_CASE("roe eval: BAG:TOPIC for the estimate and --gt, ROS 2 and ROS 1", "[cli][eval][ros2][real]") {
  const fs::path mcap = shared("rosbag2/nav2_turtlebot.mcap"), ros1 = shared("rosbag/evo_ROS_example.bag");
  if (!fs::exists(mcap) || !fs::exists(ros1)) {
    WARN("skipped: " << mcap << " or " << ros1 << " absent");
    return;
  }
  // /odom against the same transform on /tf (odom -> base_link, evo's PARENT.CHILD form): identical.
  auto r = roe::test::run_roe(
      "--json eval " + mcap.string() + ":/odom --gt " + mcap.string() + ":/tf:odom.base_link --no-out", false);
  REQUIRE(r.code == 0);
  auto j = nlohmann::json::parse(r.out);
  CHECK(j["association"]["n_matched"].get<int>() > 2600);
  CHECK(j["ape_trans_m"]["rmse"].get<double>() < 1e-9);
  // A ROS 1 bag: ORB-SLAM against the ground truth of evo's example bag.
  r = roe::test::run_roe("--json eval " + ros1.string() + ":ORB-SLAM --gt " + ros1.string() + ":groundtruth --no-out",
                         false);
  REQUIRE(r.code == 0);
  j = nlohmann::json::parse(r.out);
  CHECK(j["association"]["n_matched"].get<int>() > 1000);
  CHECK(std::isfinite(j["ape_trans_m"]["rmse"].get<double>()));  // 5.5 m: a monocular estimate, SE(3) alignment
  // A topic the bag lacks: exit 2 listing its pose topics.
  r = roe::test::run_roe("eval " + mcap.string() + ":/nope --gt " + mcap.string() + ":/odom --no-out");
  CHECK(r.code == 2);
  CHECK(r.out.find("/amcl_pose [geometry_msgs/PoseWithCovarianceStamped]") != std::string::npos);
}

TEST_CASE("roe import realsense: a truncated ROS 2 bag exits 2 naming the byte offset, --salvage keeps the rest",
          "[cli][import][ros2]") {
  const fs::path src = fs::path(ROE_SOURCE_DIR) / "tests/fixtures/ros2/rs_zstd.mcap";
  roe::test::TempDir tmp("roe_test_ros2_cut");
  std::ifstream f(src, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(f)), {});
  const fs::path cut = tmp.write("cut.mcap", bytes.substr(0, bytes.size() * 2 / 3));
  const std::string args = " --out " + (tmp / "ds").string() + " --crop-width 32 --crop-height 24";
  auto r = roe::test::run_roe("import realsense " + cut.string() + args);
  CHECK(r.code == 2);
  CHECK(r.out.find("cut.mcap") != std::string::npos);
  CHECK(r.out.find("damaged (byte ") != std::string::npos);
  CHECK_FALSE(fs::exists(tmp / "ds"));
  r = roe::test::run_roe("--json import realsense " + cut.string() + args + " --salvage", false);
  REQUIRE(r.code == 0);
  const auto j = nlohmann::json::parse(r.out);
  CHECK(j["frames"].get<int>() > 0);
  CHECK(j["frames"].get<int>() < 6);
  CHECK(j["warnings"].dump().find("byte ") != std::string::npos);
}
