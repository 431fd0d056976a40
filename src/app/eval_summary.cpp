// roe eval --summary: one row per run + mean and population std, in the paper's table layout.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <Eigen/Dense>
#include <cstdio>
#include <optional>

#include <map>

#include <algorithm>
#include <cmath>
#include <iterator>

#include "roe/app/eval.hpp"
#include "roe/core/error.hpp"
#include "roe/eval/metrics.hpp"
#include "roe/io/csv.hpp"
#include "roe/store/eval_report.hpp"
#include "roe/io/evo_result.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"

namespace roe::app {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

/// The headline columns (store::headline_metrics), then the RPE columns.
std::size_t headline_count() { return store::headline_metric_names().size(); }

/// The settings a report was made with that change its numbers: runs evaluated with different ones
/// should not be averaged without saying so. (key in the summary, its value in a report, name in messages)
struct Setting {
  const char* key;
  json (*value)(const store::EvalReportFile&);
  const char* name;
};
constexpr Setting kSettings[] = {
    {"alignment", [](const store::EvalReportFile& f) { return json(f.alignment.type); }, "alignment (--align)"},
    {"n_align", [](const store::EvalReportFile& f) { return json(f.alignment.n_align_requested); }, "--n-align"},
    {"max_dt_s", [](const store::EvalReportFile& f) { return json(f.association.max_dt_s); }, "--max-dt"},
    // --t-offset auto estimates each run's own offset: the setting is "auto", the value a figure of the run.
    {"t_offset_s", [](const store::EvalReportFile& f) { return f.time_offset ? json("auto") : json(f.association.offset_s); },
     "--t-offset"},
    {"assoc", [](const store::EvalReportFile& f) { return json(f.association.policy); }, "association (--assoc)"},
    {"euler_metric", [](const store::EvalReportFile& f) { return json(f.per_axis.euler_metric); },
     "Euler metric (--euler)"}};

std::string setting_text(const json& v) {
  if (v.is_null()) return "unknown";
  if (v.is_string()) return v.get<std::string>();
  if (v.is_number_float()) return fmt::format("{}", v.get<double>());
  return io::dump_json(v);
}

/// The RPE blocks of a report, by a key naming delta, unit and mode ("1m", "0.5m_all_gt"), with their
/// translation and rotation RMSE; blocks without pairs are left out.
std::vector<std::pair<std::string, std::pair<double, double>>> rpe_blocks(const store::EvalReportFile& f) {
  std::vector<std::pair<std::string, std::pair<double, double>>> out;
  for (const store::ReportRpe& e : f.rpe) {
    if (!e.trans_m || !e.rot_deg) continue;
    std::string key = fmt::format("{}{}", e.delta, e.unit);
    if (e.all_pairs) key += "_all";
    if (e.pairs_from == "gt") key += "_gt";
    out.push_back({key, {e.trans_m->rmse, e.rot_deg->rmse}});
  }
  return out;
}

/// A number of the table, "–" where a run does not have it (an evo result holds one metric).
std::string cell(double v, int decimals) { return std::isnan(v) ? "–" : fmt::format("{:.{}f}", v, decimals); }

std::string vec3(const std::vector<double>& v, int first, int decimals) {
  return "[" + cell(v[first], decimals) + ", " + cell(v[first + 1], decimals) + ", " + cell(v[first + 2], decimals) + "]";
}

/// The part of an evo result's title that names the alignment (evo/main_ape.py), as roe's --align value;
/// null when the title names none roe knows.
json evo_alignment(const std::string& title) {
  if (title.find("(with SE(3) Umeyama alignment)") != std::string::npos) return "se3";
  if (title.find("(with Sim(3) Umeyama alignment)") != std::string::npos) return "sim3";
  if (title.find("(with origin alignment)") != std::string::npos) return "origin";
  if (title.find("(not aligned)") != std::string::npos) return "none";
  return nullptr;
}

/// Rows that share a label cannot be told apart in the table: one warning per repeated label.
template <class Row>
std::vector<std::string> duplicate_label_warnings(const std::vector<Row>& rows) {
  std::vector<std::string> w;
  std::map<std::string, std::vector<std::size_t>> runs;
  for (std::size_t i = 0; i < rows.size(); ++i) runs[rows[i].label].push_back(i + 1);
  for (const auto& [label, idx] : runs) {
    if (idx.size() < 2) continue;
    std::string list;
    for (std::size_t k : idx) list += (list.empty() ? "" : ", ") + std::to_string(k);
    w.push_back(fmt::format("runs {} are all labelled '{}': the rows cannot be told apart by label (set "
                            "`roe eval --label NAME` when evaluating)",
                            list, label));
  }
  return w;
}

}  // namespace

namespace {

/// One result's statistics for the evo_res-style table: "APE trans [m]", "APE rot [deg]", "RPE 10m trans [m]".
struct ResultStats {
  std::string name;
  eval::Stats stats;
  std::optional<double> scale;  ///< the Sim(3) alignment's scale (1 for SE(3)); none when the file does not say
};

struct Row {
  std::string label, file;
  /// Rows are averaged only within a group: every roe report is in "roe", an evo result in its estimator's.
  std::string group = "roe";
  std::vector<ResultStats> results;
  std::optional<std::size_t> n_objects;  ///< none: not a roe run (no objects to count)
  std::size_t n_matched = 0;
  std::vector<double> v;  ///< the headline metrics (NaN where the report has no such figure), then RPE columns
  json settings = json::object();
  std::vector<std::pair<std::string, std::pair<double, double>>> rpe;
  std::optional<std::pair<double, double>> time_offset;  ///< --t-offset auto's estimate and σ (s)
};

/// evo's stats.json as Stats (n from the error array when present).
eval::Stats evo_stats(const io::EvoResult& r) {
  eval::Stats st;
  const auto get = [&r](const char* k) {
    return r.stats.contains(k) && r.stats[k].is_number() ? r.stats[k].get<double>()
                                                          : std::numeric_limits<double>::quiet_NaN();
  };
  st.rmse = get("rmse"), st.mean = get("mean"), st.median = get("median"), st.std = get("std");
  st.min = get("min"), st.max = get("max"), st.sse = get("sse");
  if (const io::NpyArray* e = r.array("error_array")) st.n = e->numel();
  return st;
}

/// The Sim(3) scale of evo's alignment_transformation_sim3 (cube root of det(sR)); none without one.
std::optional<double> evo_scale(const io::EvoResult& r) {
  const io::NpyArray* a = r.array("alignment_transformation_sim3");
  if (!a || a->numel() != 16) return std::nullopt;
  Eigen::Matrix3d sR;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) sR(i, j) = a->as_double(static_cast<std::size_t>(4 * i + j));
  return std::cbrt(sR.determinant());
}

/// An evo RPE title's second line "for delta = 10.0 (m) using consecutive pairs" as roe's RPE key ("10m",
/// "1f_all"); empty when it is not one.
std::string evo_rpe_key(const std::string& title) {
  const auto nl = title.find('\n');
  if (nl == std::string::npos) return "";
  const std::string line = title.substr(nl + 1, title.find('\n', nl + 1) - nl - 1);
  double delta = 0.0;
  char unit[16] = {0};
  if (std::sscanf(line.c_str(), "for delta = %lf (%15[^)])", &delta, unit) != 2) return "";
  static const std::map<std::string, std::string> kUnits = {{"m", "m"}, {"frames", "f"}, {"deg", "deg"}, {"rad", "rad"}};
  const auto u = kUnits.find(unit);
  if (u == kUnits.end()) return "";
  return fmt::format("{}{}", delta, u->second) + (line.find("using all pairs") != std::string::npos ? "_all" : "");
}

/// A row from an evo result zip (evo_ape / evo_rpe --save_results): its one figure in its column (APE) or
/// RPE block, the others NaN; the alignment from its title, the other settings unknown; grouped by its
/// estimator (est_name).
Row evo_row(const fs::path& f) {
  const io::EvoResult r = io::read_evo_result(f);
  Row row;
  row.file = f.string();
  const std::string title = r.info.value("title", std::string());
  const std::string first_line = title.substr(0, title.find('\n'));
  const auto& names = store::headline_metric_names();
  const auto column = [&names](const char* name) { return std::find(names.begin(), names.end(), name) - names.begin(); };
  std::ptrdiff_t col = -1;
  std::string result;
  if (first_line == "APE w.r.t. translation part (m)" || first_line == "APE w.r.t. point distance (m)")
    col = column("ate_rmse_m"), result = "APE trans [m]";
  if (first_line == "APE w.r.t. rotation angle in degrees (deg)") col = column("rot_rmse_deg"), result = "APE rot [deg]";
  const bool rpe_trans = first_line == "RPE w.r.t. translation part (m)" || first_line == "RPE w.r.t. point distance (m)";
  const bool rpe_rot = first_line == "RPE w.r.t. rotation angle in degrees (deg)";
  const std::string rpe_key = rpe_trans || rpe_rot ? evo_rpe_key(title) : "";
  if ((col < 0 && rpe_key.empty()) || !r.stats.contains("rmse") || !r.stats["rmse"].is_number())
    throw InputError(fmt::format("evo result '{}': roe --summary reads evo's APE and RPE of the translation part, "
                                 "point distance or rotation angle in degrees (the columns ate_rmse_m, rot_rmse_deg "
                                 "and rpe_DELTA_*)",
                                 first_line),
                     {row.file, 0, 0, "info.json:title"});
  row.v.assign(headline_count(), std::numeric_limits<double>::quiet_NaN());
  const double rmse = r.stats["rmse"].get<double>();
  if (col >= 0) row.v[static_cast<std::size_t>(col)] = rmse;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (!rpe_key.empty()) {
    row.rpe.push_back({rpe_key, {rpe_trans ? rmse : nan, rpe_rot ? rmse : nan}});
    result = "RPE " + rpe_key + (rpe_trans ? " trans [m]" : " rot [deg]");
  }
  row.results.push_back({result, evo_stats(r), evo_scale(r)});
  const std::string est = r.info.value("est_name", std::string());
  row.label = est.empty() ? f.stem().string() : label_from_path(est, false);
  row.group = row.label;
  if (const io::NpyArray* e = r.array("error_array")) row.n_matched = e->numel();
  for (const Setting& st : kSettings) row.settings[st.key] = nullptr;
  row.settings["alignment"] = evo_alignment(title);
  return row;
}

/// evo results of one estimator (the same label) are one row: each file fills its figure (a setting the files
/// disagree on, e.g. the APE aligned and the RPE not, reads "se3 (a.zip), none (b.zip)"). A figure two files
/// give stays in a row of its own.
std::vector<Row> merge_evo_rows(std::vector<Row> rows) {
  std::vector<Row> out;
  for (Row& r : rows) {
    Row* into = nullptr;
    for (Row& o : out) {
      if (o.group == "roe" || r.group == "roe" || o.label != r.label) continue;
      bool clash = false;
      for (std::size_t k = 0; k < r.v.size(); ++k) clash = clash || (!std::isnan(r.v[k]) && !std::isnan(o.v[k]));
      for (const auto& b : r.rpe)
        for (const auto& c : o.rpe)
          clash = clash || (b.first == c.first && ((!std::isnan(b.second.first) && !std::isnan(c.second.first)) ||
                                                   (!std::isnan(b.second.second) && !std::isnan(c.second.second))));
      if (!clash) into = &o;
    }
    if (!into) {
      out.push_back(std::move(r));
      continue;
    }
    for (std::size_t k = 0; k < r.v.size(); ++k)
      if (!std::isnan(r.v[k])) into->v[k] = r.v[k];
    for (const auto& b : r.rpe) {
      auto it = std::find_if(into->rpe.begin(), into->rpe.end(), [&](const auto& c) { return c.first == b.first; });
      if (it == into->rpe.end()) {
        into->rpe.push_back(b);
        continue;
      }
      if (!std::isnan(b.second.first)) it->second.first = b.second.first;
      if (!std::isnan(b.second.second)) it->second.second = b.second.second;
    }
    into->results.insert(into->results.end(), r.results.begin(), r.results.end());
    for (const Setting& st : kSettings)  // a setting the files disagree on: each file's value, named
      if (into->settings[st.key] != r.settings[st.key])
        into->settings[st.key] = fmt::format("{} ({}), {} ({})", setting_text(into->settings[st.key]),
                                             fs::path(into->file.substr(0, into->file.find(", "))).filename().string(),
                                             setting_text(r.settings[st.key]), fs::path(r.file).filename().string());
    into->file += ", " + r.file;
  }
  return out;
}

/// Mean and population std of each column over the rows of `group` that have it. A column some of the group's
/// rows lack is named in `partial` (one warning for all such columns, by the caller).
void column_stats(const std::vector<Row>& rows, const std::string& group, std::size_t n_cols, std::vector<double>& mean,
                  std::vector<double>& sd, std::vector<std::size_t>& partial) {
  mean.assign(n_cols, std::numeric_limits<double>::quiet_NaN());
  sd = mean;
  std::size_t n_rows = 0;
  for (const auto& r : rows) n_rows += r.group == group;
  for (std::size_t k = 0; k < n_cols; ++k) {
    std::vector<double> column;
    for (const auto& r : rows)
      if (r.group == group && !std::isnan(r.v[k])) column.push_back(r.v[k]);
    if (column.size() < n_rows && !column.empty() &&
        std::find(partial.begin(), partial.end(), k) == partial.end())
      partial.push_back(k);
    if (column.empty()) continue;
    const eval::Stats st = eval::compute_stats(column);  // mean and population std (ddof 0)
    mean[k] = st.mean;
    sd[k] = st.std;
  }
}

}  // namespace

namespace {

/// One row of the table from a report.json (or the folder holding it, or its eval/ subfolder) or an evo
/// result zip.
Row report_row(const fs::path& given) {
  fs::path f = given;
  if (io::is_folder(f)) f = io::path_exists(f / "report.json") ? f / "report.json" : f / "eval" / "report.json";
  if (io::path_exists(f) && !io::is_folder(f) && io::looks_like_zip(f)) return evo_row(f);
  const store::EvalReportFile j = store::read_eval_report_file(f);
  Row row;
  row.file = f.string();
  row.label = j.label;
  if (j.est_is_run() || !j.per_object.empty()) row.n_objects = j.per_object.size();
  row.n_matched = j.association.n_matched;
  for (const auto& [name, value] : store::headline_metrics(j)) row.v.push_back(value);
  for (const Setting& st : kSettings) row.settings[st.key] = st.value(j);
  row.rpe = rpe_blocks(j);
  if (j.time_offset) row.time_offset = {j.time_offset->offset_s, j.time_offset->sigma_s};
  row.results.push_back({"APE trans [m]", j.ape_trans_m, j.alignment.scale});
  row.results.push_back({"APE rot [deg]", j.ape_rot_deg, j.alignment.scale});
  for (const store::ReportRpe& e : j.rpe) {
    if (!e.trans_m || !e.rot_deg) continue;
    const std::string key = fmt::format("{}{}{}{}", e.delta, e.unit, e.all_pairs ? "_all" : "", e.pairs_from == "gt" ? "_gt" : "");
    row.results.push_back({"RPE " + key + " trans [m]", *e.trans_m, j.alignment.scale});
    row.results.push_back({"RPE " + key + " rot [deg]", *e.rot_deg, j.alignment.scale});
  }
  return row;
}

/// The settings every row shares. Settings that differ inside a group (whose rows are averaged) get one
/// warning per group naming all of them; between groups nothing is averaged, so nothing is mixed.
json common_settings(const std::vector<Row>& rows, const std::vector<std::string>& groups,
                     std::vector<std::string>& warnings) {
  json common = json::object();
  for (const Setting& st : kSettings) {
    bool same = true;
    for (const auto& r : rows) same = same && r.settings[st.key] == rows.front().settings[st.key];
    if (same) common[st.key] = rows.front().settings[st.key];
  }
  for (const std::string& g : groups) {
    std::string differ;
    for (const Setting& st : kSettings) {
      std::string list;
      const json* first = nullptr;
      bool same = true;
      for (std::size_t i = 0; i < rows.size(); ++i) {
        if (rows[i].group != g) continue;
        if (!first) first = &rows[i].settings[st.key];
        same = same && rows[i].settings[st.key] == *first;
        list += fmt::format("{}run {} {}", list.empty() ? "" : ", ", i + 1, setting_text(rows[i].settings[st.key]));
      }
      if (!same) differ += fmt::format("{}different {} ({})", differ.empty() ? "" : "; ", st.name, list);
    }
    if (!differ.empty())
      warnings.push_back(fmt::format("the reports{} were made with {}: the mean and std mix results that are not "
                                     "comparable",
                                     groups.size() > 1 ? " of " + g : std::string(), differ));
  }
  return common;
}

/// RPE: one pair of columns per block any row has (same delta, unit and mode); a row without it has NaN there.
void add_rpe_columns(std::vector<Row>& rows, std::vector<std::string>& cols) {
  std::vector<std::string> keys;
  for (const auto& r : rows)
    for (const auto& b : r.rpe)
      if (std::find(keys.begin(), keys.end(), b.first) == keys.end()) keys.push_back(b.first);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const auto& key : keys) {
    cols.push_back("rpe_" + key + "_trans_rmse_m");
    cols.push_back("rpe_" + key + "_rot_rmse_deg");
    for (auto& r : rows) {
      const auto it = std::find_if(r.rpe.begin(), r.rpe.end(), [&](const auto& b) { return b.first == key; });
      r.v.push_back(it == r.rpe.end() ? nan : it->second.first);
      r.v.push_back(it == r.rpe.end() ? nan : it->second.second);
    }
  }
}

/// The mean and population std of one group of rows (only groups of two rows or more get them).
struct GroupStats {
  std::string group;
  std::size_t n = 0;
  std::vector<double> mean, sd;
};

/// The table in memory: rows, the column names, the groups' means and population std, the shared settings
/// and every warning (label warnings first: `n_label_warnings` of them).
struct Table {
  std::vector<Row> rows;
  std::vector<std::string> cols;
  std::vector<GroupStats> groups;  ///< in the order of their first row; those with n >= 2
  json common;
  std::vector<std::string> warnings;
  std::size_t n_label_warnings = 0;
  /// The one group's statistics when exactly one group has them (the paper's mean over runs), else null.
  const GroupStats* only() const { return groups.size() == 1 ? &groups.front() : nullptr; }
};

json stats_json(const eval::Stats& s) {
  const auto number = [](double v) { return std::isnan(v) ? json(nullptr) : json(v); };
  return {{"rmse", number(s.rmse)}, {"mean", number(s.mean)}, {"median", number(s.median)}, {"std", number(s.std)},
          {"min", number(s.min)},   {"max", number(s.max)}};
}

json summary_json(const Table& t) {
  const std::size_t n_cols = t.cols.size();
  const auto number = [](double v) { return std::isnan(v) ? json(nullptr) : json(v); };
  const auto columns = [&](const std::vector<double>& v) {
    json j = json::object();
    for (std::size_t k = 0; k < n_cols; ++k) j[t.cols[k]] = number(v[k]);
    return j;
  };
  json runs = json::array();
  for (std::size_t i = 0; i < t.rows.size(); ++i) {
    const Row& r = t.rows[i];
    json jr = {{"run", i + 1},
               {"label", r.label},
               {"group", r.group},
               {"report", r.file},
               {"n_objects", r.n_objects ? json(*r.n_objects) : json(nullptr)},
               {"n_matched", r.n_matched}};
    for (std::size_t k = 0; k < n_cols; ++k) jr[t.cols[k]] = number(r.v[k]);
    for (const Setting& st : kSettings) jr[st.key] = r.settings[st.key];
    json res = json::array();
    for (const ResultStats& x : r.results)
      res.push_back({{"result", x.name}, {"stats", stats_json(x.stats)}, {"scale", x.scale ? json(*x.scale) : json(nullptr)}});
    jr["results"] = res;
    if (r.time_offset) jr["time_offset"] = {{"offset_s", r.time_offset->first}, {"sigma_s", r.time_offset->second}};
    runs.push_back(jr);
  }
  json groups = json::array();
  for (const GroupStats& g : t.groups)
    groups.push_back({{"group", g.group}, {"n_runs", g.n}, {"mean", columns(g.mean)}, {"std", columns(g.sd)}});
  const GroupStats* one = t.only();
  return {{"runs", runs},
          {"mean", one ? columns(one->mean) : json(nullptr)},
          {"std", one ? columns(one->sd) : json(nullptr)},
          {"groups", groups},
          {"group_rule", "rows are averaged within a group only: every roe report is in 'roe', an evo result in its "
                         "estimator's (est_name), evo results of one estimator merged into one row"},
          {"n_runs", t.rows.size()},
          {"std_definition", "population (ddof 0)"},
          {"settings", t.common},
          {"warnings", t.warnings}};
}

/// The mean and ± std lines of every group (labelled with the group when there are several).
template <class Line>
std::string group_lines(const Table& t, Line&& line) {
  std::string md;
  for (const GroupStats& g : t.groups) {
    const std::string name = t.groups.size() > 1 || g.group != "roe" ? " (" + g.group + ")" : "";
    md += line("mean" + name, g.mean, "");
    md += line("± std" + name, g.sd, "± ");
  }
  return md;
}

/// The RPE columns' Markdown table (none when no row has an RPE block).
std::string rpe_markdown(const Table& t) {
  const int n_cols = static_cast<int>(t.cols.size());
  const int n_head = static_cast<int>(headline_count());
  if (n_cols <= n_head) return "";
  std::string md = "\n| Run | Label |";
  std::string sep = "|---|---|";
  for (int k = n_head; k < n_cols; k += 2) {
    const std::string key = t.cols[k].substr(4, t.cols[k].size() - 4 - std::string("_trans_rmse_m").size());
    md += fmt::format(" RPE {} trans RMSE [m] | RPE {} rot RMSE [deg] |", key, key);
    sep += "---|---|";
  }
  md += "\n" + sep + "\n";
  const auto rpe_row = [&](const std::string& a, const std::string& b, const std::vector<double>& v,
                           const char* prefix) {
    std::string line = fmt::format("| {} | {} |", a, b);
    for (int k = n_head; k < n_cols; k += 2)
      line += fmt::format(" {}{} | {}{} |", prefix, cell(v[k], 4), prefix, cell(v[k + 1], 3));
    return line + "\n";
  };
  for (std::size_t i = 0; i < t.rows.size(); ++i) md += rpe_row(std::to_string(i + 1), t.rows[i].label, t.rows[i].v, "");
  md += group_lines(t, [&](const std::string& a, const std::vector<double>& v, const char* p) { return rpe_row(a, "", v, p); });
  return md;
}

/// evo_res's table: every result's statistics and the alignment's scale.
std::string results_markdown(const Table& t) {
  std::string md = "\n| Run | Label | Result | rmse | mean | median | std | min | max | scale |\n"
                   "|---|---|---|---|---|---|---|---|---|---|\n";
  for (std::size_t i = 0; i < t.rows.size(); ++i)
    for (const ResultStats& x : t.rows[i].results) {
      const eval::Stats& s = x.stats;
      md += fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n", i + 1, t.rows[i].label, x.name,
                        cell(s.rmse, 4), cell(s.mean, 4), cell(s.median, 4), cell(s.std, 4), cell(s.min, 4),
                        cell(s.max, 4), x.scale ? fmt::format("{:.6f}", *x.scale) : std::string("–"));
    }
  return md;
}

/// Markdown in the layout of the paper's Table I; the Euler columns under their metric's name (roe eval
/// --euler): the same words mean other figures. Then the RPE columns and evo_res's per-result table.
std::string summary_markdown(const Table& t) {
  const json& common = t.common;
  const std::string euler_name = common.contains("euler_metric") ? setting_text(common["euler_metric"]) : "mixed";
  std::string md = fmt::format(
      "| Run | Label | #objects | (x, y, z) [m] | (roll, pitch, yaw) [deg], Euler metric '{}' | APE RMSE [m], [deg] "
      "|\n|---|---|---|---|---|---|\n",
      euler_name);
  for (std::size_t i = 0; i < t.rows.size(); ++i) {
    const Row& r = t.rows[i];
    md += fmt::format("| {} | {} | {} | {} | {} | {}, {} |\n", i + 1, r.label,
                      r.n_objects ? std::to_string(*r.n_objects) : "–", vec3(r.v, 0, 3), vec3(r.v, 3, 2),
                      cell(r.v[6], 3), cell(r.v[7], 2));
  }
  md += group_lines(t, [](const std::string& name, const std::vector<double>& v, const char* p) {
    const std::string pre = p;
    return fmt::format("| {} | | | {}{} | {}{} | {}{}, {} |\n", name, pre, vec3(v, 0, 3), pre, vec3(v, 3, 2), pre,
                       cell(v[6], 3), cell(v[7], 2));
  });
  md += rpe_markdown(t);
  md += results_markdown(t);
  if (t.warnings.size() == t.n_label_warnings && common.size() == std::size(kSettings)) {
    md += fmt::format(
        "\nSettings of every run: alignment {}, --n-align {}, --max-dt {} s, --t-offset {} s, "
        "association {}, Euler metric {}.\n",
        setting_text(common["alignment"]), setting_text(common["n_align"]), setting_text(common["max_dt_s"]),
        setting_text(common["t_offset_s"]), setting_text(common["assoc"]), setting_text(common["euler_metric"]));
  }
  if (!t.warnings.empty()) {
    md += "\n";
    for (const auto& w : t.warnings) md += "warning: " + w + "\n";
  }
  return md;
}

std::string summary_csv(const Table& t) {
  io::CsvWriter w;
  std::vector<std::string> h = {"run", "label", "report", "n_objects", "n_matched"};
  for (const auto& c : t.cols) h.push_back(c);
  for (const Setting& st : kSettings) h.push_back(st.key);
  w.header(h);
  for (std::size_t i = 0; i < t.rows.size(); ++i) {
    const Row& r = t.rows[i];
    w.add(std::to_string(i + 1)).add(r.label).add(r.file);
    if (r.n_objects)
      w.add(static_cast<std::int64_t>(*r.n_objects));
    else
      w.add_empty();
    w.add(static_cast<std::int64_t>(r.n_matched));
    for (double v : r.v) std::isnan(v) ? w.add_empty() : w.add(v);
    for (const Setting& st : kSettings) {
      const json& v = r.settings[st.key];
      if (v.is_null())
        w.add_empty();
      else if (v.is_string())
        w.add(v.get<std::string>());
      else if (v.is_number_integer())
        w.add(v.get<std::int64_t>());
      else
        w.add(v.get<double>());
    }
    w.end_row();
  }
  for (const GroupStats& g : t.groups)
    for (const auto& [name, vals] : {std::pair{"mean", &g.mean}, std::pair{"std", &g.sd}}) {
      w.add(name).add(t.groups.size() > 1 ? g.group : std::string()).add_empty().add_empty().add_empty();
      for (double v : *vals) std::isnan(v) ? w.add_empty() : w.add(v);
      for (std::size_t k = 0; k < std::size(kSettings); ++k) w.add_empty();
      w.end_row();
    }
  return w.str();
}

/// --out FOLDER/ (a trailing separator) or an existing folder: FOLDER/summary.{csv,json,md}; otherwise
/// FILE with its .csv/.json/.md extension, if any, replaced. Checked before anything is written.
std::vector<fs::path> write_summary(const std::string& out_str, bool force, const Table& t, const json& summary,
                                    const std::string& md) {
  const bool trailing = out_str.back() == '/';
  const fs::path out = io::without_trailing_separator(out_str);
  fs::path base = out;
  if (trailing || io::is_folder(out)) {
    base = out / "summary";
  } else {
    const std::string ext = base.extension().string();
    if (ext == ".csv" || ext == ".json" || ext == ".md") base.replace_extension();
  }
  const fs::path csv = base.string() + ".csv", js_path = base.string() + ".json", md_path = base.string() + ".md";
  std::vector<fs::path> inputs;
  for (const auto& r : t.rows) inputs.push_back(r.file);
  for (const auto& p : {csv, js_path, md_path}) {
    io::check_file_output(p, force, inputs, "summary output " + p.string());
  }
  if (base.has_parent_path()) {
    std::error_code ec;
    fs::create_directories(base.parent_path(), ec);
    if (ec) throw InputError("cannot create folder: " + ec.message(), {base.parent_path().string()});
  }
  io::write_file_atomic(csv, summary_csv(t));
  io::write_file_atomic(js_path, io::dump_json(summary, 2) + "\n");
  io::write_file_atomic(md_path, md);
  return {csv, js_path, md_path};
}

}  // namespace

/// The groups' statistics (groups of two rows or more) and one warning for the columns some rows of a group lack.
void group_stats(Table& t) {
  std::vector<std::string> order;
  for (const Row& r : t.rows)
    if (std::find(order.begin(), order.end(), r.group) == order.end()) order.push_back(r.group);
  std::vector<std::size_t> partial;
  for (const std::string& g : order) {
    GroupStats gs;
    gs.group = g;
    for (const Row& r : t.rows) gs.n += r.group == g;
    if (gs.n < 2) continue;
    column_stats(t.rows, g, t.cols.size(), gs.mean, gs.sd, partial);
    t.groups.push_back(std::move(gs));
  }
  if (partial.empty()) return;
  std::sort(partial.begin(), partial.end());
  std::string names;
  for (std::size_t k : partial) names += (names.empty() ? "" : ", ") + t.cols[k];
  t.warnings.push_back(fmt::format("some runs lack {} (evo results hold one figure each, an RPE block may be missing or "
                                   "without pairs): their mean and std are over the runs that have them",
                                   names));
}

EvalSummaryResult summarize_eval_reports(const EvalSummaryOptions& o) {
  if (o.reports.empty()) throw InputError("--summary needs at least one report.json", {"roe eval"});
  Table t;
  std::vector<Row> rows;
  for (const auto& r : o.reports) rows.push_back(report_row(r));
  t.rows = merge_evo_rows(std::move(rows));
  t.warnings = duplicate_label_warnings(t.rows);
  t.n_label_warnings = t.warnings.size();
  std::vector<std::string> groups;
  for (const Row& r : t.rows)
    if (std::find(groups.begin(), groups.end(), r.group) == groups.end()) groups.push_back(r.group);
  t.common = common_settings(t.rows, groups, t.warnings);
  t.cols = store::headline_metric_names();
  add_rpe_columns(t.rows, t.cols);
  group_stats(t);
  if (groups.size() > 1)
    t.warnings.push_back(fmt::format("{} groups ({}): no mean across different estimators, each group's rows are "
                                     "averaged on their own",
                                     groups.size(), fmt::format("{}", fmt::join(groups, ", "))));

  EvalSummaryResult res;
  res.summary = summary_json(t);
  res.markdown = summary_markdown(t);
  if (!o.out.empty()) res.written = write_summary(o.out, o.force, t, res.summary, res.markdown);
  return res;
}

std::string EvalSummaryResult::to_text() const {
  std::string s = markdown;
  for (const auto& p : written) s += "wrote " + p.string() + "\n";
  return s;
}

}  // namespace roe::app
