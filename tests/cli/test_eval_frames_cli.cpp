// roe eval on the real files of ../shared/data (issue 50): KITTI's devkit drift against a devkit-style
// computation written here, --save_results of an RPE against evo's own zip (Python's zipfile + NumPy),
// --t-offset auto / --gt-body-pose / --t_start from the command line, OpenVINS's ground-truth header and
// TUM-VI's download layout for eval and `simulate --from-groundtruth`, --plot without --out. Skipped when
// ../shared/data is absent.
#include "support/test_util.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "roe/io/input.hpp"
#include "roe/io/output.hpp"

namespace fs = std::filesystem;

namespace {

const fs::path kData = fs::path(ROE_SHARED_DATA_DIR);

nlohmann::json report(const std::string& args) {
  const auto r = roe::test::run_roe("--json eval " + args, false);
  INFO("roe --json eval " << args << "\n" << r.out);
  REQUIRE(r.code == 0);
  return nlohmann::json::parse(r.out);
}

/// A KITTI pose file as 4x4 matrices (the devkit's loadPoses).
std::vector<Eigen::Matrix4d> load_kitti(const fs::path& f) {
  std::ifstream in(f);
  std::vector<Eigen::Matrix4d> out;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ss(line);
    Eigen::Matrix4d P = Eigen::Matrix4d::Identity();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) ss >> P(r, c);
    if (ss) out.push_back(P);
  }
  return out;
}

/// The devkit's evaluate_odometry.cpp rule, written out here (not roe's code): every 10th frame, lengths
/// 100..800, last frame = first whose path exceeds the start's by the length, errors averaged over all
/// segments; t_err in %, r_err in deg per 100 m.
std::pair<double, double> devkit(const std::vector<Eigen::Matrix4d>& gt, const std::vector<Eigen::Matrix4d>& est) {
  std::vector<double> dist(1, 0.0);
  for (std::size_t i = 1; i < gt.size(); ++i)
    dist.push_back(dist.back() + (gt[i].block<3, 1>(0, 3) - gt[i - 1].block<3, 1>(0, 3)).norm());
  double t = 0, r = 0;
  int n = 0;
  for (std::size_t first = 0; first < gt.size(); first += 10)
    for (double len = 100; len <= 800; len += 100) {
      long last = -1;
      for (std::size_t i = first; i < dist.size(); ++i)
        if (dist[i] > dist[first] + len) {
          last = static_cast<long>(i);
          break;
        }
      if (last < 0) continue;
      const Eigen::Matrix4d dg = gt[first].inverse() * gt[static_cast<std::size_t>(last)];
      const Eigen::Matrix4d de = est[first].inverse() * est[static_cast<std::size_t>(last)];
      const Eigen::Matrix4d E = de.inverse() * dg;
      const double d = std::max(std::min(0.5 * (E(0, 0) + E(1, 1) + E(2, 2) - 1.0), 1.0), -1.0);
      r += std::acos(d) / len;
      t += E.block<3, 1>(0, 3).norm() / len;
      ++n;
    }
  return {100.0 * t / n, r / n * 180.0 / M_PI * 100.0};
}

bool python_numpy() { return roe::test::run_shell("/usr/bin/python3 -c 'import numpy'").code == 0; }

}  // namespace

TEST_CASE("roe eval --kitti equals a devkit-style computation on KITTI 00 S-PTAM", "[cli][eval][kitti][real]") {
  const fs::path gt = kData / "evo_results/KITTI_00_gt.txt", est = kData / "evo_results/KITTI_00_SPTAM.txt";
  if (!fs::exists(gt)) {
    WARN("skipped: " << gt << " is absent");
    return;
  }
  const auto [t_ref, r_ref] = devkit(load_kitti(gt), load_kitti(est));
  const auto rep = report("kitti " + gt.string() + " " + est.string() + " --kitti --no-out");
  INFO("devkit t " << t_ref << " % r " << r_ref << " deg/100m; roe " << rep["kitti"].dump());
  CHECK(std::abs(rep["kitti"]["t_rel_pct"].get<double>() - t_ref) < 0.01);
  CHECK(std::abs(rep["kitti"]["r_rel_deg_per_100m"].get<double>() - r_ref) < 0.01);
  CHECK(rep["kitti"]["per_length"].size() == 8);
  // The default SE(3) alignment does not change it (relative motions), a Sim(3) scale would.
  const auto none = report("kitti " + gt.string() + " " + est.string() + " --kitti --align none --no-out");
  CHECK(none["kitti"]["t_rel_pct"].get<double>() == Approx(rep["kitti"]["t_rel_pct"].get<double>()).epsilon(1e-9));
}

TEST_CASE("roe eval --save_results with --rpe-delta writes evo's RPE zip, equal to evo's own", "[cli][eval][evo][real]") {
  const fs::path gt = kData / "evo_results/KITTI_00_gt.txt", est = kData / "evo_results/KITTI_00_SPTAM.txt";
  const fs::path evo_zip = kData / "evo_results/sptam_rpe.zip";
  if (!fs::exists(evo_zip) || !python_numpy()) {
    WARN("skipped: ../shared/data/evo_results or /usr/bin/python3 with numpy absent");
    return;
  }
  roe::test::TempDir tmp("roe_test_rpe_zip");
  const fs::path zip = tmp.path / "sptam_rpe.zip";
  // evo_rpe kitti GT EST --delta 10 --delta_unit m --save_results (not aligned), as the zip's title says.
  const auto rep = report("kitti " + gt.string() + " " + est.string() +
                          " --align none --delta 10 --delta_unit m --no-out --save_results " + zip.string());
  const std::string script = std::string(ROE_SOURCE_DIR) + "/tests/fixtures/evo/compare_evo_zips.py";
  const auto py = roe::test::run_shell("/usr/bin/python3 " + script + " " + zip.string() + " " + evo_zip.string());
  INFO(py.out);
  REQUIRE(py.code == 0);
  const auto j = nlohmann::json::parse(py.out);
  CHECK(j["members_a"] == j["members_b"]);  // info.json, stats.json, error_array
  CHECK(j["info_a"]["title"] == j["info_b"]["title"]);
  CHECK(j["info_a"]["label"] == j["info_b"]["label"]);
  // KITTI files hold the rotations to ~6 digits (|RᵀR − I| ~ 1e-6); evo computes with those matrices as read,
  // roe with the nearest rotation (a unit quaternion): the 10 m relative translations differ by ~1e-6 m.
  for (const auto& [k, d] : j["stats_max_rel_diff"].items()) {
    INFO(k);
    REQUIRE_FALSE(d.is_null());
    CHECK(d.get<double>() < 1e-4);
  }
  CHECK(j["stats_max_rel_diff"]["rmse"].get<double>() < 1e-6);
  CHECK(j["arrays"]["error_array"]["n_a"] == j["arrays"]["error_array"]["n_b"]);
  CHECK(j["arrays"]["error_array"]["max_abs_diff"].get<double>() < 1e-5);
  CHECK(rep["evo_results"] == zip.string());
  // Two deltas cannot go into one evo file.
  const auto two = roe::test::run_roe("eval kitti " + gt.string() + " " + est.string() +
                                          " --delta 10,20 --no-out --save_results " + (tmp.path / "two.zip").string(),
                                      true);
  CHECK(two.code == 2);
  CHECK_FALSE(fs::exists(tmp.path / "two.zip"));
}

TEST_CASE("eval from the command line: --t-offset auto, --gt-body-pose, --t_start/--t_end", "[cli][eval][real]") {
  const fs::path gt = kData / "eval/V102_groundtruth.csv", est = kData / "eval/V102.txt";
  if (!fs::exists(est)) {
    WARN("skipped: " << est << " is absent");
    return;
  }
  const auto clean = report(est.string() + " --gt " + gt.string() + " --no-out");
  const auto autoo = report(est.string() + " --gt " + gt.string() + " --t-offset auto --no-out");
  CHECK(std::abs(autoo["time_offset"]["offset_s"].get<double>()) < 0.005);
  CHECK(autoo["time_offset"]["sigma_s"].get<double>() > 0);
  CHECK(autoo["association"]["offset_s"] == autoo["time_offset"]["offset_s"]);
  CHECK(roe::test::run_roe("eval " + est.string() + " --gt " + gt.string() + " --t-offset soon --no-out", true).code == 2);
  // The identity body pose changes nothing; a known one is echoed.
  const auto ident = report(est.string() + " --gt " + gt.string() + " --gt-body-pose 0,0,0,0,0,0,1 --no-out");
  CHECK(ident["ape_trans_m"]["rmse"] == clean["ape_trans_m"]["rmse"]);
  CHECK(ident["body_pose"]["source"] == "given");
  CHECK(roe::test::run_roe("eval " + est.string() + " --gt " + gt.string() + " --gt-body-pose 0,0,0,1 --no-out", true).code == 2);
  // evo's --t_start / --t_end spellings.
  // V102.txt spans 1403715529.11 .. 1403715609.31 s.
  const auto crop =
      report(est.string() + " --gt " + gt.string() + " --t_start 1403715540.5 --t_end 1403715570 --no-out");
  CHECK(crop["association"]["n_matched"].get<int>() < clean["association"]["n_matched"].get<int>());
  CHECK(crop["window"]["n_cropped"].get<int>() + crop["association"]["n_matched"].get<int>() ==
        clean["association"]["n_matched"].get<int>());
  CHECK(clean["alignment"].contains("tilt_deg"));
}

TEST_CASE("OpenVINS's ground-truth header is read by eval and by simulate --from-groundtruth", "[cli][eval][formats]") {
  const fs::path src = kData / "euroc_v102_snippet/mav0";
  if (!fs::exists(src)) {
    WARN("skipped: " << src << " is absent");
    return;
  }
  roe::test::TempDir tmp("roe_test_openvins_gt");
  // The real EuRoC ground truth with OpenVINS's header line (vicon2gt / ov_eval), the rows unchanged.
  const std::string text = roe::io::read_file(src / "state_groundtruth_estimate0/data.csv");
  const std::string rows = text.substr(text.find('\n') + 1);
  const fs::path mav0 = tmp.path / "ov/mav0";
  fs::create_directories(mav0 / "state_groundtruth_estimate0");
  fs::create_directories(mav0 / "imu0");
  roe::io::write_file_atomic(mav0 / "state_groundtruth_estimate0/data.csv",
                             "#time(ns),px,py,pz,qw,qx,qy,qz,vx,vy,vz,bwx,bwy,bwz,bax,bay,baz\n" + rows);
  fs::copy_file(src / "imu0/data.csv", mav0 / "imu0/data.csv");
  const fs::path orig = src / "state_groundtruth_estimate0/data.csv";
  const fs::path ov = mav0 / "state_groundtruth_estimate0/data.csv";
  // As ground truth and as an estimate against the original: identical poses.
  const auto r = report(ov.string() + " --gt " + orig.string() + " --gt-format euroc --no-out");
  CHECK(r["ape_trans_m"]["rmse"].get<double>() < 1e-9);
  CHECK(r["association"]["n_matched"].get<int>() > 3000);
  const auto s = roe::test::run_roe("--json simulate --from-groundtruth " + (tmp.path / "ov").string() + " --out " +
                                        (tmp.path / "sim").string() + " --seed 1",
                                    false);
  INFO(s.out);
  CHECK(s.code == 0);
}

TEST_CASE("a TUM-VI download (IMU and mocap files side by side) is read by simulate --from-groundtruth", "[cli][formats]") {
  const fs::path dir = kData / "tumvi";
  if (!fs::exists(dir / "dataset-room1_512_imu.txt")) {
    WARN("skipped: " << dir << " is absent");
    return;
  }
  roe::test::TempDir tmp("roe_test_tumvi_layout");
  const auto s = roe::test::run_roe("--json simulate --from-groundtruth " + dir.string() + " --out " +
                                        (tmp.path / "sim").string() + " --seed 2",
                                    false);
  INFO(s.out);
  REQUIRE(s.code == 0);
  CHECK(fs::exists(tmp.path / "sim/mav0/imu0/data.csv"));
  // The provenance names the two files it read.
  const std::string manifest = roe::io::read_file(tmp.path / "sim/roe.json");
  CHECK_THAT(manifest, Catch::Contains("dataset-room1_512_16_gt.csv"));
  CHECK_THAT(manifest, Catch::Contains("dataset-room1_512_imu.txt"));
  // A folder with two IMU files is refused naming what it found.
  fs::create_directories(tmp.path / "two");
  fs::copy_file(dir / "dataset-room1_512_imu.txt", tmp.path / "two/a.txt");
  fs::copy_file(dir / "dataset-room1_512_imu.txt", tmp.path / "two/b.txt");
  const auto bad = roe::test::run_roe("simulate --from-groundtruth " + (tmp.path / "two").string() + " --out " +
                                          (tmp.path / "sim2").string(),
                                      true);
  CHECK(bad.code == 2);
  CHECK_THAT(bad.out, Catch::Contains("found 2 IMU and 0 ground-truth files"));
}

TEST_CASE("roe eval --summary reads evo's own APE and RPE zips: one row per estimator, evo_res's statistics", "[cli][eval][evo][real]") {
  const fs::path ape = kData / "evo_results/sptam_ape.zip", rpe = kData / "evo_results/sptam_rpe.zip";
  if (!fs::exists(ape)) {
    WARN("skipped: " << ape << " is absent");
    return;
  }
  const auto r = roe::test::run_roe("--json eval --summary " + ape.string() + " " + rpe.string(), false);
  INFO(r.out);
  REQUIRE(r.code == 0);
  const auto s = nlohmann::json::parse(r.out);
  REQUIRE(s["runs"].size() == 1);  // one estimator: the two files make one row
  const auto& row = s["runs"][0];
  CHECK(row["label"] == "KITTI_00_SPTAM");
  CHECK(row["ate_rmse_m"].get<double>() == 3.738487907582613);
  CHECK(row["rpe_10m_trans_rmse_m"].get<double>() == 0.27607109043606004);
  CHECK(row["rpe_10m_rot_rmse_deg"].is_null());
  REQUIRE(row["results"].size() == 2);
  CHECK(row["results"][0]["stats"]["median"].get<double>() == 3.6425846417432637);
  CHECK(row["results"][1]["stats"]["max"].get<double>() == 1.2065944255781629);
  CHECK(s["mean"].is_null());  // one row per group: nothing to average
  CHECK(s["warnings"].empty());
  CHECK(row["alignment"] == "se3 (sptam_ape.zip), none (sptam_rpe.zip)");  // the APE aligned, the RPE not
  // Two estimators: each its own group, never one mean.
  roe::test::TempDir tmp("roe_test_summary_groups");
  const fs::path gt = kData / "evo_results/KITTI_00_gt.txt", est = kData / "evo_results/KITTI_00_SPTAM.txt";
  const fs::path a = tmp.path / "a", b = tmp.path / "b";
  REQUIRE(roe::test::run_roe("eval kitti " + gt.string() + " " + est.string() + " --label one --out " + a.string()).code == 0);
  REQUIRE(roe::test::run_roe("eval kitti " + gt.string() + " " + est.string() + " --label two --out " + b.string()).code == 0);
  const auto m = nlohmann::json::parse(
      roe::test::run_roe("--json eval --summary " + ape.string() + " " + a.string() + " " + b.string(), false).out);
  CHECK(m["groups"].size() == 1);  // the two roe reports; evo's S-PTAM row stands alone
  CHECK(m["groups"][0]["group"] == "roe");
  CHECK(m["groups"][0]["mean"]["ate_rmse_m"].get<double>() == Approx(3.738487907582613).epsilon(1e-9));
  CHECK_THAT(m["warnings"].dump(), Catch::Contains("no mean across different estimators"));
}

namespace {

/// x, y, z columns of a matched-trajectory CSV (t,tx,ty,tz,...).
std::vector<Eigen::Vector3d> read_positions(const fs::path& f) {
  std::ifstream in(f);
  std::string line;
  std::getline(in, line);  // header
  std::vector<Eigen::Vector3d> out;
  while (std::getline(in, line)) {
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream ss(line);
    double t = 0;
    Eigen::Vector3d p;
    ss >> t >> p.x() >> p.y() >> p.z();
    if (ss) out.push_back(p);
  }
  return out;
}

/// Every matched estimate and ground-truth position inside the trajectory figure's axes (figures.json).
void check_inside(const fs::path& out, const std::string& mode) {
  const auto fj = nlohmann::json::parse(roe::io::read_file(out / "plots/figures.json"));
  nlohmann::json lim;
  for (const auto& f : fj["figures"])
    if (f["name"] == "trajectory") lim = f["data"]["axes_limits_m"];
  INFO(fj.dump().substr(0, 2000));
  REQUIRE(lim.is_object());
  std::size_t n = 0;
  for (const char* file : {"est_matched_aligned.csv", "gt_matched.csv"})
    for (const Eigen::Vector3d& p : read_positions(out / file)) {
      for (char axis : mode) {
        const int k = axis - 'x';
        const auto& l = lim[std::string(1, axis)];
        CHECK(p[k] >= l[0].get<double>());
        CHECK(p[k] <= l[1].get<double>());
      }
      ++n;
    }
  CHECK(n > 100);
}

}  // namespace

TEST_CASE("the trajectory figure's axes hold every pose: KITTI 00 and EuRoC V1_02", "[cli][eval][plot][real]") {
  const fs::path kgt = kData / "evo_results/KITTI_00_gt.txt", kest = kData / "evo_results/KITTI_00_SPTAM.txt";
  const fs::path egt = kData / "eval/V102_groundtruth.csv", eest = kData / "eval/V102.txt";
  if (!fs::exists(kgt) || !fs::exists(eest) ||
      roe::test::run_shell("/usr/bin/python3 -c 'import matplotlib, numpy'").code != 0) {
    WARN("skipped: ../shared/data or /usr/bin/python3 with matplotlib absent");
    return;
  }
  roe::test::TempDir tmp("roe_test_traj_limits");
  // KITTI's camera frame: the drive is in x-z; both planes checked, the default xy too.
  for (const std::string mode : {"xz", "xy"}) {
    const fs::path out = tmp.path / ("kitti_" + mode);
    const auto r = roe::test::run_roe("eval kitti " + kgt.string() + " " + kest.string() + " --plot --plot-mode " +
                                      mode + " --vector none --correspondences --out " + out.string());
    INFO(r.out);
    REQUIRE(r.code == 0);
    check_inside(out, mode);
  }
  const fs::path out = tmp.path / "v102";
  const auto r = roe::test::run_roe("eval " + eest.string() + " --gt " + egt.string() + " --plot --plot-mode xyz "
                                    "--vector none --out " + out.string());
  INFO(r.out);
  REQUIRE(r.code == 0);
  check_inside(out, "xyz");
  // --plot without --out: ./eval_LABEL, said in a warning.
  const auto d = roe::test::run_shell("cd " + tmp.path.string() + " && " + std::string(ROE_BINARY) + " eval " +
                                      eest.string() + " --gt " + egt.string() + " --plot --vector none 2>&1");
  INFO(d.out);
  CHECK(d.code == 0);
  CHECK(fs::exists(tmp.path / "eval_V102/plots/trajectory.png"));
  CHECK_THAT(d.out, Catch::Contains("--plot without --out"));
}

TEST_CASE("calib-check on a run it cannot judge says so instead of PASS", "[cli][calib]") {
  // A --output minimal run has no states.csv or reprojection.csv: every calibration check is inconclusive, only
  // dataset.identity (the files, not the calibration) passes.
  roe::test::TempDir tmp("roe_test_calib_minimal");
  const fs::path ds = tmp.path / "ds", run = tmp.path / "run";
  REQUIRE(roe::test::run_roe("simulate --preset matched-calib --seed 3 --duration 20 -q --out " + ds.string()).code == 0);
  REQUIRE(roe::test::run_roe("run " + ds.string() + " -q --output minimal --out " + run.string()).code == 0);
  const auto r = roe::test::run_roe("calib-check " + run.string());
  INFO(r.out);
  CHECK(r.code == 0);
  CHECK_THAT(r.out, !Catch::Contains("PASS"));
  CHECK_THAT(r.out, Catch::Contains("NOT JUDGED: 1 passed") && Catch::Contains("no check could judge this run"));
  const auto j = nlohmann::json::parse(roe::test::run_roe("calib-check --json " + run.string(), false).out);
  CHECK(j["verdict"] == "NOT JUDGED");
  CHECK(j["passed"] == false);
  CHECK(roe::test::run_roe("calib-check -q --strict " + run.string()).code == 1);
}
