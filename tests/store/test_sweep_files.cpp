// The sweep's own files typed (store/sweep_files.hpp). The fixtures in tests/store/data/sweep_8a5e53d were written
// by roe at main 8a5e53d (before the typed files), from its spec.json there: `roe sweep plan spec.json --out sw`,
// `roe sweep run sw --index 0` (done) and `--index 1` (failed: an anchor that is not in the dataset); job 2 (a
// dataset folder, detection set "sim") was left pending. They read unchanged, are written back byte for byte,
// their ids are the hashes of the typed contents, and the readers are strict: a missing, mistyped or unknown
// key is an InputError naming the file, the line (jobs.jsonl) and the key path.
#include <catch2/catch.hpp>
#include <cmath>
#include <fstream>

#include "roe/core/error.hpp"
#include "roe/io/input.hpp"
#include "roe/io/json.hpp"
#include "roe/store/eval_report.hpp"
#include "roe/store/sweep_files.hpp"
#include "support/test_util.hpp"

using namespace roe;
using namespace roe::store;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

fs::path fixture(const std::string& name) {
  return fs::path(ROE_SOURCE_DIR) / "tests/store/data/sweep_8a5e53d" / name;
}

std::string jobs_text(const std::vector<SweepJob>& jobs) {
  std::string t;
  for (std::size_t i = 0; i < jobs.size(); ++i) t += format_sweep_job_line(jobs[i], i);
  return t;
}

/// The message of the InputError `f` throws ("" when it throws none).
template <class F>
std::string input_error(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

void replace_once(std::string& s, const std::string& from, const std::string& to) {
  const std::size_t p = s.find(from);
  REQUIRE(p != std::string::npos);
  s.replace(p, from.size(), to);
}

}  // namespace

TEST_CASE("sweep files: main 8a5e53d's sweep.json, jobs.jsonl and result.json read and write back byte for byte",
          "[store][sweep]") {
  const SweepManifest m = read_sweep_manifest(fixture("sweep.json"));
  CHECK(m.n_jobs == 3);
  CHECK(m.axes == std::vector<std::string>{"dataset", "seed", "config", "filter.anchor_id", "detections"});
  CHECK(m.spec["axes"].size() == 3);
  CHECK(format_sweep_manifest(m) == io::read_file(fixture("sweep.json")));

  const std::vector<SweepJob> jobs = read_sweep_jobs(fixture("jobs.jsonl"));
  REQUIRE(jobs.size() == 3);
  // Today's writer adds the config keys added after 8a5e53d (store::keys_added_later) at their defaults; every
  // other byte is main's, the ids included (read, never recomputed: a folder planned by an older roe keeps its
  // jobs; docs/sweep.md).
  std::string today = jobs_text(jobs);
  for (const std::string later : {"\"consider_correlated_errors\":false,"})
    for (std::size_t at; (at = today.find(later)) != std::string::npos;) today.erase(at, later.size());
  CHECK(today == io::read_file(fixture("jobs.jsonl")));
  // A job's id is the hash of its whole content as written today: the same after a write and a read.
  roe::test::TempDir tmp("roe_sweep_files_ids");
  const std::vector<SweepJob> again = read_sweep_jobs(tmp.write("jobs.jsonl", jobs_text(jobs)));
  REQUIRE(again.size() == jobs.size());
  for (std::size_t k = 0; k < jobs.size(); ++k) CHECK(sweep_job_id(again[k].content) == sweep_job_id(jobs[k].content));
  const SweepDataset& d0 = jobs[0].content.dataset;
  CHECK(d0.preset == "paper-seq1");
  CHECK(d0.seed == std::optional<std::int64_t>(1));
  CHECK(d0.duration_s == std::optional<double>(3.0));
  CHECK(d0.path.empty());
  CHECK(jobs[0].axes["filter.anchor_id"].is_null());
  CHECK(jobs[1].axes["filter.anchor_id"] == 99);
  CHECK(jobs[1].content.run_config.filter.anchor_id == 99);
  CHECK(jobs[2].content.dataset.path == "/work/main/datasets/sample");
  CHECK(jobs[2].content.dataset.preset.empty());
  CHECK_FALSE(jobs[2].content.dataset.seed);
  CHECK(jobs[2].content.detections == "sim");
  CHECK(jobs[2].content.config == "paper");
  CHECK(jobs[2].content.run_config.estimator == store::Estimator::kFilter);  // configs/paper.json: the paper's filter
  CHECK(jobs[0].content.eval["align"] == "se3");

  const SweepJobResult done = read_sweep_result(fixture("result_done.json"));
  CHECK(done.done());
  CHECK(done.exit_code == 0);
  CHECK_FALSE(done.message);
  REQUIRE(done.metrics);
  CHECK(done.metrics->size() == headline_metric_names().size());
  CHECK(done.metrics->at("ate_rmse_m") == 0.013214712051444871);
  REQUIRE(done.warnings);
  CHECK(done.warnings->size() == 1);
  CHECK(done.timing_s.at("total") == 0.313057121);
  CHECK(format_sweep_result(done) == io::read_file(fixture("result_done.json")));
  const SweepJobResult failed = read_sweep_result(fixture("result_failed.json"));
  CHECK_FALSE(failed.done());
  CHECK(failed.exit_code == 2);
  CHECK_THAT(*failed.message, Catch::Contains("anchor_id 99"));
  CHECK_FALSE(failed.metrics);
  CHECK(format_sweep_result(failed) == io::read_file(fixture("result_failed.json")));
}

TEST_CASE("sweep files: a metric the evaluation had no figure for is null in result.json and NaN typed",
          "[store][sweep]") {
  SweepJobResult r = read_sweep_result(fixture("result_done.json"));
  (*r.metrics)["rot_rmse_deg"] = std::nan("");
  const std::string text = format_sweep_result(r);
  CHECK_THAT(text, Catch::Contains("\"rot_rmse_deg\": null"));
  roe::test::TempDir tmp("roe_sweep_files_nan");
  const fs::path f = tmp.write("result.json", text);
  CHECK(std::isnan(read_sweep_result(f).metrics->at("rot_rmse_deg")));
  CHECK(format_sweep_result(read_sweep_result(f)) == text);
}

TEST_CASE("sweep files: jobs.jsonl is read strictly, naming the line and the key path", "[store][sweep][hostile]") {
  roe::test::TempDir tmp("roe_sweep_files_jobs");
  const std::string good = io::read_file(fixture("jobs.jsonl"));
  const std::size_t second = good.find('\n') + 1;
  // Each edit is made to the second line (its axes come first: the keys are sorted); the error names jobs.jsonl,
  // line 2 and the key.
  const std::vector<std::tuple<std::string, std::string, std::string>> edits = {
      {"\"job\":{\"config\"", "\"job\":{\"colour\":1,\"config\"", "job.colour"},
      {"\"preset_sha256\"", "\"preset_sha\"", "job.dataset.preset_sha"},
      {"\"seed\":1},\"detections\"", "\"seed\":\"1\"},\"detections\"", "job.dataset.seed"},
      {"\"chi2_confidence\":", "\"chi2_confidance\":", "job.run_config.filter.chi2_confidance"},
      {"\"detections\":\"\",\"eval\"", "\"detections\":\"../x\",\"eval\"", "job.detections"},
      {"\"index\":1", "\"index\":2", "index"},
      {"\"id\":\"7a91a16fb275c628\"", "\"id\":\"../../victim\"", "id"},
      {"\"id\":\"7a91a16fb275c628\"", "\"id\":\"9b8223ea65582b75\"", "id"},
      {"\"eval\":{", "\"eval\":7,\"x\":{", "job.eval"},
  };
  for (const auto& [from, to, key] : edits) {
    CAPTURE(to);
    const std::size_t end = good.find('\n', second);
    std::string line2 = good.substr(second, end - second);
    replace_once(line2, from, to);
    const std::string text = good.substr(0, second) + line2 + good.substr(end);
    const fs::path f = tmp.write("jobs.jsonl", text);
    const std::string msg = input_error([&] { (void)read_sweep_jobs(f); });
    CHECK_THAT(msg, Catch::Contains(f.string() + ":2") && Catch::Contains(key));
  }
  // A line that is not JSON: its line, and the column within it.
  const fs::path f = tmp.write("jobs.jsonl", good.substr(0, second) + "{\"index\": 1,\n");
  CHECK_THAT(input_error([&] { (void)read_sweep_jobs(f); }), Catch::Contains(f.string() + ":2"));
  // The unedited text reads.
  CHECK(read_sweep_jobs(tmp.write("jobs.jsonl", good)).size() == 3);
}

TEST_CASE("sweep files: sweep.json and result.json are read strictly, another format version is refused",
          "[store][sweep][hostile]") {
  roe::test::TempDir tmp("roe_sweep_files_docs");
  std::string m = io::read_file(fixture("sweep.json"));
  std::string t = m;
  replace_once(t, "roe-sweep/1", "roe-sweep/2");
  std::string msg = input_error([&] { (void)read_sweep_manifest(tmp.write("sweep.json", t)); });
  CHECK_THAT(msg, Catch::Contains("roe-sweep/2") && Catch::Contains("plan the sweep again"));
  t = m;
  replace_once(t, "\"n_jobs\": 3", "\"n_jobs\": -3");
  msg = input_error([&] { (void)read_sweep_manifest(tmp.write("sweep.json", t)); });
  CHECK_THAT(msg, Catch::Contains("sweep.json:") && Catch::Contains("n_jobs"));
  t = m;
  replace_once(t, "\"roe_version\"", "\"roe_versio\"");
  msg = input_error([&] { (void)read_sweep_manifest(tmp.write("sweep.json", t)); });
  CHECK_THAT(msg, Catch::Contains("roe_versio"));

  const std::string done = io::read_file(fixture("result_done.json"));
  const std::vector<std::pair<std::string, std::string>> edits = {
      {"\"status\": \"done\"", "\"status\": \"finished\""},                  // status
      {"\"rmse_x_m\"", "\"rmse_w_m\""},                                      // metrics (rmse_x_m missing)
      {"\"exit_code\": 0", "\"exit_code\": 0, \"message\": \"x\""},        // message (a done job has none)
      {"\"warnings\": [", "\"warning\": ["},                                 // warnings
      {"\"roe-sweep-job/1\"", "\"roe-sweep-job/0\""},                        // format
  };
  for (const auto& [from, to] : edits) {
    CAPTURE(to);
    t = done;
    replace_once(t, from, to);
    const fs::path f = tmp.write("result.json", t);
    msg = input_error([&] { (void)read_sweep_result(f); });
    CHECK_THAT(msg, Catch::Contains(f.string() + ":"));
  }
  // A failed job's result needs its message.
  t = io::read_file(fixture("result_failed.json"));
  replace_once(t, "\"message\"", "\"messages\"");
  CHECK_THAT(input_error([&] { (void)read_sweep_result(tmp.write("result.json", t)); }), Catch::Contains("message"));
}
