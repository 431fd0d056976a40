// roe import kalibr: T_cam_imu → T_I_C (inverse), time shift, intrinsics, IMU noise, validation.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <random>

#include "support/test_util.hpp"
#include "roe/app/import.hpp"
#include "roe/store/dataset.hpp"
#include "roe/math/so3.hpp"

namespace fs = std::filesystem;
using namespace roe;

namespace {
using roe::test::TempDir;


// A Kalibr camchain as Kalibr writes it (camera rotated so that z_C = x_I, x_C = −y_I, y_C = −z_I).
const char* kCamchain = R"(cam0:
  T_cam_imu:
  - [0.0, -1.0, 0.0, 0.02]
  - [0.0, 0.0, -1.0, 0.01]
  - [1.0, 0.0, 0.0, -0.03]
  - [0.0, 0.0, 0.0, 1.0]
  cam_overlaps: []
  camera_model: pinhole
  distortion_coeffs: [0.01, -0.02, 0.001, 0.002]
  distortion_model: radtan
  intrinsics: [612.0, 611.0, 320.5, 240.5]
  resolution: [640, 480]
  rostopic: /cam0/image_raw
  timeshift_cam_imu: 0.0042
)";

const char* kImu = R"(accelerometer_noise_density: 0.002
accelerometer_random_walk: 0.0003
gyroscope_noise_density: 0.00016
gyroscope_random_walk: 0.000019
rostopic: /imu0
update_rate: 200.0
)";

std::string replace(std::string s, const std::string& a, const std::string& b) {
  const auto p = s.find(a);
  REQUIRE(p != std::string::npos);
  return s.replace(p, a.size(), b);
}

// A dataset folder whose roe.json has an undistorted pinhole camera of the given size.
fs::path dataset_with_camera(const TempDir& d, int width, int height, double f) {
  const fs::path ds = d.path / "ds";
  fs::create_directories(ds);
  DatasetManifest m;
  m.name = "x";
  CameraInfo c;
  c.width = width;
  c.height = height;
  c.fx = c.fy = f;
  c.cx = width / 2.0;
  c.cy = height / 2.0;
  m.camera = c;  // distortion_model "none": undistorted images
  store::write_manifest(m, store::manifest_path(ds));
  return ds;
}

}  // namespace

TEST_CASE("import kalibr: T_I_C is the inverse of T_cam_imu, noise and time shift", "[app][import][kalibr]") {
  TempDir d;
  const fs::path ds = d.path / "ds";
  const auto s = app::import_kalibr(d.write("cc.yaml", kCamchain), d.write("imu.yaml", kImu), ds, {});
  const auto m = store::read_manifest(ds);
  REQUIRE(m.camera);
  Eigen::Matrix3d R_C_I;
  R_C_I << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  const Eigen::Vector3d p_C_I(0.02, 0.01, -0.03);
  // x_I = R_C_Iᵀ (x_C − p_C_I)
  CHECK(m.camera->T_I_C.R().isApprox(R_C_I.transpose(), 1e-12));
  CHECK(m.camera->T_I_C.p.isApprox(-R_C_I.transpose() * p_C_I, 1e-12));
  CHECK(m.camera->T_I_C.p.isApprox(Eigen::Vector3d(0.03, 0.02, 0.01), 1e-12));
  CHECK(m.camera->time_offset_s == 0.0042);
  CHECK(m.camera->fx == 612.0);
  CHECK(m.camera->cy == 240.5);
  CHECK(m.camera->distortion_model == "radtan");
  CHECK(m.camera->distortion == std::vector<double>{0.01, -0.02, 0.001, 0.002});
  REQUIRE(m.imu);
  CHECK(m.imu->noise.gyro_noise_density == 0.00016);
  CHECK(m.imu->noise.accel_random_walk == 0.0003);
  CHECK(m.imu->rate_hz == 200.0);
  CHECK(s.created_manifest);
  CHECK(m.sources.size() == 2);
  CHECK(fs::exists(ds / "calib/camchain-imucam.yaml"));
  CHECK(fs::exists(ds / "calib/imu.yaml"));
  // Refused again without force; accepted with it (records replaced, not duplicated).
  CHECK_THROWS_WITH(app::import_kalibr(d.path / "cc.yaml", d.path / "imu.yaml", ds, {}), Catch::Contains("--force"));
  app::ImportKalibrOptions f;
  f.force = true;
  app::import_kalibr(d.path / "cc.yaml", d.path / "imu.yaml", ds, f);
  CHECK(store::read_manifest(ds).sources.size() == 2);
  // Re-importing only the camchain keeps the IMU noise, calib/imu.yaml and their source record.
  app::import_kalibr(d.path / "cc.yaml", std::nullopt, ds, f);
  const auto again = store::read_manifest(ds);
  REQUIRE(again.sources.size() == 2);
  CHECK(again.sources[0].kind == "kalibr-imu");
  CHECK(again.sources[1].kind == "kalibr-camchain");
  CHECK(again.imu->noise.gyro_noise_density == 0.00016);
  CHECK(fs::exists(ds / "calib/imu.yaml"));
  // Sources are recorded with absolute paths, whatever folder the import ran from.
  for (const auto& src : again.sources) CHECK(fs::path(src.path).is_absolute());
  CHECK(again.sources[1].path == fs::weakly_canonical(d.path / "cc.yaml").string());
}

TEST_CASE("import kalibr: a dataset with other image sizes keeps its intrinsics", "[app][import][kalibr]") {
  TempDir d;
  const fs::path ds = dataset_with_camera(d, 1280, 720, 900);
  const auto s = app::import_kalibr(d.write("cc.yaml", kCamchain), std::nullopt, ds, {});
  CHECK_FALSE(s.intrinsics_written);
  CHECK_FALSE(s.warnings.empty());
  const auto back = store::read_manifest(ds);
  CHECK(back.camera->fx == 900);
  CHECK(back.camera->T_I_C.p.isApprox(Eigen::Vector3d(0.03, 0.02, 0.01), 1e-12));
  CHECK_FALSE(s.created_manifest);
}

TEST_CASE("import kalibr: imu.yaml's update_rate against the dataset's IMU rate", "[app][import][kalibr]") {
  // A dataset whose IMU runs at `rate`; imu.yaml says 200 Hz. Within 5 %: quiet; beyond: a warning, the
  // dataset's rate kept. Its noise densities are taken either way.
  const auto import_into = [](double rate) {
    TempDir d;
    const fs::path ds = d.path / "ds";
    fs::create_directories(ds);
    DatasetManifest m;
    m.name = "x";
    m.imu = ImuInfo{rate, {}};
    store::write_manifest(m, store::manifest_path(ds));
    const auto s = app::import_kalibr(d.write("cc.yaml", kCamchain), d.write("imu.yaml", kImu), ds, {});
    const auto back = store::read_manifest(ds);
    CHECK(back.imu->rate_hz == rate);
    CHECK(back.imu->noise.gyro_noise_density == 0.00016);
    return s.warnings;
  };
  CHECK(import_into(200.0).empty());
  CHECK(import_into(205.0).empty());
  const auto w = import_into(400.0);
  REQUIRE(w.size() == 1);
  CHECK(w[0] == "imu.yaml update_rate 200 Hz differs from the dataset's IMU rate 400 Hz (kept)");
  CHECK(import_into(189.0).size() == 1);
}

TEST_CASE("import kalibr: invalid files are InputErrors naming file, line and key", "[app][import][kalibr]") {
  TempDir d;
  const fs::path ds = d.path / "ds";
  auto fails = [&](const std::string& text, const std::string& what) {
    INFO(what);
    CHECK_THROWS_WITH(app::read_kalibr_camchain(d.write("bad.yaml", text)), Catch::Contains("bad.yaml") && Catch::Contains(what));
  };
  fails(replace(kCamchain, "[1.0, 0.0, 0.0, -0.03]", "[1.1, 0.0, 0.0, -0.03]"), "not orthonormal");
  fails(replace(kCamchain, "[0.0, -1.0, 0.0, 0.02]", "[0.0, 1.0, 0.0, 0.02]"), "not orthonormal");  // det −1
  fails(replace(kCamchain, "[0.0, 0.0, 0.0, 1.0]", "[0.0, 0.0, 0.1, 1.0]"), "bottom row");
  fails(replace(kCamchain, "  intrinsics: [612.0, 611.0, 320.5, 240.5]\n", ""), "missing required key");
  fails(replace(kCamchain, "[612.0, 611.0, 320.5, 240.5]", "[612.0, 611.0, 320.5]"), "need 4 values");
  fails(replace(kCamchain, "[612.0, 611.0", "[-612.0, 611.0"), "focal");
  fails(replace(kCamchain, "611.0, 320.5", "-611.0, 320.5"), "focal");  // f_v
  // omni: [xi, fu, fv, pu, pv]; the focal lengths are the 2nd and 3rd value.
  const std::string omni = replace(replace(kCamchain, "pinhole", "omni"), "[612.0, 611.0", "[0.9, 612.0, 611.0");
  CHECK_NOTHROW(app::read_kalibr_camchain(d.write("omni.yaml", omni)));
  // A key twice in one mapping (PyYAML would keep the last, yaml-cpp the first): refused, naming both lines.
  std::string dup = kCamchain;
  dup += "  intrinsics: [1.0, 2.0, 3.0, 4.0]\n";
  CHECK_THROWS_WITH(app::read_kalibr_camchain(d.write("dup.yaml", dup)),
                    Catch::Contains("dup.yaml:15:3") && Catch::Contains("\"intrinsics\" appears twice") &&
                        Catch::Contains("first at line 11"));
  fails(replace(omni, "612.0, 611.0", "612.0, -611.0"), "focal");
  fails(replace(omni, "[0.9, 612.0", "[0.9, -612.0"), "focal");
  fails(replace(kCamchain, "radtan", "kannala"), "unknown distortion_model");
  fails(replace(kCamchain, "0.0042", "soon"), "expected a number");
  fails(replace(kCamchain, "cam0:", "cam1:"), "no camera");
  fails("cam0: [unclosed", "YAML syntax error");
  CHECK_THROWS_WITH(app::read_kalibr_imu(d.write("i.yaml", replace(kImu, "0.00016", "-0.00016"))),
                    Catch::Contains("i.yaml:3:26:") && Catch::Contains("must be > 0"));  // the value's line:column
  CHECK_THROWS_WITH(app::read_kalibr_imu(d.write("i.yaml", replace(kImu, "gyroscope_random_walk: 0.000019\n", ""))),
                    Catch::Contains("gyroscope_random_walk"));
  // Nothing is written when validation fails.
  CHECK_THROWS_AS(app::import_kalibr(d.write("cc.yaml", replace(kCamchain, "[1.0, 0.0, 0.0, -0.03]", "[2.0, 0.0, 0.0, -0.03]")),
                                     std::nullopt, ds, {}),
                  InputError);
  CHECK_FALSE(fs::exists(ds));
}

TEST_CASE("import kalibr onto undistorted images keeps their model and intrinsics, and warns, all-zero "
          "coefficients are imported as they are",
          "[app][import][kalibr]") {
  const auto import_with = [](const std::string& coeffs, DatasetManifest& after) {
    TempDir d;
    const fs::path ds = dataset_with_camera(d, 640, 480, 600);
    std::string cc = kCamchain;
    cc.replace(cc.find("[0.01, -0.02, 0.001, 0.002]"), 27, coeffs);
    const auto s = app::import_kalibr(d.write("cc.yaml", cc), std::nullopt, ds, {});
    after = store::read_manifest(ds);
    return s;
  };
  DatasetManifest m;
  const auto s = import_with("[0.01, -0.02, 0.001, 0.002]", m);
  REQUIRE(s.warnings.size() == 1);
  CHECK_THAT(s.warnings[0], Catch::StartsWith("the dataset's images are already undistorted"));
  CHECK_FALSE(s.intrinsics_written);
  REQUIRE(m.camera);
  CHECK(m.camera->distortion_model == "none");  // never the raw camera's radtan over undistorted images
  CHECK(m.camera->distortion.empty());
  CHECK(m.camera->fx == 600.0);                           // the processed images' intrinsics
  CHECK(m.camera->T_I_C.p.isApprox(Eigen::Vector3d(0.03, 0.02, 0.01), 1e-12));  // the extrinsics are imported
  CHECK(m.camera->time_offset_s == 0.0042);
  const auto zero = import_with("[0.0, 0.0, 0.0, 0.0]", m);
  CHECK(zero.warnings.empty());
  CHECK(zero.intrinsics_written);
  CHECK(m.camera->fx == 612.0);
}

TEST_CASE("import kalibr imu.yaml alone says it is an imu.yaml and what to pass", "[app][import][kalibr]") {
  TempDir d;
  const fs::path imu = d.write("imu.yaml", kImu);
  CHECK_THROWS_WITH(app::import_kalibr(imu, std::nullopt, d.path / "ds", {}),
                    Catch::Contains("this is a Kalibr imu.yaml, not a camchain") &&
                        Catch::Contains("camchain-imucam.yaml imu.yaml --into"));
  CHECK_FALSE(fs::exists(d.path / "ds"));
}
