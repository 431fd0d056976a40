// roe sweep's data decisions without files: the spec model and its errors (spec key paths), job ids
// derived from content (stable under re-planning, a new seed only adds jobs), shards, and the
// aggregation's groups and paired comparisons checked against scipy's numbers
// (tests/eval/data/stats_reference.json).
#include <catch2/catch.hpp>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include <fmt/format.h>

#include "roe/app/eval.hpp"
#include "roe/app/sweep.hpp"
#include "roe/core/error.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"
#include "support/test_util.hpp"

using nlohmann::json;
using namespace roe;
using namespace roe::app;

namespace {

json spec_with(const json& axes) { return {{"format", "roe-sweep-spec/1"}, {"axes", axes}}; }

std::string config_error(const json& spec, const std::filesystem::path& dir = ".") {
  try {
    (void)plan_sweep(spec, dir, "spec.json");
  } catch (const ConfigError& e) {
    return e.what();
  }
  FAIL("expected a ConfigError for " << spec.dump());
  return "";
}

std::set<std::string> ids(const SweepPlan& p) {
  std::set<std::string> s;
  for (const auto& id : p.ids) s.insert(id);
  return s;
}

}  // namespace

TEST_CASE("sweep spec: expansion, content-derived ids, a new seed adds jobs only", "[app][sweep]") {
  const json axes = {{"datasets", {"paper-seq1", {{"preset", "paper-seq4"}, {"duration_s", 5}}}},
                     {"seeds", {1, 2}},
                     {"configs", {"default", "paper"}},
                     {"overrides", {{"filter.chi2_confidence", {0.9, 0.99}}}}};
  const SweepPlan a = plan_sweep(spec_with(axes), ".", "spec.json");
  REQUIRE(a.size() == 2 * 2 * 2 * 2);
  CHECK(a.axis_names == std::vector<std::string>{"dataset", "seed", "config", "filter.chi2_confidence"});
  CHECK(ids(a).size() == a.size());
  // The override is in the effective config each job carries.
  CHECK(a.job(0).content.run_config.filter.chi2_confidence == 0.9);
  CHECK(a.job(1).content.run_config.filter.chi2_confidence == 0.99);
  CHECK(a.job(0).axes["filter.chi2_confidence"] == 0.9);
  CHECK(a.ids[0].size() == 16);
  // A job made on demand is the one its id names: the id is the hash of the content job(i) carries.
  for (std::size_t i = 0; i < a.size(); ++i) {
    const SweepJob j = a.job(i);
    CHECK(j.id == a.ids[i]);
    CHECK(io::sha256_hex(io::dump_json(store::sweep_job_content_json(j.content))).substr(0, 16) == a.ids[i]);
  }
  // Re-planning gives the same ids in the same order.
  const SweepPlan again = plan_sweep(spec_with(axes), ".", "spec.json");
  for (std::size_t i = 0; i < a.size(); ++i) CHECK(again.ids[i] == a.ids[i]);
  // Writing a default explicitly changes nothing; a different eval option changes every id.
  json with_eval = spec_with(axes);
  with_eval["eval"] = {{"align", "se3"}};
  CHECK(ids(plan_sweep(with_eval, ".", "spec.json")) == ids(a));
  with_eval["eval"] = {{"align", "posyaw"}};
  for (const auto& id : plan_sweep(with_eval, ".", "spec.json").ids) CHECK(ids(a).count(id) == 0);
  // One more seed: every old job keeps its id, 8 new ones; keep_indices keeps the old order first.
  json more = axes;
  more["seeds"] = {1, 2, 3};
  SweepPlan b = plan_sweep(spec_with(more), ".", "spec.json");
  REQUIRE(b.size() == 24);
  const auto old_ids = ids(a);
  std::size_t shared = 0;
  for (const auto& id : b.ids) shared += old_ids.count(id);
  CHECK(shared == a.size());
  std::vector<std::string> order;
  for (const auto& id : a.ids) order.push_back(id);
  CHECK(keep_indices(b, order).empty());
  for (std::size_t i = 0; i < order.size(); ++i) CHECK(b.ids[i] == order[i]);
  // A seed removed: the folder's job is reported as dropped.
  SweepPlan c = plan_sweep(spec_with(axes), ".", "spec.json");
  std::vector<std::string> b_order;
  for (const auto& id : b.ids) b_order.push_back(id);
  CHECK(keep_indices(c, b_order).size() == 8);
}

TEST_CASE("sweep spec: eval.t_offset_s is seconds or auto, and a number keeps the ids of before", "[app][sweep]") {
  const json axes = {{"datasets", {"paper-seq1"}}, {"seeds", {1, 2}}};
  const SweepPlan plain = plan_sweep(spec_with(axes), ".", "spec.json");
  json spec = spec_with(axes);
  spec["eval"] = {{"t_offset_s", 0}};
  CHECK(ids(plan_sweep(spec, ".", "spec.json")) == ids(plain));
  CHECK(plain.job(0).content.eval["t_offset_s"] == 0.0);  // the canonical form of before: a number
  spec["eval"] = {{"t_offset_s", "auto"}};
  const SweepPlan automatic = plan_sweep(spec, ".", "spec.json");
  CHECK(automatic.job(0).content.eval["t_offset_s"] == "auto");
  for (const auto& id : automatic.ids) CHECK(ids(plain).count(id) == 0);
  // What a job applies: the one rule both the plan and the job use.
  EvalOptions o;
  read_sweep_t_offset(automatic.job(0).content.eval["t_offset_s"], o);
  CHECK(o.t_offset_auto);
  read_sweep_t_offset(json(0.25), o);
  CHECK(!o.t_offset_auto);
  CHECK(o.t_offset_s == 0.25);
  CHECK(sweep_t_offset_json(o) == 0.25);
  for (const json& bad : {json("Auto"), json("0.1"), json(true), json::array()}) {
    spec["eval"] = {{"t_offset_s", bad}};
    const std::string msg = config_error(spec);
    CHECK_THAT(msg, Catch::Contains("eval.t_offset_s") && Catch::Contains("auto"));
  }
}

TEST_CASE("sweep spec: output.level is an override like any run config key, full is the default job",
          "[app][sweep]") {
  const json base = {{"datasets", {{{"preset", "paper-seq4"}, {"duration_s", 5}}}}};
  json axes = base;
  axes["overrides"] = {{"output.level", {"full", "minimal"}}};
  const SweepPlan p = plan_sweep(spec_with(axes), ".", "spec.json");
  REQUIRE(p.size() == 2);
  // "full" is the default: its job is the one without the override (same content, same id).
  CHECK(p.ids[0] == plan_sweep(spec_with(base), ".", "spec.json").ids[0]);
  CHECK_FALSE(store::sweep_job_content_json(p.job(0).content)["run_config"]["output"].contains("level"));
  CHECK(store::sweep_job_content_json(p.job(1).content)["run_config"]["output"]["level"] == "minimal");
  axes["overrides"] = {{"output.level", {"most"}}};
  CHECK_THAT(config_error(spec_with(axes)), Catch::Contains("axes.overrides") && Catch::Contains("output.level"));
}

TEST_CASE("sweep spec: blocks share jobs, per-dataset seeds", "[app][sweep]") {
  // Table I (every sequence, seed 1) and Tables II/III (sequence 4, seeds 1-3): seq4 seed 1 once.
  const json axes = json::array({{{"datasets", {"paper-seq1", "paper-seq4"}}, {"configs", {"paper"}}},
                                 {{"datasets", {{{"preset", "paper-seq4"}, {"seeds", {1, 2, 3}}}}},
                                  {"configs", {"paper"}}}});
  const SweepPlan p = plan_sweep(spec_with(axes), ".", "spec.json");
  CHECK(p.size() == 4);
  CHECK(p.axis_names == std::vector<std::string>{"dataset", "seed", "config"});
}

TEST_CASE("sweep spec: bad input names the spec path", "[app][sweep]") {
  roe::test::TempDir tmp("roe_sweep_spec");
  const json ok = {{"datasets", {"paper-seq1"}}, {"configs", {"default"}}};
  const auto err = [&](json axes) { return config_error(spec_with(axes), tmp.path); };
  json a = ok;
  a["bogus"] = 1;
  CHECK_THAT(err(a), Catch::Contains("'axes.bogus'") && Catch::Contains("unknown key"));
  a = ok;
  a["configs"] = {"default", "paper", "no-such-config"};
  CHECK_THAT(err(a), Catch::Contains("'axes.configs[2]'") && Catch::Contains("no-such-config"));
  a = ok;
  a["configs"] = {"default", "missing.json"};
  CHECK_THAT(err(a), Catch::Contains("'axes.configs[1]'") && Catch::Contains("not found"));
  a = ok;
  a["seeds"] = json::array();
  CHECK_THAT(err(a), Catch::Contains("'axes.seeds'") && Catch::Contains("at least one value"));
  a = ok;
  a["overrides"] = {{"filter.no_such_key", {1, 2}}};
  CHECK_THAT(err(a), Catch::Contains("axes.overrides.filter.no_such_key[0]") && Catch::Contains("not a run config key"));
  a = ok;
  a["overrides"] = {{"filter.chi2_confidence", {0.9, 1.5}}};
  CHECK_THAT(err(a), Catch::Contains("axes.overrides") && Catch::Contains("chi2_confidence"));
  a = ok;
  a["overrides"] = {{"filter", {1}}};
  CHECK_THAT(err(a), Catch::Contains("a section, not a value"));
  a = ok;
  a["datasets"] = {"paper-seq1", {{"path", "no/such/dataset"}}};
  CHECK_THAT(err(a), Catch::Contains("'axes.datasets[1].path'") && Catch::Contains("no roe.json"));
  a = ok;
  a["datasets"] = {"paper-seq99"};
  CHECK_THAT(err(a), Catch::Contains("'axes.datasets[0]'") && Catch::Contains("unknown simulator preset"));
  a = ok;
  a["datasets"] = {{{"preset", "paper-seq1"}, {"sedes", {1}}}};
  CHECK_THAT(err(a), Catch::Contains("axes.datasets[0].sedes"));
  CHECK_THAT(config_error({{"axes", ok}, {"evaluation", {}}}), Catch::Contains("'evaluation'"));
  CHECK_THAT(config_error({{"axes", ok}, {"eval", {{"align", "affine"}}}}), Catch::Contains("'eval.align'"));
  CHECK_THAT(config_error({{"format", "roe-sweep-spec/0"}, {"axes", ok}}), Catch::Contains("unsupported spec format"));
  CHECK_THAT(config_error({{"axes", json::array({ok, {{"datasets", json::array()}}})}}),
             Catch::Contains("'axes[1].datasets'"));
}

TEST_CASE("sweep shards: round-robin, 0-based, every job exactly once", "[app][sweep]") {
  std::vector<int> seen(10, 0);
  for (std::size_t s = 0; s < 4; ++s)
    for (std::size_t k : shard_indices(10, s, 4)) ++seen[k];
  for (int n : seen) CHECK(n == 1);
  CHECK(shard_indices(10, 1, 4) == std::vector<std::size_t>{1, 5, 9});
  CHECK(parse_shard("3/4", "--shard") == std::pair<std::size_t, std::size_t>{3, 4});
  for (const char* bad : {"4/4", "1/0", "a/2", "1", "-1/2", "1/2/3"})
    CHECK_THROWS_AS(parse_shard(bad, "--shard"), InputError);
}

TEST_CASE("sweep aggregate: groups, CIs and paired Wilcoxon against scipy", "[app][sweep]") {
  std::ifstream in(std::string(ROE_SOURCE_DIR) + "/tests/eval/data/stats_reference.json");
  const json ref = json::parse(in);
  const json& w = ref["wilcoxon"][0];  // "exact, no ties": 10 seeds, two configs
  REQUIRE(w["name"] == "exact, no ties");
  const auto a = w["a"].get<std::vector<double>>(), b = w["b"].get<std::vector<double>>();
  std::vector<JobResult> results;
  for (std::size_t i = 0; i < a.size(); ++i)
    for (const auto& [config, values] : {std::pair{"paper", &a}, std::pair{"default", &b}}) {
      JobResult r;
      r.id = std::string(config) + std::to_string(i);
      r.axes = {{"dataset", "paper-seq4"}, {"seed", i + 1}, {"config", config}};
      for (const auto& m : sweep_metric_names()) r.metrics[m] = (*values)[i];
      results.push_back(r);
    }
  const Aggregate ag = aggregate_results(results, {"dataset", "seed", "config"}, {});
  CHECK(ag.group_by == std::vector<std::string>{"dataset", "config"});
  REQUIRE(ag.groups.size() == 2);
  const json& s0 = ref["samples"][0];  // the same ten values as `a`
  REQUIRE(s0["values"].get<std::vector<double>>() == a);
  const auto& g = ag.groups[0].metrics.at("rmse_x_m");
  CHECK(ag.groups[0].key == json({{"dataset", "paper-seq4"}, {"config", "paper"}}));
  CHECK(g.n == 10);
  CHECK(g.ci_low == Approx(s0["ci_low"].get<double>()).epsilon(1e-9));
  CHECK(g.ci_high == Approx(s0["ci_high"].get<double>()).epsilon(1e-9));
  REQUIRE(ag.comparisons.size() == 1);
  const Comparison& c = ag.comparisons[0];
  CHECK(c.a == "paper");
  CHECK(c.b == "default");
  CHECK(c.n_pairs == 10);
  CHECK(c.metrics.at("ate_rmse_m").wilcoxon.p_value == Approx(w["p_value"].get<double>()).epsilon(1e-12));
  CHECK(c.metrics.at("ate_rmse_m").wilcoxon.statistic == w["statistic"].get<double>());
  // Outputs carry the numbers.
  CHECK_THAT(ag.markdown(), Catch::Contains("| paper-seq4 | paper | 10 |") && Catch::Contains("p=0.010"));
  CHECK_THAT(ag.latex(), Catch::Contains("\\toprule") && Catch::Contains("rmse\\_x\\_m"));
  CHECK_THAT(ag.comparisons_csv(), Catch::Contains("paper,default,all,ate_rmse_m,10,"));
  CHECK(ag.to_json()["comparisons"][0]["metrics"]["ate_rmse_m"]["wilcoxon"]["method"] == "exact");
  // Grouping by an axis that does not exist is bad usage.
  AggregateOptions bad;
  bad.group_by = {"sequence"};
  CHECK_THROWS_AS(aggregate_results(results, {"dataset", "seed", "config"}, bad), InputError);
}

namespace {
/// Python's own population and sample std of `v` (statistics.pstdev, statistics.stdev, and numpy's
/// np.std with ddof 0 / 1 as a second opinion): computed outside roe, in the test.
std::pair<double, double> python_std(const std::vector<double>& v) {
  std::string list;
  for (double x : v) list += fmt::format("{}{}", list.empty() ? "" : ",", x);
  const roe::test::RunResult r = roe::test::run_shell(fmt::format(
      "/usr/bin/python3 -c 'import statistics, numpy as np; v = [{}]; "
      "a, b = statistics.pstdev(v), statistics.stdev(v); "
      "assert abs(a - np.std(v)) < 1e-12 and abs(b - np.std(v, ddof=1)) < 1e-12; print(repr(a), repr(b))'",
      list));
  REQUIRE(r.code == 0);
  std::istringstream in(r.out);
  double pop = 0.0, sample = 0.0;
  in >> pop >> sample;
  return {pop, sample};
}
}  // namespace

TEST_CASE("sweep aggregate: std is the population std, std_sample the sample one, named in every output",
          "[app][sweep][std]") {
  const std::vector<double> v = {0.061, 0.058, 0.072, 0.049, 0.066, 0.070, 0.055};
  std::vector<JobResult> results;
  for (std::size_t i = 0; i < v.size(); ++i) {
    JobResult r;
    r.id = "j" + std::to_string(i);
    r.axes = {{"dataset", "d"}, {"seed", i + 1}};
    for (const auto& m : sweep_metric_names()) r.metrics[m] = v[i];
    results.push_back(r);
  }
  const Aggregate ag = aggregate_results(results, {"dataset", "seed"}, {});
  REQUIRE(ag.groups.size() == 1);
  const auto [pop, sample] = python_std(v);
  REQUIRE(pop < sample);  // the two differ: a swapped name cannot pass
  const eval::SampleSummary& s = ag.groups[0].metrics.at("ate_rmse_m");
  CHECK(s.std == Approx(pop).epsilon(1e-12));
  CHECK(s.std_sample == Approx(sample).epsilon(1e-12));
  const json j = ag.to_json()["groups"][0]["metrics"]["ate_rmse_m"];
  CHECK(j["std"].get<double>() == Approx(pop).epsilon(1e-12));
  CHECK(j["std_sample"].get<double>() == Approx(sample).epsilon(1e-12));
  CHECK_FALSE(j.contains("std_pop"));
  // CSV: the columns by name
  std::istringstream csv(ag.csv());
  std::string header, row;
  REQUIRE(std::getline(csv, header));
  REQUIRE(std::getline(csv, row));
  const auto cells = [](const std::string& line) {
    std::vector<std::string> c;
    std::stringstream ss(line);
    for (std::string x; std::getline(ss, x, ',');) c.push_back(x);
    return c;
  };
  const auto h = cells(header), r = cells(row);
  const auto col = [&](const char* name) {
    const auto it = std::find(h.begin(), h.end(), name);
    REQUIRE(it != h.end());
    return std::stod(r[static_cast<std::size_t>(it - h.begin())]);
  };
  CHECK(col("std") == Approx(pop).epsilon(1e-12));
  CHECK(col("std_sample") == Approx(sample).epsilon(1e-12));
  // Markdown and LaTeX show the sample std and say so
  CHECK_THAT(ag.markdown(), Catch::Contains("mean ± std_sample") && Catch::Contains(fmt::format("± {:.4f}", sample)));
  CHECK_THAT(ag.latex(), Catch::Contains("std\\_sample") || Catch::Contains("std_sample"));
}

TEST_CASE("sweep spec: the job count is checked from the axes' sizes before anything is expanded",
          "[app][sweep][hostile]") {
  json values = json::array();
  for (int i = 0; i < 1000; ++i) values.push_back(0.9 + i * 1e-5);
  // 10^9 jobs (three overrides of 1000 values): refused at `axes` with the count, without expanding.
  const json big = {{"datasets", {"paper-seq1"}},
                    {"overrides", {{"filter.chi2_confidence", values}, {"filter.meas_sigma_p_m", values},
                                   {"filter.meas_sigma_ray_m", values}}}};
  CHECK_THAT(config_error(spec_with(big)), Catch::Contains("'axes'") && Catch::Contains("1000000000 jobs"));
  // Blocks add up; per-dataset seeds count for their dataset; the limit is a parameter.
  const json blocks = json::array({{{"datasets", {{{"preset", "paper-seq1"}, {"seeds", {1, 2, 3}}}, "paper-seq4"}},
                                    {"seeds", {1, 2}}, {"configs", {"default", "paper"}}},
                                   {{"datasets", {"paper-seq1"}}, {"detections", {"a", "b"}}}});
  CHECK(plan_sweep(spec_with(blocks), ".", "spec.json", 12).size() == 12);  // (3 + 2) × 2 + 2
  CHECK_THROWS_AS(plan_sweep(spec_with(blocks), ".", "spec.json", 11), ConfigError);
  // Detection set names are one folder name; a duration the simulator refuses fails at plan time.
  CHECK_THAT(config_error(spec_with({{"datasets", {"paper-seq1"}}, {"detections", {"../x"}}})),
             Catch::Contains("axes.detections[0]"));
  CHECK_THAT(config_error(spec_with({{"datasets", {{{"preset", "paper-seq1"}, {"duration_s", 1e9}}}}})),
             Catch::Contains("axes.datasets[0].duration_s") && Catch::Contains("one day"));
}

TEST_CASE("sweep ids: only what plan_sweep makes is a job id", "[app][sweep][hostile]") {
  for (const auto& id : plan_sweep(spec_with({{"datasets", {"paper-seq1"}}, {"seeds", {1, 2}}}), ".", "s").ids)
    CHECK(store::is_sweep_job_id(id));
  for (const char* bad : {"", "../../victim", "/tmp/x", "0123456789ABCDEF", "0123456789abcde", "0123456789abcdef0",
                          "0123456789abcdeg"})
    CHECK_FALSE(store::is_sweep_job_id(bad));
}
