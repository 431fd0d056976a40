// report.json as one typed value (store/eval_report.hpp): the writer reproduces files the earlier,
// untyped writer made (a40676c) byte for byte, the reader is strict (a missing or mistyped key names its
// path), and the headline metrics agree with the summary.csv roe eval wrote beside the report.
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include "roe/core/error.hpp"
#include "roe/io/json.hpp"
#include "roe/store/eval_report.hpp"

using namespace roe;
using nlohmann::json;

namespace {

const std::string kData = std::string(ROE_SOURCE_DIR) + "/tests/store/data/";

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string file_text(const store::EvalReportFile& f) { return io::dump_json(store::to_json(f), 2) + "\n"; }

/// The InputError the reader throws for `j` (empty key when it throws none).
std::string rejected_key(const json& j) {
  try {
    (void)store::read_eval_report(j, "bad/report.json");
  } catch (const InputError& e) {
    CHECK(e.context().file == "bad/report.json");
    CHECK(std::string(e.what()).find(e.context().key) != std::string::npos);  // the message names the path
    return e.context().key;
  }
  return "";
}

/// A report without covariances, objects, body rotation or calibration, under the `error` metric, with a
/// subset without matches and the optional blocks set.
store::EvalReportFile small_report() {
  store::EvalReportFile f;
  f.title = "roe eval: t";
  f.label = "t";
  f.roe_version = "0.0.0-test";
  f.est = {"est.tum", "file", "tum", "est.tum (tum)", 10, 0};
  f.gt = {"gt.tum", "file", "tum", "gt.tum (tum)", 12, 1};
  f.association = {0.01, 0.0, "nearest", 12, 10, 10, 10, 0, 0.0};
  f.alignment.type = "se3";
  f.alignment.n_aligned = 10;
  f.ape_trans_m.rmse = 0.25;
  f.ape_trans_m.n = 10;
  f.euler_metric = f.per_axis.euler_metric = "error";
  f.per_axis.pos_rmse_m = {0.1, 0.2, 0.3};
  f.per_axis.rpy_deg.rmse = {1.0, 2.0, 3.0};
  f.consistency.gauge.reason = "no covariances";
  f.consistency.frame = "none";
  store::ReportObject o;
  o.object_id = 7;
  o.counts = {{"accepted", 3}, {"rejected_chi2", 1}};
  o.all.n = 4;
  o.all.pos_rmse_m = {0.5, 0.25, 0.125};
  f.per_object.push_back(o);  // o.accepted.n == 0: written as {"n": 0}
  store::ReportRpe e;
  e.delta = 50.0;
  e.unit = "m";
  e.pairs_from = "est";
  f.rpe.push_back(e);  // no pairs: null statistics
  f.warnings = {"w1"};
  f.outputs = store::ReportOutputs{"out", {"a.csv", "b.csv"}};
  f.plots = store::ReportPlots{true, "drawn"};
  return f;
}

}  // namespace

TEST_CASE("report.json files of the earlier writer read back and write back byte for byte", "[store][eval_report]") {
  for (const char* name : {"report_run_a40676c.json", "report_bag_a40676c.json"}) {
    INFO(name);
    const std::string text = slurp(kData + name);
    REQUIRE(!text.empty());
    const store::EvalReportFile f = store::read_eval_report(json::parse(text), name);
    CHECK(file_text(f) == text);
    // write → read → write is the identity on the typed value's file
    CHECK(file_text(store::read_eval_report(store::to_json(f), name)) == text);
  }
  // what the typed value holds, checked against the file as nlohmann parses it
  const json j = json::parse(slurp(kData + "report_run_a40676c.json"));
  const store::EvalReportFile f = store::read_eval_report(j, "run");
  CHECK(f.label == j["info"]["label"]);
  CHECK(f.est_is_run());
  CHECK(f.per_axis.pos_rmse_m.y() == j["per_axis"]["pos_rmse_m"]["y"].get<double>());
  CHECK(f.per_axis.rotation_error_euler_deg.std.z() == j["per_axis"]["rotation_error_euler_deg"]["std"]["yaw"].get<double>());
  REQUIRE(f.body_rotation);
  CHECK(f.body_rotation->with.ape_rot_deg.rmse == j["body_rotation"]["with"]["ape_rot_deg"]["rmse"].get<double>());
  REQUIRE(f.rpe.size() == 2);
  CHECK(f.rpe[1].n_pairs == 0);
  CHECK_FALSE(f.rpe[1].trans_m);
  REQUIRE(f.detection_calibration);
  CHECK(f.detection_calibration->all.sigma_scale_hi == j["detection_calibration"]["all"]["sigma_scale_ci95"][1].get<double>());
  CHECK(f.detection_calibration->per_object.size() == j["detection_calibration"]["per_object"].size());
  CHECK(f.per_object.size() == j["per_object"].size());
  CHECK(f.per_object[0].counts.at("accepted") == j["per_object"][0]["counts"]["accepted"].get<std::size_t>());
  CHECK(f.consistency.gauge.available);
  CHECK(f.evo_results == std::optional<std::string>("fx.zip"));
  REQUIRE(f.outputs);
  CHECK(f.outputs->files.size() == j["outputs"]["files"].size());
  CHECK_FALSE(f.plots);
}

TEST_CASE("headline metrics: names once, values as roe eval's summary.csv wrote them", "[store][eval_report]") {
  const std::vector<std::string> want = {"rmse_x_m",       "rmse_y_m",     "rmse_z_m",   "rmse_roll_deg",
                                         "rmse_pitch_deg", "rmse_yaw_deg", "ate_rmse_m", "rot_rmse_deg"};
  CHECK(store::headline_metric_names() == want);
  // summary.csv is written by a different writer (eval::Report → CSV) from the same evaluation
  std::istringstream csv(slurp(kData + "summary_run_a40676c.csv"));
  std::string header, row;
  REQUIRE(std::getline(csv, header));
  REQUIRE(std::getline(csv, row));
  // summary.csv: one header line, one row (numbers and paths, no quoting)
  const auto cells = [](const std::string& line) {
    std::vector<std::string> out;
    for (std::size_t a = 0, b = 0; b != std::string::npos; a = b + 1) out.push_back(line.substr(a, (b = line.find(',', a)) - a));
    return out;
  };
  const std::vector<std::string> h = cells(header), v = cells(row);
  REQUIRE(h.size() == v.size());
  const store::EvalReportFile f = store::read_eval_report_file(kData + "report_run_a40676c.json");
  const auto metrics = store::headline_metrics(f);
  REQUIRE(metrics.size() == want.size());
  for (std::size_t k = 0; k < metrics.size(); ++k) {
    INFO(metrics[k].first);
    CHECK(metrics[k].first == want[k]);
    const auto col = std::find(h.begin(), h.end(), metrics[k].first);
    REQUIRE(col != h.end());
    CHECK(metrics[k].second == Approx(std::stod(v[static_cast<std::size_t>(col - h.begin())])).epsilon(1e-12));
  }
}

TEST_CASE("the report.json reader is strict: a missing or mistyped key names its path", "[store][eval_report]") {
  const json good = json::parse(slurp(kData + "report_run_a40676c.json"));
  REQUIRE(rejected_key(good).empty());
  SECTION("missing keys") {
    const std::vector<std::vector<std::string>> paths = {{"per_axis", "pos_rmse_m", "y"},
                                                         {"info", "label"},
                                                         {"association", "n_matched"},
                                                         {"consistency", "gauge", "description"},
                                                         {"detection_calibration", "all", "nis_quantiles", "p50"},
                                                         {"warnings"}};
    for (const auto& p : paths) {
      json j = good;
      json* parent = &j;
      std::string dotted;
      for (std::size_t i = 0; i + 1 < p.size(); ++i) parent = &(*parent)[p[i]];
      for (const auto& k : p) dotted += (dotted.empty() ? "" : ".") + k;
      parent->erase(p.back());
      CHECK(rejected_key(j) == dotted);
    }
  }
  SECTION("mistyped values") {
    json j = good;
    j["ape_trans_m"]["rmse"] = "small";
    CHECK(rejected_key(j) == "ape_trans_m.rmse");
    j = good;
    j["association"]["n_matched"] = -1;  // a count
    CHECK(rejected_key(j) == "association.n_matched");
    j = good;
    j["alignment"]["t"] = {1.0, 2.0};  // three numbers
    CHECK(rejected_key(j) == "alignment.t");
    j = good;
    j["rpe"][1]["all_pairs"] = 1;
    CHECK(rejected_key(j) == "rpe[1].all_pairs");
    j = good;
    j["per_object"][0]["counts"]["accepted"] = 2.5;
    CHECK(rejected_key(j) == "per_object[0].counts.accepted");
    j = good;
    j["options"] = json::array();
    CHECK(rejected_key(j) == "options");
    CHECK_THROWS_AS(store::read_eval_report(json::array(), "list.json"), InputError);
  }
  SECTION("not JSON at all: the file named") {
    CHECK_THROWS_AS(store::read_eval_report_file(kData + "summary_run_a40676c.csv"), InputError);
  }
}

TEST_CASE("report.json: NaN is written as null and reads back as NaN", "[store][eval_report]") {
  json j = json::parse(slurp(kData + "report_bag_a40676c.json"));
  j["ape_trans_m"]["median"] = nullptr;
  const store::EvalReportFile f = store::read_eval_report(j, "nan");
  CHECK(std::isnan(f.ape_trans_m.median));
  CHECK(json::parse(io::dump_json(store::to_json(f)))["ape_trans_m"]["median"].is_null());  // as the file has it
}

TEST_CASE("report.json round trip of the optional and conditional blocks", "[store][eval_report]") {
  const store::EvalReportFile f = small_report();
  const json j = store::to_json(f);
  // conditional keys: none of the absolute-metric block under `error`, the reason of a missing gauge
  CHECK_FALSE(j["per_axis"].contains("rotation_error_euler_deg"));
  CHECK_FALSE(j["per_axis"].contains("jump_360_share"));
  CHECK(j["consistency"]["gauge"] == json{{"available", false}, {"reason", "no covariances"}});
  CHECK(j["per_object"][0]["accepted"] == json{{"n", 0}});
  CHECK(j["rpe"][0]["trans_m"].is_null());
  CHECK(j["body_rotation"].is_null());
  CHECK(j["detection_calibration"].is_null());
  CHECK_FALSE(j.contains("evo_results"));
  CHECK(j["plots"] == json{{"ok", true}, {"status", "drawn"}});
  const store::EvalReportFile back = store::read_eval_report(j, "small");
  CHECK(file_text(back) == file_text(f));
  CHECK(back.per_object[0].all.pos_rmse_m == f.per_object[0].all.pos_rmse_m);
  CHECK(back.per_object[0].counts == f.per_object[0].counts);
  CHECK(back.outputs->files == f.outputs->files);
  CHECK_FALSE(back.evo_results);
}
