// roe sweep aggregate: groups with mean, std and t CI per metric, paired comparisons between
// configuration variants, as Markdown, LaTeX (booktabs), CSV and JSON.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "roe/app/eval.hpp"
#include "roe/app/figures.hpp"
#include "roe/app/sweep.hpp"
#include "roe/core/error.hpp"
#include "roe/io/csv.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"
#include "roe/store/eval_report.hpp"
#include "roe/store/sweep_files.hpp"

namespace roe::app {
namespace detail {
const std::string& embedded_plot_sweep_script();
}

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

/// Axes that are not part of a configuration variant: what pairs two runs.
bool is_pairing_axis(const std::string& a) { return a == "dataset" || a == "seed" || a == "detections"; }

std::string value_text(const json& v) {
  if (v.is_null()) return "-";
  if (v.is_string()) return v.get<std::string>();
  return io::dump_json(v);
}

std::string variant_label(const json& axes, const std::vector<std::string>& variant_axes) {
  std::string s;
  for (const auto& a : variant_axes) {
    const json& v = axes.contains(a) ? axes[a] : json(nullptr);
    if (a == "config") {
      s = value_text(v) + s;
    } else if (!v.is_null()) {
      s += " " + a + "=" + value_text(v);
    }
  }
  return s;
}

json subset(const json& axes, const std::vector<std::string>& names) {
  json k = json::object();
  for (const auto& n : names) k[n] = axes.contains(n) ? axes[n] : json(nullptr);
  return k;
}

int decimals(const std::string& metric) { return metric.size() > 2 && metric.substr(metric.size() - 2) == "_m" ? 4 : 3; }

std::string num(double v, int d) { return std::isnan(v) ? "-" : fmt::format("{:.{}f}", v, d); }

std::string latex_escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '_' || c == '%' || c == '&' || c == '#' || c == '$' || c == '{' || c == '}') o += '\\';
    o += c;
  }
  return o;
}

std::string key_text(const json& key) {
  std::string s;
  for (const auto& [k, v] : key.items()) s += (s.empty() ? "" : ", ") + k + "=" + value_text(v);
  return s.empty() ? "all" : s;
}

/// The Euler metric of the rmse_roll/pitch/yaw_deg columns: sweep jobs evaluate with roe eval's default.
std::string sweep_euler_metric() { return kDefaultEulerMetric; }

json summary_json(const eval::SampleSummary& s) {
  const auto f = [](double v) { return std::isnan(v) ? json(nullptr) : json(v); };
  return {{"n", s.n},           {"mean", f(s.mean)},       {"std", f(s.std)},         {"std_sample", f(s.std_sample)},
          {"median", f(s.median)}, {"min", f(s.min)},      {"max", f(s.max)},         {"ci_low", f(s.ci_low)},
          {"ci_high", f(s.ci_high)}};
}

}  // namespace

const std::vector<std::string>& sweep_metric_names() { return store::headline_metric_names(); }

Aggregate aggregate_results(const std::vector<JobResult>& results, const std::vector<std::string>& axis_names,
                            const AggregateOptions& o) {
  Aggregate ag;
  ag.axis_names = axis_names;
  ag.confidence = o.confidence;
  for (const auto& g : o.group_by)
    if (std::find(axis_names.begin(), axis_names.end(), g) == axis_names.end())
      throw InputError(fmt::format("--group-by: '{}' is not an axis of this sweep (axes: {})", g,
                                   fmt::join(axis_names, ", ")),
                       {"roe sweep aggregate"});
  ag.group_by = o.group_by;
  if (ag.group_by.empty())
    for (const auto& a : axis_names)
      if (a != "seed") ag.group_by.push_back(a);
  for (const auto& a : axis_names)
    if (!is_pairing_axis(a)) ag.variant_axes.push_back(a);
  const auto& metrics = sweep_metric_names();

  // Groups, in the order of their first job.
  std::vector<std::vector<const JobResult*>> members;
  for (const auto& r : results) {
    const json key = subset(r.axes, ag.group_by);
    auto it = std::find_if(ag.groups.begin(), ag.groups.end(), [&](const GroupStats& g) { return g.key == key; });
    if (it == ag.groups.end()) {
      ag.groups.push_back({key, 0, {}});
      members.emplace_back();
      it = ag.groups.end() - 1;
    }
    members[static_cast<std::size_t>(it - ag.groups.begin())].push_back(&r);
  }
  for (std::size_t g = 0; g < ag.groups.size(); ++g) {
    ag.groups[g].n = members[g].size();
    for (const auto& m : metrics) {
      std::vector<double> v;
      for (const JobResult* r : members[g]) v.push_back(r->metrics.at(m));
      ag.groups[g].metrics[m] = eval::summarize_sample(v, o.confidence);
    }
  }

  // Paired comparisons between variants, matched on the pairing axes (same dataset, seed, detections):
  // pooled over everything, and per group of the group-by axes that are pairing axes.
  std::vector<std::string> variants;
  for (const auto& r : results) {
    const std::string v = variant_label(r.axes, ag.variant_axes);
    if (std::find(variants.begin(), variants.end(), v) == variants.end()) variants.push_back(v);
  }
  std::vector<std::string> pairing, scope_axes;
  for (const auto& a : axis_names)
    if (is_pairing_axis(a)) pairing.push_back(a);
  for (const auto& a : ag.group_by)
    if (is_pairing_axis(a)) scope_axes.push_back(a);
  std::vector<json> scopes = {json::object()};
  if (!scope_axes.empty())
    for (const auto& r : results) {
      const json s = subset(r.axes, scope_axes);
      if (std::find(scopes.begin(), scopes.end(), s) == scopes.end()) scopes.push_back(s);
    }
  if (scopes.size() == 2) scopes.pop_back();  // one group: the pooled comparison says it all
  for (std::size_t ia = 0; ia < variants.size(); ++ia)
    for (std::size_t ib = ia + 1; ib < variants.size(); ++ib)
      for (const json& scope : scopes) {
        Comparison c{variants[ia], variants[ib], scope, 0, {}};
        std::map<std::string, std::vector<double>> va, vb;
        for (const auto& ra : results) {
          if (variant_label(ra.axes, ag.variant_axes) != variants[ia]) continue;
          if (subset(ra.axes, scope_axes) != scope && !scope.empty()) continue;
          const json pk = subset(ra.axes, pairing);
          for (const auto& rb : results) {
            if (variant_label(rb.axes, ag.variant_axes) != variants[ib] || subset(rb.axes, pairing) != pk) continue;
            for (const auto& m : metrics) {
              va[m].push_back(ra.metrics.at(m));
              vb[m].push_back(rb.metrics.at(m));
            }
            ++c.n_pairs;
            break;
          }
        }
        if (c.n_pairs == 0) continue;
        for (const auto& m : metrics) c.metrics[m] = eval::compare_paired(va[m], vb[m], o.confidence);
        ag.comparisons.push_back(std::move(c));
      }
  return ag;
}

json Aggregate::to_json() const {
  json gs = json::array();
  for (const auto& g : groups) {
    json m = json::object();
    for (const auto& [name, s] : g.metrics) m[name] = summary_json(s);
    gs.push_back({{"key", g.key}, {"n", g.n}, {"metrics", m}});
  }
  json cs = json::array();
  for (const auto& c : comparisons) {
    json m = json::object();
    for (const auto& [name, p] : c.metrics) {
      m[name] = {{"difference", summary_json(p.difference)},
                 {"wilcoxon",
                  {{"statistic", std::isnan(p.wilcoxon.statistic) ? json(nullptr) : json(p.wilcoxon.statistic)},
                   {"p_value", std::isnan(p.wilcoxon.p_value) ? json(nullptr) : json(p.wilcoxon.p_value)},
                   {"n_used", p.wilcoxon.n_used},
                   {"method", p.wilcoxon.method}}}};
    }
    cs.push_back({{"a", c.a}, {"b", c.b}, {"difference", "b - a"}, {"scope", c.key}, {"n_pairs", c.n_pairs},
                  {"metrics", m}});
  }
  return {{"format", "roe-sweep-aggregate/1"},
          {"axes", axis_names},
          {"group_by", group_by},
          {"variant_axes", variant_axes},
          {"metrics", sweep_metric_names()},
          {"euler_metric", sweep_euler_metric()},
          {"confidence", confidence},
          {"std_definition", "std: population (ddof 0, numpy's default, as roe eval --summary); std_sample: "
                             "sample (ddof 1), which the tables show and the CI uses"},
          {"ci_definition", "mean ± t_{(1+confidence)/2, n-1} · std_sample / sqrt(n)"},
          {"wilcoxon_definition", "two-sided signed-rank, scipy.stats.wilcoxon defaults (zeros dropped, exact for "
                                  "n <= 50 without zeros, else normal approximation with tie correction)"},
          {"n_jobs", n_jobs},
          {"n_failed", n_failed},
          {"n_missing", n_missing},
          {"groups", gs},
          {"comparisons", cs}};
}

std::string Aggregate::markdown() const {
  const auto& metrics = sweep_metric_names();
  std::string md = fmt::format("## Groups (mean ± std_sample, [{:g} % CI]; Euler metric '{}')\n\n|", confidence * 100.0,
                               sweep_euler_metric());
  std::string sep = "|";
  for (const auto& a : group_by) {
    md += " " + a + " |";
    sep += "---|";
  }
  md += " n |";
  sep += "---|";
  for (const auto& m : metrics) {
    md += " " + m + " |";
    sep += "---|";
  }
  md += "\n" + sep + "\n";
  for (const auto& g : groups) {
    md += "|";
    for (const auto& a : group_by) md += " " + value_text(g.key[a]) + " |";
    md += fmt::format(" {} |", g.n);
    for (const auto& m : metrics) {
      const auto& s = g.metrics.at(m);
      const int d = decimals(m);
      md += fmt::format(" {} ± {} [{}, {}] |", num(s.mean, d), num(s.std_sample, d), num(s.ci_low, d),
                        num(s.ci_high, d));
    }
    md += "\n";
  }
  if (!comparisons.empty()) {
    md += fmt::format("\n## Paired comparisons (b − a on the same dataset and seed; mean [{:g} % CI], Wilcoxon p)\n\n",
                      confidence * 100.0);
    md += "| a | b | scope | pairs |";
    sep = "|---|---|---|---|";
    for (const auto& m : metrics) {
      md += " Δ " + m + " |";
      sep += "---|";
    }
    md += "\n" + sep + "\n";
    for (const auto& c : comparisons) {
      md += fmt::format("| {} | {} | {} | {} |", c.a, c.b, key_text(c.key), c.n_pairs);
      for (const auto& m : metrics) {
        const auto& p = c.metrics.at(m);
        const int d = decimals(m);
        md += fmt::format(" {} [{}, {}] p={} |", num(p.difference.mean, d), num(p.difference.ci_low, d),
                          num(p.difference.ci_high, d), num(p.wilcoxon.p_value, 3));
      }
      md += "\n";
    }
  }
  md += fmt::format("\n{} jobs aggregated, {} failed, {} not finished.\n", n_jobs, n_failed, n_missing);
  return md;
}

std::string Aggregate::latex() const {
  const auto& metrics = sweep_metric_names();
  std::string cols(group_by.size() + 1, 'l');
  cols += std::string(metrics.size(), 'r');
  std::string t = "% roe sweep aggregate: mean ± std_sample (ddof 1); Euler metric '" + sweep_euler_metric() +
                  "'; needs \\usepackage{booktabs}\n\\begin{tabular}{" + cols + "}\n\\toprule\n";
  for (const auto& a : group_by) t += latex_escape(a) + " & ";
  t += "$n$";
  for (const auto& m : metrics) t += " & " + latex_escape(m);
  t += " \\\\\n\\midrule\n";
  for (const auto& g : groups) {
    for (const auto& a : group_by) t += latex_escape(value_text(g.key[a])) + " & ";
    t += std::to_string(g.n);
    for (const auto& m : metrics) {
      const auto& s = g.metrics.at(m);
      t += fmt::format(" & ${} \\pm {}$", num(s.mean, decimals(m)), num(s.std_sample, decimals(m)));
    }
    t += " \\\\\n";
  }
  t += "\\bottomrule\n\\end{tabular}\n";
  if (!comparisons.empty()) {
    t += "\n% paired differences b - a: mean [CI] and Wilcoxon signed-rank p\n\\begin{tabular}{llll" +
         std::string(metrics.size(), 'r') + "}\n\\toprule\na & b & scope & pairs";
    for (const auto& m : metrics) t += " & $\\Delta$ " + latex_escape(m);
    t += " \\\\\n\\midrule\n";
    for (const auto& c : comparisons) {
      t += fmt::format("{} & {} & {} & {}", latex_escape(c.a), latex_escape(c.b), latex_escape(key_text(c.key)),
                       c.n_pairs);
      for (const auto& m : metrics) {
        const auto& p = c.metrics.at(m);
        const int d = decimals(m);
        t += fmt::format(" & ${}$ [${}$, ${}$] $p={}$", num(p.difference.mean, d), num(p.difference.ci_low, d),
                         num(p.difference.ci_high, d), num(p.wilcoxon.p_value, 3));
      }
      t += " \\\\\n";
    }
    t += "\\bottomrule\n\\end{tabular}\n";
  }
  return t;
}

std::string Aggregate::csv() const {
  io::CsvWriter w;
  std::vector<std::string> h = group_by;
  for (const char* c : {"metric", "n", "mean", "std_sample", "std", "median", "min", "max", "ci_low", "ci_high"})
    h.push_back(c);
  w.header(h);
  for (const auto& g : groups)
    for (const auto& m : sweep_metric_names()) {
      for (const auto& a : group_by) w.add(value_text(g.key[a]));
      const auto& s = g.metrics.at(m);
      w.add(m).add(static_cast<std::int64_t>(s.n));
      for (double v : {s.mean, s.std_sample, s.std, s.median, s.min, s.max, s.ci_low, s.ci_high}) w.add(v);
      w.end_row();
    }
  return w.str();
}

std::string Aggregate::comparisons_csv() const {
  io::CsvWriter w;
  w.header({"a", "b", "scope", "metric", "n_pairs", "mean_diff", "std_sample_diff", "ci_low", "ci_high", "wilcoxon_statistic",
            "wilcoxon_p", "wilcoxon_method"});
  for (const auto& c : comparisons)
    for (const auto& m : sweep_metric_names()) {
      const auto& p = c.metrics.at(m);
      w.add(c.a).add(c.b).add(key_text(c.key)).add(m).add(static_cast<std::int64_t>(c.n_pairs));
      for (double v : {p.difference.mean, p.difference.std_sample, p.difference.ci_low, p.difference.ci_high,
                       p.wilcoxon.statistic, p.wilcoxon.p_value})
        w.add(v);
      w.add(p.wilcoxon.method);
      w.end_row();
    }
  return w.str();
}

namespace {
/// What the aggregate's output folder must neither be, contain, nor lie inside: the sweep's manifest, job list
/// and its own folders (replacing sw/jobs or a folder inside it would delete finished jobs, even with --force).
std::vector<fs::path> sweep_inputs(const fs::path& out, const SweepFolder& s) {
  std::vector<fs::path> inputs = {s.dir, s.dir / "sweep.json", s.dir / "jobs.jsonl"};
  for (const char* sub : {"jobs", "work", "locks", "logs"}) {
    inputs.push_back(s.dir / sub);
    if (io::is_within(out, s.dir / sub))
      throw InputError(fmt::format("--out is inside the sweep's {}/ folder, which roe sweep run owns: write the "
                                   "tables elsewhere (e.g. beside the sweep folder)",
                                   sub),
                       {out.string()});
  }
  return inputs;
}
}  // namespace

SweepAggregateResult sweep_aggregate(const SweepAggregateOptions& o) {
  if (o.out.empty()) throw InputError("--out DIR is required", {"roe sweep aggregate"});
  const SweepFolder s = read_sweep(o.dir);
  const std::vector<fs::path> inputs = sweep_inputs(o.out, s);
  io::OutputDir::check(o.out, o.force, inputs);
  std::vector<JobResult> results;
  std::size_t failed = 0, missing = 0;
  io::CsvWriter jobs_csv;
  {
    std::vector<std::string> h = {"index", "id"};
    for (const auto& a : s.axis_names) h.push_back(a);
    h.push_back("variant");
    h.push_back("status");
    for (const auto& m : sweep_metric_names()) h.push_back(m);
    jobs_csv.header(h);
  }
  std::vector<std::string> variant_axes;
  for (const auto& a : s.axis_names)
    if (!is_pairing_axis(a)) variant_axes.push_back(a);
  for (std::size_t i = 0; i < s.jobs.size(); ++i) {
    const SweepJob& j = s.jobs[i];
    const fs::path f = s.dir / "jobs" / j.id / "result.json";
    std::string status = "pending";
    JobResult r{j.id, j.axes, {}};
    if (fs::exists(f)) {
      const store::SweepJobResult res = store::read_sweep_result(f);  // a done one has every metric
      status = res.status;
      if (res.done()) r.metrics = *res.metrics;
    }
    jobs_csv.add(static_cast<std::int64_t>(i)).add(j.id);
    for (const auto& a : s.axis_names) jobs_csv.add(value_text(j.axes.contains(a) ? j.axes[a] : json(nullptr)));
    jobs_csv.add(variant_label(j.axes, variant_axes)).add(status);
    for (const auto& m : sweep_metric_names()) {
      if (status == "done")
        jobs_csv.add(r.metrics[m]);
      else
        jobs_csv.add_empty();
    }
    jobs_csv.end_row();
    if (status == "done")
      results.push_back(std::move(r));
    else if (status == "pending")
      ++missing;
    else
      ++failed;
  }
  SweepAggregateResult res;
  res.aggregate = aggregate_results(results, s.axis_names, o.aggregate);
  res.aggregate.n_jobs = results.size();
  res.aggregate.n_failed = failed;
  res.aggregate.n_missing = missing;
  io::OutputDir out(o.out, o.force, inputs);
  const Aggregate& ag = res.aggregate;
  io::write_file_atomic(out.file("summary.md"), ag.markdown());
  io::write_file_atomic(out.file("summary.tex"), ag.latex());
  io::write_file_atomic(out.file("summary.csv"), ag.csv());
  io::write_file_atomic(out.file("comparisons.csv"), ag.comparisons_csv());
  json js = ag.to_json();
  js["sweep"] = io::provenance_path(s.dir);
  io::write_file_atomic(out.file("summary.json"), io::dump_json(js, 2) + "\n");
  io::write_file_atomic(out.file("jobs.csv"), jobs_csv.str());
  if (o.plot) {  // a failed plot is an error (nothing is committed), as for eval --plot and report
    run_plot_script(detail::embedded_plot_sweep_script(), "plot_sweep.py", out.tmp(), {out.tmp().string()});
    res.plot_status = "plots/box_<metric>.png";
  }
  out.commit();
  res.out = out.final_dir();
  return res;
}

json SweepAggregateResult::to_json() const {
  json j = aggregate.to_json();
  j["command"] = "sweep aggregate";
  j["out"] = out.string();
  if (!plot_status.empty()) j["plots"] = plot_status;
  return j;
}

std::string SweepAggregateResult::to_text() const {
  std::string s = aggregate.markdown();
  if (!plot_status.empty()) s += "plots: " + plot_status + "\n";
  return s + "wrote " + out.string() + "/summary.{md,tex,csv,json}, comparisons.csv, jobs.csv\n";
}

}  // namespace roe::app
