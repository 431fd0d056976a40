// roe run's batch estimator ("estimator": "batch", docs/refine.md §8): filter → smoother → refine in one
// run folder, the same estimate as roe run followed by roe refine.
#include <catch2/catch.hpp>
#include <cmath>
#include <fstream>
#include <iterator>

#include "roe/app/calib_check.hpp"
#include "roe/app/refine.hpp"
#include "roe/app/run.hpp"
#include "roe/app/simulate.hpp"
#include "roe/core/error.hpp"
#include "roe/io/json.hpp"
#include "roe/math/se3.hpp"
#include "roe/store/dataset.hpp"
#include "roe/store/run_files.hpp"
#include "roe/store/run_record.hpp"
#include "support/test_util.hpp"

namespace {

using namespace roe;
namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

/// The largest position and rotation (rad) difference between two trajectories' rows at the same times.
std::pair<double, double> max_difference(const std::vector<store::RecordedState>& a,
                                         const std::vector<store::RecordedState>& b) {
  REQUIRE(a.size() == b.size());
  double dp = 0.0, dr = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    REQUIRE(a[i].t_ns == b[i].t_ns);
    dp = std::max(dp, (a[i].x.p_W_I - b[i].x.p_W_I).norm());
    dr = std::max(dr, a[i].x.q_W_I.angularDistance(b[i].x.q_W_I));
  }
  return {dp, dr};
}

/// A preset's dataset in tmp/ds.
fs::path simulated(const test::TempDir& tmp, const char* preset, std::uint64_t seed, double duration_s) {
  app::SimulateOptions so;
  so.preset = preset;
  so.seed = seed;
  so.duration_s = duration_s;
  app::simulate(so, tmp / "ds");
  return tmp / "ds";
}

}  // namespace

TEST_CASE("refine/batch: roe run with the batch estimator is roe run then roe refine, in one folder") {
  test::TempDir tmp("roe_batch");
  simulated(tmp, "paper-real-seq4", 2, 20.0);

  app::RunOptions smoother;
  app::run(tmp / "ds", tmp / "run", smoother);
  app::refine_run(tmp / "run", tmp / "refined", {});

  app::RunOptions batch;
  batch.estimator = "batch";
  app::set_batch_estimator(nullptr);  // roe itself: refused before anything is read or written
  CHECK_THROWS_AS(app::run(tmp / "ds", tmp / "batch", batch), InputError);
  CHECK_FALSE(fs::exists(tmp / "batch"));
  app::set_batch_estimator(&app::batch_estimate);  // what roe-refine registers (cli/cmd_refine.cpp)
  const app::RunResult r = app::run(tmp / "ds", tmp / "batch", batch);

  // The filter's own estimate is in the _filter files, byte for byte the smoother run's.
  for (const char* f : {"states_filter.csv", "trajectory_filter.csv", "trajectory_filter.tum"})
    CHECK(slurp(tmp / "batch" / f) == slurp(tmp / "run" / f));
  // The main files are the refined estimate: roe refine's of the smoother run (which read the run's files, at
  // their printed precision), not the smoother's.
  const auto batch_states = store::read_states_csv(tmp / "batch" / "states.csv");
  const auto [dp, dr] = max_difference(batch_states, store::read_states_csv(tmp / "refined" / "states.csv"));
  CHECK(dp < 2e-3);
  CHECK(dr < 2e-3 / 57.3);
  const auto [sp, sr] = max_difference(batch_states, store::read_states_csv(tmp / "run" / "states.csv"));
  CHECK(sp > 5.0 * dp);
  const store::RunRecord rec = store::read_run_json(tmp / "batch" / "run.json");
  const store::RunRecord ref = store::read_run_json(tmp / "refined" / "run.json");
  CHECK(rec.command == "run");
  CHECK(rec.config.estimator == store::Estimator::kBatch);
  REQUIRE(rec.refine);
  CHECK(rec.refine->solves == ref.refine->solves);
  CHECK(std::abs(rec.refine->error_model.tau_s - ref.refine->error_model.tau_s) < 0.05 * ref.refine->error_model.tau_s);
  const Vector6d d = math::pose_difference(rec.final_T_I_C, ref.final_T_I_C);
  CHECK(d.head<3>().norm() < 1e-3);
  CHECK(rec.timing_s.count("batch") == 1);
  CHECK(rec.counts.detections.detections == r.record.counts.detections.detections);
  // The marginals of the extrinsics are the batch's (states.csv's σ), which roe refine also wrote.
  const auto ref_states = store::read_states_csv(tmp / "refined" / "states.csv");
  CHECK(batch_states.back().sigma.tail<6>().isApprox(ref_states.back().sigma.tail<6>(), 0.05));

  // A batch estimate is refined once; calib-check judges the batch itself (states.csv, its σ), not the filter.
  CHECK_THROWS_AS(app::refine_run(tmp / "batch", tmp / "twice", {}), InputError);
  const auto cc = app::calib_check(tmp / "batch", {}).to_json();
  for (const auto& c : cc.at("checks"))
    if (c.at("name") == "extrinsics.settled") CHECK(c.at("message").get<std::string>().find("batch") != std::string::npos);
    else if (c.at("name") == "extrinsics.sigma")
      CHECK(c.at("values").at("sigma_p_x_m").get<double>() == Approx(batch_states.back().sigma(15)).epsilon(1e-3));
}

TEST_CASE("refine/batch: the estimator option over the config, and bad values") {
  test::TempDir tmp("roe_batch_opt");
  const fs::path cfg = tmp.write("c.json", R"({"estimator": "filter"})");
  app::RunOptions o;
  o.config_file = cfg.string();
  CHECK(app::effective_run_config(o).estimator == store::Estimator::kFilter);
  o.estimator = "batch";
  CHECK(app::effective_run_config(o).estimator == store::Estimator::kBatch);
  o.estimator = "rts";
  CHECK_THROWS_AS(app::effective_run_config(o), InputError);
  CHECK(app::effective_run_config({}).estimator == store::Estimator::kSmoother);  // roe's default stays the smoother (§8)
}

// The camera–IMU time offset in the batch (docs/refine.md §2b): a run whose filter estimates t_d is refined with
// t_d a parameter, the detections predicted at t + t_d. matched-calib-offset30 (true +30 ms, declared 0).
TEST_CASE("refine/batch: the batch estimates the camera-IMU time offset when the run does") {
  test::TempDir tmp("roe_batch_td");
  simulated(tmp, "matched-calib-offset30", 3, 20.0);
  const double truth = store::read_manifest(tmp / "ds").truth->camera_time_offset_s;
  REQUIRE(truth == Approx(0.030));
  app::set_batch_estimator(&app::batch_estimate);
  app::RunOptions o;
  o.config_file = tmp.write("td.json", R"({"filter": {"estimate_time_offset": true}, "estimator": "batch"})").string();
  app::run(tmp / "ds", tmp / "batch", o);
  const store::RunRecord rec = store::read_run_json(tmp / "batch" / "run.json");
  REQUIRE(rec.final_time_offset);
  const store::FinalTimeOffset& td = *rec.final_time_offset;
  CHECK(td.estimated);
  CHECK(td.declared_s == 0.0);
  INFO("batch t_d " << td.value_s * 1e3 << " ± " << td.sigma_s * 1e3 << " ms");
  CHECK(td.sigma_s > 0.0);
  CHECK(td.sigma_s < 0.005);
  CHECK(std::abs(td.value_s - truth) < std::max(0.001, 3.0 * td.sigma_s));
  const auto states = store::read_states_csv(tmp / "batch" / "states.csv");
  CHECK(states.back().time_offset_s == Approx(td.value_s).margin(1e-9));
  CHECK(states.back().sigma_time_offset_s == Approx(td.sigma_s).margin(1e-9));
  // roe refine of the same run: its reprojection.csv rows are stamped where the filter processed each image
  // (t + t_d), and are paired back with the images in order; the same estimate as the batch's.
  app::RunOptions smoother = o;
  smoother.estimator = "smoother";
  app::run(tmp / "ds", tmp / "run", smoother);
  const auto ref = app::refine_run(tmp / "run", tmp / "refined", {});
  CHECK(ref.result.time_offset_estimated);
  CHECK(ref.result.time_offset_s == Approx(td.value_s).margin(2e-4));
  // Without the state the batch holds the declared offset: σ 0 and "estimated" false.
  app::RunOptions held;
  held.estimator = "batch";
  app::run(tmp / "ds", tmp / "held", held);
  const store::RunRecord h = store::read_run_json(tmp / "held" / "run.json");
  REQUIRE(h.final_time_offset);
  CHECK_FALSE(h.final_time_offset->estimated);
  CHECK(h.final_time_offset->value_s == 0.0);
  CHECK(h.final_time_offset->sigma_s == 0.0);
}
