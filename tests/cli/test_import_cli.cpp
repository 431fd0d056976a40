// End-to-end: roe import realsense|mocap|kalibr through the executable — exit codes and messages
// for good and corrupt inputs (DESIGN §1: 2 = bad input).
#include <sys/wait.h>

#include <array>
#include <catch2/catch.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <string>

#include "support/test_util.hpp"
#include "fixtures/gen_d435i_bag.hpp"

namespace fs = std::filesystem;

namespace {
using Result = roe::test::RunResult;
Result run(const std::string& args, bool merge_stderr = true) {
  return roe::test::run_roe(args, merge_stderr);
}

/// A temporary folder whose paths come back as strings (they are spliced into command lines).
struct TempDir {
  roe::test::TempDir dir{"roe_test_cli_import"};
  std::string write(const std::string& name, const std::string& bytes) const {
    return dir.write(name, bytes).string();
  }
  std::string operator/(const std::string& rel) const { return (dir.path / rel).string(); }
};

// A valid Kalibr camchain (identity rotation, 10 cm lever arm, −10 ms time shift).
const std::string cc =
    "cam0:\n  T_cam_imu:\n  - [1.0, 0.0, 0.0, 0.1]\n  - [0.0, 1.0, 0.0, 0.0]\n  - [0.0, 0.0, 1.0, 0.0]\n"
    "  - [0.0, 0.0, 0.0, 1.0]\n  camera_model: pinhole\n  distortion_coeffs: [0, 0, 0, 0]\n"
    "  distortion_model: radtan\n  intrinsics: [600, 600, 320, 240]\n  resolution: [640, 480]\n"
    "  timeshift_cam_imu: -0.01\n";

// 2 s of TUM poses at 100 Hz.
std::string tum_poses() {
  std::string tum;
  for (int k = 0; k < 200; ++k) tum += std::to_string(1000.0 + 0.01 * k) + " 0.1 0.2 0.3 0 0 0 1\n";
  return tum;
}

std::string small_d435i(const std::string& compression) {
  roe::testing::D435iBagSpec s;
  s.compression = compression;
  s.n_frames = 2;
  s.imu_duration_s = 0.3;
  return roe::testing::generate_d435i_bag(s);
}
}  // namespace

TEST_CASE("roe import realsense: a generated bag imports (exit 0, JSON summary)", "[cli][import]") {
  TempDir d;
  const auto bag = d.write("a.bag", small_d435i("lz4"));
  const auto r = run("import realsense " + bag + " --out " + d / "ds" + " --json", false);
  REQUIRE(r.code == 0);
  const auto j = nlohmann::json::parse(r.out);
  CHECK(j["frames"] == 2);
  CHECK(j["camera"]["width"] == 640);
  CHECK(j["source_camera"]["distortion_model"] == "Inverse Brown Conrady");
  CHECK(fs::exists(d / "ds/roe.json"));
  // Existing output without --force: exit 2; with --force: 0.
  const auto again = run("import realsense " + bag + " --out " + d / "ds");
  CHECK(again.code == 2);
  CHECK(again.out.find("--force") != std::string::npos);
  CHECK(run("import realsense " + bag + " --out " + d / "ds" + " --force -q").code == 0);
}

TEST_CASE("roe import realsense: corrupt bags exit 2 with the byte offset", "[cli][import]") {
  TempDir d;
  const std::string good = small_d435i("lz4");
  // Wrong magic.
  auto r = run("import realsense " + d.write("magic.bag", "#ROSBAG V9.9\n" + good.substr(13)) + " --out " + d / "o1");
  CHECK(r.code == 2);
  CHECK(r.out.find("version") != std::string::npos);
  r = run("import realsense " + d.write("text.bag", "hello") + " --out " + d / "o1");
  CHECK(r.code == 2);
  CHECK(r.out.find("wrong magic") != std::string::npos);
  // Truncated.
  const auto cut = d.write("cut.bag", good.substr(0, good.size() / 2));
  r = run("import realsense " + cut + " --out " + d / "o2");
  CHECK(r.code == 2);
  CHECK(r.out.find("damaged") != std::string::npos);
  CHECK(r.out.find("byte ") != std::string::npos);
  CHECK(r.out.find("--salvage") != std::string::npos);
  CHECK_FALSE(fs::exists(d / "o2"));
  CHECK(run("import realsense " + cut + " --out " + d / "o2" + " --salvage -q").code == 0);
  // A corrupt chunk (bytes flipped inside the second chunk's LZ4 data).
  std::string bad = good;
  const std::size_t second = bad.find("compression=lz4", bad.find("compression=lz4") + 1);
  REQUIRE(second != std::string::npos);
  for (std::size_t i = second + 200; i < second + 400; ++i) bad[i] ^= 0x33;
  r = run("import realsense " + d.write("bad.bag", bad) + " --out " + d / "o3");
  CHECK(r.code == 2);
  CHECK(r.out.find("damaged") != std::string::npos);
  // Not a file.
  CHECK(run("import realsense " + d / "missing.bag" + " --out " + d / "o4").code == 2);
}

TEST_CASE("roe import realsense: IMU topics by type (--accel-topic, --gyro-topic, --imu-topic), 2.49+ bags",
          "[cli][import]") {
  TempDir d;
  roe::testing::D435iBagSpec s;
  s.layout = roe::testing::D435iBagSpec::Layout::kRealsenseRos;
  s.ros_namespace = "/d455";
  s.ros_extra_imu_namespaces = {"/t265"};
  s.n_frames = 2;
  s.imu_duration_s = 0.3;
  const auto bag = d.write("ns.bag", roe::testing::generate_d435i_bag(s));
  auto r = run("import realsense " + bag + " --out " + d / "a" + " --json", false);
  REQUIRE(r.code == 0);
  auto j = nlohmann::json::parse(r.out);
  CHECK(j["topics"]["gyro"] == "/d455/gyro/sample");
  CHECK(j["imu_samples"].get<int>() > 0);
  r = run("import realsense " + bag + " --out " + d / "b" + " --json --accel-topic /t265/accel/sample --gyro-topic "
          "/t265/gyro/sample", false);
  REQUIRE(r.code == 0);
  j = nlohmann::json::parse(r.out);
  CHECK(j["topics"]["accel"] == "/t265/accel/sample");
  CHECK(j["topics"]["gyro"] == "/t265/gyro/sample");
  r = run("import realsense " + bag + " --out " + d / "c" + " --imu-topic /camera/imu");
  CHECK(r.code == 2);
  CHECK(r.out.find("ns.bag") != std::string::npos);
  CHECK(r.out.find("--imu-topic \"/camera/imu\" is not in the bag") != std::string::npos);
  CHECK_FALSE(fs::exists(d / "c"));
  // A librealsense >= 2.49 recorder bag (float32 depth_units after every image): exit 0.
  roe::testing::D435iBagSpec m;
  m.modern_image_header = true;
  m.n_frames = 2;
  m.imu_duration_s = 0.3;
  r = run("import realsense " + d.write("modern.bag", roe::testing::generate_d435i_bag(m)) + " --out " + d / "m");
  CHECK(r.code == 0);
  CHECK(r.out.find("colour: 2 frame(s)") != std::string::npos);
  CHECK(r.out.find("domain \"Global Time\"") != std::string::npos);
}

TEST_CASE("roe import mocap: malformed rows and non-unit quaternions exit 2 naming line:column", "[cli][import]") {
  TempDir d;
  const std::string motive =
      "Format Version,1.23,Export Frame Rate,100,Rotation Type,Quaternion,Length Units,Meters\n\n"
      ",Type,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body\n"
      ",Name,b,b,b,b,b,b,b\n,ID,1,1,1,1,1,1,1\n,,Rotation,Rotation,Rotation,Rotation,Position,Position,Position\n"
      "Frame,Time (Seconds),X,Y,Z,W,X,Y,Z\n"
      "0,0.00,0,0,0,1,1,2,3\n"
      "1,0.01,0,0,0,1,1,2,3\n";
  auto r = run("import mocap " + d.write("ok.csv", motive) + " --into " + d / "ds" + " --json", false);
  REQUIRE(r.code == 0);
  CHECK(nlohmann::json::parse(r.out)["poses"] == 2);
  std::string bad = motive;
  bad.replace(bad.rfind("1,2,3"), 1, "?");
  r = run("import mocap " + d.write("bad.csv", bad) + " --into " + d / "ds2");
  CHECK(r.code == 2);
  CHECK(r.out.find("bad.csv:9:7") != std::string::npos);
  std::string nonunit = motive;
  nonunit.replace(nonunit.rfind("0,0,0,1,"), 8, "0,0,0,2,");
  r = run("import mocap " + d.write("nu.csv", nonunit) + " --into " + d / "ds3");
  CHECK(r.code == 2);
  CHECK(r.out.find("unit norm") != std::string::npos);
  r = run("import mocap " + d.write("nu.tum", "0.0 1 2 3 0 0 0 1\n0.1 1 2 3 0 0 0 3\n") + " --into " + d / "ds4");
  CHECK(r.code == 2);
  CHECK(r.out.find("nu.tum:2") != std::string::npos);
  // The dataset already has mocap0: exit 2 without --force.
  r = run("import mocap " + d / "ok.csv" + " --into " + d / "ds");
  CHECK(r.code == 2);
  CHECK(r.out.find("--force") != std::string::npos);
  // --estimate-offset without an IMU in the dataset.
  r = run("import mocap " + d / "ok.csv" + " --into " + d / "ds5 --estimate-offset");
  CHECK(r.code == 2);
  CHECK(r.out.find("imu0") != std::string::npos);
  // --name: only mocap* folders (exit 2 naming the option), and the summary says where the offset went.
  r = run("--force import mocap " + d / "ok.csv" + " --into " + d / "ds --name imu0");
  CHECK(r.code == 2);
  CHECK(r.out.find("must start with \"mocap\"") != std::string::npos);
  r = run("import mocap " + d / "ok.csv" + " --into " + d / "ds --name mocap1 --time-offset 5");
  CHECK(r.code == 0);
  CHECK(r.out.find("time offset 5 s recorded in roe.json (this import's sources[].options.time_offset_s)") !=
        std::string::npos);
  // csv-ns (roe's own trajectory.csv) is a --format choice.
  r = run("import mocap " + d.write("t.csv", "timestamp_ns,tx,ty,tz,qx,qy,qz,qw\n0,1,2,3,0,0,0,1\n10000000,1,2,3,0,0,0,1\n") +
          " --format csv-ns --into " + d / "ds6");
  CHECK(r.code == 0);
}

TEST_CASE("roe import kalibr: valid and invalid files", "[cli][import]") {
  TempDir d;
  auto r = run("import kalibr " + d.write("cc.yaml", cc) + " --into " + d / "ds" + " --json", false);
  REQUIRE(r.code == 0);
  const auto j = nlohmann::json::parse(r.out);
  CHECK(j["T_I_C"]["p"][0] == -0.1);
  CHECK(j["timeshift_cam_imu"] == -0.01);
  std::string bad = cc;
  bad.replace(bad.find("[1.0, 0.0, 0.0, 0.1]"), 20, "[1.0, 0.5, 0.0, 0.1]");
  r = run("import kalibr " + d.write("bad.yaml", bad) + " --into " + d / "ds2");
  CHECK(r.code == 2);
  CHECK(r.out.find("orthonormal") != std::string::npos);
  r = run("import kalibr " + d / "cc.yaml " + d.write("imu.yaml", "accelerometer_noise_density: 0\n") + " --into " + d / "ds3");
  CHECK(r.code == 2);
}

TEST_CASE("roe import mocap and kalibr into one dataset at once: both are recorded", "[cli][import]") {
  // Each import reads roe.json, adds its record and writes it back; without the dataset's lock the
  // second writer silently dropped the first one's record (9 of 20 runs before the lock existed).
  TempDir d;
  const auto cc_file = d.write("cc.yaml", cc);
  const std::string tum = tum_poses();
  const auto tum_file = d.write("gt.txt", tum);
  const std::string roe = ROE_BINARY;
  for (int i = 0; i < 12; ++i) {
    const std::string ds = d / ("ds" + std::to_string(i));
    const std::string cmd = "( '" + roe + "' -q import mocap '" + tum_file + "' --format tum --into '" + ds +
                            "' & '" + roe + "' -q import kalibr '" + cc_file + "' --into '" + ds + "' & wait ) 2>/dev/null";
    REQUIRE(std::system(cmd.c_str()) == 0);
    std::ifstream in(ds + "/roe.json");
    const auto j = nlohmann::json::parse(in);
    std::set<std::string> kinds;
    for (const auto& s : j["sources"]) kinds.insert(s["kind"].get<std::string>());
    INFO("run " << i);
    CHECK(kinds.count("tum") == 1);
    CHECK(kinds.count("kalibr-camchain") == 1);
    CHECK(j.contains("camera"));
    CHECK(j.contains("mocap"));
  }
}

TEST_CASE("roe import: a failure before roe.json is written leaves the dataset as it was", "[cli][import]") {
  TempDir d;
  const std::string tum = tum_poses();
  const auto tum_file = d.write("gt.txt", tum);
  // --estimate-offset into a new folder without an IMU: exit 2 and no folder left behind.
  auto r = run("import mocap " + tum_file + " --format tum --estimate-offset --into " + d / "new");
  CHECK(r.code == 2);
  CHECK_FALSE(fs::exists(d / "new"));
  // A Kalibr import whose camchain fails validation after nothing was staged leaves no calib/ and
  // an unchanged roe.json (the staging itself: io/StagedFiles in tests/io).
  REQUIRE(run("import mocap " + tum_file + " --format tum --into " + d / "ds -q").code == 0);
  const std::string before = [&] {
    std::ifstream in(d / "ds/roe.json");
    return std::string(std::istreambuf_iterator<char>(in), {});
  }();
  r = run("import kalibr " + d.write("bad.yaml", "cam0:\n  camera_model: pinhole\n") + " --into " + d / "ds");
  CHECK(r.code == 2);
  CHECK_FALSE(fs::exists(d / "ds/calib"));
  std::ifstream in(d / "ds/roe.json");
  CHECK(std::string(std::istreambuf_iterator<char>(in), {}) == before);
}
