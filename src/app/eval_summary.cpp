// roe eval --summary: one row per run + mean and population std, in the paper's table layout.
#include <fmt/format.h>

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
    {"t_offset_s", [](const store::EvalReportFile& f) { return json(f.association.offset_s); }, "--t-offset"},
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

struct Row {
  std::string label, file;
  std::optional<std::size_t> n_objects;  ///< none: not a roe run (no objects to count)
  std::size_t n_matched = 0;
  std::vector<double> v;  ///< the headline metrics (NaN where the report has no such figure), then RPE columns
  json settings = json::object();
  std::vector<std::pair<std::string, std::pair<double, double>>> rpe;
};

/// A row from an evo result zip (evo_ape --save_results): its one APE figure in its column, the others NaN;
/// the alignment from its title, the other settings unknown.
Row evo_row(const fs::path& f) {
  const io::EvoResult r = io::read_evo_result(f);
  Row row;
  row.file = f.string();
  const std::string title = r.info.value("title", std::string());
  const std::string first_line = title.substr(0, title.find('\n'));
  const auto& names = store::headline_metric_names();
  const auto column = [&names](const char* name) { return std::find(names.begin(), names.end(), name) - names.begin(); };
  std::ptrdiff_t col = -1;
  if (first_line == "APE w.r.t. translation part (m)" || first_line == "APE w.r.t. point distance (m)")
    col = column("ate_rmse_m");
  if (first_line == "APE w.r.t. rotation angle in degrees (deg)") col = column("rot_rmse_deg");
  if (col < 0 || !r.stats.contains("rmse"))
    throw InputError(fmt::format("evo result '{}': roe --summary reads evo's APE of the translation part, point "
                                 "distance or rotation angle in degrees (the columns ate_rmse_m, rot_rmse_deg)",
                                 first_line),
                     {row.file, 0, 0, "info.json:title"});
  row.v.assign(headline_count(), std::numeric_limits<double>::quiet_NaN());
  row.v[static_cast<std::size_t>(col)] = r.stats["rmse"].get<double>();
  const std::string est = r.info.value("est_name", std::string());
  row.label = est.empty() ? f.stem().string() : label_from_path(est, false);
  if (const io::NpyArray* e = r.array("error_array")) row.n_matched = e->numel();
  for (const Setting& st : kSettings) row.settings[st.key] = nullptr;
  row.settings["alignment"] = evo_alignment(title);
  return row;
}

/// Mean and population std of each column over the runs that have it; a warning for a column that some
/// runs lack (evo result files hold one metric each).
void column_stats(const std::vector<Row>& rows, const std::vector<std::string>& cols, std::vector<double>& mean,
                  std::vector<double>& sd, std::vector<std::string>& warnings) {
  const std::size_t n_cols = cols.size();
  mean.assign(n_cols, std::numeric_limits<double>::quiet_NaN());
  sd = mean;
  for (std::size_t k = 0; k < n_cols; ++k) {
    std::vector<double> column;
    for (const auto& r : rows)
      if (!std::isnan(r.v[k])) column.push_back(r.v[k]);
    if (column.size() < rows.size() && !column.empty())
      warnings.push_back(fmt::format("{}: {} of the {} runs have it (the others are evo results of another metric); "
                                     "its mean and std are over those",
                                     cols[k], column.size(), rows.size()));
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
  return row;
}

/// The settings every row shares (the others get a warning each: the table is still written, comparing
/// settings can be the point).
json common_settings(const std::vector<Row>& rows, std::vector<std::string>& warnings) {
  json common = json::object();
  for (const Setting& st : kSettings) {
    bool same = true;
    for (const auto& r : rows) same = same && r.settings[st.key] == rows.front().settings[st.key];
    if (same) {
      common[st.key] = rows.front().settings[st.key];
      continue;
    }
    std::string list;
    for (std::size_t i = 0; i < rows.size(); ++i)
      list += fmt::format("{}run {} {}", i == 0 ? "" : ", ", i + 1, setting_text(rows[i].settings[st.key]));
    warnings.push_back(fmt::format(
        "the reports were made with different {} ({}): the mean and std mix results that are not comparable",
        st.name, list));
  }
  return common;
}

/// RPE: the blocks every report has (same delta, unit and mode), as two more columns each; a warning for
/// each block some reports lack.
void add_rpe_columns(std::vector<Row>& rows, std::vector<std::string>& cols, std::vector<std::string>& warnings) {
  std::vector<std::string> common_keys, partial;
  for (const auto& [key, val] : rows.front().rpe) {
    bool everywhere = true;
    for (const auto& r : rows) {
      bool found = false;
      for (const auto& b : r.rpe) found = found || b.first == key;
      everywhere = everywhere && found;
    }
    (everywhere ? common_keys : partial).push_back(key);
  }
  for (const auto& r : rows)
    for (const auto& b : r.rpe)
      if (std::find(common_keys.begin(), common_keys.end(), b.first) == common_keys.end() &&
          std::find(partial.begin(), partial.end(), b.first) == partial.end())
        partial.push_back(b.first);
  for (const auto& key : partial)
    warnings.push_back(fmt::format("RPE {} is not in every report (or has no pairs in some): not summarised", key));
  for (const auto& key : common_keys) {
    cols.push_back("rpe_" + key + "_trans_rmse_m");
    cols.push_back("rpe_" + key + "_rot_rmse_deg");
    for (auto& r : rows)
      for (const auto& b : r.rpe)
        if (b.first == key) {
          r.v.push_back(b.second.first);
          r.v.push_back(b.second.second);
          break;
        }
  }
}

/// The table in memory: rows, the column names, their mean and population std, the shared settings and
/// every warning (label warnings first: `n_label_warnings` of them).
struct Table {
  std::vector<Row> rows;
  std::vector<std::string> cols;
  std::vector<double> mean, sd;
  json common;
  std::vector<std::string> warnings;
  std::size_t n_label_warnings = 0;
};

json summary_json(const Table& t) {
  const std::size_t n_cols = t.cols.size();
  const auto number = [](double v) { return std::isnan(v) ? json(nullptr) : json(v); };
  json runs = json::array();
  for (std::size_t i = 0; i < t.rows.size(); ++i) {
    const Row& r = t.rows[i];
    json jr = {{"run", i + 1},
               {"label", r.label},
               {"report", r.file},
               {"n_objects", r.n_objects ? json(*r.n_objects) : json(nullptr)},
               {"n_matched", r.n_matched}};
    for (std::size_t k = 0; k < n_cols; ++k) jr[t.cols[k]] = number(r.v[k]);
    for (const Setting& st : kSettings) jr[st.key] = r.settings[st.key];
    runs.push_back(jr);
  }
  json jm, js;
  for (std::size_t k = 0; k < n_cols; ++k) {
    jm[t.cols[k]] = number(t.mean[k]);
    js[t.cols[k]] = number(t.sd[k]);
  }
  return {{"runs", runs},
          {"mean", jm},
          {"std", js},
          {"n_runs", t.rows.size()},
          {"std_definition", "population (ddof 0)"},
          {"settings", t.common},
          {"warnings", t.warnings}};
}

/// The RPE columns' Markdown table (none when no RPE block is in every report).
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
      line += fmt::format(" {}{:.4f} | {}{:.3f} |", prefix, v[k], prefix, v[k + 1]);
    return line + "\n";
  };
  for (std::size_t i = 0; i < t.rows.size(); ++i) md += rpe_row(std::to_string(i + 1), t.rows[i].label, t.rows[i].v, "");
  md += rpe_row("mean", "", t.mean, "");
  md += rpe_row("± std", "", t.sd, "± ");
  return md;
}

/// Markdown in the layout of the paper's Table I; the Euler columns under their metric's name (roe eval
/// --euler): the same words mean other figures.
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
  md += fmt::format("| mean | | - | {} | {} | {}, {} |\n", vec3(t.mean, 0, 3), vec3(t.mean, 3, 2), cell(t.mean[6], 3),
                    cell(t.mean[7], 2));
  md += fmt::format("| ± std | | | ± {} | ± {} | ± {}, {} |\n", vec3(t.sd, 0, 3), vec3(t.sd, 3, 2), cell(t.sd[6], 3),
                    cell(t.sd[7], 2));
  md += rpe_markdown(t);
  if (t.warnings.size() == t.n_label_warnings) {  // the settings agree (labels alone say nothing of them)
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
  for (const auto& [name, vals] : {std::pair{"mean", &t.mean}, std::pair{"std", &t.sd}}) {
    w.add(name).add_empty().add_empty().add_empty().add_empty();
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

EvalSummaryResult summarize_eval_reports(const EvalSummaryOptions& o) {
  if (o.reports.empty()) throw InputError("--summary needs at least one report.json", {"roe eval"});
  Table t;
  for (const auto& r : o.reports) t.rows.push_back(report_row(r));
  t.warnings = duplicate_label_warnings(t.rows);
  t.n_label_warnings = t.warnings.size();
  t.common = common_settings(t.rows, t.warnings);
  t.cols = store::headline_metric_names();
  add_rpe_columns(t.rows, t.cols, t.warnings);
  column_stats(t.rows, t.cols, t.mean, t.sd, t.warnings);

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
