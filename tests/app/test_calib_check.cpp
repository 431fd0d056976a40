// roe calib-check end to end in the library: simulate → write → roe run → calib_check, on a
// calibration motion (matched-calib, 40 s) where every check can be decided.
#include <catch2/catch.hpp>
#include "../calib/check_lookup.hpp"
#include <fstream>

#include "../ekf/filter_support.hpp"
#include "../support/test_util.hpp"
#include "roe/app/calib_check.hpp"
#include "roe/app/run.hpp"
#include "roe/core/error.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/json.hpp"
#include "roe/math/so3.hpp"

using namespace roe;
using calib::CheckStatus;
namespace fs = std::filesystem;

namespace {

/// Writes the dataset and runs roe run on it with the self-calibration settings of the issue's
/// test (per-detection σ, a 5 cm / 5° prior); returns the run folder.
fs::path write_and_run(const Dataset& d, const test::TempDir& tmp, const std::string& name,
                       const std::string& filter_json =
                           R"({"use_detection_sigmas": true, "extrinsics_sigma_p_m": 0.05, "extrinsics_sigma_rot_deg": 5.0})") {
  const fs::path ds = tmp / name;
  store::write_dataset(d, ds, false);
  // The causal filter: calib-check judges the filter (it reads states_filter.csv after a smoother).
  const fs::path cfg = tmp.write(name + ".json", R"({"smoother": "none", "filter": )" + filter_json + "}");
  app::RunOptions o;
  o.config_file = cfg.string();
  const fs::path run = tmp / (name + "-run");
  app::run(ds, run, o);
  return run;
}

const Dataset& calibration_dataset() {
  static const Dataset d = test::simulate_preset("matched-calib", 7, 40.0);
  return d;
}

const calib::CheckResult& get(const app::CalibCheckResult& r, const std::string& name) {
  return test::check_named(r.report, name);
}
double value(const calib::CheckResult& c, const std::string& key) { return test::check_value(c, key); }

std::string describe(const app::CalibCheckResult& r) { return r.to_text(); }

}  // namespace

TEST_CASE("calib-check: a self-calibrating run under a calibration motion passes all eight checks",
          "[app][calib]") {
  const test::TempDir tmp("roe_calib");
  const fs::path run = write_and_run(calibration_dataset(), tmp, "ds");
  const auto r = app::calib_check(run, {});
  INFO(describe(r));
  REQUIRE(r.report.checks.size() == 8);
  CHECK(r.report.checks.front().name == "dataset.identity");
  for (const auto& c : r.report.checks) CHECK(c.status == CheckStatus::kPass);
  CHECK(r.exit_code() == 0);
  CHECK(r.dataset_from == "run.json");
  const auto& t = get(r, "camera.time_offset");
  CHECK(std::abs(value(t, "estimate_s")) < 0.005);
  // Measured 3.4 ms, the jackknife's (curvature 2.4, cluster-robust 2.7), with object 16's detections
  // left out.
  CHECK(value(t, "sigma_s") < 0.004);
  // Objects marked symmetric in roe.json are left out of the time offset (docs/calib-check.md §3).
  const Dataset& d = calibration_dataset();
  std::size_t of_symmetric = 0;
  for (const auto& o : d.manifest.objects)
    if (o.symmetric)
      for (const auto& det : d.detections.at(r.detections)) of_symmetric += det.object_id == o.id;
  CHECK(of_symmetric > 0);
  CHECK(value(t, "symmetric_excluded") == static_cast<double>(of_symmetric));
  CHECK_THAT(t.message, Catch::Contains("detections of symmetric objects left out"));
  const auto j = r.to_json();
  CHECK(j["command"] == "calib-check");
  CHECK(j["passed"] == true);
  CHECK(j["counts"]["pass"] == 8);
  CHECK(j["checks"][1]["name"] == "extrinsics.sigma");
  CHECK(j["checks"][1]["values"].contains("sigma_p_x_m"));
}

TEST_CASE("calib-check: a wrong extrinsics prior fails extrinsics.prior even when the filter recovers the truth",
          "[app][calib]") {
  // The camchain is 6 cm off per axis (10 cm) against the default 2 cm / 2° prior σ. Under the
  // calibration motion the filter pulls p_I_C back to within a few mm of the truth (measured 3.8 mm),
  // and the shift from the prior is what tells the user that the camchain file is wrong.
  Dataset d = calibration_dataset();
  d.manifest.camera->T_I_C.p += Eigen::Vector3d(0.06, -0.06, 0.06);
  const test::TempDir tmp("roe_calib");
  const fs::path run = write_and_run(d, tmp, "ds", R"({"use_detection_sigmas": true})");
  const auto r = app::calib_check(run, {});
  INFO(describe(r));
  const auto& p = get(r, "extrinsics.prior");
  CHECK(p.status == CheckStatus::kFail);
  CHECK(value(p, "d2") > value(p, "limit_d2"));
  CHECK_THAT(p.message, Catch::Contains("disagree with the prior"));
  CHECK(value(p, "shift_p_m") > 0.08);
  CHECK(get(r, "truth.extrinsics").status == CheckStatus::kPass);
  CHECK(r.exit_code() == 1);
}

TEST_CASE("calib-check: camera stamps 30 ms early fail camera.time_offset, declaring the offset passes it",
          "[app][calib]") {
  Dataset d = calibration_dataset();
  for (auto& [name, set] : d.detections)
    for (auto& det : set) det.t_ns -= 30'000'000;  // the image was taken 30 ms after its stamp
  const test::TempDir tmp("roe_calib");
  {
    const auto r = app::calib_check(write_and_run(d, tmp, "late"), {});
    INFO(describe(r));
    const auto& t = get(r, "camera.time_offset");
    CHECK(t.status == CheckStatus::kFail);
    CHECK(value(t, "estimate_s") == Approx(0.030).margin(0.005));
    CHECK_THAT(t.message, Catch::Contains("set camera.time_offset_s to 0.0"));
    CHECK(r.exit_code() == 1);
  }
  d.manifest.camera->time_offset_s = 0.030;  // roe run applies it: t_imu = t_cam + offset
  {
    const auto r = app::calib_check(write_and_run(d, tmp, "declared"), {});
    INFO(describe(r));
    const auto& t = get(r, "camera.time_offset");
    CHECK(t.status == CheckStatus::kPass);
    CHECK(std::abs(value(t, "difference_s")) < 0.005);
    CHECK(r.exit_code() == 0);
  }
}

TEST_CASE("calib-check: the dataset is the run's, another one given, none, or changed since", "[app][calib]") {
  const test::TempDir tmp("roe_calib");
  const fs::path run = write_and_run(calibration_dataset(), tmp, "ds");
  SECTION("--no-dataset: only the run folder's checks, the others skipped, which --strict accepts") {
    app::CalibCheckOptions o;
    o.no_dataset = true;
    auto r = app::calib_check(run, o);
    INFO(describe(r));
    REQUIRE(r.report.checks.size() == 8);
    for (const char* n : {"dataset.identity", "truth.extrinsics", "truth.objects", "camera.time_offset"}) {
      CHECK(get(r, n).status == CheckStatus::kSkipped);
      CHECK(get(r, n).message == "--no-dataset");
    }
    CHECK(get(r, "extrinsics.sigma").status == CheckStatus::kPass);
    CHECK(r.exit_code() == 0);
    o.strict = true;
    r = app::calib_check(run, o);
    CHECK(r.exit_code() == 0);
    CHECK_THAT(r.to_text(), Catch::Contains("--strict"));
  }
  SECTION("a changed detection file fails dataset.identity and the truth is not used") {
    std::ofstream(tmp / "ds/detections/sim/detections.csv", std::ios::app) << "\n";
    const auto r = app::calib_check(run, {});
    INFO(describe(r));
    CHECK(get(r, "dataset.identity").status == CheckStatus::kFail);
    CHECK_THAT(get(r, "dataset.identity").message, Catch::Contains("detections/sim/detections.csv"));
    CHECK(get(r, "truth.extrinsics").status == CheckStatus::kSkipped);
    CHECK(get(r, "truth.objects").status == CheckStatus::kSkipped);
    CHECK(get(r, "camera.time_offset").status == CheckStatus::kSkipped);
    CHECK(r.exit_code() == 1);
  }
  SECTION("the run's dataset moved away: a warning, identity inconclusive (--strict fails); --dataset finds it") {
    fs::rename(tmp / "ds", tmp / "moved");
    auto r = app::calib_check(run, {});
    INFO(describe(r));
    REQUIRE(r.warnings.size() == 1);
    CHECK_THAT(r.warnings[0], Catch::Contains("give --dataset"));
    CHECK(r.dataset.empty());
    CHECK(get(r, "dataset.identity").status == CheckStatus::kInconclusive);
    CHECK(get(r, "truth.extrinsics").status == CheckStatus::kSkipped);
    CHECK_THAT(get(r, "truth.extrinsics").message, Catch::Contains("no dataset"));
    CHECK(r.exit_code() == 0);
    app::CalibCheckOptions o;
    o.strict = true;
    CHECK(app::calib_check(run, o).exit_code() == 1);
    o.strict = false;
    o.dataset = (tmp / "moved").string();
    r = app::calib_check(run, o);
    CHECK(r.dataset_from == "option");
    CHECK(get(r, "dataset.identity").status == CheckStatus::kPass);
    CHECK(get(r, "truth.objects").status == CheckStatus::kPass);
  }
}

TEST_CASE("calib-check: a broken run folder is an input error naming the file, row and column", "[app][calib]") {
  const test::TempDir tmp("roe_calib");
  const fs::path run = write_and_run(calibration_dataset(), tmp, "ds");
  SECTION("no run.json") {
    fs::remove(run / "run.json");
    const auto e = test::expect_input_error([&] { app::calib_check(run, {}); });
    CHECK_THAT(e.what(), Catch::Contains("run.json is missing"));
  }
  SECTION("run.json without the extrinsics prior (an older roe)") {
    std::string text;
    {
      std::ifstream in(run / "run.json");
      text.assign(std::istreambuf_iterator<char>(in), {});
    }
    const auto at = text.find("\"T_I_C\"", text.find("\"init\""));
    REQUIRE(at != std::string::npos);
    text.replace(at, 7, "\"T_I_X\"");
    std::ofstream(run / "run.json") << text;
    const auto e = test::expect_input_error([&] { app::calib_check(run, {}); });
    CHECK(e.context().key == "init.T_I_C");  // the missing key (the unknown T_I_X comes after it)
    CHECK_THAT(e.what(), Catch::Contains("run.json"));
  }
  SECTION("an anchor_id that is not an object id") {
    auto j = io::parse_json_file(run / "run.json");
    j["anchor_id"] = "five";
    std::ofstream(run / "run.json") << j.dump();
    const auto e = test::expect_input_error([&] { app::calib_check(run, {}); });
    CHECK(e.context().key == "anchor_id");
  }
  SECTION("a malformed states.csv value") {
    std::string text;
    {
      std::ifstream in(run / "states.csv");
      text.assign(std::istreambuf_iterator<char>(in), {});
    }
    // Row 2 (line 3), column 18 = p_I_C_x.
    std::size_t line3 = text.find('\n', text.find('\n') + 1) + 1;
    std::size_t col = line3;
    for (int c = 1; c < 18; ++c) col = text.find(',', col) + 1;
    text.insert(col, "x");
    std::ofstream(run / "states.csv") << text;
    const auto e = test::expect_input_error([&] { app::calib_check(run, {}); });
    CHECK(e.context().line == 3);
    CHECK(e.context().column == 18);
    CHECK_THAT(e.context().file, Catch::Contains("states.csv"));
  }
  SECTION("--dataset that is not a dataset, and --dataset with --no-dataset") {
    app::CalibCheckOptions o;
    o.dataset = (tmp / "nowhere").string();
    CHECK_THAT(test::expect_input_error([&] { app::calib_check(run, o); }).what(), Catch::Contains("roe.json is missing"));
    o.no_dataset = true;
    CHECK_THAT(test::expect_input_error([&] { app::calib_check(run, o); }).what(), Catch::Contains("exclude"));
  }
}
