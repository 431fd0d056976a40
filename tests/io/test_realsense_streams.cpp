// Stream discovery as a pure function of a bag's (topic, type) list, for both bag generations and
// both layouts, and the static-transform chain used for T_I_C. No bag is read here.
#include <catch2/catch.hpp>

#include "roe/core/error.hpp"
#include "roe/io/ros/realsense_streams.hpp"
#include "roe/math/so3.hpp"

using namespace roe;

namespace {
const std::string kImu = "sensor_msgs/Imu", kImage = "sensor_msgs/Image", kInfo = "sensor_msgs/CameraInfo";
}

TEST_CASE("realsense streams: realsense-ros 4.x (ROS 2) united IMU under /camera/camera", "[io][realsense][streams]") {
  const auto s = io::discover_realsense_streams({{"/camera/camera/color/image_raw", kImage},
                                                 {"/camera/camera/color/camera_info", kInfo},
                                                 {"/camera/camera/imu", kImu},
                                                 {"/tf_static", "tf2_msgs/TFMessage"},
                                                 {"/rosout", "rcl_interfaces/Log"}},
                                                {});
  CHECK(s.layout == "realsense-ros");
  CHECK(s.color_topic == "/camera/camera/color/image_raw");
  CHECK(s.camera_info_topic == "/camera/camera/color/camera_info");
  CHECK(s.imu_topic == "/camera/camera/imu");
  CHECK(s.accel_topic.empty());
  CHECK(s.tf_static_topic == "/tf_static");
  CHECK(s.warnings.empty());
}

TEST_CASE("realsense streams: split accel/gyro, compressed only, any namespace", "[io][realsense][streams]") {
  const auto s = io::discover_realsense_streams({{"/rig/d435i/color/image_raw/compressed", "sensor_msgs/CompressedImage"},
                                                 {"/rig/d435i/color/camera_info", kInfo},
                                                 {"/rig/d435i/accel/sample", kImu},
                                                 {"/rig/d435i/gyro/sample", kImu}},
                                                {});
  CHECK(s.color_topic == "/rig/d435i/color/image_raw/compressed");
  CHECK(s.camera_info_topic == "/rig/d435i/color/camera_info");
  CHECK(s.accel_topic == "/rig/d435i/accel/sample");
  CHECK(s.gyro_topic == "/rig/d435i/gyro/sample");
  CHECK(s.imu_topic.empty());
  CHECK(s.tf_static_topic.empty());
}

TEST_CASE("realsense streams: raw before compressed, default namespace first, a warning for the others",
          "[io][realsense][streams]") {
  const auto s = io::discover_realsense_streams({{"/a/color/image_raw", kImage},
                                                 {"/camera/camera/color/image_raw/compressed", "sensor_msgs/CompressedImage"},
                                                 {"/camera/camera/color/image_raw", kImage},
                                                 {"/a/imu", kImu},
                                                 {"/camera/camera/imu", kImu}},
                                                {});
  CHECK(s.color_topic == "/camera/camera/color/image_raw");
  CHECK(s.imu_topic == "/camera/camera/imu");
  REQUIRE(s.warnings.size() == 2);
  CHECK(s.warnings[0].find("several cameras") != std::string::npos);
  CHECK(s.warnings[1].find("several namespaces") != std::string::npos);
}

TEST_CASE("realsense streams: the recorder layout, sensors chosen by name", "[io][realsense][streams]") {
  const std::vector<io::TopicType> t = {{"/device_0/sensor_0/Color_0/image/data", kImage},
                                        {"/device_0/sensor_1/Color_0/image/data", kImage},
                                        {"/device_0/sensor_1/Color_0/info/camera_info", kInfo},
                                        {"/device_0/sensor_2/Accel_0/imu/data", kImu},
                                        {"/device_0/sensor_2/Gyro_0/imu/data", kImu}};
  const auto by_index = io::discover_realsense_streams(t, {});
  CHECK(by_index.layout == "recorder");
  CHECK(by_index.color_topic == "/device_0/sensor_0/Color_0/image/data");
  const auto by_name = io::discover_realsense_streams(t, {}, {{"/device_0/sensor_1", "RGB Camera"}});
  CHECK(by_name.color_topic == "/device_0/sensor_1/Color_0/image/data");
  CHECK(by_name.camera_info_topic == "/device_0/sensor_1/Color_0/info/camera_info");
  CHECK(by_name.accel_topic == "/device_0/sensor_2/Accel_0/imu/data");
  CHECK(by_name.gyro_intr_topic == "/device_0/sensor_2/Gyro_0/imu_intrinsic");
}

TEST_CASE("realsense streams: bad choices and an unusable topic list are errors listing the topics",
          "[io][realsense][streams]") {
  const std::vector<io::TopicType> t = {{"/odom", "nav_msgs/Odometry"}, {"/camera/camera/imu", kImu}};
  CHECK_THROWS_WITH(io::discover_realsense_streams(t, {"", "", "", "/nope"}),
                    Catch::Contains("--imu-topic \"/nope\" is not in the bag") && Catch::Contains("/camera/camera/imu"));
  CHECK_THROWS_WITH(io::discover_realsense_streams(t, {"", "/odom", "", ""}),
                    Catch::Contains("has type nav_msgs/Odometry, expected sensor_msgs/Imu"));
  CHECK_THROWS_WITH(io::discover_realsense_streams(t, {"/camera/camera/imu", "", "", ""}),
                    Catch::Contains("expected sensor_msgs/Image or CompressedImage"));
  CHECK_THROWS_WITH(io::discover_realsense_streams({{"/odom", "nav_msgs/Odometry"}}, {}),
                    Catch::Contains("no colour image and no IMU stream") && Catch::Contains("/odom (nav_msgs/Odometry)"));
  // Only an IMU: no colour stream is a warning, not an error.
  const auto s = io::discover_realsense_streams(t, {});
  CHECK(s.color_topic.empty());
  CHECK(s.imu_topic == "/camera/camera/imu");
  CHECK(s.warnings.back().find("no colour image stream") != std::string::npos);
}

TEST_CASE("static_transform: chains to a common root, nullopt when unconnected", "[io][realsense][streams]") {
  auto tf = [](const char* parent, const char* child, const Pose& T) {
    io::ros::StampedTransform s;
    s.header.frame_id = parent;
    s.child_frame_id = child;
    s.transform.t = T.p;
    s.transform.q = T.q;
    return s;
  };
  const Pose T_L_A(math::exp_quat(Eigen::Vector3d(0.1, -0.2, 0.3)), Eigen::Vector3d(1, 2, 3));
  const Pose T_A_B(math::exp_quat(Eigen::Vector3d(-0.4, 0.1, 0.05)), Eigen::Vector3d(-0.5, 0.2, 0.1));
  const Pose T_L_C(math::exp_quat(Eigen::Vector3d(0.0, 0.3, -0.1)), Eigen::Vector3d(0.01, 0.02, -0.03));
  const std::vector<io::ros::StampedTransform> tfs = {tf("link", "a", T_L_A), tf("a", "b", T_A_B),
                                                      tf("link", "c", T_L_C), tf("x", "y", Pose())};
  const auto T_B_C = io::static_transform(tfs, "b", "c");
  REQUIRE(T_B_C);
  const Pose expect = (T_L_A * T_A_B).inverse() * T_L_C;
  CHECK((T_B_C->p - expect.p).norm() < 1e-12);
  CHECK(math::angle_between(T_B_C->q, expect.q) < 1e-12);
  CHECK(io::static_transform(tfs, "c", "c"));
  CHECK_FALSE(io::static_transform(tfs, "b", "y"));
  CHECK_FALSE(io::static_transform(tfs, "b", "unknown"));
}

TEST_CASE("realsense streams: without images, the colour CameraInfo beside the IMU is still found",
          "[io][realsense][streams]") {
  const auto s = io::discover_realsense_streams({{"/camera/camera/color/camera_info", kInfo},
                                                 {"/camera/camera/imu", kImu},
                                                 {"/tf_static", "tf2_msgs/TFMessage"}},
                                                {});
  CHECK(s.color_topic.empty());
  CHECK(s.camera_info_topic == "/camera/camera/color/camera_info");
  CHECK(s.imu_topic == "/camera/camera/imu");
}
