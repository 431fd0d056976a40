// roe eval at the app level: a synthetic run folder (trajectory.csv + reprojection.csv + states.csv)
// against a synthetic dataset folder (roe.json with mocap T_B_I and time offset + mocap0), the
// output files, per-object traces, NEES, error paths, and --summary.
#include <catch2/catch.hpp>
#include <fmt/format.h>
#include <sstream>
#include <cmath>
#include <filesystem>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "roe/app/eval.hpp"
#include "roe/core/error.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"
#include "roe/io/trajectory_io.hpp"
#include "roe/math/euler.hpp"
#include "support/test_util.hpp"

using namespace roe;
namespace fs = std::filesystem;
using Eigen::Vector3d;

namespace {

struct Fixture {
  fs::path root;
  fs::path dataset, run;
  Pose T_B_I;  // mocap body -> IMU
  Pose T_W_M;  // the run's world vs the mocap world
  double offset_s = 0.05;
  Timestamp t0 = 1'700'000'000'000'000'000LL;

  explicit Fixture(const std::string& name, bool with_noise = true, bool straight = false) {
    root = fs::temp_directory_path() / ("roe_test_eval_" + name);
    fs::remove_all(root);
    dataset = root / "dataset";
    run = root / "run";
    fs::create_directories(dataset);
    fs::create_directories(run);
    T_B_I =
        Pose(Eigen::Quaterniond(math::from_euler_zyx(Vector3d(0.1, -0.2, 0.3))), Vector3d(0.02, -0.01, 0.05));
    T_W_M = Pose(Eigen::Quaterniond(math::from_euler_zyx(Vector3d(0.0, 0.0, 1.0))), Vector3d(1.0, 2.0, -0.5));

    // Mocap at 100 Hz: T_M_B(t). The IMU pose truth is T_M_I = T_M_B T_B_I at t_imu = t_mocap + offset.
    std::vector<StampedPose> mocap;
    const auto truth_imu = [&](double s) {
      const Vector3d p = straight ? Vector3d(0.5 * s, 0.25 * s, 0.1 * s)
                                  : Vector3d(std::cos(0.5 * s), std::sin(0.7 * s), 0.3 * std::sin(0.3 * s));
      return Pose(Eigen::Quaterniond(math::from_euler_zyx(Vector3d(0.2 * std::sin(s), 0.1 * s, 0.4 * s))), p);
    };
    for (int i = 0; i <= 2000; ++i) {
      const double s = 0.01 * i;
      mocap.push_back({t0 + i * 10'000'000LL, truth_imu(s + offset_s) * T_B_I.inverse()});
    }
    store::write_mocap_csv(dataset / "mav0/mocap0/data.csv", mocap);
    DatasetManifest m;
    m.name = "synthetic";
    m.mocap = MocapInfo{"rig", T_B_I, offset_s};
    store::write_manifest(m, dataset / "roe.json");

    // Run: T_W_I at 20 Hz in the run's world (T_W_M · T_M_I), with alternating errors.
    std::vector<Timestamp> t;
    std::vector<Pose> est;
    for (int i = 0; i < 380; ++i) {
      const double s = 0.05 * i + 0.3;
      Pose T = T_W_M * truth_imu(s + offset_s);
      if (with_noise) {
        const double sign = (i % 2 == 0) ? 1.0 : -1.0;
        T.p += T_W_M.q * Vector3d(0.01 * sign, 0.0, 0.0);
        T.q = T.q * Eigen::Quaterniond(Eigen::AngleAxisd(sign * 1.0 * math::kRadPerDeg, Vector3d::UnitZ()));
      }
      t.push_back(t0 + static_cast<Timestamp>(std::llround(s * 1e9)) +
                  static_cast<Timestamp>(offset_s * 1e9));
      est.push_back(T);
    }
    io::write_trajectory(run / "trajectory.csv", t, est, io::TrajectoryFormat::kCsv);
    // reprojection.csv: object 1 exact, object 2 offset by 0.1 m in x (run world); statuses mixed.
    std::ofstream rep(run / "reprojection.csv");
    rep << "timestamp_ns,object_id,tx,ty,tz,qx,qy,qz,qw,status,nis\n";
    std::ofstream st(run / "states.csv");
    st << "timestamp_ns,p_W_I_x,p_W_I_y,p_W_I_z,sigma_p_W_I_x,sigma_p_W_I_y,sigma_p_W_I_z,sigma_theta_W_I_x,"
          "sigma_theta_W_I_y,sigma_theta_W_I_z\n";
    for (std::size_t i = 0; i < t.size(); ++i) {
      const Pose truth = T_W_M * truth_imu(0.05 * static_cast<double>(i) + 0.3 + offset_s);
      for (int obj : {1, 2}) {
        Pose T = truth;
        if (obj == 2) T.p += Vector3d(0.1, 0, 0);
        const char* status = (obj == 2 && i % 4 == 0) ? "rejected_chi2" : "accepted";
        rep << t[i] << "," << obj << "," << fmt(T.p.x()) << "," << fmt(T.p.y()) << "," << fmt(T.p.z()) << ","
            << fmt(T.q.x()) << "," << fmt(T.q.y()) << "," << fmt(T.q.z()) << "," << fmt(T.q.w()) << ","
            << status << ",1.5\n";
      }
      st << t[i] << "," << fmt(est[i].p.x()) << "," << fmt(est[i].p.y()) << "," << fmt(est[i].p.z())
         << ",0.01,0.01,0.01," << fmt(1.0 * math::kRadPerDeg) << "," << fmt(1.0 * math::kRadPerDeg) << ","
         << fmt(1.0 * math::kRadPerDeg) << "\n";
    }
  }
  ~Fixture() { fs::remove_all(root); }
  static std::string fmt(double v) {
    char b[64];
    std::snprintf(b, sizeof b, "%.17g", v);
    return b;
  }
};

}  // namespace

TEST_CASE("roe eval: run folder vs dataset (mocap with T_B_I and time offset)", "[app][eval]") {
  Fixture f("run");
  app::EvalOptions o;
  o.est = f.run.string();
  o.gt = f.dataset.string();
  const app::EvalResult r = app::run_eval(o);
  const auto j = r.report_json();
  // every estimate pose has a mocap stamp within 10 ms (mocap at 100 Hz, shifted by the offset)
  CHECK(j["association"]["n_matched"] == 380);
  CHECK(j["association"]["max_abs_dt_s"].get<double>() < 1e-6);
  // the alignment recovers T_M_W = T_W_M⁻¹ (noise is symmetric)
  const Eigen::Matrix3d R_expected = f.T_W_M.inverse().R();
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b)
      CHECK(j["alignment"]["R"][a][b].get<double>() == Approx(R_expected(a, b)).margin(2e-3));
  CHECK(j["alignment"]["scale"] == 1.0);
  // per-axis: the injected ±1 cm in the estimate's x (world frame rotated by R_W_M) and ±1° local yaw
  const auto& pa = j["per_axis"];
  const double ex = pa["pos_rmse_m"]["x"].get<double>(), ey = pa["pos_rmse_m"]["y"].get<double>();
  CHECK(std::hypot(ex, ey) == Approx(0.01).epsilon(0.05));
  CHECK(pa["pos_rmse_m"]["z"].get<double>() < 1e-3);
  CHECK(pa["rpy_rmse_deg"]["yaw"].get<double>() == Approx(1.0).epsilon(0.01));
  CHECK(pa["rpy_rmse_deg"]["roll"].get<double>() < 0.05);
  CHECK(j["ape_rot_deg"]["max"].get<double>() == Approx(1.0).epsilon(0.01));
  // NEES from states.csv: e_p ≈ 1 cm with σ = 1 cm per axis → ~1; rotation 1° with σ = 1° → ~1
  REQUIRE(j["consistency"]["available"] == true);
  CHECK(j["consistency"]["anees_p"].get<double>() == Approx(1.0).epsilon(0.1));
  // No truth in the estimator's gauge here (mocap ground truth, no run.json): the orientation NEES is
  // given only relative to the alignment, not headlined.
  CHECK(j["consistency"]["frame"] == "alignment");
  CHECK(j["consistency"]["anees_r"].is_null());
  CHECK(j["consistency"]["gauge"]["available"] == false);
  CHECK(j["consistency"]["aligned"]["anees_p"] == j["consistency"]["anees_p"]);
  CHECK(j["consistency"]["aligned"]["anees_r"].get<double>() == Approx(1.0).epsilon(0.05));
  CHECK(j["cnspy"]["ANEES_R"] == j["consistency"]["aligned"]["anees_r"]);
  // per-object traces: object 1 exact, object 2 off by 10 cm (rotated into the GT frame)
  REQUIRE(j["per_object"].size() == 2);
  const auto& o1 = j["per_object"][0];
  const auto& o2 = j["per_object"][1];
  CHECK(o1["object_id"] == 1);
  CHECK(o1["n_detections"] == 380);
  CHECK(o1["all"]["ape_trans_rmse_m"].get<double>() < 2e-3);
  CHECK(o2["all"]["ape_trans_rmse_m"].get<double>() == Approx(0.1).epsilon(0.03));
  CHECK(o2["counts"]["rejected_chi2"] == 95);
  CHECK(o2["counts"]["accepted"] == 285);
  CHECK(o2["accepted"]["n"] == 285);
  // files
  const fs::path out = f.run / "eval";
  REQUIRE(r.out == out);
  for (const char* name :
       {"est_matched_aligned.csv", "gt_matched.csv", "errors.csv", "err_matched_aligned.csv", "summary.csv",
        "report.json", "reprojection_aligned.csv", "per_object.csv", "est_matched_aligned.tum",
        "gt_matched.tum"})
    CHECK(fs::exists(out / name));
  const io::Trajectory aligned = io::read_trajectory(out / "est_matched_aligned.csv");
  CHECK(aligned.size() == 380);
  const io::Trajectory gtm = io::read_trajectory(out / "gt_matched.csv");
  CHECK(gtm.size() == 380);
  CHECK((aligned.poses[10].p - gtm.poses[10].p).norm() < 0.02);
  const io::Trajectory err = io::read_trajectory(out / "err_matched_aligned.csv");  // cnspy PoseTypedStamped
  CHECK(err.size() == 380);
  const auto rj = io::parse_json_file(out / "report.json");
  for (const char* key : {"info", "association", "alignment", "ape_trans_m", "ape_rot_deg", "per_axis",
                          "cnspy", "consistency", "per_object"})
    CHECK(rj.contains(key));
  for (const char* key : {"rmse", "mean", "median", "std", "min", "max", "sse"})
    CHECK(rj["ape_trans_m"].contains(key));
  // human text mentions the per-object table
  const std::string text = r.to_text();
  CHECK(text.find("per object") != std::string::npos);
  CHECK(text.find("rejected_chi2 95") != std::string::npos);

  // Running again without --force refuses to replace the output; with force it works.
  CHECK_THROWS_AS(app::run_eval(o), InputError);
  o.force = true;
  CHECK_NOTHROW(app::run_eval(o));

  // Without the mocap time offset the association still finds pairs but the errors grow: the offset
  // and T_B_I from roe.json are what make the result exact.
  SECTION("ignoring the dataset's T_B_I shows up in the errors") {
    app::EvalOptions o2 = o;
    o2.gt = (f.dataset / "mav0/mocap0/data.csv").string();
    o2.no_out = true;
    o2.t_offset_s = -f.offset_s;
    const auto r2 = app::run_eval(o2);
    CHECK(r2.report_json()["ape_trans_m"]["rmse"].get<double>() > 0.02);
  }
}

TEST_CASE("roe eval: cnspy covariance in the body frame (type1) is rotated into the world, path lengths",
          "[app][eval]") {
  const fs::path root = fs::temp_directory_path() / "roe_test_eval_cnspy_cov";
  fs::remove_all(root);
  fs::create_directories(root);
  // A tumbling body on a circle at 20 Hz; the estimate has deterministic position errors e_W with a
  // known, anisotropic world-frame covariance P_W, written once as type1 (body frame: Rᵀ P_W R) and
  // once as type2 (world frame, as given).
  const Eigen::Matrix3d Q = math::from_euler_zyx(Vector3d(0.3, -0.4, 1.1));
  const Eigen::Matrix3d P_W = Q * Vector3d(1e-4, 4e-4, 9e-4).asDiagonal() * Q.transpose();
  std::ofstream gt(root / "gt.tum");
  std::ofstream b1(root / "est1.csv"), b2(root / "est2.csv");
  const char* header = "t,tx,ty,tz,qx,qy,qz,qw,pxx,pxy,pxz,pyy,pyz,pzz,qrr,qrp,qry,qpp,qpy,qyy,est_err_type,err_representation\n";
  b1 << header;
  b2 << header;
  double nees_sum = 0.0, L = 0.0;
  Vector3d last;
  const int n = 400;
  for (int k = 0; k < n; ++k) {
    const double s = 0.05 * k;
    const Vector3d p(2.0 * std::cos(0.3 * s), 2.0 * std::sin(0.3 * s), 0.5 * std::sin(0.2 * s));
    if (k > 0) L += (p - last).norm();
    last = p;
    const Eigen::Quaterniond q(math::from_euler_zyx(Vector3d(0.5 * std::sin(0.7 * s), 0.4 * std::cos(0.5 * s), 0.9 * s)));
    const Vector3d e(0.01 * std::sin(3.1 * k), 0.02 * std::cos(5.3 * k), 0.03 * std::sin(7.7 * k + 1.0));
    nees_sum += e.dot(P_W.inverse() * e);
    gt << Fixture::fmt(s) << " " << Fixture::fmt(p.x()) << " " << Fixture::fmt(p.y()) << " " << Fixture::fmt(p.z()) << " "
       << Fixture::fmt(q.x()) << " " << Fixture::fmt(q.y()) << " " << Fixture::fmt(q.z()) << " " << Fixture::fmt(q.w()) << "\n";
    const Eigen::Matrix3d R = q.toRotationMatrix();
    const Eigen::Matrix3d P_B = R.transpose() * P_W * R;
    for (int file = 1; file <= 2; ++file) {
      std::ofstream& o = file == 1 ? b1 : b2;
      const Eigen::Matrix3d& P = file == 1 ? P_B : P_W;
      const Vector3d pe = p + e;
      o << Fixture::fmt(s) << "," << Fixture::fmt(pe.x()) << "," << Fixture::fmt(pe.y()) << "," << Fixture::fmt(pe.z()) << ","
        << Fixture::fmt(q.x()) << "," << Fixture::fmt(q.y()) << "," << Fixture::fmt(q.z()) << "," << Fixture::fmt(q.w());
      for (auto [i, j] : {std::pair{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}}) o << "," << Fixture::fmt(P(i, j));
      o << ",1e-4,0,0,1e-4,0,1e-4," << (file == 1 ? "type1" : "type2") << ",theta_R\n";
    }
  }
  gt.close();
  b1.close();
  b2.close();
  app::EvalOptions o;
  o.gt = (root / "gt.tum").string();
  o.align = "none";
  o.no_out = true;
  o.est = (root / "est1.csv").string();
  const auto r1 = app::run_eval(o);
  o.est = (root / "est2.csv").string();
  const auto r2 = app::run_eval(o);
  REQUIRE(r1.report_json()["association"]["n_matched"].get<int>() == n);
  // The average NEES (1/n) Σ eᵀ P_W⁻¹ e (3 for a consistent estimate), from either file.
  CHECK(r2.report_json()["consistency"]["anees_p"].get<double>() == Approx(nees_sum / n).epsilon(1e-6));
  CHECK(r1.report_json()["consistency"]["anees_p"].get<double>() == Approx(nees_sum / n).epsilon(1e-6));
  // Path lengths: the ground truth's, and the estimate's (longer: its errors zig-zag).
  CHECK(r1.report_json()["path_length_m"]["gt"].get<double>() == Approx(L).epsilon(1e-9));
  CHECK(r1.report_json()["path_length_m"]["est"].get<double>() > L + 0.5);
  fs::remove_all(root);
}

TEST_CASE("roe eval: alignment variants and options", "[app][eval]") {
  Fixture f("variants", false);
  app::EvalOptions o;
  o.est = f.run.string();
  o.gt = f.dataset.string();
  o.no_out = true;
  for (const char* a : {"se3", "sim3", "posyaw", "origin"}) {
    o.align = a;
    const auto r = app::run_eval(o);
    INFO(a);
    if (std::string(a) == "posyaw") {
      // T_W_M is a pure yaw + translation: posyaw recovers it exactly as well
      CHECK(r.report_json()["ape_trans_m"]["rmse"].get<double>() < 1e-6);
    } else {
      CHECK(r.report_json()["ape_trans_m"]["rmse"].get<double>() < 1e-6);
      CHECK(r.report_json()["ape_rot_deg"]["rmse"].get<double>() < 1e-4);
    }
  }
  o.align = "none";
  CHECK(app::run_eval(o).report_json()["ape_trans_m"]["rmse"].get<double>() > 0.5);
  o.align = "se3";
  o.n_align = 10;
  CHECK(app::run_eval(o).report_json()["alignment"]["n_aligned"] == 10);
  o.n_align = 0;
  CHECK_THROWS_AS(app::run_eval(o), InputError);
  o.n_align = -1;
  o.align = "affine";
  CHECK_THROWS_AS(app::run_eval(o), InputError);
  o.align = "se3";
  o.assoc = "unique";
  CHECK(app::run_eval(o).report_json()["association"]["policy"] == "unique");
  o.assoc = "nearest";
  o.plot = true;  // --plot with --no-out: they contradict
  CHECK_THROWS_AS(app::run_eval(o), InputError);
}

TEST_CASE("roe eval: error paths", "[app][eval]") {
  Fixture f("errors");
  app::EvalOptions o;
  o.est = f.run.string();
  o.gt = f.dataset.string();
  o.no_out = true;
  SECTION("no match: the message gives both ranges and a hint") {
    o.t_offset_s = 1000.0;
    try {
      app::run_eval(o);
      FAIL("no error");
    } catch (const InputError& e) {
      const std::string m = e.what();
      CHECK(m.find("span") != std::string::npos);
      CHECK(m.find("--t-offset") != std::string::npos);
    }
  }
  SECTION("missing inputs") {
    o.gt = (f.root / "nope").string();
    CHECK_THROWS_AS(app::run_eval(o), InputError);
    o.gt = f.root.string();  // a folder without ground truth
    CHECK_THROWS_AS(app::run_eval(o), InputError);
    o.gt = f.dataset.string();
    o.est = f.dataset.string();  // a folder without trajectory.csv
    CHECK_THROWS_AS(app::run_eval(o), InputError);
  }
  SECTION("malformed reprojection.csv names line and column") {
    std::ofstream(f.run / "reprojection.csv")
        << "timestamp_ns,object_id,tx,ty,tz,qx,qy,qz,qw,status,nis\n"
        << "1,1,0,0,0,0,0,0,1,accepted,1\n2,x,0,0,0,0,0,0,1,accepted,1\n";
    try {
      app::run_eval(o);
      FAIL("no error");
    } catch (const InputError& e) {
      CHECK(e.context().line == 3);
      CHECK(e.context().column == 2);
    }
  }
}

TEST_CASE("roe eval: degenerate (straight-line) trajectory is refused for se3, fine for origin",
          "[app][eval]") {
  Fixture f("straight", false, true);
  app::EvalOptions o;
  o.est = f.run.string();
  o.gt = f.dataset.string();
  o.no_out = true;
  CHECK_THROWS_AS(app::run_eval(o), eval::DegenerateAlignmentError);
  o.align = "origin";
  CHECK(app::run_eval(o).report_json()["ape_trans_m"]["rmse"].get<double>() < 1e-6);
}

TEST_CASE("roe eval --summary: rows, mean and population std", "[app][eval]") {
  Fixture f("summary");
  std::vector<std::string> reports;
  for (int k = 0; k < 3; ++k) {
    app::EvalOptions o;
    o.est = f.run.string();
    o.gt = f.dataset.string();
    o.out = (f.root / ("eval" + std::to_string(k))).string();
    o.label = "run" + std::to_string(k);
    o.n_align = 50 + 100 * k;  // different results per "run"
    app::run_eval(o);
    reports.push_back(o.out);  // a folder containing report.json is accepted
  }
  app::EvalSummaryOptions so;
  so.reports = reports;
  so.out = (f.root / "table.csv").string();
  const auto s = app::summarize_eval_reports(so);
  REQUIRE(s.summary["runs"].size() == 3);
  double mean = 0.0, var = 0.0;
  std::vector<double> xs;
  for (const auto& r : s.summary["runs"]) xs.push_back(r["rmse_x_m"].get<double>());
  for (double x : xs) mean += x / 3.0;
  for (double x : xs) var += (x - mean) * (x - mean) / 3.0;
  CHECK(s.summary["mean"]["rmse_x_m"].get<double>() == Approx(mean));
  CHECK(s.summary["std"]["rmse_x_m"].get<double>() == Approx(std::sqrt(var)));
  // roe's one `std` convention: numpy's default (ddof 0), as evo_res prints it, and Python's pstdev;
  // computed outside roe from the rows' values (docs/eval.md "One std convention")
  for (const char* m : {"rmse_x_m", "rmse_yaw_deg", "ate_rmse_m"}) {
    std::string list;
    for (const auto& r : s.summary["runs"]) list += fmt::format("{}{}", list.empty() ? "" : ",", r[m].get<double>());
    const test::RunResult py = test::run_shell(fmt::format("/usr/bin/python3 -c 'import statistics, numpy as np; v = [{}]; "
                                               "print(repr(float(np.std(v))), repr(statistics.pstdev(v)), "
                                               "repr(statistics.stdev(v)))'",
                                               list));
    REQUIRE(py.code == 0);
    std::istringstream in(py.out);
    double np_std = 0.0, pstdev = 0.0, stdev = 0.0;
    in >> np_std >> pstdev >> stdev;
    INFO(m << ": " << py.out);
    CHECK(s.summary["std"][m].get<double>() == Approx(np_std).epsilon(1e-12));
    CHECK(s.summary["std"][m].get<double>() == Approx(pstdev).epsilon(1e-12));
    CHECK(s.summary["std"][m].get<double>() != Approx(stdev).epsilon(1e-6));  // not the sample std
  }
  CHECK(s.summary["std_definition"] == "population (ddof 0)");
  CHECK(s.summary["runs"][1]["label"] == "run1");
  CHECK(s.summary["runs"][0]["n_objects"] == 2);
  CHECK(s.markdown.find("| mean |") != std::string::npos);
  CHECK(s.markdown.find("± std") != std::string::npos);
  for (const char* ext : {".csv", ".json", ".md"}) CHECK(fs::exists(f.root / (std::string("table") + ext)));
  // table.csv: runs numbered from 1, in the order given, each with its label and report; then the
  // mean and std rows.
  {
    std::ifstream csv(f.root / "table.csv");
    std::string line;
    std::getline(csv, line);
    CHECK(line.rfind("run,label,report,n_objects,n_matched,", 0) == 0);
    for (int k = 0; k < 3; ++k) {
      REQUIRE(std::getline(csv, line));
      CHECK(line.rfind(std::to_string(k + 1) + ",run" + std::to_string(k) + ",", 0) == 0);
    }
    REQUIRE(std::getline(csv, line));
    CHECK(line.rfind("mean,,,,,", 0) == 0);
    REQUIRE(std::getline(csv, line));
    CHECK(line.rfind("std,,,,,", 0) == 0);
    CHECK_FALSE(std::getline(csv, line));
  }
  CHECK_THROWS_AS(app::summarize_eval_reports(so), InputError);  // exists, no force
  so.force = true;
  CHECK_NOTHROW(app::summarize_eval_reports(so));
  so.reports = {(f.root / "table.json").string()};  // not a report
  CHECK_THROWS_AS(app::summarize_eval_reports(so), InputError);
  std::ofstream(f.root / "bad.json") << R"({"per_axis": {"pos_rmse_m": {"x": "a"}, "rpy_rmse_deg": {}}})";
  so.reports = {(f.root / "bad.json").string()};  // wrong types: a clear InputError, not an internal error
  CHECK_THROWS_AS(app::summarize_eval_reports(so), InputError);
  // the typed reader is strict: a report missing a field is refused, naming the file and the key path
  {
    io::json j = io::parse_json_file(fs::path(reports[0]) / "report.json");
    j["per_axis"].erase("euler_metric");
    std::ofstream(f.root / "old.json") << j.dump(2);
    so.reports = {reports[1], (f.root / "old.json").string()};
    const InputError e = test::expect_input_error([&] { app::summarize_eval_reports(so); });
    CHECK(e.context().key == "per_axis.euler_metric");
    CHECK(e.context().file == (f.root / "old.json").string());
    CHECK_THAT(e.what(), Catch::Contains("not a roe eval report") && Catch::Contains("per_axis.euler_metric"));
  }
}

TEST_CASE("roe eval --plot draws the figure set when matplotlib is available", "[app][eval][plot]") {
  Fixture f("plot");
  app::EvalOptions o;
  o.est = f.run.string();
  o.gt = f.dataset.string();
  o.plot = true;
  app::EvalResult r;
  try {
    r = app::run_eval(o);
  } catch (const InputError& e) {
    if (std::string(e.what()).find("cannot draw the figures") == std::string::npos) throw;
    WARN("skipped: " << e.what());
    return;
  }
  CHECK(r.report_json()["plots"]["ok"] == true);
  const fs::path plots = f.run / "eval/plots";
  for (const char* p : {"fig3", "consistency", "trajectory", "errors"}) {
    CHECK(fs::file_size(plots / (std::string(p) + ".png")) > 10000);
    CHECK(fs::file_size(plots / (std::string(p) + ".pdf")) > 5000);
  }
  // This run folder has no objects.csv and no extrinsics in states.csv: those figures are skipped and
  // the status says why (the sample run of tests/cli/test_report_cli.cpp has them all).
  CHECK_FALSE(fs::exists(plots / "extrinsics.png"));
  CHECK(r.plot_status.find("fig4 skipped") != std::string::npos);
  CHECK(r.plot_status.find("extrinsics skipped") != std::string::npos);
  CHECK(fs::exists(plots / "figures.json"));
  CHECK_FALSE(fs::exists(plots / "rpe.png"));  // only with --rpe-delta
  CHECK(r.plot_status.find("rpe") == std::string::npos);
  CHECK_FALSE(fs::exists(plots / ".plot_run.py"));

  // With --rpe-delta: the RPE figure too, and the status names it; --vector svg.
  o.rpe_delta = {1.0, 2.0};
  o.rpe_unit = "s";
  o.force = true;
  o.figures.vector = "svg";
  const auto r2 = app::run_eval(o);
  REQUIRE(r2.report_json()["plots"]["ok"] == true);
  CHECK(fs::file_size(plots / "rpe.png") > 10000);
  CHECK(fs::exists(plots / "rpe.svg"));
  CHECK(r2.plot_status.find("rpe") != std::string::npos);
}

namespace {

/// A TUM file with the given stamps on a circle with a slow climb (enough spread for se3).
void write_tum(const fs::path& file, const std::vector<Timestamp>& t_ns) {
  fs::create_directories(file.parent_path());
  std::ofstream f(file);
  f << "# timestamp tx ty tz qx qy qz qw\n";
  for (Timestamp t : t_ns) {
    const double s = to_seconds(t);
    char line[256];
    std::snprintf(line, sizeof line, "%lld.%09lld %.9f %.9f %.9f 0 0 0 1\n", static_cast<long long>(t / 1'000'000'000),
                  static_cast<long long>(t % 1'000'000'000), std::cos(0.2 * s), std::sin(0.3 * s), 0.01 * s);
    f << line;
  }
}

std::vector<Timestamp> stamps(Timestamp t0, Timestamp step, int n) {
  std::vector<Timestamp> t;
  for (int i = 0; i < n; ++i) t.push_back(t0 + step * i);
  return t;
}

bool any_warning_contains(const nlohmann::json& report, const std::string& needle) {
  for (const auto& w : report["warnings"])
    if (w.get<std::string>().find(needle) != std::string::npos) return true;
  return false;
}

/// Sets an environment variable for one scope.
struct ScopedEnv {
  std::string name;
  std::optional<std::string> old;
  ScopedEnv(const std::string& n, const std::string& value) : name(n) {
    if (const char* v = std::getenv(n.c_str())) old = v;
    setenv(n.c_str(), value.c_str(), 1);
  }
  ~ScopedEnv() {
    if (old)
      setenv(name.c_str(), old->c_str(), 1);
    else
      unsetenv(name.c_str());
  }
};

}  // namespace

// A mocap take imported without a clock offset starts near 0 s; the run's stamps are epoch time. The
// diagnosis must say so (and suggest the offset), not blame a ns/s mix-up.
TEST_CASE("roe eval: no match between a relative-time ground truth and an epoch-time estimate", "[app][eval]") {
  Fixture f("relative_gt");
  const fs::path gt = f.root / "take.tum";
  write_tum(gt, stamps(0, 10'000'000, 201));  // 0 .. 2 s
  app::EvalOptions o;
  o.est = f.run.string();
  o.gt = gt.string();
  o.no_out = true;
  const InputError e = test::expect_input_error([&] { app::run_eval(o); });
  const std::string m = e.what();
  INFO(m);
  CHECK(m.find("scaled by") == std::string::npos);
  CHECK(m.find("ground truth starts near 0 s") != std::string::npos);
  CHECK(m.find("--t-offset -") != std::string::npos);
  CHECK(m.find("--time-offset") != std::string::npos);
}

// EuRoC-style: the ground truth covers 83 s, the estimate 40 s of it. Every ground-truth pose in the
// common span is matched: no "only N of at most M" warning. A real --max-dt problem still warns.
TEST_CASE("roe eval: the matched-pairs warning counts only the span both trajectories cover", "[app][eval]") {
  test::TempDir dir("roe_test_eval_overlap");
  const fs::path gt = dir / "gt.tum", est = dir / "est.tum";
  write_tum(gt, stamps(0, 25'000'000, 3321));                    // 0 .. 83 s at 40 Hz
  write_tum(est, stamps(20'000'000'000LL, 5'000'000, 8001));      // 20 .. 60 s at 200 Hz
  app::EvalOptions o;
  o.est = est.string();
  o.gt = gt.string();
  o.no_out = true;
  const auto r = app::run_eval(o);
  INFO(r.report_json()["warnings"].dump());
  CHECK(r.report_json()["association"]["n_matched"] == 1601);
  CHECK(r.report_json()["association"]["n_overlap_max"] == 1601);
  CHECK_FALSE(any_warning_contains(r.report_json(), "were matched"));

  // Two of three estimate stamps 7 ms late with --max-dt 5 ms: a third of the span matches.
  std::vector<Timestamp> late = stamps(0, 100'000'000, 101);  // 0 .. 10 s at 10 Hz
  for (std::size_t i = 0; i < late.size(); ++i)
    if (i % 3 != 0) late[i] += 7'000'000;
  write_tum(est, late);
  o.max_dt_s = 0.005;
  const auto r2 = app::run_eval(o);
  INFO(r2.report_json()["warnings"].dump());
  CHECK(r2.report_json()["association"]["n_matched"] == 34);
  CHECK(any_warning_contains(r2.report_json(), "only 34 of at most 101 poses were matched"));
}

TEST_CASE("roe eval: conflicting and invalid options are refused or named", "[app][eval]") {
  Fixture f("options", false);
  app::EvalOptions o;
  o.est = f.run.string();
  o.gt = f.dataset.string();
  SECTION("--no-out with --out") {
    o.no_out = true;
    o.out = (f.root / "out").string();
    const std::string m = test::expect_input_error([&] { app::run_eval(o); }).what();
    CHECK(m.find("--no-out") != std::string::npos);
    CHECK(m.find("--out") != std::string::npos);
    CHECK_FALSE(fs::exists(f.root / "out"));
  }
  SECTION("format and source values are checked even where they do not apply") {
    o.no_out = true;
    o.est_format = "foo";  // a run folder: the format is not used, the value is still wrong
    std::string m = test::expect_input_error([&] { app::run_eval(o); }).what();
    CHECK(m.find("--est-format") != std::string::npos);
    CHECK(m.find("'foo'") != std::string::npos);
    o.est_format = "auto";
    o.gt_format = "bar";  // a dataset folder
    m = test::expect_input_error([&] { app::run_eval(o); }).what();
    CHECK(m.find("--gt-format") != std::string::npos);
    o.gt_format = "auto";
    o.gt = (f.dataset / "mav0/mocap0/data.csv").string();
    o.gt_source = "baz";  // a ground-truth file
    m = test::expect_input_error([&] { app::run_eval(o); }).what();
    CHECK(m.find("--gt-source") != std::string::npos);
    // valid but unused values: a warning says they are ignored
    o.gt_source = "mocap";
    o.est_format = "tum";
    o.t_offset_s = -f.offset_s;
    const auto r = app::run_eval(o);
    CHECK(any_warning_contains(r.report_json(), "--gt-source mocap is ignored"));
    CHECK(any_warning_contains(r.report_json(), "--est-format tum is ignored"));
  }
  SECTION("--n-align with --align origin: a warning, the first pair is used") {
    o.no_out = true;
    o.align = "origin";
    o.n_align = 5;
    const auto r = app::run_eval(o);
    CHECK(r.report_json()["alignment"]["n_aligned"] == 1);
    CHECK(any_warning_contains(r.report_json(), "--n-align 5 is ignored with --align origin"));
    o.n_align = -1;
    CHECK_FALSE(any_warning_contains(app::run_eval(o).report_json(), "--n-align"));
  }
}

TEST_CASE("roe eval CLI: --summary with an evaluation's options, --no-out with --out", "[app][eval][cli]") {
  Fixture f("cli_usage", false);
  app::EvalOptions o;
  o.est = f.run.string();
  o.gt = f.dataset.string();
  app::run_eval(o);  // writes run/eval/report.json
  const std::string report = (f.run / "eval/report.json").string();
  auto r = test::run_roe("eval " + f.run.string() + " --gt " + f.dataset.string() + " --summary " + report);
  INFO(r.out);
  CHECK(r.code == 2);
  CHECK(r.out.find("--summary") != std::string::npos);
  CHECK(r.out.find("--gt") != std::string::npos);
  r = test::run_roe("eval --summary " + report + " --align none");
  CHECK(r.code == 2);
  CHECK(r.out.find("--align") != std::string::npos);
  r = test::run_roe("eval --summary " + report);
  CHECK(r.code == 0);
  r = test::run_roe("eval " + f.run.string() + " --gt " + f.dataset.string() + " --no-out --out " +
                    (f.root / "x").string());
  INFO(r.out);
  CHECK(r.code == 2);
  CHECK(r.out.find("--no-out") != std::string::npos);
  CHECK(r.out.find("--out") != std::string::npos);
  r = test::run_roe("eval " + f.run.string() + " --gt " + f.dataset.string() + " --no-out --est-format foo");
  CHECK(r.code == 2);
  CHECK(r.out.find("--est-format") != std::string::npos);
}

TEST_CASE("roe eval --summary: mixed settings are warned about and listed per run", "[app][eval]") {
  Fixture f("summary_mixed");
  const auto eval_to = [&](const std::string& name, const std::string& align, double max_dt) {
    app::EvalOptions o;
    o.est = f.run.string();
    o.gt = f.dataset.string();
    o.out = (f.root / name).string();
    o.label = name;  // one run folder evaluated three ways: labelled apart (else a duplicate-label warning)
    o.align = align;
    o.max_dt_s = max_dt;
    app::run_eval(o);
    return (f.root / name / "report.json").string();
  };
  const std::string a = eval_to("a", "se3", 0.01), b = eval_to("b", "none", 0.01), c = eval_to("c", "se3", 0.02);
  app::EvalSummaryOptions so;
  so.reports = {a, c};
  so.out = (f.root / "same").string();
  // same alignment, different max-dt
  auto s = app::summarize_eval_reports(so);
  REQUIRE(s.summary["warnings"].size() == 1);
  CHECK(s.summary["warnings"][0].get<std::string>().find("--max-dt (run 1 0.01, run 2 0.02)") !=
        std::string::npos);
  CHECK(s.to_text().find("warning: the reports were made with different --max-dt") != std::string::npos);
  CHECK(s.summary["settings"]["alignment"] == "se3");
  CHECK_FALSE(s.summary["settings"].contains("max_dt_s"));
  // alignment differs too
  so.reports = {a, b};
  so.out = (f.root / "mixed.csv").string();
  s = app::summarize_eval_reports(so);
  INFO(s.summary["warnings"].dump());
  REQUIRE(s.summary["warnings"].size() == 1);
  CHECK(s.summary["warnings"][0].get<std::string>().find("alignment (--align) (run 1 se3, run 2 none)") !=
        std::string::npos);
  CHECK(s.summary["runs"][1]["alignment"] == "none");
  CHECK(s.summary["runs"][0]["max_dt_s"] == 0.01);
  CHECK(s.summary["runs"][0]["t_offset_s"] == 0.0);
  CHECK(s.summary["runs"][0]["assoc"] == "nearest");
  CHECK(s.summary["runs"][0]["n_align"] == -1);
  const auto js = io::parse_json_file(f.root / "mixed.json");
  CHECK(js["warnings"].size() == 1);
  {
    std::ifstream csv(f.root / "mixed.csv");
    std::string header, row1, row2;
    std::getline(csv, header);
    std::getline(csv, row1);
    std::getline(csv, row2);
    CHECK(header.size() > 40);
    CHECK(header.find(",alignment,n_align,max_dt_s,t_offset_s,assoc") != std::string::npos);
    CHECK(row1.find(",se3,-1,0.01,0,nearest") != std::string::npos);
    CHECK(row2.find(",none,-1,0.01,0,nearest") != std::string::npos);
  }
  // identical settings: no settings warning, the settings under the table; the one report given twice
  // has one label twice, which is said
  so.reports = {a, a};
  so.out.clear();
  s = app::summarize_eval_reports(so);
  REQUIRE(s.summary["warnings"].size() == 1);
  CHECK(s.summary["warnings"][0].get<std::string>() ==
        "runs 1, 2 are all labelled 'a': the rows cannot be told apart by label (set `roe eval --label NAME` when "
        "evaluating)");
  CHECK(s.markdown.find("Settings of every run: alignment se3") != std::string::npos);
}

TEST_CASE("roe eval --summary --out: a folder gets summary.*, the input reports are never replaced",
          "[app][eval]") {
  Fixture f("summary_out");
  app::EvalOptions o;
  o.est = f.run.string();
  o.gt = f.dataset.string();
  app::run_eval(o);
  const fs::path report = f.run / "eval/report.json";
  const std::string before = io::read_file(report);
  app::EvalSummaryOptions so;
  so.reports = {report.string()};
  SECTION("a path ending in / : created, summary.csv/.json/.md inside, no hidden files") {
    so.out = (f.root / "sumdir").string() + "/";
    const auto s = app::summarize_eval_reports(so);
    for (const char* n : {"summary.csv", "summary.json", "summary.md"}) CHECK(fs::exists(f.root / "sumdir" / n));
    CHECK_FALSE(fs::exists(f.root / "sumdir/.csv"));
    CHECK(s.written.size() == 3);
  }
  SECTION("an existing folder without the trailing separator") {
    fs::create_directories(f.root / "existing");
    so.out = (f.root / "existing").string();
    app::summarize_eval_reports(so);
    for (const char* n : {"summary.csv", "summary.json", "summary.md"}) CHECK(fs::exists(f.root / "existing" / n));
    CHECK_FALSE(fs::exists(f.root / "existing/.csv"));
  }
  SECTION("--out naming an input report, even with --force") {
    so.force = true;
    so.out = (f.run / "eval/report").string();  // would write eval/report.json
    const std::string m = test::expect_input_error([&] { app::summarize_eval_reports(so); }).what();
    CHECK(m.find("input") != std::string::npos);
    CHECK(io::read_file(report) == before);
    CHECK_FALSE(fs::exists(f.run / "eval/report.csv"));
    so.out = (f.run / "eval").string() + "/";  // the folder form is eval/summary.*: fine
    CHECK_NOTHROW(app::summarize_eval_reports(so));
    CHECK(io::read_file(report) == before);
  }
}

// ROE_PYTHON names an interpreter that exists but cannot import matplotlib: the status says the
// import failed (with Python's own message), not that python is missing. A bare name is looked up on
// PATH.
TEST_CASE("roe eval --plot: interpreter not found vs matplotlib import failure", "[app][eval][plot]") {
  Fixture f("plot_msg");
  const fs::path bin = f.root / "bin";
  fs::create_directories(bin);
  const fs::path fake = bin / "fakepython";
  std::ofstream(fake) << "#!/bin/sh\n"
                         "echo 'Traceback (most recent call last):' >&2\n"
                         "echo \"ModuleNotFoundError: No module named 'matplotlib'\" >&2\n"
                         "exit 1\n";
  fs::permissions(fake, fs::perms::owner_all);
  app::EvalOptions o;
  o.est = f.run.string();
  o.gt = f.dataset.string();
  o.plot = true;
  o.force = true;
  const fs::path eval_dir = f.run / "eval";
  // A plotting failure is an error, and nothing of the output folder is written (nor left behind).
  const auto message = [&] {
    const InputError e = test::expect_input_error([&] { app::run_eval(o); });
    CHECK_FALSE(fs::exists(eval_dir));
    for (const auto& entry : fs::directory_iterator(f.run)) CHECK(entry.path().filename().string().find(".tmp") == std::string::npos);
    return std::string(e.what());
  };
  SECTION("a path to an interpreter without matplotlib") {
    ScopedEnv py("ROE_PYTHON", fake.string());
    const std::string m = message();
    INFO(m);
    CHECK(m.find("importing matplotlib or numpy failed") != std::string::npos);
    CHECK(m.find("No module named 'matplotlib'") != std::string::npos);
    CHECK(m.find("not found") == std::string::npos);
  }
  SECTION("a bare name found on PATH") {
    ScopedEnv path("PATH", bin.string() + ":" + (std::getenv("PATH") ? std::getenv("PATH") : "/usr/bin:/bin"));
    ScopedEnv py("ROE_PYTHON", "fakepython");
    const std::string m = message();
    INFO(m);
    CHECK(m.find("importing matplotlib or numpy failed") != std::string::npos);
    CHECK(m.find(fake.string()) != std::string::npos);
  }
  SECTION("an interpreter that does not exist") {
    ScopedEnv py("ROE_PYTHON", "no-such-python-roe");
    CHECK(message().find("no-such-python-roe was not found on PATH") != std::string::npos);
    ScopedEnv py2("ROE_PYTHON", (f.root / "nope/python3").string());
    CHECK(message().find("was not found") != std::string::npos);
  }
  SECTION("a script that crashes is an internal error naming its last lines") {
    const fs::path crash = bin / "crashpython";
    std::ofstream(crash) << "#!/bin/sh\necho 'ZeroDivisionError: division by zero' >&2\nexit 1\n";
    fs::permissions(crash, fs::perms::owner_all);
    ScopedEnv py("ROE_PYTHON", crash.string());
    try {
      app::run_eval(o);
      FAIL("expected an error");
    } catch (const InputError&) {
      FAIL("a crash is not bad input");
    } catch (const Error& e) {
      CHECK(std::string(e.what()).find("ZeroDivisionError") != std::string::npos);
    }
    CHECK_FALSE(fs::exists(eval_dir));
  }
}

TEST_CASE("roe eval: the two inputs are read at once, their errors as a sequential read reports them",
          "[app][eval]") {
  // The estimate is read on this thread while the ground truth is read on another: a bad file is named
  // with its line and column, and when both are bad it is the estimate (the file a sequential read
  // opens first), every time.
  const fs::path dir = fs::temp_directory_path() / "roe_test_eval_concurrent_errors";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const auto write = [&](const std::string& name, bool tum, int bad_line) {
    std::ofstream f(dir / name);
    if (!tum) f << "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z []\n";
    for (int i = 0; i < 20000; ++i) {
      const int line = i + (tum ? 1 : 2);
      const std::string x = line == bad_line ? "1.5x" : std::to_string(0.01 * i);
      if (tum)
        f << fmt::format("{}.{:09d} {} {} {} 0 0 0 1\n", 1000 + i / 100, (i % 100) * 10'000'000, x, i % 7, i % 5);
      else
        f << fmt::format("{},{},{},{},1,0,0,0\n", 1'000'000'000'000LL + i * 10'000'000LL, x, i % 7, i % 5);
    }
  };
  write("est.tum", true, 0);
  write("est_bad.tum", true, 15000);
  write("gt.csv", false, 0);
  write("gt_bad.csv", false, 123);
  app::EvalOptions o;
  o.no_out = true;
  const auto error_of = [&](const std::string& est, const std::string& gt) {
    o.est = (dir / est).string();
    o.gt = (dir / gt).string();
    try {
      app::run_eval(o);
    } catch (const InputError& e) {
      return e.context();
    }
    return ErrorContext("");
  };
  CHECK(error_of("est.tum", "gt.csv").file.empty());
  for (int rep = 0; rep < 10; ++rep) {
    const ErrorContext est_bad = error_of("est_bad.tum", "gt.csv");
    CHECK(est_bad.file == (dir / "est_bad.tum").string());
    CHECK(est_bad.line == 15000);
    CHECK(est_bad.column == 2);
    const ErrorContext gt_bad = error_of("est.tum", "gt_bad.csv");
    CHECK(gt_bad.file == (dir / "gt_bad.csv").string());
    CHECK(gt_bad.line == 123);
    CHECK(gt_bad.column == 2);
    const ErrorContext both = error_of("est_bad.tum", "gt_bad.csv");  // the ground truth fails first in time
    CHECK(both.file == (dir / "est_bad.tum").string());
    CHECK(both.line == 15000);
  }
  fs::remove_all(dir);
}
