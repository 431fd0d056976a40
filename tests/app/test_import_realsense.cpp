// roe import realsense: generated D435i-layout bags (LZ4, bz2, unindexed, permuted sensors,
// realsense-ros with compressed images) checked against the generator's truth, and the real
// RealSense recorder bag of ../shared/data.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <random>
#include <sstream>

#include "support/test_util.hpp"
#include "fixtures/gen_d435i_bag.hpp"
#include "roe/io/ros/imu_streams.hpp"
#include "roe/app/import.hpp"
#include "roe/image/frame_processor.hpp"
#include "roe/io/csv.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/json.hpp"
#include "roe/io/ros/ros1_bag.hpp"

namespace fs = std::filesystem;
namespace ros1 = roe::io::ros1;
using namespace roe;

namespace {
using roe::test::TempDir;


fs::path write_bag(const TempDir& d, const std::string& name, const std::string& bytes) {
  const fs::path p = d.path / name;
  std::ofstream(p, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return p;
}

std::string png_encoder(const std::string& raw, int w, int h) {
  return image::encode_png({w, h, "rgb8", static_cast<std::size_t>(w) * 3, raw}, "test");
}

/// Checks a dataset imported from a generated bag against the generator's truth.
void check_against_truth(const fs::path& ds, const testing::D435iBagSpec& spec, const testing::D435iBagTruth& truth,
                         const app::ImportRealsenseSummary& s) {
  // Merged IMU: every gyro stamp inside the accel range, gyro exact, accel = the (linear) truth.
  const auto imu = store::read_imu_csv(store::imu_csv_path(ds));
  std::size_t inside = 0;
  for (Timestamp t : truth.gyro_stamps)
    if (t >= truth.accel_stamps.front() && t <= truth.accel_stamps.back()) ++inside;
  REQUIRE(imu.size() == inside);
  CHECK(s.imu_samples == inside);
  CHECK(s.gyro_outside_accel == truth.gyro_stamps.size() - inside);
  CHECK(s.accel_samples == truth.accel_stamps.size());
  CHECK(s.gyro_samples == truth.gyro_stamps.size());
  CHECK(s.accel_rate_hz == spec.accel_hz);
  CHECK(s.gyro_rate_hz == spec.gyro_hz);
  double max_acc_err = 0, max_gyr_err = 0;
  for (const auto& x : imu) {
    const double t = static_cast<double>(x.t_ns - truth.t0_ns) * 1e-9;
    max_acc_err = std::max(max_acc_err, (x.accel - testing::D435iBagTruth::accel_at(t)).cwiseAbs().maxCoeff());
    max_gyr_err = std::max(max_gyr_err, (x.gyro - testing::D435iBagTruth::gyro_at(t)).cwiseAbs().maxCoeff());
  }
  CHECK(max_acc_err < 1e-9);
  CHECK(max_gyr_err < 1e-12);
  // The raw streams are kept at their native rates.
  io::CsvReader acc(ds / "mav0/imu0_raw/accel.csv");
  std::size_t n = 0;
  while (acc.next()) CHECK(acc.get_int64(0) == truth.accel_stamps[n++]);
  CHECK(n == truth.accel_stamps.size());
  // Frames: header.stamp names, configured size.
  const auto frames = store::read_cam_csv(store::cam_csv_path(ds));
  REQUIRE(frames.size() == truth.frame_stamps.size());
  for (std::size_t k = 0; k < frames.size(); ++k) {
    CHECK(frames[k].t_ns == truth.frame_stamps[k]);
    CHECK(frames[k].filename == std::to_string(truth.frame_stamps[k]) + ".png");
  }
  const auto img = image::read_image(store::cam_image_dir(ds) / frames[0].filename);
  CHECK(img.width == 640);
  CHECK(img.height == 480);
  CHECK(img.channels == 3);
  // Manifest: processed intrinsics (centre crop of (704 − 640)/2 = 32, (528 − 480)/2 = 24 px).
  const auto m = store::read_manifest(ds);
  REQUIRE(m.camera);
  CHECK(m.camera->width == 640);
  CHECK(m.camera->height == 480);
  CHECK(m.camera->fx == Approx(spec.fx));
  CHECK(m.camera->fy == Approx(spec.fy));
  CHECK(m.camera->cx == Approx(spec.cx - 32));
  CHECK(m.camera->cy == Approx(spec.cy - 24));
  CHECK(m.camera->distortion_model == "none");
  REQUIRE(m.imu);
  CHECK(m.imu->rate_hz == spec.gyro_hz);
  REQUIRE(m.sources.size() == 1);
  CHECK(m.sources[0].sha256.size() == 64);
}

}  // namespace

TEST_CASE("import realsense: generated D435i bags (LZ4, bz2, none) match the generator's truth", "[app][import]") {
  for (const char* comp : {"lz4", "bz2", "none"}) {
    INFO(comp);
    TempDir d;
    testing::D435iBagSpec spec;
    spec.compression = comp;
    testing::D435iBagTruth truth;
    const fs::path b = write_bag(d, "d435i.bag", testing::generate_d435i_bag(spec, &truth));
    app::ImportRealsenseOptions o;
    std::size_t progress_calls = 0;
    const auto s = app::import_realsense(b, d.path / "ds", o, [&](std::size_t, std::size_t) { ++progress_calls; });
    CHECK(progress_calls == static_cast<std::size_t>(spec.n_frames));
    CHECK(s.layout == "recorder");
    CHECK(s.color_topic == "/device_0/sensor_1/Color_0/image/data");
    CHECK(s.accel_topic == "/device_0/sensor_2/Accel_0/imu/data");
    CHECK(s.timestamp_domain == "Global Time");
    CHECK(s.source_distortion == "Inverse Brown Conrady");
    check_against_truth(d.path / "ds", spec, truth, s);
    const auto m = store::read_manifest(d.path / "ds");
    const auto& opt = m.sources[0].options;
    CHECK(opt.at("source_distortion_model") == "Inverse Brown Conrady");
    CHECK(opt.at("timestamp_domain") == "Global Time");
    CHECK(m.sources[0].kind == "realsense-bag");
    // A bag has no IMU noise densities: left out of roe.json (unknown), not written as 0 (noise-free).
    CHECK_FALSE(m.imu->noise.known());
    CHECK_FALSE(io::parse_json_file(d.path / "ds" / "roe.json").at("imu").contains("gyro_noise_density"));
    // T_I_C from the tf/0 extrinsics: T_accel_depth · T_color_depth⁻¹.
    REQUIRE(s.have_T_I_C);
    const Pose T_C_D(truth.q_color_depth, truth.t_color_depth), T_A_D(truth.q_accel_depth, truth.t_accel_depth);
    const Pose expect = T_A_D * T_C_D.inverse();
    CHECK((m.camera->T_I_C.p - expect.p).norm() < 1e-12);
    CHECK(math::angle_between(m.camera->T_I_C.q, expect.q) < 1e-9);
  }
}

TEST_CASE("import realsense: repeated IMU messages are dropped and counted", "[app][import]") {
  for (const char* layout : {"recorder", "ros"}) {
    INFO(layout);
    TempDir d;
    testing::D435iBagSpec spec;
    spec.layout = std::string(layout) == "ros" ? testing::D435iBagSpec::Layout::kRealsenseRos
                                               : testing::D435iBagSpec::Layout::kRecorder;
    spec.repeated_imu = 3;  // 3 accel + 3 gyro messages written twice
    testing::D435iBagTruth truth;
    const fs::path b = write_bag(d, "rep.bag", testing::generate_d435i_bag(spec, &truth));
    const auto s = app::import_realsense(b, d.path / "ds", {});
    // Everything else as without the repeats: the first copy of each is kept.
    check_against_truth(d.path / "ds", spec, truth, s);
    CHECK(std::count(s.warnings.begin(), s.warnings.end(), "6 IMU samples with a repeated stamp dropped") == 1);
  }
}

TEST_CASE("import realsense: sensors are found by name, unindexed bags are scanned", "[app][import]") {
  TempDir d;
  testing::D435iBagSpec spec;
  spec.motion_module_first = true;
  spec.indexed = false;
  spec.n_frames = 2;
  testing::D435iBagTruth truth;
  const fs::path b = write_bag(d, "perm.bag", testing::generate_d435i_bag(spec, &truth));
  const auto s = app::import_realsense(b, d.path / "ds", {});
  CHECK(s.color_topic == "/device_0/sensor_2/Color_0/image/data");
  CHECK(s.gyro_topic == "/device_0/sensor_0/Gyro_0/imu/data");
  check_against_truth(d.path / "ds", spec, truth, s);
}

TEST_CASE("import realsense: realsense-ros layout with compressed images", "[app][import]") {
  TempDir d;
  testing::D435iBagSpec spec;
  spec.layout = testing::D435iBagSpec::Layout::kRealsenseRos;
  spec.compressed_images = true;
  spec.n_frames = 2;
  spec.coeffs = {0, 0, 0, 0, 0};
  testing::D435iBagTruth truth;
  const fs::path b = write_bag(d, "ros.bag", testing::generate_d435i_bag(spec, &truth, png_encoder));
  const auto s = app::import_realsense(b, d.path / "ds", {});
  CHECK(s.layout == "realsense-ros");
  CHECK(s.color_topic == "/camera/color/image_raw/compressed");
  CHECK(s.source_distortion == "plumb_bob");
  check_against_truth(d.path / "ds", spec, truth, s);
  // With zero distortion the output is an exact centre crop: compare pixels with the generator.
  const auto frames = store::read_cam_csv(store::cam_csv_path(d.path / "ds"));
  const auto img = image::read_image(store::cam_image_dir(d.path / "ds") / frames[1].filename);
  for (auto [u, v] : {std::pair{0, 0}, std::pair{100, 200}, std::pair{639, 479}}) {
    const auto p = testing::D435iBagTruth::pixel(1, u + 32, v + 24);
    CHECK(img.at(u, v, 2) == p[0]);  // PNG pixels are BGR
    CHECK(img.at(u, v, 1) == p[1]);
    CHECK(img.at(u, v, 0) == p[2]);
  }
}

TEST_CASE("import realsense: options, overwrite protection, damaged bags", "[app][import]") {
  TempDir d;
  testing::D435iBagSpec spec;
  spec.n_frames = 2;
  spec.compression = "none";
  const std::string bytes = testing::generate_d435i_bag(spec);
  const fs::path b = write_bag(d, "x.bag", bytes);
  app::ImportRealsenseOptions o;
  o.crop_width = 700;
  o.crop_height = 500;
  o.out_width = 350;
  o.out_height = 250;
  const auto s = app::import_realsense(b, d.path / "ds", o);
  CHECK(s.camera.width == 350);
  CHECK(s.camera.fx == Approx(spec.fx / 2));
  CHECK(s.camera.cx == Approx((spec.cx - 2 + 0.5) / 2 - 0.5));
  // An existing dataset is refused without force, replaced with it.
  CHECK_THROWS_WITH(app::import_realsense(b, d.path / "ds", {}), Catch::Contains("--force"));
  app::ImportRealsenseOptions f;
  f.force = true;
  CHECK(app::import_realsense(b, d.path / "ds", f).camera.width == 640);
  // A crop larger than the image is bad input.
  app::ImportRealsenseOptions big;
  big.crop_width = 2000;
  CHECK_THROWS_AS(app::import_realsense(b, d.path / "ds2", big), InputError);
  CHECK_FALSE(fs::exists(d.path / "ds2"));
  // Cut inside its first chunk, before any stream's topics: "damaged", with or without --salvage.
  {
    testing::D435iBagSpec one = spec;
    one.chunk_threshold = 64 << 20;  // a single chunk
    const std::string all = testing::generate_d435i_bag(one);
    const fs::path early = write_bag(d, "early.bag", all.substr(0, all.size() / 2));
    for (bool salvage : {false, true}) {
      app::ImportRealsenseOptions so;
      so.salvage = salvage;
      CHECK_THROWS_WITH(app::import_realsense(early, d.path / "ds4", so),
                        Catch::Contains("the bag is damaged (byte ") && Catch::Contains("nothing to import"));
      CHECK_FALSE(fs::exists(d.path / "ds4"));
    }
  }
  // Truncated: an InputError naming the byte offset; --salvage imports the intact part.
  const fs::path cut = write_bag(d, "cut.bag", bytes.substr(0, bytes.size() * 6 / 10));
  CHECK_THROWS_WITH(app::import_realsense(cut, d.path / "ds3", {}), Catch::Contains("damaged") && Catch::Contains("byte "));
  CHECK_FALSE(fs::exists(d.path / "ds3"));
  app::ImportRealsenseOptions salv;
  salv.salvage = true;
  const auto ss = app::import_realsense(cut, d.path / "ds3", salv);
  CHECK(ss.imu_samples > 0);
  CHECK_FALSE(ss.warnings.empty());
}

TEST_CASE("merge_accel_gyro: interpolation and range", "[app][import]") {
  using V = std::vector<std::pair<Timestamp, Eigen::Vector3d>>;
  const V acc = {{10, {0, 0, 0}}, {20, {10, 20, 30}}, {40, {30, 20, 10}}};
  const V gyr = {{5, {1, 1, 1}}, {10, {2, 2, 2}}, {15, {3, 3, 3}}, {30, {4, 4, 4}}, {40, {5, 5, 5}}, {45, {6, 6, 6}}};
  std::size_t dropped = 0;
  const auto m = io::merge_accel_gyro(acc, gyr, &dropped);
  REQUIRE(m.size() == 4);
  CHECK(dropped == 2);
  CHECK(m[0].accel.isApprox(Eigen::Vector3d(0, 0, 0)));
  CHECK(m[1].accel.isApprox(Eigen::Vector3d(5, 10, 15)));
  CHECK(m[2].accel.isApprox(Eigen::Vector3d(20, 20, 20)));
  CHECK(m[3].accel.isApprox(Eigen::Vector3d(30, 20, 10)));
  CHECK(m[2].gyro.isApprox(Eigen::Vector3d(4, 4, 4)));
}

TEST_CASE("import realsense: the real RealSense recorder bag", "[app][import][shared]") {
  const fs::path bagf = fs::path(ROE_SHARED_DATA_DIR) / "realsense/single_depth_color_640x480.bag";
  if (!fs::exists(bagf)) {
    WARN("skipped: " << bagf << " absent");
    return;
  }
  TempDir d;
  const auto s = app::import_realsense(bagf, d.path / "ds", {});
  CHECK(s.layout == "recorder");
  CHECK(s.frames == 1);
  CHECK(s.imu_samples == 0);
  // A bag without the motion module: imported, but said loudly (roe run needs an IMU).
  CHECK(std::count_if(s.warnings.begin(), s.warnings.end(), [](const std::string& w) {
          return w.find("the bag has no IMU stream") == 0;
        }) == 1);
  CHECK_FALSE(fs::exists(d.path / "ds" / "mav0" / "imu0" / "data.csv"));
  CHECK(s.timestamp_domain == "Hardware Clock");
  const auto m = store::read_manifest(d.path / "ds");
  REQUIRE(m.camera);
  // 640x480 source, 640x480 crop: the intrinsics pass through unchanged.
  CHECK(m.camera->width == 640);
  CHECK(m.camera->height == 480);
  CHECK(m.camera->fx == Approx(613.204).margin(5e-4));
  CHECK(m.camera->fy == Approx(613.419).margin(5e-4));
  CHECK(m.camera->cx == Approx(319.939).margin(5e-4));
  CHECK(m.camera->cy == Approx(239.183).margin(5e-4));
  const auto& o = m.sources.at(0).options;
  CHECK(o.at("source_distortion_model") == "Brown Conrady");
  CHECK(o.at("source_distortion") == "0,0,0,0,0");
  CHECK(o.at("tf0_Depth_0") == "p=[0,0,0] q_xyzw=[0,0,0,1]");
  REQUIRE(s.extrinsics.count("Color_0"));
  const Pose& T = s.extrinsics.at("Color_0");
  CHECK(T.p.x() == Approx(0.0143113).margin(1e-6));
  CHECK(T.p.y() == Approx(0.000602306).margin(1e-8));
  CHECK(T.p.z() == Approx(0.000610804).margin(1e-8));
  CHECK(std::abs(T.q.w()) == Approx(0.999966).margin(1e-6));
  CHECK(T.q.y() * T.q.w() > 0);  // q and −q are the same rotation; compare up to sign
  CHECK(std::abs(T.q.y()) == Approx(0.00646343).margin(1e-7));
  CHECK(std::abs(T.q.z()) == Approx(0.00515485).margin(1e-7));
  const auto frames = store::read_cam_csv(store::cam_csv_path(d.path / "ds"));
  REQUIRE(frames.size() == 1);
  const auto img = image::read_image(store::cam_image_dir(d.path / "ds") / frames[0].filename);
  CHECK(img.width == 640);
  CHECK(img.height == 480);
  CHECK(img.channels == 3);
}

TEST_CASE("import realsense: a stream label without an index is not a stream", "[app][import]") {
  // The recorder names streams <Kind>_<index> (Accel_0, Accel_1); "Accel_" or "Accel_x" is another topic,
  // so the bag has a gyro but no accelerometer: the raw gyro is kept, imu0 is not written.
  for (const char* label : {"Accel_", "Accel_x", "Accel_3"}) {
    INFO(label);
    TempDir d;
    testing::D435iBagSpec spec;
    spec.n_frames = 2;
    spec.accel_stream = label;
    const fs::path b = write_bag(d, "x.bag", testing::generate_d435i_bag(spec));
    const auto s = app::import_realsense(b, d.path / "ds", {});
    if (std::string(label) == "Accel_3") {
      CHECK(s.accel_topic == "/device_0/sensor_2/Accel_3/imu/data");
      CHECK(s.imu_samples > 0);
    } else {
      CHECK(s.accel_topic.empty());
      CHECK(s.imu_samples == 0);
      CHECK(std::count(s.warnings.begin(), s.warnings.end(),
                       "only one of accel/gyro is present: imu0 not written (raw stream kept in imu0_raw)") == 1);
      CHECK_FALSE(fs::exists(d.path / "ds/mav0/imu0/data.csv"));
    }
  }
}

namespace {
/// Every file of a dataset folder (relative path → bytes), roe.json without the lines that name the
/// bag (path, sha256, name).
std::map<std::string, std::string> dataset_files(const fs::path& ds) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(ds)) {
    if (!e.is_regular_file()) continue;
    std::ifstream f(e.path(), std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    const std::string rel = fs::relative(e.path(), ds).generic_string();
    if (rel == "roe.json") {
      std::string kept, line;
      std::istringstream in(bytes);
      while (std::getline(in, line))
        if (line.find("\"sha256\"") == std::string::npos && line.find("\"path\"") == std::string::npos &&
            line.find("\"name\"") == std::string::npos)
          kept += line + "\n";
      bytes = kept;
    }
    files[rel] = bytes;
  }
  return files;
}

std::size_t count_prefix(const std::vector<std::string>& v, const std::string& prefix) {
  return static_cast<std::size_t>(
      std::count_if(v.begin(), v.end(), [&](const std::string& w) { return w.compare(0, prefix.size(), prefix) == 0; }));
}

testing::D435iBagSpec ros_spec() {
  testing::D435iBagSpec spec;
  spec.layout = testing::D435iBagSpec::Layout::kRealsenseRos;
  spec.n_frames = 2;
  spec.imu_duration_s = 0.5;
  spec.coeffs = {0, 0, 0, 0, 0};
  return spec;
}

/// The bytes with every occurrence of `a` replaced by `b` of the same length (a topic name inside
/// the connection records of an uncompressed bag).
std::string rename_in_bag(std::string bytes, const std::string& a, const std::string& b) {
  REQUIRE(a.size() == b.size());
  for (std::size_t p = bytes.find(a); p != std::string::npos; p = bytes.find(a, p + b.size())) bytes.replace(p, a.size(), b);
  return bytes;
}
}  // namespace

TEST_CASE("import realsense: librealsense >= 2.49 bags (depth_units after every image) import as the old layout",
          "[app][import]") {
  for (const char* comp : {"lz4", "none"}) {
    INFO(comp);
    TempDir d;
    testing::D435iBagSpec spec;
    spec.compression = comp;
    spec.n_frames = 3;
    testing::D435iBagTruth truth;
    const std::string old_bytes = testing::generate_d435i_bag(spec, &truth);
    spec.modern_image_header = true;
    const std::string new_bytes = testing::generate_d435i_bag(spec);
    REQUIRE(new_bytes != old_bytes);
    const auto s_old = app::import_realsense(write_bag(d, "old.bag", old_bytes), d.path / "old", {});
    const auto s_new = app::import_realsense(write_bag(d, "new.bag", new_bytes), d.path / "new", {});
    CHECK(s_new.frames == 3);
    check_against_truth(d.path / "new", spec, truth, s_new);
    CHECK(s_new.warnings == s_old.warnings);
    // Byte for byte the same dataset (PNGs, CSVs, roe.json but for the bag's name and hash).
    const auto a = dataset_files(d.path / "old"), b = dataset_files(d.path / "new");
    REQUIRE(a.size() == b.size());
    for (const auto& [rel, bytes] : a) {
      INFO(rel);
      REQUIRE(b.count(rel));
      CHECK((b.at(rel) == bytes));
    }
  }
}

TEST_CASE("import realsense: colour in librealsense's format names (YUYV, RGB8) imports as yuyv, rgb8",
          "[app][import]") {
  for (const auto& [rs, ros] : {std::pair{"YUYV", "yuyv"}, std::pair{"RGB8", "rgb8"}}) {
    INFO(rs);
    TempDir d;
    testing::D435iBagSpec spec;
    spec.n_frames = 2;
    spec.imu_duration_s = 0.3;
    spec.color_encoding = rs;
    const auto s_rs = app::import_realsense(write_bag(d, "rs.bag", testing::generate_d435i_bag(spec)), d.path / "rs", {});
    spec.color_encoding = ros;
    const auto s_ros = app::import_realsense(write_bag(d, "ros.bag", testing::generate_d435i_bag(spec)), d.path / "ros", {});
    CHECK(s_rs.frames == 2);
    const auto a = dataset_files(d.path / "rs"), b = dataset_files(d.path / "ros");
    REQUIRE(a.size() == b.size());
    for (const auto& [rel, bytes] : a) {
      INFO(rel);
      CHECK((b.at(rel) == bytes));
    }
  }
}

TEST_CASE("import realsense: realsense-ros IMU topics are found by type under any namespace", "[app][import]") {
  TempDir d;
  auto spec = ros_spec();
  spec.ros_namespace = "/d455";
  testing::D435iBagTruth truth;
  const fs::path b = write_bag(d, "d455.bag", testing::generate_d435i_bag(spec, &truth));
  const auto s = app::import_realsense(b, d.path / "ds", {});
  CHECK(s.color_topic == "/d455/color/image_raw");
  CHECK(s.accel_topic == "/d455/accel/sample");
  CHECK(s.gyro_topic == "/d455/gyro/sample");
  CHECK(count_prefix(s.warnings, "the bag has no IMU stream") == 0);
  check_against_truth(d.path / "ds", spec, truth, s);

  // Two cameras' IMUs: the colour topic's namespace wins (/a_cam sorts first), with a warning.
  spec.ros_extra_imu_namespaces = {"/a_cam"};
  const fs::path two = write_bag(d, "two.bag", testing::generate_d435i_bag(spec, &truth));
  const auto s2 = app::import_realsense(two, d.path / "ds2", {});
  CHECK(s2.gyro_topic == "/d455/gyro/sample");
  CHECK(count_prefix(s2.warnings, "IMU topics under several namespaces (/a_cam, /d455): using those of /d455") == 1);
  // --accel-topic/--gyro-topic choose other ones; a wrong name or type is an error naming the bag.
  app::ImportRealsenseOptions o;
  o.accel_topic = "/a_cam/accel/sample";
  o.gyro_topic = "/a_cam/gyro/sample";
  const auto s3 = app::import_realsense(two, d.path / "ds3", o);
  CHECK(s3.accel_topic == "/a_cam/accel/sample");
  CHECK(s3.gyro_topic == "/a_cam/gyro/sample");
  CHECK(count_prefix(s3.warnings, "IMU topics under several namespaces") == 0);
  check_against_truth(d.path / "ds3", spec, truth, s3);
  app::ImportRealsenseOptions bad;
  bad.imu_topic = "/camera/imu";
  CHECK_THROWS_WITH(app::import_realsense(two, d.path / "ds4", bad),
                    Catch::Contains("two.bag") && Catch::Contains("--imu-topic \"/camera/imu\" is not in the bag") &&
                        Catch::Contains("/a_cam/accel/sample, /a_cam/gyro/sample, /d455/accel/sample"));
  bad.imu_topic = "/d455/color/image_raw";
  CHECK_THROWS_WITH(app::import_realsense(two, d.path / "ds4", bad),
                    Catch::Contains("has type sensor_msgs/Image, expected sensor_msgs/Imu"));
  CHECK_FALSE(fs::exists(d.path / "ds4"));

  // Imu topics with names roe does not know: the warning lists them; the options import them.
  spec.ros_extra_imu_namespaces.clear();
  spec.compression = "none";
  std::string odd = testing::generate_d435i_bag(spec, &truth);
  odd = rename_in_bag(rename_in_bag(odd, "/accel/sample", "/accel/raw_xx"), "/gyro/sample", "/gyro/raw_xx");
  const fs::path oddb = write_bag(d, "odd.bag", odd);
  const auto s5 = app::import_realsense(oddb, d.path / "ds5", {});
  CHECK(s5.imu_samples == 0);
  CHECK(count_prefix(s5.warnings, "the bag has no IMU stream that roe recognises") == 1);
  CHECK(std::count_if(s5.warnings.begin(), s5.warnings.end(), [](const std::string& w) {
          return w.find("sensor_msgs/Imu topics in the bag: /d455/accel/raw_xx, /d455/gyro/raw_xx") != std::string::npos;
        }) == 1);
  o.accel_topic = "/d455/accel/raw_xx";
  o.gyro_topic = "/d455/gyro/raw_xx";
  const auto s6 = app::import_realsense(oddb, d.path / "ds6", o);
  check_against_truth(d.path / "ds6", spec, truth, s6);
}

TEST_CASE("import realsense: a united realsense-ros IMU topic: repeated stamps counted, its rate recorded",
          "[app][import]") {
  TempDir d;
  auto spec = ros_spec();
  spec.ros_namespace = "/d455";
  spec.ros_united_imu = true;
  spec.repeated_imu = 3;
  testing::D435iBagTruth truth;
  const fs::path b = write_bag(d, "united.bag", testing::generate_d435i_bag(spec, &truth));
  const auto s = app::import_realsense(b, d.path / "ds", {});
  CHECK(s.imu_topic == "/d455/imu");
  CHECK(s.accel_topic.empty());
  std::vector<Timestamp> expect;
  for (Timestamp t : truth.gyro_stamps)
    if (t >= truth.accel_stamps.front() && t <= truth.accel_stamps.back()) expect.push_back(t);
  const auto imu = store::read_imu_csv(store::imu_csv_path(d.path / "ds"));
  REQUIRE(imu.size() == expect.size());
  for (std::size_t k = 0; k < imu.size(); ++k) {
    CHECK(imu[k].t_ns == expect[k]);
    const double t = static_cast<double>(imu[k].t_ns - truth.t0_ns) * 1e-9;
    CHECK((imu[k].accel - testing::D435iBagTruth::accel_at(t)).cwiseAbs().maxCoeff() < 1e-12);
    CHECK((imu[k].gyro - testing::D435iBagTruth::gyro_at(t)).cwiseAbs().maxCoeff() < 1e-12);
  }
  CHECK(std::count(s.warnings.begin(), s.warnings.end(), "3 IMU samples with a repeated stamp dropped") == 1);
  // The united topic carries the gyro stamps: its rate is the gyro's; the accelerometer's is unknown.
  CHECK(s.gyro_rate_hz == Approx(spec.gyro_hz).epsilon(1e-6));
  CHECK(s.accel_rate_hz == 0);
  const auto m = store::read_manifest(d.path / "ds");
  REQUIRE(m.imu);
  CHECK(m.imu->rate_hz == Approx(spec.gyro_hz).epsilon(1e-6));
  const auto& opt = m.sources.at(0).options;
  CHECK(opt.at("imu_merge") == "united topic");
  CHECK(std::stod(opt.at("gyro_rate_hz")) == Approx(spec.gyro_hz).epsilon(1e-6));
  CHECK_FALSE(opt.count("accel_rate_hz"));
}

TEST_CASE("import realsense: a bag with infrared images only names its image topics", "[app][import]") {
  TempDir d;
  auto spec = ros_spec();
  spec.ros_image = "infra1/image_rect_raw";
  const fs::path b = write_bag(d, "infra.bag", testing::generate_d435i_bag(spec));
  // With an IMU: the IMU is imported, and the warning says why there is no cam0 and what to choose.
  const auto s = app::import_realsense(b, d.path / "ds", {});
  CHECK(s.frames == 0);
  CHECK(s.imu_samples > 0);
  CHECK(std::count(s.warnings.begin(), s.warnings.end(),
                   "no colour image stream found: cam0 not written; image topics in the bag: "
                   "/camera/infra1/image_rect_raw (choose one with --color-topic)") == 1);
  CHECK_FALSE(fs::exists(d.path / "ds/mav0/cam0"));
  // --color-topic takes it (its camera_info is beside it).
  app::ImportRealsenseOptions o;
  o.color_topic = "/camera/infra1/image_rect_raw";
  CHECK(app::import_realsense(b, d.path / "ds2", o).frames == 2);
  // Without an IMU: an error that lists the image topics.
  spec.imu_duration_s = 0;
  const fs::path b2 = write_bag(d, "infra_only.bag", testing::generate_d435i_bag(spec));
  CHECK_THROWS_WITH(app::import_realsense(b2, d.path / "ds3", {}),
                    Catch::Contains("no colour image and no IMU stream found") &&
                        Catch::Contains("image topics: /camera/infra1/image_rect_raw (choose one with --color-topic)"));
  CHECK_FALSE(fs::exists(d.path / "ds3"));
}

TEST_CASE("import realsense: each stream's timestamp domain is recorded, different clocks warned", "[app][import]") {
  TempDir d;
  // IMU only (no colour frame): the IMU's domain, not "unknown".
  testing::D435iBagSpec spec;
  spec.n_frames = 0;
  spec.imu_duration_s = 0.3;
  spec.imu_domain = "Global Time";
  const auto s = app::import_realsense(write_bag(d, "imu.bag", testing::generate_d435i_bag(spec)), d.path / "ds", {});
  CHECK(s.imu_samples > 0);
  CHECK(s.timestamp_domain == "Global Time");
  CHECK(s.imu_timestamp_domain == "Global Time");
  const auto m = store::read_manifest(d.path / "ds");
  CHECK(m.sources.at(0).options.at("timestamp_domain") == "Global Time");
  CHECK(m.sources.at(0).options.at("imu_timestamp_domain") == "Global Time");
  // Colour and IMU in different clocks: both recorded, and a warning.
  spec.n_frames = 2;
  spec.color_domain = "Hardware Clock";
  const auto s2 = app::import_realsense(write_bag(d, "mixed.bag", testing::generate_d435i_bag(spec)), d.path / "ds2", {});
  CHECK(s2.timestamp_domain == "Hardware Clock");
  CHECK(s2.imu_timestamp_domain == "Global Time");
  CHECK(count_prefix(s2.warnings, "the colour frames are stamped in \"Hardware Clock\" and the IMU samples in "
                                  "\"Global Time\": the two clocks are not comparable") == 1);
  const auto m2 = store::read_manifest(d.path / "ds2");
  CHECK(m2.sources.at(0).options.at("timestamp_domain") == "Hardware Clock");
  CHECK(m2.sources.at(0).options.at("imu_timestamp_domain") == "Global Time");
  // The same clock: no warning.
  spec.color_domain = "Global Time";
  const auto s3 = app::import_realsense(write_bag(d, "same.bag", testing::generate_d435i_bag(spec)), d.path / "ds3", {});
  CHECK(count_prefix(s3.warnings, "the colour frames are stamped in") == 0);
}

TEST_CASE("import realsense: a truncated bag fails before any frame is decoded, naming the truncation",
          "[app][import]") {
  TempDir d;
  testing::D435iBagSpec spec;
  spec.compression = "none";
  spec.n_frames = 4;
  const std::string bytes = testing::generate_d435i_bag(spec);
  const fs::path cut = write_bag(d, "cut.bag", bytes.substr(0, bytes.size() * 6 / 10));
  std::size_t frames_done = 0;
  std::string msg;
  try {
    app::import_realsense(cut, d.path / "ds", {}, [&](std::size_t, std::size_t) { ++frames_done; });
  } catch (const InputError& e) {
    msg = e.what();
  }
  CHECK(frames_done == 0);  // no PNG was decoded or written before the failure
  CHECK_FALSE(fs::exists(d.path / "ds"));
  // The first problem cited is the truncated record, not the index that points past the end.
  const std::size_t open = msg.find("the bag is damaged (byte ");
  REQUIRE(open != std::string::npos);
  const std::string cited = msg.substr(open, msg.find("problem(s)", open) - open);
  CHECK(cited.find("truncated record") != std::string::npos);
  CHECK(cited.find("index position") == std::string::npos);
  CHECK(msg.find("; 2 problem(s)); use --salvage") != std::string::npos);
  // Every problem is listed.
  CHECK(msg.find("\nproblems found:\n  byte 13: index position") != std::string::npos);
}

TEST_CASE("import realsense: a corrupt first chunk (CameraInfo) is reported as damage with its offset",
          "[app][import]") {
  for (bool recorder : {true, false}) {
    INFO((recorder ? "recorder" : "realsense-ros"));
    TempDir d;
    testing::D435iBagSpec spec = recorder ? testing::D435iBagSpec() : ros_spec();
    spec.compression = "lz4";
    spec.n_frames = 3;
    std::string bytes = testing::generate_d435i_bag(spec);
    const ros1::ChunkInfo first = [&] {
      ros1::Reader r(bytes, "x");
      REQUIRE(r.chunks().size() > 2);
      return r.chunks()[0];
    }();
    for (std::size_t i = 8; i < std::min<std::size_t>(first.data_size, 200); ++i) bytes[first.data_offset + i] ^= 0x5A;
    const fs::path b = write_bag(d, "bad.bag", bytes);
    // One problem, although the recorder layout reads the chunk twice (sensor names, then the streams).
    const std::string at = "the bag is damaged (byte " + std::to_string(first.offset) +
                           ": LZ4 chunk fails to decompress; chunk skipped; 1 problem(s))";
    // Without --salvage: damaged, use --salvage.
    CHECK_THROWS_WITH(app::import_realsense(b, d.path / "ds", {}), Catch::Contains(at) && Catch::Contains("--salvage"));
    // With it: the CameraInfo was in the lost chunk, and the error says so.
    app::ImportRealsenseOptions salv;
    salv.salvage = true;
    CHECK_THROWS_WITH(app::import_realsense(b, d.path / "ds", salv),
                      Catch::Contains("no CameraInfo for the colour stream") &&
                          Catch::Contains("in the intact part of the bag: " + at) && Catch::Contains("--no-images"));
    CHECK_FALSE(fs::exists(d.path / "ds"));
    salv.images = false;
    const auto s = app::import_realsense(b, d.path / "ds", salv);
    CHECK(s.imu_samples > 0);
    CHECK(count_prefix(s.warnings, "no CameraInfo for the colour stream in the intact part of the bag: " + at) == 1);
  }
}
