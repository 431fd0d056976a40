// Mocap readers: the real Motive 1.21 export, synthetic Motive 1.23/3.x-style and Vicon files,
// malformed rows and non-unit quaternions, ROS bag pose topics (generated and the real evo bag).
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <random>

#include "support/test_util.hpp"
#include "fixtures/bag_writer.hpp"
#include "roe/io/mocap_formats.hpp"
#include "roe/io/ros/bag_poses.hpp"
#include "roe/io/output.hpp"
#include "roe/io/ros/msgs.hpp"
#include "roe/math/so3.hpp"

namespace fs = std::filesystem;
using namespace roe;
namespace msg = roe::io::ros::msg;
using roe::io::ros::Wire;

namespace {
using roe::test::TempDir;


// A Motive 3.x-style export: labels in the second column, TimeCode column, two rigid bodies,
// millimetres, an occluded frame for body "cam".
const char* kMotive3 =
    "Format Version,1.24,Take Name,t,Capture Frame Rate,100.000000,Export Frame Rate,100.000000,Capture Start "
    "Time,2024-01-01 01.02.03.004 P.M.,Total Frames in Take,4,Total Exported Frames,4,Rotation Type,Quaternion,"
    "Length Units,Millimeters,Coordinate Space,Global\n"
    "\n"
    ",Type,,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid "
    "Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body\n"
    ",Name,,obj,obj,obj,obj,obj,obj,obj,cam,cam,cam,cam,cam,cam,cam\n"
    ",ID,,1,1,1,1,1,1,1,2,2,2,2,2,2,2\n"
    ",,,Rotation,Rotation,Rotation,Rotation,Position,Position,Position,Position,Position,Position,Rotation,Rotation,"
    "Rotation,Rotation\n"
    "Frame,Time (Seconds),TimeCode,X,Y,Z,W,X,Y,Z,X,Y,Z,X,Y,Z,W\n"
    "0,0.000000,00:00:00:00,0,0,0,1,1000,2000,3000,10,20,30,0,0,0.7071068,0.7071068\n"
    "1,0.010000,00:00:00:01,0,0,0,1,1000,2000,3000,,,,,,,\n"
    "2,0.020000,00:00:00:02,0,0,0,1,1000,2000,3000,11,21,31,0,0,0.7071068,0.7071068\n"
    "3,0.030000,00:00:00:03,0,0,0,1,1000,2000,3000,12,22,32,0,0,0.7071068,0.7071068\n";

}  // namespace

TEST_CASE("motive: the real v1.21 export", "[io][mocap][shared]") {
  const fs::path f = fs::path(ROE_SHARED_DATA_DIR) / "mocap/sample_optitrack_take_v1.21.csv";
  if (!fs::exists(f)) {
    WARN("skipped: " << f << " absent");
    return;
  }
  const auto d = io::read_motive_csv(f);
  CHECK(d.body == "Rigid Body 1");
  CHECK(d.bodies == std::vector<std::string>{"Rigid Body 1"});
  CHECK(d.rows == 250);
  CHECK(d.occluded == 0);  // the 2000 empty cells are all in marker columns
  REQUIRE(d.poses.size() == 250);
  CHECK(d.rate_hz == Approx(120.0));
  CHECK(d.y_up);
  CHECK(d.length_unit == "Meters");
  CHECK(d.rotation_type == "Quaternion");
  // Row "0,0.000000,0.000035,0.000016,-0.000030,-1.000000,0.060002,0.019150,0.076611,..."
  CHECK(d.poses[0].t_ns == 0);
  CHECK(d.poses[0].T.p.isApprox(Eigen::Vector3d(0.060002, 0.019150, 0.076611), 1e-12));
  const Eigen::Quaterniond q0 = Eigen::Quaterniond(-1.0, 0.000035, 0.000016, -0.000030).normalized();
  CHECK(math::angle_between(d.poses[0].T.q, q0) < 1e-9);
  CHECK(d.poses[1].t_ns == 8'333'000);  // 0.008333 s, exactly
  // Last row: "249,2.075000,...,0.060349,0.019146,0.076408"
  CHECK(d.poses.back().t_ns == 2'075'000'000);
  CHECK(d.poses.back().T.p.isApprox(Eigen::Vector3d(0.060349, 0.019146, 0.076408), 1e-12));
}

TEST_CASE("motive: 3.x layout, body selection by name, occlusions, units", "[io][mocap]") {
  TempDir d;
  const fs::path f = d.write("m3.csv", kMotive3);
  CHECK_THROWS_WITH(io::read_motive_csv(f), Catch::Contains("--body") && Catch::Contains("\"cam\""));
  CHECK_THROWS_WITH(io::read_motive_csv(f, "nope"), Catch::Contains("not in the file"));
  const auto m = io::read_motive_csv(f, "cam");
  CHECK(m.rows == 4);
  CHECK(m.occluded == 1);
  REQUIRE(m.poses.size() == 3);
  CHECK(m.rate_hz == Approx(100.0));
  CHECK(m.poses[1].t_ns == 20'000'000);
  CHECK(m.poses[0].T.p.isApprox(Eigen::Vector3d(0.010, 0.020, 0.030), 1e-12));  // mm → m
  // Columns are found by header, not by position: cam's rotation follows its position here.
  CHECK(math::angle_between(m.poses[0].T.q, Eigen::Quaterniond(0.7071068, 0, 0, 0.7071068).normalized()) < 1e-9);
  const auto o = io::read_motive_csv(f, "obj");
  CHECK(o.occluded == 0);
  CHECK(o.poses[0].T.p.isApprox(Eigen::Vector3d(1, 2, 3), 1e-12));
}

TEST_CASE("motive: Euler rotation types", "[io][mocap]") {
  TempDir d;
  const std::string text =
      "Format Version,1.23,Export Frame Rate,120,Rotation Type,ZYX,Length Units,Meters\n\n"
      ",Type,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body\n"
      ",Name,b,b,b,b,b,b\n,ID,1,1,1,1,1,1\n,,Rotation,Rotation,Rotation,Position,Position,Position\n"
      "Frame,Time (Seconds),X,Y,Z,X,Y,Z\n"
      "0,0.0,10,20,30,0,0,0\n";
  const auto m = io::read_motive_csv(d.write("e.csv", text));
  REQUIRE(m.poses.size() == 1);
  // "ZYX" = R = Rz(30°)·Ry(20°)·Rx(10°), the columns giving the angle about each axis.
  const double k = 3.14159265358979323846 / 180;
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(30 * k, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(20 * k, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(10 * k, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  CHECK(m.poses[0].T.R().isApprox(R, 1e-12));
}

TEST_CASE("motive: malformed rows and non-unit quaternions name line and column", "[io][mocap]") {
  TempDir d;
  std::string bad = kMotive3;
  bad.replace(bad.find("11,21,31"), 2, "1x");
  CHECK_THROWS_WITH(io::read_motive_csv(d.write("bad.csv", bad), "cam"), Catch::Contains("bad.csv:10:11"));
  std::string nonunit = kMotive3;
  nonunit.replace(nonunit.find("12,22,32,0,0,0.7071068,0.7071068"), 32, "12,22,32,0,0,0.8,0.8");
  CHECK_THROWS_WITH(io::read_motive_csv(d.write("nu.csv", nonunit), "cam"),
                    Catch::Contains("nu.csv:11:") && Catch::Contains("unit norm"));
  std::string back = kMotive3;
  back.replace(back.find("3,0.030000"), 10, "3,0.005000");
  CHECK_THROWS_WITH(io::read_motive_csv(d.write("back.csv", back), "cam"), Catch::Contains("does not increase"));
  CHECK_THROWS_WITH(io::read_motive_csv(d.write("notmotive.csv", "a,b\n1,2\n")), Catch::Contains("Format Version"));
  std::string unit = kMotive3;
  unit.replace(unit.find("Millimeters"), 11, "Furlongs");
  CHECK_THROWS_WITH(io::read_motive_csv(d.write("u.csv", unit), "cam"),
                    Catch::Contains("Furlongs") && Catch::Contains("u.csv:1"));
}

TEST_CASE("motive: a file cut inside its last row, and an unknown Format Version, are warned about", "[io][mocap]") {
  TempDir d;
  const auto has = [](const io::MocapData& m, const std::string& what) {
    for (const auto& w : m.warnings)
      if (w.find(what) != std::string::npos) return true;
    return false;
  };
  // Intact: no warning.
  CHECK(io::read_motive_csv(d.write("ok.csv", kMotive3), "cam").warnings.empty());
  // Cut after the 5th cell of the last row, no line end: the row is dropped, with a warning.
  std::string cut = kMotive3;
  cut.resize(cut.rfind("12,22,32"));
  cut.pop_back();  // the comma
  const auto m = io::read_motive_csv(d.write("cut.csv", cut), "cam");
  CHECK(m.occluded == 1);
  CHECK(m.rows == 3);
  CHECK(m.poses.size() == 2);
  CHECK(has(m, "cut.csv:11: the last row has 10 of 17 cells and no line end: the file looks truncated; that row "
               "was dropped"));
  // Cut inside a number of the body's own cells (z = 32 mm → "3"): dropped too, never a 3 mm pose.
  std::string mid = kMotive3;
  mid.resize(mid.rfind("12,22,32") + 7);
  const auto c = io::read_motive_csv(d.write("mid.csv", mid), "cam");
  CHECK(c.rows == 3);
  CHECK(c.occluded == 1);
  REQUIRE(c.poses.size() == 2);
  CHECK(c.poses.back().T.p.x() == Approx(0.011));
  CHECK(has(c, "mid.csv:11: the last row has 13 of 17 cells"));
  // A short last row that ends its line is an ordinary occlusion (Motive drops trailing empty cells).
  const auto s = io::read_motive_csv(d.write("short.csv", cut + "\n"), "cam");
  CHECK(s.occluded == 2);
  CHECK(s.rows == 4);
  CHECK_FALSE(has(s, "truncated"));
  CHECK(s.capture_start_time == "2024-01-01 01.02.03.004 P.M.");
  // A body name in the Windows code page (cp1252 "ö" = 0xF6) is read as Latin-1: found by its
  // UTF-8 spelling, and said so.
  std::string cp = kMotive3;
  for (std::size_t at = cp.find(",cam"); at != std::string::npos; at = cp.find(",cam", at + 1))
    cp.replace(at, 4, ",k\xf6rper");
  const auto k = io::read_motive_csv(d.write("cp.csv", cp), "k\xc3\xb6rper");
  CHECK(k.body == "k\xc3\xb6rper");
  CHECK(k.poses.size() == 3);
  CHECK(has(k, "not UTF-8: read as Latin-1"));
  std::string v = kMotive3;
  v.replace(v.find("1.24"), 4, "9.99");
  CHECK(has(io::read_motive_csv(d.write("v.csv", v), "cam"), "Format Version 9.99 has not been checked"));
}

TEST_CASE("vicon: Tracker-style Objects section", "[io][mocap]") {
  TempDir d;
  const std::string text =
      "Objects\n100\n,,Global Angle cam:cam,,,,,,Global Angle obj:obj,,,,,\n"
      "Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ,RX,RY,RZ,TX,TY,TZ\n"
      ",,deg,deg,deg,mm,mm,mm,deg,deg,deg,mm,mm,mm\n"
      "10,0,0,0,90,100,200,300,0,0,0,0,0,0\n"
      "11,0,,,,,,,0,0,0,0,0,0\n"
      "12,0,0,0,90,110,200,300,0,0,0,0,0,0\n"
      "\nTrajectories\n100\n";
  const fs::path f = d.write("v.csv", text);
  CHECK_THROWS_WITH(io::read_vicon_csv(f), Catch::Contains("--body"));
  const auto v = io::read_vicon_csv(f, "cam");
  CHECK(v.body == "cam");
  CHECK(v.rows == 3);
  CHECK(v.occluded == 1);
  REQUIRE(v.poses.size() == 2);
  CHECK(v.poses[0].t_ns == 0);
  CHECK(v.poses[1].t_ns == 20'000'000);
  CHECK(v.poses[1].T.p.isApprox(Eigen::Vector3d(0.11, 0.2, 0.3), 1e-12));
  CHECK(math::angle_between(v.poses[0].T.q,
                            Eigen::Quaterniond(Eigen::AngleAxisd(3.14159265358979323846 / 2, Eigen::Vector3d::UnitZ()))) <
        1e-9);
  CHECK_THROWS_AS(io::read_vicon_csv(d.write("nov.csv", "Trajectories\n100\n")), InputError);
}

TEST_CASE("vicon: Nexus-style Segments section, a body by its segment name, full rotation vectors", "[io][mocap]") {
  TempDir d;
  const std::string text =
      "Segments\n200\n,,Rig:base,,,,,,Wand:tip,,,,,\n"
      "Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ,RX,RY,RZ,TX,TY,TZ\n"
      ",,rad,rad,rad,m,m,m,rad,rad,rad,m,m,m\n"
      "5,0,0.1,0.2,0.3,1,2,3,0.4,-0.5,0.6,4,5,6\n"
      "6,0,-0.3,0.1,0.2,-1,-2,-3,-0.7,0.2,0.1,-4,-5,-6\n";
  const fs::path f = d.write("n.csv", text);
  // The rotation columns are a rotation vector (axis x angle), each component in its own column.
  const auto rotvec = [](double x, double y, double z) {
    const Eigen::Vector3d v(x, y, z);
    return Eigen::Quaterniond(Eigen::AngleAxisd(v.norm(), v.normalized()));
  };
  const auto tip = io::read_vicon_csv(f, "tip");  // "Subject:Segment" matched by the segment name
  CHECK(tip.body == "Wand:tip");
  REQUIRE(tip.poses.size() == 2);
  CHECK(tip.poses[1].t_ns == 5'000'000);
  CHECK(tip.poses[0].T.p == Eigen::Vector3d(4, 5, 6));
  CHECK(tip.poses[1].T.p == Eigen::Vector3d(-4, -5, -6));
  CHECK(math::angle_between(tip.poses[0].T.q, rotvec(0.4, -0.5, 0.6)) < 1e-12);
  CHECK(math::angle_between(tip.poses[1].T.q, rotvec(-0.7, 0.2, 0.1)) < 1e-12);
  const auto base = io::read_vicon_csv(f, "Rig:base");  // or by the whole label
  CHECK(base.body == "Rig:base");
  REQUIRE(base.poses.size() == 2);
  CHECK(base.poses[1].T.p == Eigen::Vector3d(-1, -2, -3));
  CHECK(math::angle_between(base.poses[0].T.q, rotvec(0.1, 0.2, 0.3)) < 1e-12);
  CHECK(math::angle_between(base.poses[1].T.q, rotvec(-0.3, 0.1, 0.2)) < 1e-12);
  // Only a whole segment name after the ':' matches.
  for (const char* part : {"ip", "Wand", "d:tip", "base:"})
    CHECK_THROWS_WITH(io::read_vicon_csv(f, part), Catch::Contains("is not in the file"));
  // Two subjects of one model share segment names: the segment alone is ambiguous and refused; the
  // whole label, or a label that is exactly the name, is not.
  const fs::path two = d.write("two.csv",
                               "Segments\n200\n,,S1:Root,,,,,,S2:Root,,,,,,Root,,,,,\n"
                               "Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ,RX,RY,RZ,TX,TY,TZ,RX,RY,RZ,TX,TY,TZ\n"
                               ",,rad,rad,rad,m,m,m,rad,rad,rad,m,m,m,rad,rad,rad,m,m,m\n"
                               "5,0,0,0,0,1,1,1,0,0,0,2,2,2,0,0,0,3,3,3\n");
  const fs::path two_only = d.write("two_only.csv",
                                    "Segments\n200\n,,S1:Root,,,,,,S2:Root,,,,,\n"
                                    "Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ,RX,RY,RZ,TX,TY,TZ\n"
                                    ",,rad,rad,rad,m,m,m,rad,rad,rad,m,m,m\n"
                                    "5,0,0,0,0,1,1,1,0,0,0,2,2,2\n");
  CHECK_THROWS_WITH(io::read_vicon_csv(two_only, "Root"),
                    Catch::Contains("matches several objects") && Catch::Contains("\"S1:Root\" \"S2:Root\""));
  CHECK(io::read_vicon_csv(two_only, "S2:Root").poses.at(0).T.p.x() == 2);
  CHECK(io::read_vicon_csv(two, "Root").poses.at(0).T.p.x() == 3);  // the exact name wins
}

TEST_CASE("bag poses: PoseStamped, TransformStamped, Odometry and TF topics", "[io][mocap]") {
  TempDir d;
  testing::BagWriter w("lz4", 1000);
  for (int k = 0; k < 20; ++k) {
    io::ros::StampedTransform p;
    p.header.stamp_ns = 1'000'000'000LL + k * 10'000'000LL;
    p.child_frame_id = "body";
    p.transform.t = Eigen::Vector3d(k, 2 * k, 3);
    p.transform.q = Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * k, Eigen::Vector3d::UnitZ()));
    w.write("/pose", "geometry_msgs/PoseStamped", p.header.stamp_ns + 5,
            io::ros::encode<msg::PoseStamped>(Wire::ros1, p));
    w.write("/ts", "geometry_msgs/TransformStamped", p.header.stamp_ns + 5,
            io::ros::encode<msg::TransformStamped>(Wire::ros1, p));
    w.write("/odom", "nav_msgs/Odometry", p.header.stamp_ns + 5,
            io::ros::encode<msg::Odometry>(Wire::ros1, p));
    io::ros::StampedTransform other = p;
    other.child_frame_id = "other";
    other.transform.t = -p.transform.t;
    w.write("/tf", "tf2_msgs/TFMessage", p.header.stamp_ns + 5,
            io::ros::encode<msg::TFMessage>(Wire::ros1, {p, other}));
  }
  io::ros::StampedTransform bad;
  bad.header.stamp_ns = 5'000'000'000LL;
  bad.transform.q = Eigen::Quaterniond(0.5, 0.5, 0.5, 0.6);
  w.write("/badq", "geometry_msgs/PoseStamped", 1, io::ros::encode<msg::PoseStamped>(Wire::ros1, bad));
  const fs::path f = d.path / "p.bag";
  w.save(f.string());
  for (const char* topic : {"/pose", "/ts", "/odom"}) {
    INFO(topic);
    const auto m = io::read_bag_poses(f, topic);
    REQUIRE(m.poses.size() == 20);
    CHECK(m.poses[3].t_ns == 1'030'000'000LL);
    CHECK(m.poses[3].T.p.isApprox(Eigen::Vector3d(3, 6, 3)));
    CHECK(math::angle_between(m.poses[3].T.q, Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()))) <
          1e-12);
  }
  CHECK_THROWS_WITH(io::read_bag_poses(f, "/tf"), Catch::Contains("several child frames"));
  const auto tf = io::read_bag_poses(f, "/tf", "other");
  REQUIRE(tf.poses.size() == 20);
  CHECK(tf.poses[2].T.p.isApprox(Eigen::Vector3d(-2, -4, -3)));
  CHECK_THROWS_WITH(io::read_bag_poses(f, "/nope"), Catch::Contains("/pose [geometry_msgs/PoseStamped]"));
  CHECK_THROWS_WITH(io::read_bag_poses(f, "/badq"), Catch::Contains("unit norm"));
}

TEST_CASE("bag poses: a bag cut inside its only chunk says it is damaged, not that the topic is missing",
          "[io][mocap]") {
  TempDir d;
  testing::BagWriter w("none", 1 << 20);  // one chunk holds everything
  for (int k = 0; k < 50; ++k) {
    io::ros::StampedTransform p;
    p.header.stamp_ns = 1'000'000'000LL + k * 10'000'000LL;
    p.transform.q = Eigen::Quaterniond::Identity();
    w.write("/pose", "geometry_msgs/PoseStamped", p.header.stamp_ns,
            io::ros::encode<msg::PoseStamped>(Wire::ros1, p));
  }
  const fs::path whole = d.path / "whole.bag";
  w.save(whole.string());
  const std::string bytes = io::read_file(whole);
  const fs::path cut = d.path / "cut.bag";
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  for (bool salvage : {false, true}) {
    INFO(salvage);
    CHECK_THROWS_WITH(io::read_bag_poses(cut, "/pose", "", salvage),
                      Catch::Contains("topic \"/pose\" is not in the intact part of the bag") &&
                          Catch::Contains("the bag is damaged (byte "));
  }
  CHECK(io::read_bag_poses(whole, "/pose").poses.size() == 50);
  // An intact bag without the topic says just that.
  CHECK_THROWS_WITH(io::read_bag_poses(whole, "/nope"), !Catch::Contains("damaged") && Catch::Contains("is not in the bag"));
}

TEST_CASE("bag poses: the evo example bag's groundtruth topic", "[io][mocap][shared]") {
  const fs::path f = fs::path(ROE_SHARED_DATA_DIR) / "rosbag/evo_ROS_example.bag";
  if (!fs::exists(f)) {
    WARN("skipped: " << f << " absent");
    return;
  }
  const auto m = io::read_bag_poses(f, "groundtruth");
  CHECK(m.rows == 12765);
  REQUIRE(m.poses.size() == 12765);
  CHECK(m.poses.front().t_ns == 1502792570283404827LL);
  CHECK(std::is_sorted(m.poses.begin(), m.poses.end(), [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; }));
  CHECK(m.poses.front().T.p.isApprox(Eigen::Vector3d(-0.004899939787714927, -0.01775981455685227, -0.013755318406774505)));
  CHECK(m.warnings.empty());
}
