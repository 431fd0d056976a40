// End-to-end: the roe executable's `calib-check`. Exit codes (DESIGN §1): 0 no check failed, 1 a
// check failed (or, with --strict, one was skipped or inconclusive), 2 bad usage or bad input. With
// --json stdout is one JSON document with every check; nothing is written to disk.
#include "support/test_util.hpp"

#include <catch2/catch.hpp>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

namespace fs = std::filesystem;

namespace {
std::string q(const fs::path& p) { return "'" + p.string() + "'"; }
}  // namespace

TEST_CASE("roe calib-check: exit codes 0/1/2, --json, --strict, thresholds", "[cli][calib]") {
  roe::test::TempDir tmp("roe_cli_calib");
  const fs::path ds = tmp / "ds", run = tmp / "run";
  const fs::path cfg = tmp.write("sc.json", R"({"filter": {"use_detection_sigmas": true,
    "extrinsics_sigma_p_m": 0.05, "extrinsics_sigma_rot_deg": 5.0}})");
  REQUIRE(roe::test::run_roe("simulate --preset matched-calib --seed 7 --duration 40 -q --out " + q(ds)).code == 0);
  REQUIRE(roe::test::run_roe("run " + q(ds) + " -q --config " + q(cfg) + " --out " + q(run)).code == 0);
  const auto listing_before = std::distance(fs::directory_iterator(run), fs::directory_iterator{});

  // Every check passes; the human table names each one.
  auto r = roe::test::run_roe("calib-check " + q(run));
  INFO(r.out);
  CHECK(r.code == 0);
  for (const char* name : {"dataset.identity", "extrinsics.sigma", "extrinsics.settled", "extrinsics.prior",
                           "objects.sigma", "truth.extrinsics", "truth.objects", "camera.time_offset"})
    CHECK_THAT(r.out, Catch::Contains(name));
  CHECK_THAT(r.out, Catch::Contains("PASS: 8 passed"));

  // --json: one document on stdout.
  r = roe::test::run_roe("calib-check --json " + q(run), false);
  const auto j = nlohmann::json::parse(r.out);
  CHECK(j["command"] == "calib-check");
  CHECK(j["out"].is_null());
  CHECK(j["passed"] == true);
  CHECK(j["checks"].size() == 8);
  CHECK(j["warnings"].is_array());

  // A σ limit tighter than the run achieved is "unobservable" (not calibrated by these data, not
  // contradicted by them): exit 0, and 1 with --strict.
  r = roe::test::run_roe("calib-check " + q(run) + " --max-sigma-p 0.0001");
  CHECK(r.code == 0);
  CHECK_THAT(r.out, Catch::Contains("unobservable"));
  CHECK(roe::test::run_roe("calib-check -q --strict " + q(run) + " --max-sigma-p 0.0001").code == 1);

  // --no-dataset skips four checks: not applicable, so fine even with --strict. An inconclusive
  // check (a settle window longer than half the 40 s run) fails only with --strict.
  CHECK(roe::test::run_roe("calib-check -q --no-dataset " + q(run)).code == 0);
  CHECK(roe::test::run_roe("calib-check -q --no-dataset --strict " + q(run)).code == 0);
  CHECK(roe::test::run_roe("calib-check -q --no-dataset --settle-min 25 " + q(run)).code == 0);
  CHECK(roe::test::run_roe("calib-check -q --no-dataset --settle-min 25 --strict " + q(run)).code == 1);

  // Bad usage and bad input: exit 2, naming what is wrong.
  r = roe::test::run_roe("calib-check " + q(run) + " --max-time-offset 0");
  CHECK(r.code == 2);
  CHECK_THAT(r.out, Catch::Contains("--max-time-offset"));
  // A confidence of 1 has no χ² quantile; a fraction of 1 is the whole run.
  r = roe::test::run_roe("calib-check " + q(run) + " --confidence 1");
  CHECK(r.code == 2);
  CHECK_THAT(r.out, Catch::Contains("--confidence: must be a number in (0.5, 1), got '1'"));
  r = roe::test::run_roe("calib-check --no-dataset " + q(run) + " --settle-fraction 1");
  CHECK(r.code == 0);  // the whole run: the convergence from the prior, explained by its shrinking σ
  CHECK_THAT(r.out, Catch::Contains("over the last 40.0 s"));
  CHECK_THAT(r.out, Catch::Contains("still converging"));
  CHECK(roe::test::run_roe("calib-check -q " + q(run) + " --settle-fraction 0").code == 2);
  r = roe::test::run_roe("calib-check " + q(run) + " --no-dataset --dataset " + q(ds));
  CHECK(r.code == 2);
  r = roe::test::run_roe("calib-check " + q(ds));
  CHECK(r.code == 2);
  CHECK_THAT(r.out, Catch::Contains("run.json is missing"));

  // It writes nothing.
  CHECK(std::distance(fs::directory_iterator(run), fs::directory_iterator{}) == listing_before);
}
