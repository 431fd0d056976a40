// io::TfBuffer: chains of /tf and /tf_static edges, interpolated like tf2 (docs/import.md, "tf chains").
// The real-bag case compares with tests/fixtures/ros2/nav2_tf_chain.json, composed by hand from the
// Nav2 TurtleBot MCAP by tf_chain_reference.mjs with Foxglove's MCAP and CDR readers (not roe's).
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "roe/core/error.hpp"
#include "roe/io/mocap_formats.hpp"
#include "roe/io/ros/bag_poses.hpp"
#include "roe/io/ros/tf_buffer.hpp"
#include "roe/math/so3.hpp"

namespace fs = std::filesystem;
using namespace roe;
namespace ros = roe::io::ros;

namespace {

ros::StampedTransform edge(const std::string& parent, const std::string& child, Timestamp t, const Pose& T) {
  ros::StampedTransform s;
  s.header.frame_id = parent;
  s.header.stamp_ns = t;
  s.child_frame_id = child;
  s.transform.t = T.p;
  s.transform.q = T.q;
  return s;
}

Pose yaw(double rad, const Eigen::Vector3d& p) {
  return Pose(Eigen::Quaterniond(Eigen::AngleAxisd(rad, Eigen::Vector3d::UnitZ())), p);
}

double pose_error(const Pose& a, const Pose& b) {
  return std::max((a.p - b.p).norm(), a.q.angularDistance(b.q));
}

}  // namespace

TEST_CASE("tf buffer: a chain of dynamic and static edges, interpolated between stamps, inverted upwards",
          "[io][tf]") {
  io::TfBuffer b("test.mcap");
  // map -> odom at 0 s and 2 s (yaw 0 -> 90 deg, x 0 -> 2), odom -> base at 0, 1, 2 s, base -> imu static.
  b.add(edge("map", "odom", 0, yaw(0.0, {0, 0, 0})), false, "m1");
  b.add(edge("map", "odom", 2'000'000'000, yaw(M_PI / 2, {2, 0, 0})), false, "m2");
  for (int k = 0; k <= 2; ++k) b.add(edge("odom", "base", k * 1'000'000'000LL, yaw(0.0, {0, 1.0 * k, 0})), false, "m3");
  b.add(edge("base", "imu", 5, yaw(M_PI, {0.1, 0, 0})), true, "s1");
  // A repeated stamp keeps the first transform.
  b.add(edge("odom", "base", 1'000'000'000, yaw(0.0, {9, 9, 9})), false, "m4");

  // At 1 s: map->odom halfway (yaw 45 deg, x 1), odom->base (0, 1, 0).
  const Pose mo = yaw(M_PI / 4, {1, 0, 0}), ob = yaw(0.0, {0, 1, 0}), bi = yaw(M_PI, {0.1, 0, 0});
  const auto T = b.lookup("map", "imu", 1'000'000'000);
  REQUIRE(T);
  CHECK(pose_error(*T, mo * ob * bi) < 1e-12);
  // Upwards: imu -> map is the inverse; across branches: odom -> imu.
  CHECK(pose_error(*b.lookup("imu", "map", 1'000'000'000), (mo * ob * bi).inverse()) < 1e-12);
  CHECK(pose_error(*b.lookup("odom", "imu", 1'000'000'000), ob * bi) < 1e-12);
  CHECK(pose_error(*b.lookup("imu", "odom", 500'000'000), (yaw(0.0, {0, 0.5, 0}) * bi).inverse()) < 1e-12);
  // No extrapolation; static alone at any time.
  CHECK_FALSE(b.lookup("map", "base", 2'000'000'001));
  CHECK(pose_error(*b.lookup("base", "imu", -7), bi) < 1e-15);

  // The trajectory: at the stamps of the densest dynamic edge (odom -> base: 0, 1, 2 s).
  const auto traj = b.trajectory("map", "imu");
  REQUIRE(traj.size() == 3);
  CHECK(traj[1].t_ns == 1'000'000'000);
  CHECK(pose_error(traj[1].T, mo * ob * bi) < 1e-12);
  CHECK(b.trajectory("base", "imu").size() == 1);  // static only: one pose
}

TEST_CASE("tf buffer: errors list the frames and edges found", "[io][tf][bad]") {
  io::TfBuffer b("bag.mcap");
  b.add(edge("map", "odom", 0, Pose()), false, "m1");
  b.add(edge("map", "odom", 10, Pose()), false, "m1");
  b.add(edge("odom", "base", 20, Pose()), false, "m2");
  b.add(edge("odom", "base", 30, Pose()), false, "m2");
  b.add(edge("world", "cam", 0, Pose()), true, "s1");
  CHECK_THROWS_WITH(b.trajectory("map", "nope"),
                    Catch::Contains("no frame \"nope\"") && Catch::Contains("frames: base, cam, map, odom, world") &&
                        Catch::Contains("map -> odom (2 stamps") && Catch::Contains("world -> cam (static)"));
  CHECK_THROWS_WITH(b.trajectory("map", "cam"), Catch::Contains("not connected") && Catch::Contains("\"world\""));
  CHECK_THROWS_WITH(b.trajectory("map", "base"), Catch::Contains("never known at one time") &&
                                                     Catch::Contains("map -> odom: 0.000 .. 0.000 s"));
  CHECK_THROWS_WITH(b.trajectory("map", "map"), Catch::Contains("same frame"));
  b.add(edge("world", "base", 0, Pose()), true, "s2");  // base re-parented
  CHECK_THROWS_WITH(b.trajectory("map", "base"), Catch::Contains("more than one parent") && Catch::Contains("s2"));
  // One pair on /tf_static and on /tf: two edges into one child, refused by name, not merged into one.
  io::TfBuffer both("both.mcap");
  both.add(edge("map", "odom", 0, Pose()), true, "s9");
  both.add(edge("map", "odom", 10, Pose()), false, "m9");
  CHECK_THROWS_WITH(both.trajectory("map", "odom"), Catch::Contains("more than one parent") &&
                                                        Catch::Contains("map static and map") && Catch::Contains("m9"));
  ros::StampedTransform bad = edge("a", "b", 0, Pose());
  bad.transform.q.coeffs() *= 1.1;
  CHECK_THROWS_WITH(b.add(bad, false, "msg 7"), Catch::Contains("msg 7") && Catch::Contains("unit norm"));
  CHECK_THROWS_AS(b.add(edge("a", "a", 0, Pose()), false, "x"), InputError);
}

TEST_CASE("tf buffer: 200 000 edges as a deep chain, a star and unknown frames are resolved or refused, "
          "listing a few", "[io][tf][hostile]") {
  constexpr int kN = 200'000;
  const auto f = [](const char* tag, int k) { return std::string(tag) + std::to_string(k); };
  SECTION("a deep static chain f0 -> f1 -> ... composes every edge") {
    io::TfBuffer b("deep.bag");
    for (int k = 0; k < kN; ++k) b.add(edge(f("f", k), f("f", k + 1), 5, yaw(0.0, {1, 0, 0})), true, "s");
    const auto traj = b.trajectory("f0", f("f", kN));
    REQUIRE(traj.size() == 1);
    CHECK(std::abs(traj[0].T.p.x() - kN) < 1e-6);
    CHECK(std::abs(b.lookup(f("f", kN), "f0", 0)->p.x() + kN) < 1e-6);  // upwards: the inverse
    CHECK(std::abs(b.lookup(f("f", 1000), f("f", 1500), 0)->p.x() - 500) < 1e-9);  // a common ancestor inside
  }
  SECTION("a deep dynamic chain, its stamps added out of order") {
    io::TfBuffer b("deep.bag");
    for (int k = kN - 1; k >= 0; --k) b.add(edge(f("f", k), f("f", k + 1), 7, yaw(0.0, {0, 1, 0})), false, "m");
    const auto traj = b.trajectory("f0", f("f", kN));
    REQUIRE(traj.size() == 1);
    CHECK(traj[0].t_ns == 7);
    CHECK(std::abs(traj[0].T.p.y() - kN) < 1e-6);
  }
  SECTION("a star of 200 000 children, two of them related through the root") {
    io::TfBuffer b("star.bag");
    for (int k = 0; k < kN; ++k) b.add(edge("root", f("c", k), 0, yaw(0.0, {double(k), 0, 0})), true, "s");
    CHECK(std::abs(b.lookup("c3", f("c", kN - 1), 0)->p.x() - (kN - 1 - 3)) < 1e-9);
    // An unknown frame: refused with the first frames named and the rest counted, not 200 000 names.
    try {
      (void)b.trajectory("root", "nope");
      FAIL("an unknown frame was accepted");
    } catch (const InputError& e) {
      const std::string m = e.what();
      CHECK(m.find("no frame \"nope\"") != std::string::npos);
      CHECK(m.find("(200001 frames in all)") != std::string::npos);
      CHECK(m.find("and 199980 more edges") != std::string::npos);
      CHECK(m.size() < 4000);
    }
  }
  SECTION("200 000 frames in pairs that are not connected") {
    io::TfBuffer b("pairs.bag");
    for (int k = 0; k < kN; k += 2) b.add(edge(f("p", k), f("p", k + 1), 0, Pose()), true, "s");
    CHECK_THROWS_WITH(b.trajectory("p0", "p3"), Catch::Contains("not connected") && Catch::Contains("frames in all"));
  }
}

TEST_CASE("tf buffer: a cycle is refused naming its frames, an empty frame id naming the field",
          "[io][tf][bad][hostile]") {
  io::TfBuffer b("cycle.bag");
  b.add(edge("a", "b", 0, Pose()), true, "msg 1");
  b.add(edge("b", "c", 0, Pose()), true, "msg 2");
  b.add(edge("c", "a", 0, Pose()), true, "msg 3");
  b.add(edge("world", "x", 0, Pose()), true, "msg 4");
  CHECK_THROWS_WITH(b.trajectory("a", "b"), Catch::Contains("cycle: b -> c -> a -> b") && Catch::Contains("msg 1"));
  CHECK_THROWS_WITH(b.lookup("x", "c", 0), Catch::Contains("cycle: a -> b -> c -> a"));
  CHECK(b.lookup("world", "x", 0));  // a chain that does not touch the cycle is answered
  ros::StampedTransform empty_child = edge("world", "", 0, Pose());
  CHECK_THROWS_WITH(b.add(empty_child, false, "msg 9"), Catch::Contains("msg 9") && Catch::Contains("child_frame_id"));
  CHECK_THROWS_WITH(b.add(edge("", "x", 0, Pose()), false, "msg 10"), Catch::Contains("header.frame_id"));
}

TEST_CASE("tf buffer: stamps added out of order are sorted, a repeated stamp keeps the first transform",
          "[io][tf]") {
  io::TfBuffer b("order.bag");
  b.add(edge("map", "odom", 2'000'000'000, yaw(0.0, {2, 0, 0})), false, "m1");
  b.add(edge("map", "odom", 0, yaw(0.0, {0, 0, 0})), false, "m2");
  b.add(edge("map", "odom", 2'000'000'000, yaw(0.0, {9, 9, 9})), false, "m3");  // repeated: ignored
  b.add(edge("map", "odom", 1'000'000'000, yaw(0.0, {1, 0, 0})), false, "m4");
  const auto traj = b.trajectory("map", "odom");
  REQUIRE(traj.size() == 3);
  CHECK(traj[0].t_ns == 0);
  CHECK(traj[2].T.p.x() == 2.0);
  CHECK(std::abs(b.lookup("map", "odom", 1'500'000'000)->p.x() - 1.5) < 1e-12);
}

TEST_CASE("tf buffer: the real Nav2 bag's map -> base_link and map -> imu_link equal the chains composed by hand",
          "[io][tf][ros2][real]") {
  const fs::path bag = fs::path(ROE_SHARED_DATA_DIR) / "rosbag2/nav2_turtlebot.mcap";
  if (!fs::exists(bag)) {
    WARN("skipped: " << bag << " absent");
    return;
  }
  std::ifstream in(fs::path(ROE_SOURCE_DIR) / "tests/fixtures/ros2/nav2_tf_chain.json");
  const auto ref = nlohmann::json::parse(in);
  for (const std::string child : {"base_link", "imu_link"}) {
    INFO(child);
    const auto d = io::read_bag_poses(bag, "/tf", child, false, "map");
    CHECK(d.parent_frame == "map");
    CHECK(d.body == child);
    REQUIRE(d.poses.size() == ref["stamps"].get<std::size_t>());
    // Inside the time both dynamic edges cover (map -> odom starts later than odom -> base_link).
    CHECK(d.poses.front().t_ns >= std::stoll(ref["first_stamp_ns"].get<std::string>()));
    CHECK(d.poses.back().t_ns <= std::stoll(ref["last_stamp_ns"].get<std::string>()));
    const auto& rows = ref["chains"]["map." + child];
    REQUIRE(rows.size() > 200);
    double worst = 0.0;
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const auto& r = rows[i];
      const auto& p = d.poses[i * ref["every"].get<std::size_t>()];
      REQUIRE(p.t_ns == std::stoll(r[0].get<std::string>()));
      const Pose want(Eigen::Quaterniond(r[7].get<double>(), r[4].get<double>(), r[5].get<double>(), r[6].get<double>()),
                      Eigen::Vector3d(r[1].get<double>(), r[2].get<double>(), r[3].get<double>()));
      worst = std::max(worst, pose_error(p.T, want));
    }
    CHECK(worst < 1e-9);
  }
  // The inverse chain is the inverse pose, at the same stamps.
  const auto fwd = io::read_bag_poses(bag, "/tf", "base_link", false, "map");
  const auto inv = io::read_bag_poses(bag, "/tf", "map", false, "base_link");
  REQUIRE(inv.poses.size() == fwd.poses.size());
  CHECK(pose_error(inv.poses[100].T, fwd.poses[100].T.inverse()) < 1e-12);
  // A frame that is not in the tree: the error lists the frames and the edges with their stamps.
  CHECK_THROWS_WITH(io::read_bag_poses(bag, "/tf", "base_lnk", false, "map"),
                    Catch::Contains("no frame \"base_lnk\"") && Catch::Contains("oakd_link") &&
                        Catch::Contains("map -> odom (921 stamps") && Catch::Contains("base_link -> imu_link (static)"));
}

TEST_CASE("bag pose errors name the syntax of both commands, not options roe eval lacks", "[io][tf][ros2][real]") {
  const fs::path bag = fs::path(ROE_SHARED_DATA_DIR) / "rosbag2/nav2_turtlebot.mcap";
  if (!fs::exists(bag)) {
    WARN("skipped: " << bag << " absent");
    return;
  }
  CHECK_THROWS_WITH(io::read_bag_poses(bag, "/tf"),
                    Catch::Contains("BAG:/tf:PARENT.CHILD (roe eval") && Catch::Contains("(roe import mocap)"));
  CHECK_THROWS_WITH(io::read_bag_poses(bag, ""),
                    Catch::Contains("BAG:/tf:PARENT.CHILD") && Catch::Contains("/amcl_pose") &&
                        !Catch::Contains("choose a pose topic with --topic"));
}
