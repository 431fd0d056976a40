// roe run's output levels (issue 41, docs/filter.md §9): full, standard, minimal, and what the readers of a
// run folder (eval, calib-check, refine) say about each.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "../ekf/filter_support.hpp"
#include "roe/app/calib_check.hpp"
#include "roe/app/eval.hpp"
#include "roe/app/refine.hpp"
#include "roe/app/run.hpp"
#include "roe/core/error.hpp"
#include "roe/io/csv.hpp"
#include "roe/io/json.hpp"
#include "roe/store/dataset.hpp"
#include "support/test_util.hpp"

namespace fs = std::filesystem;
using namespace roe;

namespace {

std::set<std::string> files_in(const fs::path& dir) {
  std::set<std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) out.insert(e.path().filename().string());
  return out;
}

/// The rows of a CSV as text fields (header first).
std::vector<std::vector<std::string>> csv_rows(const fs::path& file) {
  std::ifstream in(file);
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) f.push_back(cell);
    if (!line.empty() && line.back() == ',') f.push_back("");
    rows.push_back(f);
  }
  return rows;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// One simulated dataset and its three runs, made once for the test cases below.
struct Runs {
  test::TempDir tmp{"roe_test_levels"};
  fs::path ds = tmp / "ds", full = tmp / "full", standard = tmp / "standard", minimal = tmp / "minimal";
  app::RunResult r_full, r_standard, r_minimal;
  Runs() {
    store::write_dataset(test::simulate_preset("matched", 5, 10.0), ds, true);
    app::RunOptions o;
    r_full = app::run(ds, full, o);  // the default level
    o.output_level = "standard";
    r_standard = app::run(ds, standard, o);
    o.output_level = "minimal";
    r_minimal = app::run(ds, minimal, o);
  }
};

Runs& runs() {
  static Runs r;
  return r;
}

}  // namespace

TEST_CASE("output levels: which files each writes, and run.json says the level", "[app][run][levels]") {
  Runs& r = runs();
  const std::set<std::string> all = {"objects.csv",         "reprojection.csv",      "run.json",
                                     "states.csv",          "states_filter.csv",     "trajectory.csv",
                                     "trajectory.tum",      "trajectory_filter.csv", "trajectory_filter.tum"};
  CHECK(files_in(r.full) == all);
  CHECK(files_in(r.standard) == all);
  CHECK(files_in(r.minimal) == std::set<std::string>{"run.json", "trajectory.csv", "trajectory.tum"});
  // "full" is not echoed (a default run's config, and a sweep job's id, stay what they were); the others are.
  CHECK_FALSE(io::parse_json_file(r.full / "run.json").at("config").at("output").contains("level"));
  CHECK(io::parse_json_file(r.standard / "run.json").at("config").at("output").at("level") == "standard");
  CHECK(io::parse_json_file(r.minimal / "run.json").at("config").at("output").at("level") == "minimal");
  // The trajectory is the same at every level, byte for byte.
  for (const char* f : {"trajectory.csv", "trajectory.tum"}) {
    CHECK(slurp(r.full / f) == slurp(r.standard / f));
    CHECK(slurp(r.full / f) == slurp(r.minimal / f));
  }
  for (const char* f : {"trajectory_filter.csv", "objects.csv", "reprojection.csv"})
    CHECK(slurp(r.full / f) == slurp(r.standard / f));
}

TEST_CASE("output level standard: the full level's rows, σ at the first row and the first after each image",
          "[app][run][levels]") {
  Runs& r = runs();
  // The image times with detections (reprojection.csv) and the rows at which σ is due: the first, then the
  // first row strictly after each image.
  std::vector<std::int64_t> images;
  for (const auto& p : store::read_reprojection_csv(r.full / "reprojection.csv"))
    if (images.empty() || images.back() != p.t_ns) images.push_back(p.t_ns);
  REQUIRE(images.size() > 100);
  for (const char* file : {"states.csv", "states_filter.csv"}) {
    INFO(file);
    const auto a = csv_rows(r.full / file), b = csv_rows(r.standard / file);
    REQUIRE(a.size() == b.size());
    REQUIRE(a[0] == b[0]);
    const std::size_t first_sigma =
        static_cast<std::size_t>(std::find(a[0].begin(), a[0].end(), "sigma_p_W_I_x") - a[0].begin());
    // 21 σ, then time_offset_s (a value on every row) and sigma_time_offset_s (a σ like the others).
    REQUIRE(first_sigma + 23 == a[0].size());
    const std::size_t td_col = first_sigma + 21;
    std::size_t next_image = 0, with_sigma = 0, means_differ = 0, sigma_differ = 0, misplaced = 0;
    for (std::size_t i = 1; i < a.size(); ++i) {
      REQUIRE(b[i].size() == a[i].size());
      const std::int64_t t = std::stoll(a[i][0]);
      bool due = i == 1;
      while (next_image < images.size() && images[next_image] < t) {
        due = true;
        ++next_image;
      }
      for (std::size_t c = 0; c < first_sigma; ++c) means_differ += a[i][c] != b[i][c];
      means_differ += a[i][td_col] != b[i][td_col];
      const bool has = !b[i][first_sigma].empty();
      misplaced += has != due;
      for (std::size_t c = first_sigma; c < a[i].size(); ++c) {
        if (c == td_col) continue;
        CHECK(b[i][c].empty() == !has);  // all 22 σ cells or none
        if (has) sigma_differ += a[i][c] != b[i][c];
      }
      with_sigma += has;
    }
    CHECK(means_differ == 0);
    CHECK(sigma_differ == 0);  // the smoother forms the same covariance where it is asked, bit for bit
    CHECK(misplaced == 0);
    CHECK(with_sigma > images.size() / 2);
    CHECK(with_sigma < (a.size() - 1) / 4);
  }
  // The reader gives the unrecorded σ as nan; the recorded ones as written.
  // (The rows went into the file as they were produced: the file's own cells are the reference.)
  const auto rows = store::read_states_csv(r.standard / "states.csv");
  const auto cells = csv_rows(r.standard / "states.csv");  // the header, then the rows
  REQUIRE(rows.size() == r.r_standard.output.state_rows);
  REQUIRE(cells.size() == rows.size() + 1);
  const std::size_t s0 = 24;  // sigma_p_W_I_x, then the other 20 σ
  REQUIRE(cells[0][s0] == "sigma_p_W_I_x");
  std::size_t nan_rows = 0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const auto& c = cells[i + 1];
    const bool none = c[s0].empty();
    nan_rows += none;
    CHECK(rows[i].sigma.array().isNaN().all() == none);
    for (int k = 0; k < 21 && !none; ++k) CHECK(rows[i].sigma(k) == std::stod(c[s0 + static_cast<std::size_t>(k)]));
  }
  CHECK(nan_rows > rows.size() / 2);
}

TEST_CASE("output levels: roe eval's NEES over the poses with σ, and what it cannot compute", "[app][run][levels]") {
  Runs& r = runs();
  const auto eval_of = [&](const fs::path& run) {
    app::EvalOptions o;
    o.est = run.string();
    o.gt = r.ds.string();
    return app::run_eval(o).report;
  };
  const store::EvalReportFile full = eval_of(r.full), standard = eval_of(r.standard), minimal = eval_of(r.minimal);
  // Same trajectory, same metrics.
  CHECK(full.ape_trans_m.rmse == standard.ape_trans_m.rmse);
  CHECK(full.ape_trans_m.rmse == minimal.ape_trans_m.rmse);
  REQUIRE(full.consistency.available);
  REQUIRE(standard.consistency.available);
  // The estimator-gauge NEES over the poses that have σ: fewer poses, the same consistency within noise.
  REQUIRE(full.consistency.gauge.available);
  REQUIRE(standard.consistency.gauge.available);
  CHECK(standard.consistency.gauge.n < full.consistency.gauge.n / 4);
  CHECK(standard.consistency.gauge.n > 100);
  CHECK(*standard.consistency.gauge.anees_p == Approx(*full.consistency.gauge.anees_p).epsilon(0.3));
  const auto has_warning = [](const store::EvalReportFile& f, const std::string& text) {
    return std::any_of(f.warnings.begin(), f.warnings.end(),
                       [&](const std::string& w) { return w.find(text) != std::string::npos; });
  };
  CHECK(has_warning(standard, "NEES over the "));
  CHECK_FALSE(has_warning(full, "NEES over the "));
  // minimal: no NEES, no per-object traces, and the warnings say why.
  CHECK_FALSE(minimal.consistency.available);
  CHECK(minimal.per_object.empty());
  CHECK(has_warning(minimal, "NEES not computed: the run was written with output level minimal"));
  CHECK(has_warning(minimal, "per-object reprojection traces not computed: the run was written with output level minimal"));
}

TEST_CASE("output level minimal: calib-check cannot judge, refine refuses with the reason", "[app][run][levels]") {
  Runs& r = runs();
  const app::CalibCheckResult full = app::calib_check(r.full, {}), minimal = app::calib_check(r.minimal, {});
  REQUIRE(minimal.report.checks.size() == full.report.checks.size());
  for (std::size_t i = 0; i < full.report.checks.size(); ++i) {
    const calib::CheckResult& c = minimal.report.checks[i];
    CHECK(c.name == full.report.checks[i].name);
    if (c.name == "dataset.identity") {
      CHECK(c.status == calib::CheckStatus::kPass);
      continue;
    }
    CHECK(c.status == calib::CheckStatus::kInconclusive);
    CHECK(c.message.find("cannot judge: the run was written with output level minimal") == 0);
  }
  CHECK(minimal.exit_code() == 0);
  app::CalibCheckOptions strict;
  strict.strict = true;
  CHECK(app::calib_check(r.minimal, strict).exit_code() == 1);
  // standard: the same verdicts and numbers as full (the extrinsics trace is the rows with σ).
  const app::CalibCheckResult standard = app::calib_check(r.standard, {});
  CHECK(standard.to_json().at("checks") == full.to_json().at("checks"));

  const test::TempDir tmp("roe_test_levels_refine");
  const fs::path out = tmp / "refine";
  try {
    app::refine_run(r.minimal, out, {});
    FAIL("no error");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).find("output level minimal") != std::string::npos);
    CHECK(e.context().key == "config.output.level");
  }
  CHECK_FALSE(fs::exists(out));
}

TEST_CASE("output level: the config key, --output over it, and bad values", "[app][run][levels]") {
  const store::RunConfig c = store::run_config_from_json(io::json::parse(R"({"output": {"level": "standard"}})"), "c.json");
  CHECK(c.output_level == store::OutputLevel::kStandard);
  CHECK(store::run_config_to_json(c).at("output").at("level") == "standard");
  CHECK(store::run_config_from_json(store::run_config_to_json(c), "echo").output_level == store::OutputLevel::kStandard);
  CHECK_FALSE(store::run_config_to_json(store::RunConfig{}).at("output").contains("level"));
  try {
    store::run_config_from_json(io::json::parse(R"({"output": {"level": "most"}})"), "c.json");
    FAIL("no error");
  } catch (const ConfigError& e) {
    CHECK(e.context().key == "output.level");
    CHECK(std::string(e.what()).find("\"full\", \"standard\" or \"minimal\"") != std::string::npos);
  }
  // What each level holds, and why a reader finds a file absent.
  store::RunConfig m;
  m.output_level = store::OutputLevel::kMinimal;
  CHECK(store::run_folder_has(m, "trajectory.tum"));
  CHECK_FALSE(store::run_folder_has(m, "objects.csv"));
  CHECK(store::run_file_absent_reason(m, "states.csv").find("output level minimal") != std::string::npos);
  store::RunConfig none;
  none.estimator = store::Estimator::kFilter;
  CHECK_FALSE(store::run_folder_has(none, "states_filter.csv"));
  CHECK(store::run_folder_has(none, "states.csv"));
  CHECK(store::run_file_absent_reason(none, "states.csv").empty());
  CHECK_FALSE(store::sigma_at_every_row(store::run_config_from_json(io::json::parse(R"({"output": {"level": "standard"}})"), "c")));
  CHECK(store::sigma_at_every_row(
      store::run_config_from_json(io::json::parse(R"({"output": {"level": "standard", "rate": "images"}})"), "c")));

  // --output wins over the config's level.
  Runs& r = runs();
  const test::TempDir tmp("roe_test_levels_override");
  const fs::path cfg = tmp.write("cfg.json", R"({"output": {"level": "full"}})"), out = tmp / "override";
  app::RunOptions o;
  o.config_file = cfg.string();
  o.output_level = "minimal";
  app::run(r.ds, out, o);
  CHECK(files_in(out) == std::set<std::string>{"run.json", "trajectory.csv", "trajectory.tum"});
}
