// io/ros/realsense_recording: the RealSense recording reader on generated D435i bags (both layouts), checked
// against the generator's truth (tests/fixtures/gen_d435i_bag.hpp), not against the importer that calls it.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "fixtures/gen_d435i_bag.hpp"
#include "roe/core/error.hpp"
#include "roe/io/ros/message_bag.hpp"
#include "roe/io/ros/realsense_recording.hpp"
#include "support/test_util.hpp"

using namespace roe;
namespace fs = std::filesystem;
using roe::test::TempDir;

namespace {
fs::path write_file(const TempDir& d, const std::string& name, const std::string& bytes) {
  const fs::path p = d.path / name;
  std::ofstream(p, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return p;
}

double seconds_since(Timestamp t, Timestamp t0) { return static_cast<double>(t - t0) * 1e-9; }

/// The split accel and gyro samples are the generator's, stamp for stamp and value for value.
void check_split_imu(const io::RealsenseRecording& r, const testing::D435iBagTruth& truth) {
  REQUIRE(r.accel.size() == truth.accel_stamps.size());
  REQUIRE(r.gyro.size() == truth.gyro_stamps.size());
  double acc_err = 0, gyr_err = 0;
  for (std::size_t k = 0; k < r.accel.size(); ++k) {
    CHECK(r.accel[k].first == truth.accel_stamps[k]);
    const double t = seconds_since(r.accel[k].first, truth.t0_ns);
    acc_err = std::max(acc_err, (r.accel[k].second - testing::D435iBagTruth::accel_at(t)).cwiseAbs().maxCoeff());
  }
  for (std::size_t k = 0; k < r.gyro.size(); ++k) {
    CHECK(r.gyro[k].first == truth.gyro_stamps[k]);
    const double t = seconds_since(r.gyro[k].first, truth.t0_ns);
    gyr_err = std::max(gyr_err, (r.gyro[k].second - testing::D435iBagTruth::gyro_at(t)).cwiseAbs().maxCoeff());
  }
  CHECK(acc_err < 1e-9);
  CHECK(gyr_err < 1e-9);
}
}  // namespace

TEST_CASE("io/ros/realsense_recording: a recorder bag's streams, IMU, camera info, stream info and tf/0",
          "[io][realsense]") {
  TempDir d;
  testing::D435iBagSpec spec;
  testing::D435iBagTruth truth;
  const auto bag = io::open_bag(write_file(d, "rec.bag", testing::generate_d435i_bag(spec, &truth)));
  const io::RealsenseStreams st = io::discover_realsense_bag(*bag, {});
  CHECK(st.layout == "recorder");
  CHECK(st.color_topic == "/device_0/sensor_1/Color_0/image/data");
  CHECK(st.accel_topic == "/device_0/sensor_2/Accel_0/imu/data");
  const io::RealsenseRecording r = io::read_realsense_recording(*bag, st);
  check_split_imu(r, truth);
  CHECK(r.united.empty());
  REQUIRE(r.cam_info);
  CHECK(r.cam_info->width == static_cast<std::uint32_t>(spec.width));
  CHECK(r.cam_info->height == static_cast<std::uint32_t>(spec.height));
  CHECK(r.cam_info->K[0] == spec.fx);
  CHECK(r.cam_info->K[4] == spec.fy);
  CHECK(r.color_fps == static_cast<std::uint32_t>(spec.fps));
  CHECK(r.accel_fps == static_cast<std::uint32_t>(spec.accel_hz));
  CHECK(r.gyro_fps == static_cast<std::uint32_t>(spec.gyro_hz));
  CHECK(r.domain_of.at(st.metadata_topic) == spec.color_domain);
  CHECK(r.accel_intr.has_value());
  REQUIRE(r.recorder_tf.count("Color_0"));
  REQUIRE(r.recorder_tf.count("Accel_0"));
  CHECK((r.recorder_tf.at("Color_0").t - truth.t_color_depth).norm() < 1e-12);
  CHECK((r.recorder_tf.at("Accel_0").t - truth.t_accel_depth).norm() < 1e-12);
  CHECK(r.tf_static.empty());
}

TEST_CASE("io/ros/realsense_recording: realsense-ros bags, split and united IMU", "[io][realsense]") {
  for (const bool united : {false, true}) {
    INFO("united IMU: " << united);
    TempDir d;
    testing::D435iBagSpec spec;
    spec.layout = testing::D435iBagSpec::Layout::kRealsenseRos;
    spec.ros_united_imu = united;
    testing::D435iBagTruth truth;
    const auto bag = io::open_bag(write_file(d, "ros.bag", testing::generate_d435i_bag(spec, &truth)));
    const io::RealsenseStreams st = io::discover_realsense_bag(*bag, {});
    CHECK(st.layout == "realsense-ros");
    CHECK(st.color_topic == "/camera/color/image_raw");
    const io::RealsenseRecording r = io::read_realsense_recording(*bag, st);
    REQUIRE(r.cam_info);
    CHECK(r.cam_info->header.frame_id == "camera_color_optical_frame");
    CHECK(r.recorder_tf.empty());
    if (united) {
      CHECK(st.imu_topic == "/camera/imu");
      CHECK(r.accel.empty());
      REQUIRE_FALSE(r.united.empty());
      // unite_imu_method linear_interpolation: one sample per gyro stamp inside the accel range.
      for (const auto& s : r.united) {
        const double t = seconds_since(s.t_ns, truth.t0_ns);
        CHECK((s.gyro - testing::D435iBagTruth::gyro_at(t)).cwiseAbs().maxCoeff() < 1e-9);
      }
    } else {
      CHECK(st.imu_topic.empty());
      check_split_imu(r, truth);
    }
    CHECK_FALSE(r.imu_frame.empty());
  }
}

TEST_CASE("io/ros/realsense_recording: a chosen topic that is not in the bag is an error naming the bag",
          "[io][realsense]") {
  TempDir d;
  testing::D435iBagSpec spec;
  const fs::path file = write_file(d, "rec.bag", testing::generate_d435i_bag(spec));
  const auto bag = io::open_bag(file);
  io::RealsenseTopicChoice choice;
  choice.color_topic = "/no/such/image";
  CHECK_THROWS_WITH(io::discover_realsense_bag(*bag, choice),
                    Catch::Contains(file.string()) && Catch::Contains("/no/such/image"));
}
