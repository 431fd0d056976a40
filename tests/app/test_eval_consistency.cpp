// roe eval's consistency figures and Euler metrics end to end: matched Monte-Carlo runs
// (simulate -> run -> eval) whose ANEES in the estimator's gauge lies in its 95 % bounds for the
// position and the orientation; report.json's Euler-metric keys and the text on trajectory files
// that cross ±180°; --fit-body-rotation on a run folder.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "../ekf/filter_support.hpp"
#include "roe/app/eval.hpp"
#include "roe/app/run.hpp"
#include "roe/app/sweep.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/json.hpp"
#include "roe/math/distributions.hpp"
#include "roe/math/euler.hpp"

using namespace roe;
namespace fs = std::filesystem;
using Eigen::Vector3d;

namespace {

fs::path fresh_dir(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("roe_test_eval_cons_" + name);
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}

void write_tum(const fs::path& f, const std::vector<double>& t, const std::vector<Pose>& poses) {
  std::ofstream o(f);
  o.precision(17);
  for (std::size_t i = 0; i < t.size(); ++i)
    o << t[i] << " " << poses[i].p.x() << " " << poses[i].p.y() << " " << poses[i].p.z() << " " << poses[i].q.x()
      << " " << poses[i].q.y() << " " << poses[i].q.z() << " " << poses[i].q.w() << "\n";
}

}  // namespace

// The matched preset's noise is the configured noise (the per-detection σ the simulator wrote), as in
// the filter's own Monte-Carlo test (tests/ekf/test_filter_sim.cpp), but through the files and roe eval:
// N runs, the mean of their ANEES against the two-sided 95 % bounds [χ²_{3N}(0.025)/N, χ²_{3N}(0.975)/N].
TEST_CASE("roe eval: matched Monte-Carlo ANEES in the estimator's gauge inside the 95 % bounds, position and orientation",
          "[app][eval][consistency][mc]") {
  const fs::path root = fresh_dir("mc");
  app::RunConfig cfg = test::plain_config();
  cfg.filter.use_detection_sigmas = true;
  cfg.filter.init_sigma_v_mps = 1.0;
  {
    std::ofstream(root / "config.json") << io::dump_json(app::run_config_to_json(cfg), 2);
  }
  const int N = 20;
  double sum_p = 0.0, sum_r = 0.0, sum_r_aligned = 0.0;
  for (int run = 0; run < N; ++run) {
    const fs::path ds = root / ("ds" + std::to_string(run)), out = root / ("run" + std::to_string(run));
    store::write_dataset(test::simulate_preset("matched", 100 + run, 20.0), ds, true);
    app::RunOptions ro;
    ro.config_file = (root / "config.json").string();
    (void)app::run(ds, out, ro);
    app::EvalOptions eo;
    eo.est = out.string();
    eo.gt = ds.string();
    eo.no_out = true;
    const auto r = app::run_eval(eo);
    const auto c = r.report_json()["consistency"];
    INFO("run " << run << ": " << io::dump_json(c, 2));
    REQUIRE(c["frame"] == "estimator gauge");
    sum_p += c["anees_p"].get<double>();
    sum_r += c["anees_r"].get<double>();
    sum_r_aligned += c["aligned"]["anees_r"].get<double>();
  }
  const double lo = math::chi2_quantile(0.025, 3.0 * N) / N, hi = math::chi2_quantile(0.975, 3.0 * N) / N;
  WARN("matched MC through roe eval: ANEES position " << sum_p / N << ", orientation " << sum_r / N << " (bounds " << lo
                                                     << ", " << hi << "); orientation after the alignment "
                                                     << sum_r_aligned / N);
  CHECK(sum_p / N > lo);
  CHECK(sum_p / N < hi);
  CHECK(sum_r / N > lo);
  CHECK(sum_r / N < hi);
  fs::remove_all(root);
}

TEST_CASE("roe eval --euler: report.json keys, the rotation error beside it, the 360-deg share, the text",
          "[app][eval][euler]") {
  const fs::path root = fresh_dir("euler");
  // Ground truth yaw sweeping through ±180° (positions on a curve, so the SE(3) alignment is exact),
  // the estimate 4° ahead in yaw: it crosses one sample before the truth does.
  std::vector<double> t;
  std::vector<Pose> gt, est;
  for (int i = 0; i < 40; ++i) {
    const double yaw = 151.0 + 2.0 * i;  // 151 .. 229 = −131 (never exactly ±180)
    const Vector3d p(std::cos(0.1 * i), std::sin(0.13 * i), 0.05 * i);
    t.push_back(1.0 + 0.1 * i);
    gt.push_back(Pose(Eigen::Quaterniond(math::from_euler_zyx(Vector3d(0, 0, yaw * math::kRadPerDeg))), p));
    est.push_back(Pose(Eigen::Quaterniond(math::from_euler_zyx(Vector3d(0, 0, (yaw + 4.0) * math::kRadPerDeg))), p));
  }
  write_tum(root / "gt.tum", t, gt);
  write_tum(root / "est.tum", t, est);
  app::EvalOptions o;
  o.est = (root / "est.tum").string();
  o.gt = (root / "gt.tum").string();
  const auto def = app::run_eval([&] {
    app::EvalOptions d = o;
    d.out = (root / "e_error").string();
    return d;
  }());
  CHECK(def.report_json()["euler_metric"] == "error");
  CHECK(def.report_json()["per_axis"]["euler_metric"] == "error");
  CHECK(!def.report_json()["per_axis"].contains("rotation_error_euler_deg"));
  CHECK(def.report_json()["per_axis"]["rpy_rmse_deg"]["yaw"].get<double>() == Approx(4.0).epsilon(1e-9));
  CHECK(def.report_json()["per_axis"]["rpy_mean_deg"]["yaw"].get<double>() == Approx(-4.0).epsilon(1e-9));
  CHECK(def.report_json()["per_axis"]["rpy_std_deg"]["yaw"].get<double>() == Approx(0.0).margin(1e-5));

  o.euler = "absolute-unwrapped";
  o.out = (root / "e_unwrapped").string();
  const auto un = app::run_eval(o);
  const auto pa = un.report_json()["per_axis"];
  // The estimate crosses 180 two samples before the truth: gt 177 / est 181 = −179 and gt 179 / est 183 =
  // −177 give est − gt = −356; the other 38 pairs +4.
  const double rmse = std::sqrt((38 * 16.0 + 2 * 356.0 * 356.0) / 40);
  CHECK(un.report_json()["euler_metric"] == "absolute-unwrapped");
  CHECK(pa["rpy_rmse_deg"]["yaw"].get<double>() == Approx(rmse).epsilon(1e-6));
  CHECK(pa["rpy_mean_deg"]["yaw"].get<double>() == Approx((38 * 4.0 - 2 * 356.0) / 40).epsilon(1e-6));
  CHECK(pa["jump_360_share"]["yaw"].get<double>() == Approx(2.0 / 40));
  CHECK(pa["jump_360_share"]["any"].get<double>() == Approx(2.0 / 40));
  CHECK(pa["rotation_error_euler_deg"]["rmse"]["yaw"].get<double>() ==
        def.report_json()["per_axis"]["rpy_rmse_deg"]["yaw"].get<double>());
  CHECK(pa["warning"].get<std::string>().find("not a rotation error") != std::string::npos);
  bool warned = false;
  for (const std::string& w : un.report.warnings)
    warned = warned || w.find("not a rotation error (5.00 % of the pairs jumped") != std::string::npos;
  CHECK(warned);
  const std::string text = un.to_text();
  CHECK(text.find("metric 'absolute-unwrapped'") != std::string::npos);
  CHECK(text.find("rotation error R_est^T*R_gt (metric 'error')") != std::string::npos);
  CHECK(text.find("any axis 5.00 %") != std::string::npos);
  CHECK(un.report_json()["options"]["euler"] == "absolute-unwrapped");

  o.euler = "absolute";
  o.out = (root / "e_absolute").string();
  const auto ab = app::run_eval(o);
  CHECK(ab.report_json()["per_axis"]["rpy_rmse_deg"]["yaw"].get<double>() == Approx(4.0).epsilon(1e-9));
  CHECK(ab.report_json()["per_axis"]["rpy_mean_deg"]["yaw"].get<double>() == Approx(4.0).epsilon(1e-9));

  // --summary carries the metric's name in its header, and warns when the runs mix metrics.
  app::EvalSummaryOptions so;
  so.reports = {(root / "e_unwrapped").string(), (root / "e_unwrapped" / "report.json").string()};
  const auto s1 = app::summarize_eval_reports(so);
  CHECK(s1.markdown.find("(roll, pitch, yaw) [deg], Euler metric 'absolute-unwrapped'") != std::string::npos);
  CHECK(s1.markdown.find("Euler metric absolute-unwrapped.") != std::string::npos);
  so.reports = {(root / "e_unwrapped").string(), (root / "e_error").string()};
  const auto s2 = app::summarize_eval_reports(so);
  CHECK(s2.markdown.find("Euler metric 'mixed'") != std::string::npos);
  CHECK(s2.markdown.find("different Euler metric (--euler)") != std::string::npos);

  o.euler = "wrapped";
  CHECK_THROWS_AS(app::run_eval(o), InputError);
  fs::remove_all(root);
}

TEST_CASE("roe eval --fit-body-rotation: report.json and text, never applied to the headline", "[app][eval][body]") {
  const fs::path root = fresh_dir("body");
  const Eigen::Quaterniond q_body(Eigen::AngleAxisd(30.0 * math::kRadPerDeg, Vector3d(0.3, -1, 0.5).normalized()));
  std::vector<double> t;
  std::vector<Pose> gt, est;
  for (int i = 0; i < 200; ++i) {
    const double s = 0.05 * i;
    t.push_back(0.1 * i);
    gt.push_back(Pose(Eigen::Quaterniond(math::from_euler_zyx(Vector3d(0.5 * std::sin(s), 0.3 * std::cos(0.7 * s), s))),
                      Vector3d(std::cos(s), std::sin(0.8 * s), 0.2 * s)));
    est.push_back(Pose(gt.back().q * q_body.conjugate(), gt.back().p));
  }
  write_tum(root / "gt.tum", t, gt);
  write_tum(root / "est.tum", t, est);
  app::EvalOptions o;
  o.est = (root / "est.tum").string();
  o.gt = (root / "gt.tum").string();
  o.no_out = true;
  o.fit_body_rotation = true;
  const auto r = app::run_eval(o);
  const auto b = r.report_json()["body_rotation"];
  REQUIRE(b.is_object());
  CHECK(b["angle_deg"].get<double>() == Approx(30.0).margin(1e-6));
  CHECK(b["with"]["ape_rot_deg"]["rmse"].get<double>() < 1e-6);
  CHECK(b["without"]["ape_rot_deg"]["rmse"].get<double>() == Approx(30.0).margin(1e-6));
  CHECK(r.report_json()["ape_rot_deg"]["rmse"].get<double>() == Approx(30.0).margin(1e-6));  // the headline keeps it
  CHECK(r.report_json()["options"]["fit_body_rotation"] == true);
  CHECK(r.to_text().find("body-frame rotation fit (diagnostic, not applied above)") != std::string::npos);
  o.fit_body_rotation = false;
  CHECK(app::run_eval(o).report_json()["body_rotation"].is_null());
  fs::remove_all(root);
}

TEST_CASE("roe sweep aggregate names the Euler metric of its columns", "[app][eval][euler][sweep]") {
  // Sweep jobs evaluate with roe eval's default metric: the tables say which one the roll/pitch/yaw columns hold.
  std::vector<app::JobResult> jobs;
  for (int seed = 1; seed <= 2; ++seed) {
    app::JobResult j{"job" + std::to_string(seed), {{"dataset", "d"}, {"seed", seed}}, {}};
    for (const auto& m : app::sweep_metric_names()) j.metrics[m] = 0.1 * seed;
    jobs.push_back(j);
  }
  const app::Aggregate ag = app::aggregate_results(jobs, {"dataset", "seed"}, {});
  CHECK(std::string(app::kDefaultEulerMetric) == "error");
  CHECK(ag.markdown().find("Euler metric 'error'") != std::string::npos);
  CHECK(ag.latex().find("Euler metric 'error'") != std::string::npos);
  CHECK(ag.to_json()["euler_metric"] == "error");
}
