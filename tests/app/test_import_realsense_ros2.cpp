// roe import realsense on realsense-ros 4.x ROS 2 bags written by independent writers
// (tests/fixtures/ros2/make_fixtures.mjs: @mcap/core + @foxglove/rosmsg2-serialization; make_sqlite.py:
// Python sqlite3): MCAP with zstd chunks (united IMU, raw rgb8), MCAP with lz4 chunks (split
// accel/gyro, PNG CompressedImage), a split folder with metadata.yaml, and a rosbag2 SQLite folder.
// The imported images, IMU samples, intrinsics and T_I_C must equal what the writer put in
// (tests/fixtures/ros2/expected.json).
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "roe/app/import.hpp"
#include "roe/image/frame_processor.hpp"
#include "roe/store/dataset.hpp"
#include "roe/math/so3.hpp"
#include "fixtures/mcap_writer.hpp"
#include "roe/app/run.hpp"
#include "roe/io/ros/cdr.hpp"
#include "support/test_util.hpp"

namespace fs = std::filesystem;
using namespace roe;
namespace msg = roe::io::ros::msg;
using roe::io::ros::Wire;

namespace {

const fs::path kDir = fs::path(ROE_SOURCE_DIR) / "tests/fixtures/ros2";

nlohmann::json expected() { return nlohmann::json::parse(std::ifstream(kDir / "expected.json")); }

Timestamp ns(const nlohmann::json& s) { return std::stoll(s.get<std::string>()); }

std::array<int, 3> pixel(int k, int x, int y) {  // expected.json "pixel_rule"
  return {(7 * x + 11 * k) % 256, (9 * y + 3 * k) % 256, (x * y + k) % 256};
}

Pose pose_of(const nlohmann::json& j) {
  const auto& q = j.at("q");
  const auto& p = j.at("p");
  return Pose(Eigen::Quaterniond(q[3].get<double>(), q[0].get<double>(), q[1].get<double>(), q[2].get<double>()),
              Eigen::Vector3d(p[0].get<double>(), p[1].get<double>(), p[2].get<double>()));
}

void check_dataset(const fs::path& ds, const app::ImportRealsenseSummary& s, bool united) {
  const auto E = expected();
  const int W = E["width"], H = E["height"];
  // Images: the stamps and every pixel of every frame (no distortion, full-size crop: unchanged).
  const auto cams = store::read_cam_csv(ds / "mav0/cam0/data.csv");
  REQUIRE(cams.size() == E["frames"].size());
  for (std::size_t k = 0; k < cams.size(); ++k) {
    CHECK(cams[k].t_ns == ns(E["frames"][k]));
    const auto img = image::read_image(ds / "mav0/cam0/data" / cams[k].filename);
    REQUIRE(img.width == W);
    REQUIRE(img.height == H);
    REQUIRE(img.channels == 3);
    int bad = 0;
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const auto rgb = pixel(static_cast<int>(k), x, y);
        // read_image keeps OpenCV's BGR order.
        bad += img.at(x, y, 0) != rgb[2] || img.at(x, y, 1) != rgb[1] || img.at(x, y, 2) != rgb[0];
      }
    CHECK(bad == 0);
  }
  // Intrinsics.
  const auto m = store::read_manifest(ds);
  REQUIRE(m.camera);
  CHECK(m.camera->width == W);
  CHECK(m.camera->height == H);
  CHECK(m.camera->fx == E["K"][0].get<double>());
  CHECK(m.camera->fy == E["K"][4].get<double>());
  CHECK(m.camera->cx == E["K"][2].get<double>());
  CHECK(m.camera->cy == E["K"][5].get<double>());
  // IMU: the united topic as written, or accel interpolated at the gyro stamps.
  const auto imu = store::read_imu_csv(ds / "mav0/imu0/data.csv");
  const auto& gyro = E["gyro"];
  const auto& acc = E["united_accel"];
  REQUIRE(imu.size() == gyro.size() - (united ? 0 : 1));  // the last gyro stamp is past the last accel
  for (std::size_t i = 0; i < imu.size(); ++i) {
    CHECK(imu[i].t_ns == ns(gyro[i][0]));
    for (int c = 0; c < 3; ++c) {
      CHECK(imu[i].gyro[c] == Approx(gyro[i][c + 1].get<double>()).epsilon(1e-12).margin(1e-15));
      CHECK(imu[i].accel[c] == Approx(acc[i][c].get<double>()).epsilon(1e-9).margin(1e-12));
    }
  }
  // T_I_C from /tf_static, IMU frame <- colour optical frame.
  REQUIRE(s.have_T_I_C);
  const Pose expect = pose_of(E[united ? "T_I_C_united" : "T_I_C_split"]);
  CHECK((m.camera->T_I_C.p - expect.p).norm() < 1e-12);
  CHECK(math::angle_between(m.camera->T_I_C.q, expect.q) < 1e-9);
  CHECK(m.sources[0].kind == "ros2-bag");
  CHECK(m.sources[0].options.at("T_I_C_source").rfind("/tf_static: ", 0) == 0);
}

app::ImportRealsenseOptions small_frames() {
  app::ImportRealsenseOptions o;
  o.crop_width = 32;
  o.crop_height = 24;
  return o;
}

}  // namespace

TEST_CASE("import realsense ROS 2: independent writers' MCAP (zstd, lz4), split folder and SQLite", "[app][import][ros2]") {
  struct Case {
    const char* path;
    bool united;
    const char* color;
  };
  for (const Case& c : {Case{"rs_zstd.mcap", true, "/camera/camera/color/image_raw"},
                        Case{"rs_lz4.mcap", false, "/camera/camera/color/image_raw/compressed"},
                        Case{"rs_split", true, "/camera/camera/color/image_raw"},
                        Case{"rs_sqlite", false, "/camera/camera/color/image_raw/compressed"}}) {
    INFO(c.path);
    test::TempDir d;
    const auto s = app::import_realsense(kDir / c.path, d.path / "ds", small_frames());
    CHECK(s.layout == "realsense-ros");
    CHECK(s.color_topic == c.color);
    CHECK(s.imu_topic == (c.united ? "/camera/camera/imu" : ""));
    CHECK(s.gyro_topic == (c.united ? "" : "/camera/camera/gyro/sample"));
    CHECK(s.frames == 6);
    check_dataset(d.path / "ds", s, c.united);
  }
}

TEST_CASE("import realsense ROS 2: a missing split file is an error naming it, --salvage keeps the rest",
          "[app][import][ros2]") {
  test::TempDir d;
  fs::copy(kDir / "rs_split", d.path / "bag");
  fs::remove(d.path / "bag/rs_split_1.mcap");
  CHECK_THROWS_WITH(app::import_realsense(d.path / "bag", d.path / "ds", small_frames()),
                    Catch::Contains("rs_split_1.mcap") && Catch::Contains("missing"));
  CHECK_FALSE(fs::exists(d.path / "ds"));
  auto o = small_frames();
  o.salvage = true;
  const auto s = app::import_realsense(d.path / "bag", d.path / "ds", o);
  CHECK(s.frames > 0);
  CHECK(s.frames < 6);
  bool named = false;
  for (const auto& w : s.warnings) named = named || w.find("rs_split_1.mcap") != std::string::npos;
  CHECK(named);
}

TEST_CASE("import realsense ROS 2: a simulated recording written as a ROS 2 bag imports and roe run works",
          "[app][import][ros2][run]") {
  // The embedded simulated dataset's IMU, camera intrinsics and T_I_C, written as realsense-ros 4.x
  // topics (united IMU, CameraInfo, /tf_static) into an MCAP with zstd chunks; no images.
  const fs::path sample = fs::path(ROE_SOURCE_DIR) / "datasets/sample";
  const auto man = store::read_manifest(sample);
  const auto imu = store::read_imu_csv(sample / "mav0/imu0/data.csv");
  const auto cams = store::read_cam_csv(sample / "mav0/cam0/data.csv");
  test::TempDir d;
  {
    testing::McapWriter w(d.path / "sim.mcap", true);
    w.channel(1, "/camera/camera/imu", "sensor_msgs/msg/Imu");
    w.channel(2, "/camera/camera/color/camera_info", "sensor_msgs/msg/CameraInfo");
    w.channel(3, "/tf_static", "tf2_msgs/msg/TFMessage");
    io::ros::StampedTransform l_i, l_c;
    l_i.header.frame_id = l_c.header.frame_id = "camera_link";
    l_i.child_frame_id = "camera_imu_optical_frame";
    l_c.child_frame_id = "camera_color_optical_frame";
    l_c.transform.t = man.camera->T_I_C.p;  // camera_link = the IMU frame here
    l_c.transform.q = man.camera->T_I_C.q;
    w.message(3, static_cast<std::uint64_t>(imu.front().t_ns),
              io::ros::encode<msg::TFMessage>(Wire::cdr, {l_i, l_c}));
    std::size_t c = 0;
    for (const auto& s : imu) {
      while (c < cams.size() && cams[c].t_ns <= s.t_ns) {
        io::ros::CameraInfo ci;
        ci.header.stamp_ns = cams[c].t_ns;
        ci.header.frame_id = "camera_color_optical_frame";
        ci.width = static_cast<std::uint32_t>(man.camera->width);
        ci.height = static_cast<std::uint32_t>(man.camera->height);
        ci.distortion_model = "plumb_bob";
        ci.D = {0, 0, 0, 0, 0};
        ci.K = {man.camera->fx, 0, man.camera->cx, 0, man.camera->fy, man.camera->cy, 0, 0, 1};
        w.message(2, static_cast<std::uint64_t>(cams[c].t_ns),
                  io::ros::encode<msg::CameraInfo>(Wire::cdr, ci));
        ++c;
      }
      io::ros::Imu m;
      m.header.stamp_ns = s.t_ns;
      m.header.frame_id = "camera_imu_optical_frame";
      m.angular_velocity = s.gyro;
      m.linear_acceleration = s.accel;
      w.message(1, static_cast<std::uint64_t>(s.t_ns), io::ros::encode<msg::Imu>(Wire::cdr, m));
    }
    w.finish();
  }
  app::ImportRealsenseOptions o;
  o.images = false;
  const fs::path ds = d.path / "ds";
  const auto s = app::import_realsense(d.path / "sim.mcap", ds, o);
  CHECK(s.imu_samples == imu.size());
  REQUIRE(s.have_T_I_C);
  const auto got = store::read_imu_csv(ds / "mav0/imu0/data.csv");
  REQUIRE(got.size() == imu.size());
  for (std::size_t i = 0; i < imu.size(); i += 97) {
    CHECK(got[i].t_ns == imu[i].t_ns);
    CHECK((got[i].gyro - imu[i].gyro).norm() < 1e-12);
    CHECK((got[i].accel - imu[i].accel).norm() < 1e-12);
  }
  // The detections, objects and IMU noise of the simulation join the imported dataset; then roe run.
  auto m = store::read_manifest(ds);
  REQUIRE(m.camera);
  CHECK((m.camera->T_I_C.p - man.camera->T_I_C.p).norm() < 1e-12);
  CHECK(math::angle_between(m.camera->T_I_C.q, man.camera->T_I_C.q) < 1e-9);
  CHECK(m.camera->fx == man.camera->fx);
  m.objects = man.objects;
  m.imu->noise = man.imu->noise;
  store::write_manifest(m, ds / "roe.json");
  fs::copy(sample / "detections", ds / "detections", fs::copy_options::recursive);
  fs::create_directories(ds / "mav0/cam0");
  fs::copy_file(sample / "mav0/cam0/data.csv", ds / "mav0/cam0/data.csv");
  const auto r = app::run(ds, d.path / "run", {});
  CHECK(fs::exists(d.path / "run/trajectory.csv"));
  CHECK(r.output.state_rows > 1000);
}
