// roe import mocap: real files into a dataset, the clock-offset estimator on simulated data, and
// overwrite protection.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <filesystem>
#include <fstream>
#include <random>

#include "support/test_util.hpp"
#include "roe/app/import.hpp"
#include "roe/calib/mocap_time_offset.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/trajectory_io.hpp"
#include "roe/math/so3.hpp"

namespace fs = std::filesystem;
using namespace roe;

namespace {
using roe::test::TempDir;


// A smooth rotation R(t) = Exp(a(t)) and its body angular rate Jr(a) ȧ.
Eigen::Vector3d a_of(double t) {
  return {0.8 * std::sin(0.9 * t) + 0.3 * std::sin(3.7 * t), 0.6 * std::sin(1.7 * t + 1.0),
          0.5 * std::sin(2.3 * t + 2.0) + 0.2 * std::sin(5.1 * t)};
}
Eigen::Vector3d adot_of(double t) {
  return {0.8 * 0.9 * std::cos(0.9 * t) + 0.3 * 3.7 * std::cos(3.7 * t), 0.6 * 1.7 * std::cos(1.7 * t + 1.0),
          0.5 * 2.3 * std::cos(2.3 * t + 2.0) + 0.2 * 5.1 * std::cos(5.1 * t)};
}

/// IMU at 200 Hz in an epoch clock, mocap at 120 Hz in its own clock with t_imu = t_mocap + offset.
/// `noise` scales the gyro (0.01 rad/s), mocap position (0.5 mm) and rotation (1 mrad) noise.
void simulate(double offset_s, std::vector<ImuSample>& imu, std::vector<StampedPose>& mocap, unsigned seed,
              double noise = 1.0) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gyro_noise(0.0, 0.01 * noise), pos_noise(0.0, 0.0005 * noise),
      rot_noise(0.0, 0.001 * noise);
  const Timestamp t_imu0 = 1'700'000'000'000'000'000LL;
  for (int k = 0; k < 200 * 30; ++k) {
    const double t = k / 200.0;
    ImuSample s;
    s.t_ns = t_imu0 + from_seconds(t);
    s.gyro = math::right_jacobian(a_of(t)) * adot_of(t) + Eigen::Vector3d(gyro_noise(rng), gyro_noise(rng), gyro_noise(rng));
    s.accel = Eigen::Vector3d(0, 0, 9.81);
    imu.push_back(s);
  }
  // Mocap clock starts near 0 (a Motive take); it covers IMU time [2 s, 27 s].
  for (int k = 0; k < 120 * 25; ++k) {
    const double t_m = 1.0 + k / 120.0;
    const double t_imu = t_m + offset_s - static_cast<double>(t_imu0) * 1e-9;  // relative IMU time
    Eigen::Vector3d noise(rot_noise(rng), rot_noise(rng), rot_noise(rng));
    const Eigen::Quaterniond q = math::exp_quat(a_of(t_imu)) * math::exp_quat(noise);
    mocap.push_back({from_seconds(t_m), Pose(q, Eigen::Vector3d(pos_noise(rng), 0, 0))});
  }
}

}  // namespace

TEST_CASE("estimate_mocap_time_offset recovers a known offset within one mocap frame", "[app][import][offset]") {
  for (double rel : {1.0, 1.4567, 0.6123}) {
    // Offset so that mocap time 1 s = IMU relative time `rel`.
    const double offset = 1'700'000'000.0 + rel - 1.0;
    std::vector<ImuSample> imu;
    std::vector<StampedPose> mocap;
    simulate(offset, imu, mocap, 7);
    const auto e = calib::estimate_mocap_time_offset(imu, mocap, 2.0);
    INFO("true " << rel - 1.0 << " estimated " << e.offset_s - 1'700'000'000.0);
    CHECK(std::abs(e.offset_s - offset) < 1.0 / 120.0);
    CHECK(std::abs(e.offset_s - offset) < 2e-3);  // in practice much better than a frame
    CHECK(e.correlation > 0.9);
    CHECK(e.peak_ratio > 1.0);
    CHECK_FALSE(e.peak_at_edge);
  }
  // Clocks that do not overlap are searched around the offset that lines up the first stamps
  // (1'699'999'999 s here, so `rel` is the true offset from it). A true offset 0.55 s from it, either
  // way, with a ±0.5 s search: the peak sits on that edge, flagged.
  for (double rel : {0.55, -0.55}) {
    const double offset = 1'700'000'000.0 + rel - 1.0;
    std::vector<ImuSample> imu;
    std::vector<StampedPose> mocap;
    simulate(offset, imu, mocap, 7);
    const auto e = calib::estimate_mocap_time_offset(imu, mocap, 0.5);
    CHECK(e.peak_at_edge);
    CHECK(std::abs(e.offset_s - (1'699'999'999.0 + (rel > 0.0 ? 0.5 : -0.5))) < 1e-6);
  }
  // Without noise the peak's parabolic refinement places it within a small fraction of the 5 ms grid.
  // The grid is laid from the streams' first stamps; dropping the first 1 or 2 mocap poses (8.33 ms
  // each) puts the true offset 3.33 or 1.67 ms off it, where the raw peak alone is that far off.
  for (int drop : {0, 1, 2}) {
    const double offset = 1'700'000'000.0 + 0.4567;
    std::vector<ImuSample> imu;
    std::vector<StampedPose> mocap;
    simulate(offset, imu, mocap, 7, 0.0);
    mocap.erase(mocap.begin(), mocap.begin() + drop);
    const auto e = calib::estimate_mocap_time_offset(imu, mocap, 2.0);
    REQUIRE(e.grid_dt_s == 0.005);
    CHECK(std::abs(e.offset_s - offset) < 0.3e-3);
  }
  // No rotation → a clear DataError.
  std::vector<ImuSample> imu(100);
  std::vector<StampedPose> mocap(100);
  for (int k = 0; k < 100; ++k) {
    imu[k].t_ns = k * 5'000'000LL;
    mocap[k].t_ns = k * 8'000'000LL;
  }
  CHECK_THROWS_AS(calib::estimate_mocap_time_offset(imu, mocap, 0.5), DataError);
}

TEST_CASE("import mocap --estimate-offset writes the offset into roe.json", "[app][import][offset]") {
  TempDir d;
  const double offset = 1'700'000'000.25;
  std::vector<ImuSample> imu;
  std::vector<StampedPose> mocap;
  simulate(offset, imu, mocap, 3);
  const fs::path ds = d.path / "ds";
  fs::create_directories(ds / "mav0/imu0");
  store::write_imu_csv(store::imu_csv_path(ds), imu);
  io::write_trajectory(d.path / "gt.tum", mocap, io::TrajectoryFormat::kTum);
  app::ImportMocapOptions o;
  o.estimate_offset = true;
  const auto s = app::import_mocap(d.path / "gt.tum", ds, o);
  CHECK(s.format == "tum");
  CHECK(s.created_manifest);
  REQUIRE(s.estimate);
  CHECK(std::abs(s.time_offset_s - offset) < 1.0 / 120.0);
  const auto m = store::read_manifest(ds);
  REQUIRE(m.mocap);
  CHECK(m.mocap->time_offset_s == s.time_offset_s);
  // Stamps stay in the mocap clock (the offset is applied by readers of roe.json).
  const auto written = store::read_mocap_csv(store::mocap_csv_path(ds));
  REQUIRE(written.size() == mocap.size());
  CHECK(written.front().t_ns == mocap.front().t_ns);
  CHECK(m.sources.at(0).options.at("time_offset_source") == "estimated");
  CHECK(s.warnings.empty());  // neither weak nor at the edge of the search
  CHECK(s.to_json().at("offset_estimate").at("peak_at_edge") == false);

  // --time-offset with --estimate-offset: the given offset centres a narrow search.
  o.time_offset_s = 1'700'000'000.2;
  o.max_offset_s = 0.1;
  o.force = true;
  const auto centred = app::import_mocap(d.path / "gt.tum", ds, o);
  REQUIRE(centred.estimate);
  CHECK(std::abs(centred.time_offset_s - offset) < 1.0 / 120.0);
  CHECK_FALSE(centred.estimate->peak_at_edge);
  CHECK(centred.warnings.empty());
  // The same with the given offset 0.3 s off: the peak is at the search's edge, and the summary says so
  o.time_offset_s = 1'700'000'000.55;
  const auto edge = app::import_mocap(d.path / "gt.tum", ds, o);
  REQUIRE(edge.estimate);
  CHECK(edge.estimate->peak_at_edge);
  CHECK(edge.time_offset_s == Approx(1'700'000'000.45).margin(1e-6));
  // ... and so far from the true peak the correlation is weak as well (0.46).
  REQUIRE(edge.warnings.size() == 2);
  CHECK(edge.warnings[0].find("time-offset estimate is weak") != std::string::npos);
  CHECK(edge.warnings[1].find("edge of the ±0.1 s search range; widen --max-offset") != std::string::npos);
  CHECK(edge.to_json().at("warnings").size() == 2);
}

TEST_CASE("import mocap: the real Motive file into a new dataset, then overwrite rules", "[app][import][shared]") {
  const fs::path f = fs::path(ROE_SHARED_DATA_DIR) / "mocap/sample_optitrack_take_v1.21.csv";
  if (!fs::exists(f)) {
    WARN("skipped: " << f << " absent");
    return;
  }
  TempDir d;
  const fs::path ds = d.path / "seq";
  app::ImportMocapOptions o;
  o.time_offset_s = 12.5;
  const auto s = app::import_mocap(f, ds, o);
  CHECK(s.format == "motive");
  CHECK(s.rows == 250);
  CHECK(s.poses == 250);
  CHECK(s.occluded == 0);
  CHECK(s.rate_hz == Approx(120));
  CHECK(s.up == "y");
  CHECK(s.created_manifest);
  const auto m = store::read_manifest(ds);
  CHECK(m.name == "seq");
  REQUIRE(m.mocap);
  CHECK(m.mocap->body == "Rigid Body 1");
  CHECK(m.mocap->time_offset_s == 12.5);
  REQUIRE(m.sources.size() == 1);
  CHECK(m.sources[0].kind == "motive-csv");
  CHECK(m.sources[0].sha256 == "1c1aa181bc1015bc782fe6577c1e437ada25e9fdb7ff4f3682ddd9d64b030280");
  const auto p = store::read_mocap_csv(store::mocap_csv_path(ds));
  REQUIRE(p.size() == 250);
  // Y-up → Z-up: (x, y, z)_Y = (0.060002, 0.019150, 0.076611) → (0.060002, −0.076611, 0.019150).
  CHECK(p[0].T.p.isApprox(Eigen::Vector3d(0.060002, -0.076611, 0.019150), 1e-9));
  // The body's rotation is expressed in the Z-up world: R_Z = R_x(+90°) R_Y.
  const Eigen::Quaterniond qY = Eigen::Quaterniond(-1.0, 0.000035, 0.000016, -0.000030).normalized();
  const Eigen::Quaterniond qZ = Eigen::Quaterniond(Eigen::AngleAxisd(3.14159265358979323846 / 2, Eigen::Vector3d::UnitX())) * qY;
  CHECK(math::angle_between(p[0].T.q, qZ) < 1e-9);
  // Refused without force; replaced with force (one source record for the folder).
  CHECK_THROWS_WITH(app::import_mocap(f, ds, {}), Catch::Contains("--force"));
  app::ImportMocapOptions forced;
  forced.force = true;
  forced.up = "z";
  app::import_mocap(f, ds, forced);
  const auto m2 = store::read_manifest(ds);
  CHECK(m2.sources.size() == 1);
  CHECK(store::read_mocap_csv(store::mocap_csv_path(ds))[0].T.p.isApprox(Eigen::Vector3d(0.060002, 0.019150, 0.076611), 1e-9));
}

TEST_CASE("import mocap: the evo bag's groundtruth topic and EuRoC/TUM-VI ground truth", "[app][import][shared]") {
  const fs::path b = fs::path(ROE_SHARED_DATA_DIR) / "rosbag/evo_ROS_example.bag";
  const fs::path g = fs::path(ROE_SHARED_DATA_DIR) / "tumvi/dataset-room1_512_16_gt.csv";
  if (!fs::exists(b) || !fs::exists(g)) {
    WARN("skipped: shared data absent");
    return;
  }
  TempDir d;
  app::ImportMocapOptions o;
  o.topic = "groundtruth";
  const auto s = app::import_mocap(b, d.path / "evo", o);
  CHECK(s.format == "rosbag");
  CHECK(s.poses == 12765);
  CHECK(store::read_mocap_csv(store::mocap_csv_path(d.path / "evo")).size() == 12765);
  CHECK(store::read_manifest(d.path / "evo").sources.at(0).kind == "ros1-bag");
  CHECK_THROWS_WITH(app::import_mocap(b, d.path / "evo2", {}), Catch::Contains("--topic") && Catch::Contains("groundtruth"));
  const auto t = app::import_mocap(g, d.path / "tumvi", {});
  CHECK(t.format == "euroc");
  // No rate in the file: the median interval's (8.333 ms; the mean, 8.53 ms, is stretched by a 1.06 s gap).
  CHECK(t.rate_hz == Approx(1e9 / 8'333'000).epsilon(1e-12));
  const auto p = store::read_mocap_csv(store::mocap_csv_path(d.path / "tumvi"));
  REQUIRE_FALSE(p.empty());
  CHECK(p[0].t_ns == 1520530308189679351LL);
  CHECK(p[0].T.p.isApprox(Eigen::Vector3d(0.8417820384, -0.2193354118, 1.2499749141), 1e-12));
  // cnspy CSV (t,tx,ty,tz,qx,qy,qz,qw; 12590 rows of which 590 repeat the previous stamp).
  const fs::path c = fs::path(ROE_SHARED_DATA_DIR) / "cnspy/ID1-pose-gt.csv";
  if (fs::exists(c)) {
    const auto cs = app::import_mocap(c, d.path / "cnspy", {});
    CHECK(cs.format == "csv");
    CHECK(cs.rows == 12590);
    CHECK(cs.duplicates == 590);
    CHECK(cs.poses == 12000);
    const auto cp = store::read_mocap_csv(store::mocap_csv_path(d.path / "cnspy"));
    CHECK(cp[0].t_ns == 5'000'000);
    CHECK(cp[0].T.p.isApprox(Eigen::Vector3d(-0.000693000000000055, 0.00131999999999999, 0.000394999999999923), 1e-15));
  }
}

TEST_CASE("import mocap: format detection (Vicon, Motive) and occlusion counts", "[app][import]") {
  TempDir d;
  const fs::path v = d.path / "tracker.csv";
  std::ofstream(v) << "Objects\n100\n,,Global Angle cam:cam,,,,,\n"
                      "Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ\n,,rad,rad,rad,mm,mm,mm\n"
                      "1,0,0,0,0,1000,0,0\n2,0,,,,,,\n3,0,0,0,0.1,1000,10,0\n";
  const auto s = app::import_mocap(v, d.path / "ds", {});
  CHECK(s.format == "vicon");
  CHECK(s.body == "cam");
  CHECK(s.rows == 3);
  CHECK(s.occluded == 1);
  CHECK(s.poses == 2);
  CHECK(s.up == "z");
  const auto p = store::read_mocap_csv(store::mocap_csv_path(d.path / "ds"));
  REQUIRE(p.size() == 2);
  CHECK(p[1].t_ns == 20'000'000);
  CHECK(p[1].T.p.isApprox(Eigen::Vector3d(1.0, 0.01, 0.0), 1e-12));
  const auto m = store::read_manifest(d.path / "ds");
  CHECK(m.sources.at(0).kind == "vicon-csv");
  CHECK(m.sources.at(0).options.at("occluded") == "1");
  // Every frame occluded → nothing to import is bad input.
  const fs::path all = d.path / "all.csv";
  std::ofstream(all) << "Objects\n100\n,,Global Angle cam:cam,,,,,\n"
                        "Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ\n,,rad,rad,rad,mm,mm,mm\n1,0,,,,,,\n";
  CHECK_THROWS_WITH(app::import_mocap(all, d.path / "ds2", {}), Catch::Contains("occluded"));
}

TEST_CASE("import mocap: --time-offset and --max-offset are checked before anything is written", "[app][import]") {
  TempDir d;
  const fs::path v = d.path / "tracker.csv";
  std::ofstream(v) << "Objects\n100\n,,Global Angle cam:cam,,,,,\n"
                      "Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ\n,,rad,rad,rad,mm,mm,mm\n"
                      "1,0,0,0,0,1000,0,0\n2,0,0,0,0,1000,0,0\n";
  for (double bad : {std::nan(""), 1e300, -4.1e9, std::numeric_limits<double>::infinity()}) {
    INFO(bad);
    app::ImportMocapOptions o;
    o.time_offset_s = bad;
    CHECK_THROWS_WITH(app::import_mocap(v, d.path / "ds", o), Catch::Contains("--time-offset must be a finite"));
    CHECK_FALSE(fs::exists(d.path / "ds"));
  }
  for (double bad : {0.0, -1.0, 61.0, std::nan("")}) {
    INFO(bad);
    app::ImportMocapOptions o;
    o.max_offset_s = bad;
    CHECK_THROWS_WITH(app::import_mocap(v, d.path / "ds", o), Catch::Contains("--max-offset must be in (0, 60]"));
    CHECK_FALSE(fs::exists(d.path / "ds"));
  }
  // A relative take clock moved onto epoch time is fine.
  app::ImportMocapOptions o;
  o.time_offset_s = 1.7e9;
  const auto s = app::import_mocap(v, d.path / "ds", o);
  CHECK(s.time_offset_s == 1.7e9);
  CHECK(store::read_manifest(d.path / "ds").mocap->time_offset_s == 1.7e9);
}

TEST_CASE("import mocap: --name cannot land on another stream, T_B_I follows its body, Motive's start time is kept",
          "[app][import]") {
  TempDir d;
  const fs::path v = d.path / "tracker.csv";
  std::ofstream(v) << "Objects\n100\n,,Global Angle cam:cam,,,,,,Global Angle obj:obj,,,,,\n"
                      "Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ,RX,RY,RZ,TX,TY,TZ\n,,rad,rad,rad,mm,mm,mm,rad,rad,rad,mm,mm,mm\n"
                      "1,0,0,0,0,1000,0,0,0,0,0,0,0,0\n2,0,0,0,0,1000,0,0,0,0,0,0,0,0\n";
  const fs::path ds = d.path / "ds";
  for (const char* bad : {"imu0", "cam0", "state_groundtruth_estimate0", "mocap/../imu0", "mocap 1", "..", ""}) {
    INFO(bad);
    app::ImportMocapOptions o;
    o.body = "cam";
    o.mocap_name = bad;
    o.force = true;
    CHECK_THROWS_WITH(app::import_mocap(v, ds, o), Catch::Contains("must start with \"mocap\""));
    CHECK_FALSE(fs::exists(ds));
  }
  app::ImportMocapOptions o;
  o.body = "obj";
  o.mocap_name = "mocap_box-1";
  CHECK(app::import_mocap(v, ds, o).poses == 2);
  CHECK_FALSE(store::read_manifest(ds).mocap);  // only mocap0 fills the mocap section

  // mocap0 of body "cam" with a hand-set T_B_I; a forced re-import of the same body keeps it ...
  o.mocap_name = "mocap0";
  o.body = "cam";
  app::import_mocap(v, ds, o);
  auto m = store::read_manifest(ds);
  m.mocap->T_B_I = Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.1, 0, 0));
  store::write_manifest(m, store::manifest_path(ds));
  o.force = true;
  CHECK(app::import_mocap(v, ds, o).warnings.empty());
  CHECK(store::read_manifest(ds).mocap->T_B_I.p.x() == 0.1);
  // ... one of another body resets it, with a warning.
  o.body = "obj";
  const auto s = app::import_mocap(v, ds, o);
  REQUIRE(s.warnings.size() == 1);
  CHECK_THAT(s.warnings[0], Catch::Contains("T_B_I is reset to identity"));
  CHECK(store::read_manifest(ds).mocap->body == "obj");
  CHECK(store::read_manifest(ds).mocap->T_B_I.p.isZero());

  // Motive's "Capture Start Time" is recorded with the import.
  const fs::path f = fs::path(ROE_SHARED_DATA_DIR) / "mocap/sample_optitrack_take_v1.21.csv";
  if (fs::exists(f)) {
    app::import_mocap(f, d.path / "motive", {});
    const auto mm = store::read_manifest(d.path / "motive");
    CHECK(mm.sources.at(0).options.at("capture_start_time") == "2016-01-05 03.49.50.755 PM");
  }
}

TEST_CASE("import mocap --estimate-offset without an IMU says what it needs and the ways on", "[app][import][offset]") {
  TempDir d;
  std::vector<ImuSample> imu;
  std::vector<StampedPose> mocap;
  simulate(0.5, imu, mocap, 4);
  io::write_trajectory(d.path / "gt.tum", mocap, io::TrajectoryFormat::kTum);
  app::ImportMocapOptions o;
  o.estimate_offset = true;
  CHECK_THROWS_WITH(app::import_mocap(d.path / "gt.tum", d.path / "ds", o),
                    Catch::Contains("correlates the mocap's angular rate with the gyro") &&
                        Catch::Contains("--time-offset S") && Catch::Contains("roe import realsense"));
  CHECK_FALSE(fs::exists(d.path / "ds"));
}
