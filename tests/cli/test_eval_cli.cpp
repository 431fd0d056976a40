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
#include <nlohmann/json.hpp>
#include <string>

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

  // --summary: RPE columns for the blocks every report has; a block in only some is named in a warning.
  REQUIRE(run("eval " + est + " --gt " + gt + " --rpe-delta 1 --rpe-unit f --out " + (dir / "out2").string())
              .code == 0);
  const auto s = run("--json eval --summary " + (dir / "out").string() + " " + (dir / "out2").string() +
                         " --out " + (dir / "table.csv").string(),
                     false);
  REQUIRE(s.code == 0);
  const auto js = nlohmann::json::parse(s.out);
  CHECK(js["mean"]["rpe_1f_trans_rmse_m"].get<double>() == Approx(0.04).epsilon(1e-3));
  CHECK(!js["mean"].contains("rpe_2f_trans_rmse_m"));
  CHECK(js["warnings"].dump().find("RPE 2f is not in every report") != std::string::npos);
  std::ifstream t(dir / "table.csv");
  std::string header;
  std::getline(t, header);
  CHECK(header.find("rpe_1f_trans_rmse_m,rpe_1f_rot_rmse_deg") != std::string::npos);
  fs::remove_all(dir);
}
