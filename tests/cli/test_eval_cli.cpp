// End-to-end: the roe executable's `eval` command on files and a run folder written here (TUM estimate,
// EuRoC ground truth), exit codes (0 ok, 1 degenerate alignment, 2 bad input / no match), --json,
// --summary. Works on any machine (no shared data needed).
#include "support/test_util.hpp"
#include <sys/wait.h>

#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "roe/app/eval.hpp"
#include "roe/store/run_record.hpp"

namespace fs = std::filesystem;

namespace {
using Result = roe::test::RunResult;
Result run(const std::string& args, bool merge_stderr = true) {
  return roe::test::run_roe(args, merge_stderr);
}

/// Ground truth (EuRoC, 200 Hz, ns) and an estimate (TUM, 20 Hz, seconds) rotated by 90° about z,
/// shifted, with ±2 cm alternating error in z.
void write_pair(const fs::path& dir, bool straight = false) {
  fs::create_directories(dir);
  std::ofstream gt(dir / "gt.csv");
  gt << "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z []\n";
  const long long t0 = 1403715524000000000LL;
  const auto pos = [&](double s, double& x, double& y, double& z) {
    x = straight ? s : std::cos(s);
    y = straight ? 2 * s : std::sin(1.3 * s);
    z = straight ? 0.5 * s : 0.2 * s;
  };
  for (int i = 0; i <= 2000; ++i) {
    const double s = 0.005 * i;
    double x, y, z;
    pos(s, x, y, z);
    gt << (t0 + 5000000LL * i) << "," << x << "," << y << "," << z << ",1,0,0,0\n";
  }
  std::ofstream est(dir / "est.tum");
  est << "# timestamp tx ty tz qx qy qz qw\n";
  const double c = std::sqrt(0.5);
  for (int i = 0; i < 190; ++i) {
    const double s = 0.05 * i + 0.2;
    double x, y, z;
    pos(s, x, y, z);
    // estimate world = Rz(90°) * gt world + (1, 2, 3); orientation Rz(90°)
    char line[256];
    std::snprintf(line, sizeof line, "%lld.%09lld %.9f %.9f %.9f 0 0 %.12f %.12f\n",
                  (t0 + static_cast<long long>(std::llround(s * 1e9))) / 1000000000LL,
                  (t0 + static_cast<long long>(std::llround(s * 1e9))) % 1000000000LL, -y + 1.0, x + 2.0,
                  z + 3.0 + ((i % 2) ? 0.02 : -0.02), c, c);
    est << line;
  }
}
}  // namespace

TEST_CASE("roe eval: TUM estimate vs EuRoC ground truth, --json and files", "[cli][eval]") {
  const fs::path dir = fs::temp_directory_path() / "roe_cli_eval";
  fs::remove_all(dir);
  write_pair(dir);
  const std::string est = (dir / "est.tum").string(), gt = (dir / "gt.csv").string();
  const auto r = run("--json eval " + est + " --gt " + gt + " --out " + (dir / "out").string(), false);
  REQUIRE(r.code == 0);
  const auto j = nlohmann::json::parse(r.out);
  CHECK(j["association"]["n_matched"] == 190);
  CHECK(j["per_axis"]["pos_rmse_m"]["z"].get<double>() == Approx(0.02).epsilon(1e-3));
  CHECK(j["per_axis"]["pos_rmse_m"]["x"].get<double>() < 1e-3);
  CHECK(j["ape_rot_deg"]["rmse"].get<double>() < 0.05);
  CHECK(j["alignment"]["R"][0][1].get<double>() == Approx(1.0));  // Rz(-90°)
  for (const char* f :
       {"report.json", "summary.csv", "errors.csv", "est_matched_aligned.csv", "gt_matched.csv"})
    CHECK(fs::exists(dir / "out" / f));

  // human output (default) and -q
  const auto h = run("eval " + est + " --gt " + gt + " --no-out --align sim3");
  CHECK(h.code == 0);
  CHECK(h.out.find("per-axis") != std::string::npos);
  CHECK(run("-q eval " + est + " --gt " + gt + " --no-out", false).out.empty());

  // an existing output folder is refused (2), replaced with --force (0)
  CHECK(run("eval " + est + " --gt " + gt + " --out " + (dir / "out").string()).code == 2);
  CHECK(run("--force eval " + est + " --gt " + gt + " --out " + (dir / "out").string()).code == 0);

  // --summary over two reports
  CHECK(run("--force eval " + est + " --gt " + gt + " --out " + (dir / "out2").string() + " --n-align 20")
            .code == 0);
  const auto s = run("eval --summary " + (dir / "out/report.json").string() + " " + (dir / "out2").string() +
                     " --out " + (dir / "table.csv").string());
  CHECK(s.code == 0);
  CHECK(s.out.find("| mean |") != std::string::npos);
  CHECK(fs::exists(dir / "table.md"));
  fs::remove_all(dir);
}

TEST_CASE("roe eval: exit codes for no match, bad input and degenerate alignment", "[cli][eval]") {
  const fs::path dir = fs::temp_directory_path() / "roe_cli_eval_err";
  fs::remove_all(dir);
  write_pair(dir);
  const std::string est = (dir / "est.tum").string(), gt = (dir / "gt.csv").string();
  const auto nm = run("eval " + est + " --gt " + gt + " --no-out --t-offset 5000");
  CHECK(nm.code == 2);
  CHECK(nm.out.find("span") != std::string::npos);
  CHECK(run("eval " + est + " --gt " + gt + " --no-out --align nope").code == 2);
  CHECK(run("eval " + est + " --no-out").code == 2);  // --gt missing
  std::ofstream(dir / "bad.tum") << "1 0 0 0 0 0 0 1\n2 0 0 zero 0 0 0 1\n";
  const auto bad = run("eval " + (dir / "bad.tum").string() + " --gt " + gt + " --no-out");
  CHECK(bad.code == 2);
  CHECK(bad.out.find("bad.tum:2:4") != std::string::npos);
  write_pair(dir / "line", true);
  const auto deg = run("eval " + (dir / "line/est.tum").string() + " --gt " + (dir / "line/gt.csv").string() +
                       " --no-out");
  CHECK(deg.code == 1);
  CHECK(deg.out.find("collinear") != std::string::npos);
  fs::remove_all(dir);
}

TEST_CASE("roe eval: a run folder writes RUN_DIR/eval", "[cli][eval]") {
  const fs::path dir = fs::temp_directory_path() / "roe_cli_eval_run";
  fs::remove_all(dir);
  write_pair(dir);
  fs::create_directories(dir / "run");
  // trajectory.csv in roe's (cnspy) CSV form, converted from the TUM file
  std::ifstream in(dir / "est.tum");
  std::ofstream out(dir / "run/trajectory.csv");
  out << "t,tx,ty,tz,qx,qy,qz,qw\n";
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    for (char& ch : line)
      if (ch == ' ') ch = ',';
    out << line << "\n";
  }
  out.close();
  const auto r = run("eval " + (dir / "run").string() + " --gt " + (dir / "gt.csv").string());
  CHECK(r.code == 0);
  CHECK(fs::exists(dir / "run/eval/report.json"));
  fs::remove_all(dir);
}

TEST_CASE("roe eval: --rpe-delta adds the relative pose error to the report, files and summary", "[cli][eval][rpe]") {
  const fs::path dir = fs::temp_directory_path() / "roe_cli_eval_rpe";
  fs::remove_all(dir);
  write_pair(dir);
  const std::string est = (dir / "est.tum").string(), gt = (dir / "gt.csv").string();
  // The estimate's z error alternates ±2 cm from pose to pose: over one matched pose the relative error
  // is 4 cm, over two it cancels.
  const auto r = run("--json eval " + est + " --gt " + gt + " --rpe-delta 1,2 --rpe-unit f --out " +
                         (dir / "out").string(),
                     false);
  REQUIRE(r.code == 0);
  const auto j = nlohmann::json::parse(r.out);
  REQUIRE(j["rpe"].size() == 2);
  CHECK(j["rpe"][0]["unit"] == "f");
  CHECK(j["rpe"][0]["n_pairs"] == 189);
  CHECK(j["rpe"][0]["trans_m"]["rmse"].get<double>() == Approx(0.04).epsilon(1e-3));
  CHECK(j["rpe"][0]["trans_m"]["min"].get<double>() == Approx(0.04).epsilon(1e-3));
  CHECK(j["rpe"][0]["rot_deg"]["max"].get<double>() < 1e-6);
  CHECK(j["rpe"][1]["n_pairs"] == 94);
  CHECK(j["rpe"][1]["trans_m"]["max"].get<double>() < 1e-5);  // 9-digit TUM values
  CHECK(j["options"]["rpe_delta"] == nlohmann::json::array({1.0, 2.0}));
  for (const char* f : {"rpe.csv", "rpe_summary.csv"}) CHECK(fs::exists(dir / "out" / f));
  {
    std::ifstream f(dir / "out/rpe.csv");
    std::string header, line;
    std::getline(f, header);
    CHECK(header == "delta,unit,t_i,t_j,dt_s,path_gt_m,trans_m,rot_deg,drift_pct");
    int rows = 0;
    while (std::getline(f, line)) ++rows;
    CHECK(rows == 189 + 94);
  }
  // Without --rpe-delta: no RPE files, an empty list.
  const auto none = run("--json eval " + est + " --gt " + gt + " --no-out", false);
  REQUIRE(none.code == 0);
  CHECK(nlohmann::json::parse(none.out)["rpe"].empty());

  // A delta longer than the trajectory: a warning, not an error.
  const auto far = run("--json eval " + est + " --gt " + gt + " --no-out --rpe-delta 1000", false);
  REQUIRE(far.code == 0);
  const auto jf = nlohmann::json::parse(far.out);
  CHECK(jf["rpe"][0]["n_pairs"] == 0);
  CHECK(jf["rpe"][0]["trans_m"].is_null());
  CHECK(jf["warnings"].dump().find("RPE delta 1000 m") != std::string::npos);

  // Usage errors (exit 2): settings without a delta, bad deltas and units, RPE options with --summary.
  CHECK(run("eval " + est + " --gt " + gt + " --no-out --rpe-unit s").code == 2);
  CHECK(run("eval " + est + " --gt " + gt + " --no-out --rpe-all-pairs").code == 2);
  CHECK(run("eval " + est + " --gt " + gt + " --no-out --rpe-delta 0").code == 2);
  CHECK(run("eval " + est + " --gt " + gt + " --no-out --rpe-delta 1.5 --rpe-unit f").code == 2);
  CHECK(run("eval " + est + " --gt " + gt + " --no-out --rpe-delta 1 --rpe-unit km").code == 2);
  CHECK(run("eval " + est + " --gt " + gt + " --no-out --rpe-delta 1 --rpe-pairs-from both").code == 2);
  const auto twice = run("eval " + est + " --gt " + gt + " --no-out --rpe-delta 1,2,1.0");
  CHECK(twice.code == 2);
  CHECK(twice.out.find("--rpe-delta lists 1 twice") != std::string::npos);
  CHECK(run("eval --summary " + (dir / "out").string() + " --rpe-delta 1").code == 2);

  // --summary: RPE columns for the blocks the reports have.
  REQUIRE(run("eval " + est + " --gt " + gt + " --rpe-delta 1 --rpe-unit f --out " + (dir / "out2").string())
              .code == 0);
  const auto s = run("--json eval --summary " + (dir / "out").string() + " " + (dir / "out2").string() +
                         " --out " + (dir / "table.csv").string(),
                     false);
  REQUIRE(s.code == 0);
  const auto js = nlohmann::json::parse(s.out);
  CHECK(js["mean"]["rpe_1f_trans_rmse_m"].get<double>() == Approx(0.04).epsilon(1e-3));
  // A block only some reports have is a column with "–" in the others, its mean over those that have it, and
  // one warning names every such column (issue 50: one warning per cause).
  CHECK(js["runs"][1]["rpe_2f_trans_rmse_m"].is_null());
  CHECK(js["mean"]["rpe_2f_trans_rmse_m"].get<double>() == js["runs"][0]["rpe_2f_trans_rmse_m"].get<double>());
  CHECK(js["warnings"].dump().find("some runs lack rpe_2f_trans_rmse_m, rpe_2f_rot_rmse_deg") != std::string::npos);
  std::ifstream t(dir / "table.csv");
  std::string header;
  std::getline(t, header);
  CHECK(header.find("rpe_1f_trans_rmse_m,rpe_1f_rot_rmse_deg") != std::string::npos);
  fs::remove_all(dir);
}

namespace {
/// est.tum's rows as a run folder's trajectory.csv (roe's cnspy CSV).
void write_run_folder(const fs::path& est_tum, const fs::path& run_dir) {
  fs::create_directories(run_dir);
  std::ifstream in(est_tum);
  std::ofstream out(run_dir / "trajectory.csv");
  out << "t,tx,ty,tz,qx,qy,qz,qw\n";
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    for (char& ch : line)
      if (ch == ' ') ch = ',';
    out << line << "\n";
  }
}

/// The poses of a TUM file as KITTI rows (3×4 [R|t] row-major) and its stamps as a KITTI times file.
void tum_to_kitti(const fs::path& tum, const fs::path& kitti, const fs::path& times) {
  std::ifstream in(tum);
  std::ofstream k(kitti), t(times);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ss(line);
    std::string stamp;
    double x, y, z, qx, qy, qz, qw;
    ss >> stamp >> x >> y >> z >> qx >> qy >> qz >> qw;
    const Eigen::Matrix3d R = Eigen::Quaterniond(qw, qx, qy, qz).normalized().toRotationMatrix();
    char buf[512];
    std::snprintf(buf, sizeof buf, "%.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e\n",
                  R(0, 0), R(0, 1), R(0, 2), x, R(1, 0), R(1, 1), R(1, 2), y, R(2, 0), R(2, 1), R(2, 2), z);
    k << buf;
    t << stamp << "\n";
  }
}
}  // namespace

TEST_CASE("roe eval RUN_DIR without --gt uses the dataset run.json names, and says so", "[cli][eval]") {
  roe::test::TempDir tmp("roe_cli_eval_nogt");
  const fs::path dir = tmp.path;
  write_pair(dir);
  const fs::path ds = dir / "V1_01_easy";
  fs::create_directories(ds / "mav0/state_groundtruth_estimate0");
  fs::copy_file(dir / "gt.csv", ds / "mav0/state_groundtruth_estimate0/data.csv");
  write_run_folder(dir / "est.tum", dir / "run");
  // No run.json: --gt is still required, and the message says why.
  const auto missing = run("eval " + (dir / "run").string() + " --no-out");
  CHECK(missing.code == 2);
  CHECK_THAT(missing.out, Catch::Contains("run.json"));
  // run.json through its writer (store/run_record.hpp), naming the dataset (a roe dataset: it has a roe.json).
  std::ofstream(ds / "roe.json") << R"({"schema": "roe-dataset/1", "name": "V1_01_easy"})";
  roe::store::RunRecord rec;
  rec.inputs.dataset = ds.string();
  roe::store::write_run_json(dir / "run/run.json", rec);
  const auto r = run("eval " + (dir / "run").string() + " --no-out", false);
  REQUIRE(r.code == 0);
  CHECK_THAT(r.out, Catch::Contains("from the dataset"));
  CHECK_THAT(r.out, Catch::Contains("run.json"));
  const auto j = run("--json eval " + (dir / "run").string() + " --no-out", false);
  REQUIRE(j.code == 0);
  const auto rep = nlohmann::json::parse(j.out);
  CHECK(rep["inputs"]["gt"]["path"] == ds.string());
  CHECK(rep["association"]["n_matched"] == 190);
  // A dataset that moved away: exit 2 naming run.json's key.
  fs::rename(ds, dir / "elsewhere");
  const auto gone = run("eval " + (dir / "run").string() + " --no-out");
  CHECK(gone.code == 2);
  CHECK_THAT(gone.out, Catch::Contains("inputs.dataset"));
}

TEST_CASE("roe eval accepts evo's spellings or answers with roe's", "[cli][eval]") {
  roe::test::TempDir tmp("roe_cli_eval_evo");
  const fs::path dir = tmp.path;
  write_pair(dir);
  const std::string base = "--json eval " + (dir / "est.tum").string() + " --gt " + (dir / "gt.csv").string() + " --no-out ";
  const auto align_of = [&](const std::string& extra) {
    const auto r = run(base + extra, false);
    REQUIRE(r.code == 0);
    return nlohmann::json::parse(r.out);
  };
  CHECK(align_of("-a")["alignment"]["type"] == "se3");
  CHECK(align_of("-as")["alignment"]["type"] == "sim3");
  CHECK(align_of("-a -s")["alignment"]["type"] == "sim3");
  CHECK(align_of("--align_origin")["alignment"]["type"] == "origin");
  const auto o = align_of("--n_to_align 20 --t_max_diff 0.02 --t_offset 0.001");
  CHECK(o["options"]["n_align"] == 20);
  CHECK(o["options"]["max_dt_s"].get<double>() == 0.02);
  CHECK(o["options"]["t_offset_s"].get<double>() == 0.001);
  CHECK(align_of("--rpe-delta 10 --delta_unit d")["rpe"][0]["unit"] == "deg");
  // -s alone is evo's scale-only correction: refused with the roe spelling.
  const auto s = run(base + "-s");
  CHECK(s.code == 2);
  CHECK_THAT(s.out, Catch::Contains("-as"));
  CHECK(run(base + "-a --align sim3").code == 2);  // named twice
  // evo's --save_results writes evo's result file (tests/cli/test_evo_cli.cpp checks its contents).
  const auto zip = run(base + "--save_results " + (dir / "r.zip").string());
  CHECK(zip.code == 0);
  CHECK(fs::exists(dir / "r.zip"));
}

TEST_CASE("roe eval labels: from the path (EuRoC's data.csv is its sequence), --label, duplicate warning",
          "[cli][eval]") {
  CHECK(roe::app::label_from_path("/d/V1_01_easy/mav0/state_groundtruth_estimate0/data.csv", false) == "V1_01_easy");
  CHECK(roe::app::label_from_path("runs/seed3/trajectory.csv", false) == "seed3");
  CHECK(roe::app::label_from_path("runs/seed3/", true) == "seed3");
  CHECK(roe::app::label_from_path("results/orbslam_v101.tum", false) == "orbslam_v101");
  roe::test::TempDir tmp("roe_cli_eval_label");
  const fs::path dir = tmp.path;
  write_pair(dir);
  const fs::path seq = dir / "V1_01_easy/mav0/state_groundtruth_estimate0";
  fs::create_directories(seq);
  fs::copy_file(dir / "gt.csv", seq / "data.csv");
  const std::string gt = (dir / "gt.csv").string();
  REQUIRE(run("eval " + (seq / "data.csv").string() + " --gt " + gt + " --align none --out " + (dir / "a").string()).code == 0);
  CHECK(nlohmann::json::parse(std::ifstream(dir / "a/report.json"))["info"]["label"] == "V1_01_easy");
  REQUIRE(run("eval " + (dir / "est.tum").string() + " --gt " + gt + " --label mine --out " + (dir / "b").string()).code == 0);
  REQUIRE(run("eval " + (dir / "est.tum").string() + " --gt " + gt + " --label mine --out " + (dir / "c").string()).code == 0);
  CHECK(nlohmann::json::parse(std::ifstream(dir / "b/report.json"))["info"]["label"] == "mine");
  const auto s = run("--json eval --summary " + (dir / "a").string() + " " + (dir / "b").string() + " " +
                     (dir / "c").string(), false);
  REQUIRE(s.code == 0);
  const auto w = nlohmann::json::parse(s.out)["warnings"].dump();
  CHECK_THAT(w, Catch::Contains("runs 2, 3 are all labelled 'mine'"));
  CHECK_THAT(w, !Catch::Contains("V1_01_easy"));
}

TEST_CASE("roe eval reads KITTI pose files: by index as evo, or by a times file", "[cli][eval][kitti]") {
  roe::test::TempDir tmp("roe_cli_eval_kitti");
  const fs::path dir = tmp.path;
  write_pair(dir);
  const std::string gt = (dir / "gt.csv").string();
  // The matched pairs of a TUM evaluation, converted to KITTI, give the same figures.
  REQUIRE(run("eval " + (dir / "est.tum").string() + " --gt " + gt + " --align none --out " + (dir / "tum").string()).code == 0);
  tum_to_kitti(dir / "tum/est_matched_aligned.tum", dir / "est.txt", dir / "est_times.txt");
  tum_to_kitti(dir / "tum/gt_matched.tum", dir / "gt.txt", dir / "gt_times.txt");
  const auto ref = nlohmann::json::parse(std::ifstream(dir / "tum/report.json"));
  const auto by_index = run("--json eval " + (dir / "est.txt").string() + " --gt " + (dir / "gt.txt").string() + " --align none --no-out", false);
  REQUIRE(by_index.code == 0);
  const auto k = nlohmann::json::parse(by_index.out);
  CHECK(k["inputs"]["est"]["format"] == "kitti");
  CHECK(k["association"]["n_matched"] == 190);
  CHECK(k["ape_trans_m"]["rmse"].get<double>() == Approx(ref["ape_trans_m"]["rmse"].get<double>()).epsilon(1e-6));
  // With the times files, against the stamped EuRoC ground truth directly.
  const auto timed = run("--json eval " + (dir / "est.txt").string() + " --est-times " + (dir / "est_times.txt").string() +
                         " --gt " + gt + " --align none --no-out", false);
  REQUIRE(timed.code == 0);
  CHECK(nlohmann::json::parse(timed.out)["association"]["n_matched"] == 190);
  // Without them a KITTI file cannot meet a stamped trajectory: say which option to pass.
  const auto mixed = run("eval " + (dir / "est.txt").string() + " --gt " + gt + " --no-out");
  CHECK(mixed.code == 2);
  CHECK_THAT(mixed.out, Catch::Contains("--est-times"));
  std::ofstream(dir / "short.txt") << "1 0 0 0 0 1 0 0 0 0 1 0\n";
  const auto count = run("eval " + (dir / "short.txt").string() + " --gt " + (dir / "gt.txt").string() + " --no-out");
  CHECK(count.code == 2);
  CHECK_THAT(count.out, Catch::Contains("by index"));
  std::ofstream(dir / "skew.txt") << "1 0 0 0 0 2 0 0 0 0 1 0\n";
  CHECK(run("eval " + (dir / "skew.txt").string() + " --gt " + (dir / "skew.txt").string() + " --no-out").code == 2);
}

TEST_CASE("roe eval on a ROS bag says it is a bag and how to read it", "[cli][eval]") {
  roe::test::TempDir tmp("roe_cli_eval_bag");
  const fs::path dir = tmp.path;
  write_pair(dir);
  std::ofstream(dir / "rec.bag", std::ios::binary) << std::string("#ROSBAG V2.0\n\x04\x00\x00\x00op=\x03\xff\xfe", 23);
  const auto r = run("eval " + (dir / "rec.bag").string() + " --gt " + (dir / "gt.csv").string() + " --no-out");
  CHECK(r.code == 2);
  CHECK_THAT(r.out, Catch::Contains("ROS bag"));
  CHECK_THAT(r.out, Catch::Contains("TOPIC"));
}

TEST_CASE("roe eval --euler and --fit-body-rotation from the command line, refused with --summary", "[cli][eval][euler]") {
  const fs::path dir = fs::temp_directory_path() / "roe_cli_eval_euler";
  fs::remove_all(dir);
  write_pair(dir);
  const std::string est = (dir / "est.tum").string(), gt = (dir / "gt.csv").string();
  const Result e = run("--json eval " + est + " --gt " + gt + " --no-out", false);
  REQUIRE(e.code == 0);
  const Result u =
      run("--json eval " + est + " --gt " + gt + " --no-out --euler absolute-unwrapped --fit-body-rotation", false);
  REQUIRE(u.code == 0);
  const auto je = nlohmann::json::parse(e.out), ju = nlohmann::json::parse(u.out);
  CHECK(je["euler_metric"] == "error");
  CHECK(je["body_rotation"].is_null());
  CHECK(ju["euler_metric"] == "absolute-unwrapped");
  CHECK(ju["per_axis"]["rotation_error_euler_deg"]["rmse"] == je["per_axis"]["rpy_rmse_deg"]);
  CHECK(ju["body_rotation"]["angle_deg"].get<double>() < 0.5);  // only the alignment's own error: no body offset here
  const Result bad = run("eval " + est + " --gt " + gt + " --no-out --euler wrapped");
  CHECK(bad.code == 2);
  CHECK(bad.out.find("error, absolute or absolute-unwrapped") != std::string::npos);
  CHECK(run("eval --summary " + est + " --euler absolute").code == 2);
  const Result h = run("eval --help");
  CHECK(h.out.find("--euler") != std::string::npos);
  CHECK(h.out.find("--fit-body-rotation") != std::string::npos);
  fs::remove_all(dir);
}
