// roe report's HTML from typed values (issue 52 item 3): report_html takes the run's store::RunRecord and
// calib-check's typed result, never their JSON. The evaluation and the run are files roe wrote at earlier
// versions (tests/store/data: report.json of a40676c, run.json of fc12dc3), read by their store readers.
#include <catch2/catch.hpp>
#include <filesystem>

#include "roe/app/report.hpp"
#include "roe/store/eval_report.hpp"
#include "roe/store/run_record.hpp"

using namespace roe;
namespace fs = std::filesystem;

namespace {

fs::path data(const std::string& name) { return fs::path(ROE_SOURCE_DIR) / "tests/store/data" / name; }

std::size_t count(const std::string& s, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

}  // namespace

TEST_CASE("report html: the run's record and calib-check's result typed, or neither", "[app][report]") {
  const store::EvalReportFile ev = store::read_eval_report_file(data("report_run_a40676c.json"));
  store::RunRecord run = store::read_run_json(data("run_fc12dc3.json"));
  run.warnings = {"a <warning> & more"};
  app::CalibCheckResult calib;
  calib.report.checks = {{"extrinsics.sigma", calib::CheckStatus::kPass, "within 2 mm", {}},
                         {"gyro.bias", calib::CheckStatus::kFail, "bias < 1 deg/s", {}}};
  calib.dataset = "ds/seq4";
  const app::FigureSet none;

  const std::string with = app::report_html(ev, &run, {calib, ""}, none, ".");
  // calib-check's verdict and checks, escaped.
  CHECK_THAT(with, Catch::Contains("Verdict: <b class=\"fail\">FAIL</b> (dataset: ds/seq4)"));
  CHECK_THAT(with, Catch::Contains("<th>gyro.bias</th><td class=\"fail\">fail</td><td>bias &lt; 1 deg/s</td>"));
  CHECK_THAT(with, Catch::Contains("<th>extrinsics.sigma</th><td class=\"pass\">pass</td>"));
  // The run's blocks as run.json spells them: health open, the configuration folded; its warnings and anchor.
  CHECK(count(with, "<section id=\"health\"><details open>") == 1);
  CHECK(count(with, "<section id=\"configuration\"><details>") == 1);
  CHECK_THAT(with, Catch::Contains("<tr><th>config.filter.chi2_confidence</th>"));
  CHECK_THAT(with, Catch::Contains("<tr><th>inputs.dataset_abs</th>"));
  CHECK_THAT(with, Catch::Contains("<p>run: a &lt;warning&gt; &amp; more</p>"));
  CHECK_THAT(with, Catch::Contains("(run.json; anchor object " + std::to_string(run.anchor_id) + ")"));
  // Passing, and with no dataset: the verdict says so ("null" as calib-check's JSON has it).
  calib.report.checks.pop_back();
  calib.dataset.clear();
  CHECK_THAT(app::report_html(ev, &run, {calib, ""}, none, "."),
             Catch::Contains("Verdict: <b class=\"pass\">PASS</b> (dataset: null)"));

  // A folder without run.json, where calib-check could not run: no run tables, the reason instead.
  const std::string without = app::report_html(ev, nullptr, {std::nullopt, "not a run folder: <x>"}, none, ".");
  CHECK_THAT(without, Catch::Contains("<p class=\"fail\">calib-check could not run: not a run folder: &lt;x&gt;</p>"));
  CHECK(count(without, "id=\"health\"") == 0);
  CHECK(count(without, "id=\"configuration\"") == 0);
  CHECK(count(without, "<p>run: ") == 0);
  CHECK(count(without, "(run.json; anchor object") == 0);
}

TEST_CASE("report summary: --json and the text from the typed result", "[app][report]") {
  app::ReportResult r;
  r.out = "r.html";
  r.bytes = 2500000;
  r.figures = {"fig3"};
  r.skipped = {{"fig5", "no states.csv"}};
  r.calib.error = "no run.json";
  r.timing_s = {{"eval", 1.0}, {"calib_check", 0.5}, {"figures", 2.0}, {"html", 0.25}, {"total", 3.5}};
  r.eval = store::read_eval_report_file(data("report_run_a40676c.json"));
  const nlohmann::json j = r.to_json();
  CHECK(j["calib_check"] == nlohmann::json{{"error", "no run.json"}});
  CHECK(j["figures_skipped"][0]["reason"] == "no states.csv");
  CHECK(j["figures_dir"].is_null());
  CHECK(j["ape_trans_rmse_m"] == r.eval.ape_trans_m.rmse);
  const std::string t = r.to_text();
  CHECK_THAT(t, Catch::Contains("roe report: r.html (2.5 MB, 1 figures)"));
  CHECK_THAT(t, Catch::Contains("calib-check: not run (no run.json)"));
  CHECK_THAT(t, Catch::Contains("fig5 not drawn: no states.csv"));
  CHECK_THAT(t, Catch::Contains("3.50 s (eval 1.00, figures 2.00 with calib-check 0.50 alongside, html 0.25)"));
  r.calib = {app::CalibCheckResult{}, ""};
  CHECK(r.to_json()["calib_check"]["counts"]["pass"] == 0);
  CHECK_THAT(r.to_text(), Catch::Contains("calib-check: FAIL"));  // nothing judged: not passed
}
