// roe import realsense: generated D435i-layout bags (LZ4, bz2, unindexed, permuted sensors,
// realsense-ros with compressed images) checked against the generator's truth, and the real
// RealSense recorder bag of ../shared/data.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <random>

#include "support/test_util.hpp"
#include "fixtures/gen_d435i_bag.hpp"
#include "roe/app/import.hpp"
#include "roe/image/frame_processor.hpp"
#include "roe/io/csv.hpp"
#include "roe/io/dataset.hpp"
#include "roe/io/json.hpp"

namespace fs = std::filesystem;
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
  const auto imu = io::read_imu_csv(io::imu_csv_path(ds));
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
  const auto frames = io::read_cam_csv(io::cam_csv_path(ds));
  REQUIRE(frames.size() == truth.frame_stamps.size());
  for (std::size_t k = 0; k < frames.size(); ++k) {
    CHECK(frames[k].t_ns == truth.frame_stamps[k]);
    CHECK(frames[k].filename == std::to_string(truth.frame_stamps[k]) + ".png");
  }
  const auto img = image::read_image(io::cam_image_dir(ds) / frames[0].filename);
  CHECK(img.width == 640);
  CHECK(img.height == 480);
  CHECK(img.channels == 3);
  // Manifest: processed intrinsics (centre crop of (704 − 640)/2 = 32, (528 − 480)/2 = 24 px).
  const auto m = io::read_manifest(ds);
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
    const auto m = io::read_manifest(d.path / "ds");
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
  const auto frames = io::read_cam_csv(io::cam_csv_path(d.path / "ds"));
  const auto img = image::read_image(io::cam_image_dir(d.path / "ds") / frames[1].filename);
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
  const auto m = app::merge_accel_gyro(acc, gyr, &dropped);
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
  const auto m = io::read_manifest(d.path / "ds");
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
  const auto frames = io::read_cam_csv(io::cam_csv_path(d.path / "ds"));
  REQUIRE(frames.size() == 1);
  const auto img = image::read_image(io::cam_image_dir(d.path / "ds") / frames[0].filename);
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
