// run.json typed (store/run_record.hpp): write → read → write is the same text, the reader is strict
// (missing, mistyped and unknown keys name the key path, line and column), and the one rule for the dataset a
// run read.
#include <catch2/catch.hpp>
#include <cmath>
#include <fstream>
#include <limits>

#include "roe/core/error.hpp"
#include "roe/io/json.hpp"
#include "roe/store/run_record.hpp"
#include "support/test_util.hpp"

using namespace roe;
using namespace roe::store;
namespace fs = std::filesystem;

namespace {

/// A record with a value in every field (none at its default), as roe run and roe refine write them.
RunRecord full_record() {
  RunRecord r;
  r.roe_version = "9.9.9";
  r.config.filter.min_score = 0.25;
  r.config.estimator = Estimator::kFilter;
  r.inputs = {"ds", "/abs/ds", "poet", {{"roe.json", "ab"}, {"mav0/imu0/data.csv", "cd"}}, "c.json", "/abs/c.json"};
  r.anchor_id = 3;
  r.counts.imu_samples = 24000;
  r.counts.camera_frames = 600;
  r.counts.images_with_detections = 590;
  r.counts.updates = 580;
  r.counts.trajectory_rows = 24000;
  r.counts.per_object[3].detections = 7;
  r.counts.per_object[3].accepted = 5;
  r.counts.per_object[12].rejected_chi2 = 2;
  r.counts.detections.detections = 9;
  r.nis = {10, 5.1, 3.0, 7.5, 12.0, 20.0, 5.9, 12.59, 0.1, 0.95};
  r.health = {{"a problem"}, 60.0, 580, 0.97, 1.5, 10.25, 11.75, 0.95, {}};
  r.relocks.push_back({12.5, 11.0, {0.1, -0.2, 0.3}, {0.01, 0.02, -0.03}, 0.004, 14, 2});
  r.detection_sigmas = {true, true, 1.7};
  r.init.T_I_C = Pose(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized())),
                      Eigen::Vector3d(0.01, -0.02, 0.1 / 3.0));
  r.init.window_samples = 200;
  r.init.window_s = 0.995;
  r.init.gyro_bias = {1e-3, -2e-3, 1.0 / 3.0};
  r.init.gyro_bias_from = "rest";
  r.init.gyro_bias_rest_refused = "moving";
  r.imu_noise = {1e-4, 2e-5, 1e-3, 3e-3};
  r.imu_noise_from = {"dataset", "config", "dataset", "dataset"};
  r.final_T_I_C = r.init.T_I_C;
  r.final_objects = {{3, true, Pose()}, {12, false, r.init.T_I_C}};
  r.final_time_offset = FinalTimeOffset{true, 0.002, 0.0173, 0.0004};
  r.warnings = {"w1", "w2"};
  r.timing_s = {{"read", 0.125}, {"total", 0.5}};
  return r;
}

RunRecord refine_record() {
  RunRecord r = full_record();
  r.command = "refine";
  r.refine.emplace();
  r.refine->loss = "cauchy";
  r.refine->linear_solver = "sparse_normal_cholesky";
  r.refine->loss_scale = 3.5;
  r.refine->max_iterations = 50;
  r.refine->fit_rounds = 2;
  r.refine->error_model.fitted_tau = true;
  r.refine->error_model.tau_s = std::numeric_limits<double>::quiet_NaN();  // written as null, read as NaN
  r.refine->error_model.scale_rotation = 0.3;
  r.refine->error_model.gross = 80;
  r.refine->nodes = 61;
  r.refine->termination = "CONVERGENCE";
  r.refine->input_run = "run";
  return r;
}

}  // namespace

TEST_CASE("run.json: write, read and write again give the same text, every field", "[store][run_json]") {
  for (const RunRecord& r : {full_record(), refine_record(), RunRecord{}}) {
    const std::string text = format_run_json(r);
    const RunRecord back = run_record_from_json(io::parse_json_text(text, "run.json"), "run.json");
    CHECK(format_run_json(back) == text);
    CHECK(back.counts.per_object.size() == r.counts.per_object.size());
    CHECK(back.init.T_I_C.q.coeffs() == r.init.T_I_C.q.coeffs());
    CHECK(back.refine.has_value() == r.refine.has_value());
  }
  const RunRecord back = run_record_from_json(io::json::parse(format_run_json(refine_record())), "x");
  CHECK(std::isnan(back.refine->error_model.tau_s));
  CHECK(back.refine->error_model.gross == 80);
  CHECK(back.refine->error_model.scale_rotation == 0.3);
  CHECK(back.counts.per_object.at(12).rejected_chi2 == 2);
  CHECK(back.relocks.at(0).drift_per_s.z() == -0.03);
  CHECK(back.inputs.config_abs == "/abs/c.json");
  CHECK(back.health.problems == std::vector<std::string>{"a problem"});
  CHECK(back.config.filter.min_score == 0.25);
  CHECK(back.config.estimator == Estimator::kFilter);
  // final.time_offset (issue 49) round-trips; a run.json written before it has none.
  const RunRecord full = run_record_from_json(io::json::parse(format_run_json(full_record())), "x");
  REQUIRE(full.final_time_offset.has_value());
  CHECK(full.final_time_offset->estimated);
  CHECK(full.final_time_offset->value_s == 0.0173);
  CHECK(full.final_time_offset->sigma_s == 0.0004);
  CHECK(full.final_time_offset->declared_s == 0.002);
  io::json old = run_record_to_json(full_record());
  old["final"].erase("time_offset");
  CHECK(!run_record_from_json(old, "x").final_time_offset.has_value());
  // Without --config the two config keys are absent, and read back empty.
  RunRecord plain = full_record();
  plain.inputs.config.clear();
  plain.inputs.config_abs.clear();
  const io::json j = run_record_to_json(plain);
  CHECK(!j.at("inputs").contains("config"));
  CHECK(run_record_from_json(j, "x").inputs.config.empty());
}

TEST_CASE("run.json: a missing, mistyped or unknown key is an input error naming the key, line and column",
          "[store][run_json]") {
  const test::TempDir tmp("roe_run_record");
  const fs::path file = tmp.path / "run.json";
  // A key that is there (or whose object is) is located by line; a missing top-level key has no line.
  const auto expect = [&](const std::function<void(io::json&)>& edit, const std::string& key, bool located = true) {
    io::json j = run_record_to_json(full_record());
    edit(j);
    std::ofstream(file) << io::dump_json(j, 2);
    const auto e = test::expect_input_error([&] { read_run_json(file); });
    CHECK(e.context().key == key);
    CHECK(e.context().file == file.string());
    CHECK((e.context().line > 0) == located);
  };
  expect([](io::json& j) { j["counts"]["detections"]["per_object"]["3"].erase("accepted"); },
         "counts.detections.per_object.3.accepted");
  expect([](io::json& j) { j["inputs"]["detections"] = 5; }, "inputs.detections");
  expect([](io::json& j) { j["anchor_id"] = "five"; }, "anchor_id");
  expect([](io::json& j) { j["health"]["limits"]["extra"] = 1; }, "health.limits.extra");
  expect([](io::json& j) { j["config"]["filter"]["min_score"] = "high"; }, "config.filter.min_score");
  expect([](io::json& j) { j["init"]["gyro_bias"] = {1, 2}; }, "init.gyro_bias");
  expect([](io::json& j) { j["health"]["healthy"] = true; }, "health.healthy");  // contradicts its problems
  expect([](io::json& j) { j["relocks"][0].erase("objects"); }, "relocks[0].objects");
  expect([](io::json& j) { j["command"] = "refine"; }, "refine", false);  // roe refine's run.json has its block
  expect([](io::json& j) { j.erase("timing_s"); }, "timing_s", false);
  // A folder without run.json names the folder.
  const auto e = test::expect_input_error([&] { read_run_folder_record(tmp.path / "nothing"); });
  CHECK_THAT(e.what(), Catch::Contains("run.json is missing"));
}

TEST_CASE("run.json: the dataset a run read is inputs.dataset_abs, else inputs.dataset, when it holds roe.json",
          "[store][run_json]") {
  const test::TempDir tmp("roe_run_dataset");
  const fs::path abs = tmp.path / "abs", rel = tmp.path / "rel";
  fs::create_directories(abs);
  fs::create_directories(rel);
  RunRecord r;
  r.inputs.dataset_abs = abs.string();
  r.inputs.dataset = rel.string();
  CHECK(!find_run_dataset(r));  // neither is a dataset folder (no roe.json)
  std::ofstream(rel / "roe.json") << "{}";
  CHECK(find_run_dataset(r) == rel);
  std::ofstream(abs / "roe.json") << "{}";
  CHECK(find_run_dataset(r) == abs);  // the absolute path first
  fs::remove(abs / "roe.json");
  fs::remove(rel / "roe.json");
  CHECK(!find_run_dataset(r));
}

TEST_CASE("run.json: a config without one of its sections or keys, and a detection σ scale the filter never writes, "
          "are refused naming the key", "[store][run_json][hostile]") {
  const test::TempDir tmp("roe_run_record");
  const fs::path file = tmp.path / "run.json";
  const auto refused = [&](const std::function<void(io::json&)>& edit) {
    io::json j = run_record_to_json(full_record());
    edit(j);
    std::ofstream(file) << io::dump_json(j, 2);
    return test::expect_input_error([&] { read_run_json(file); });
  };
  CHECK(refused([](io::json& j) { j["config"].erase("filter"); }).context().key == "config.filter");
  CHECK(refused([](io::json& j) { j["config"]["filter"].erase("min_score"); }).context().key ==
        "config.filter.min_score");
  CHECK(refused([](io::json& j) { j["config"].erase("health"); }).context().key == "config.health");
  for (const io::json& bad : {io::json(0.0), io::json(-1.0), io::json(nullptr), io::json(1e308), io::json(8.5),
                             io::json(0.1)}) {
    const auto e = refused([&](io::json& j) { j["detection_sigmas"]["final_scale"] = bad; });
    CHECK(e.context().key == "detection_sigmas.final_scale");
  }
  // The filter's own bounds are read: σ scale 1/8 and 8 (variance 1/64 and 64).
  for (const double ok : {0.125, 8.0, 1.0}) {
    io::json j = run_record_to_json(full_record());
    j["detection_sigmas"]["final_scale"] = ok;
    CHECK(run_record_from_json(j, "run.json").detection_sigmas.final_scale == ok);
  }
}

// Run folders written before 2026-12-07 (roe at fc12dc3: `roe run` and `roe refine` on datasets/sample, the files
// kept in tests/store/data) still read: the configuration keys added since (the time offset, issue 49) are
// absent there and read as the default that roe ran with, and the refine block of the white-factor refine
// (issue 48 replaced it) reads with its error model marked as of that layout. Any other missing key is refused.
TEST_CASE("run.json: run and refine folders written before issues 48 and 49 still read", "[store][run_json]") {
  const std::string data = std::string(ROE_SOURCE_DIR) + "/tests/store/data/";
  const RunRecord run = read_run_json(data + "run_fc12dc3.json");
  CHECK(run.command == "run");
  CHECK_FALSE(run.config.filter.estimate_time_offset);
  CHECK_FALSE(run.final_time_offset.has_value());
  CHECK_FALSE(run.refine.has_value());
  const RunRecord ref = read_run_json(data + "refine_fc12dc3.json");
  REQUIRE(ref.refine.has_value());
  CHECK(ref.refine->earlier_layout);
  CHECK(ref.refine->loss == "cauchy");
  CHECK(ref.refine->detection_factors == 2456);
  CHECK(std::isnan(ref.refine->error_model.tau_s));
  // Today's writer writes today's layout; what it writes reads back as today's record.
  const RunRecord again = run_record_from_json(run_record_to_json(ref), "again");
  CHECK_FALSE(again.refine->earlier_layout);
  CHECK(again.refine->detection_factors == 2456);
  // Only the keys added later may be absent: a key the older roe wrote is still required.
  io::json j = io::json::parse(std::ifstream(data + "run_fc12dc3.json"));
  j["config"]["filter"].erase("min_score");
  const InputError e = test::expect_input_error([&] { run_record_from_json(j, "run.json"); });
  CHECK(e.context().key == "config.filter.min_score");
  // The earlier refine layout is recognised by its own keys, not by a missing one.
  io::json r = io::json::parse(std::ifstream(data + "refine_fc12dc3.json"));
  r["refine"]["options"].erase("correlated_errors");
  test::expect_input_error([&] { run_record_from_json(r, "run.json"); });
}
