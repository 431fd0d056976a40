// roe report: the HTML document (no script, no external resource; figures as data: URIs).
#include <fmt/format.h>

#include <array>
#include <cmath>
#include <iterator>
#include <map>
#include <set>
#include <tuple>

#include "roe/app/report.hpp"
#include "roe/store/eval_report.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"
#include "roe/version.hpp"

namespace roe::app {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string esc(const std::string& s) {
  std::string o;
  o.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}

std::string base64(const std::string& bytes) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string o;
  o.reserve((bytes.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) | (static_cast<unsigned char>(bytes[i + 1]) << 8) |
                       static_cast<unsigned char>(bytes[i + 2]);
    o += {k[v >> 18], k[(v >> 12) & 63], k[(v >> 6) & 63], k[v & 63]};
  }
  if (i + 1 == bytes.size()) {
    const unsigned v = static_cast<unsigned char>(bytes[i]) << 16;
    o += {k[v >> 18], k[(v >> 12) & 63], '=', '='};
  } else if (i + 2 == bytes.size()) {
    const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) | (static_cast<unsigned char>(bytes[i + 1]) << 8);
    o += {k[v >> 18], k[(v >> 12) & 63], k[(v >> 6) & 63], '='};
  }
  return o;
}

}  // namespace

std::string caption_html(const std::string& text) {
  std::string o;
  o.reserve(text.size() + 32);
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if ((c == '_' || c == '^') && i + 1 < text.size() && text[i + 1] == '{') {
      const std::size_t close = text.find('}', i + 2);
      const std::size_t open = text.find('{', i + 2);
      if (close != std::string::npos && (open == std::string::npos || open > close)) {
        const char* tag = c == '_' ? "sub" : "sup";
        o += fmt::format("<{}>{}</{}>", tag, esc(text.substr(i + 2, close - i - 2)), tag);
        i = close;
        continue;
      }
    }
    o += esc(std::string(1, c));
  }
  return o;
}

namespace {

/// A table cell holding a number of the evaluation report: the shown value is rounded, the exact
/// one is in data-value, and data-path says where it is in report.json (the browser test reads both).
std::string num_cell(const std::string& path, const std::optional<double>& v, int decimals) {
  if (!v) return "<td class=\"na\">–</td>";
  return fmt::format("<td data-path=\"{}\" data-value=\"{}\">{:.{}f}</td>", esc(path), io::dump_json(json(*v)), *v,
                     decimals);
}

std::string plain(double v) { return fmt::format("{:.6g}", v); }

std::string plain(const json& v) {
  if (v.is_string()) return v.get<std::string>();
  if (v.is_number_float()) return fmt::format("{:.6g}", v.get<double>());
  return io::dump_json(v);
}

/// Every leaf of `j` as a two-column table row (key path, value): configurations and health.
void flatten_rows(const json& j, const std::string& prefix, std::string& out) {
  if (j.is_object() && !j.empty()) {
    for (const auto& [k, v] : j.items()) flatten_rows(v, prefix.empty() ? k : prefix + "." + k, out);
  } else if (j.is_array() && !j.empty() && (j.front().is_object() || j.front().is_array())) {
    for (std::size_t i = 0; i < j.size(); ++i) flatten_rows(j[i], fmt::format("{}[{}]", prefix, i), out);
  } else {
    out += fmt::format("<tr><th>{}</th><td>{}</td></tr>\n", esc(prefix), esc(plain(j)));
  }
}

std::string section_summary(const store::EvalReportFile& ev) {
  std::string s = "<section id=\"evaluation\"><h2>Evaluation</h2>\n";
  const store::ReportAssociation& as = ev.association;
  const store::ReportAlignment& al = ev.alignment;
  s += fmt::format(
      "<p>Estimate {} against ground truth {}: {} of {} estimate poses matched (max Δt {} s, {}); alignment "
      "<b>{}</b> on {} pairs, scale {:.6f}.</p>\n",
      esc(ev.est.description), esc(ev.gt.description), as.n_matched, as.n_est, plain(as.max_dt_s), esc(as.policy),
      esc(al.type), al.n_aligned, al.scale);
  s += "<table class=\"num\" id=\"per-axis\"><caption>RMSE per axis (the paper's tables)</caption>\n"
       "<tr><th></th><th>x [m]</th><th>y [m]</th><th>z [m]</th><th>roll [°]</th><th>pitch [°]</th>"
       "<th>yaw [°]</th></tr>\n<tr><th>RMSE</th>";
  const std::vector<store::ReportCell> axes = store::per_axis_rmse_cells(ev);
  for (std::size_t i = 0; i < axes.size(); ++i) s += num_cell(axes[i].path, axes[i].value, i < 3 ? 4 : 3);
  s += "</tr></table>\n";
  s += "<table class=\"num\" id=\"ape\"><caption>Absolute pose error (evo's statistics)</caption>\n<tr><th></th>";
  for (const char* k : {"rmse", "mean", "median", "std", "min", "max"}) s += fmt::format("<th>{}</th>", k);
  s += "</tr>\n";
  for (const auto& [rotation, name, dec] : {std::tuple{false, "translation [m]", 4}, std::tuple{true, "rotation [°]", 3}}) {
    s += fmt::format("<tr><th>{}</th>", name);
    for (const store::ReportCell& c : store::ape_cells(ev, rotation)) s += num_cell(c.path, c.value, dec);
    s += "</tr>\n";
  }
  s += "</table>\n";
  if (ev.consistency.available) {
    // Each value with its frame: the estimator's gauge (the consistency figure's) and after the alignment, whose
    // orientation NEES the alignment's rotation error inflates.
    s += "<table class=\"num\" id=\"nees\"><caption>Average NEES per 3-dof block (3 expected), in each frame"
         "</caption><tr><th>frame</th><th>position</th><th>orientation</th></tr>\n";
    for (const store::NeesFrame& f : store::nees_frames(ev)) {
      s += fmt::format("<tr><th>{}{}</th>", esc(f.frame), f.headline ? " (headline)" : "");
      for (const store::ReportCell& c : f.cells) s += num_cell(c.path, c.value, 3);
      s += "</tr>\n";
    }
    s += "</table>\n";
  }
  if (!ev.rpe.empty()) {
    s += "<table class=\"num\" id=\"rpe\"><caption>Relative pose error</caption><tr><th>Δ</th><th>pairs</th>"
         "<th>trans rmse [m]</th><th>rot rmse [°]</th></tr>\n";
    for (const store::ReportRpe& e : ev.rpe) {
      s += fmt::format("<tr><th>{} {}</th><td>{}</td>", plain(e.delta), esc(e.unit), e.n_pairs);
      // rpe is an array: its cells carry no data-path.
      for (const std::optional<eval::Stats>& st : {e.trans_m, e.rot_deg})
        s += st ? fmt::format("<td>{:.4f}</td>", st->rmse) : "<td class=\"na\">–</td>";
      s += "</tr>\n";
    }
    s += "</table>\n";
  }
  return s + "</section>\n";
}

/// The RMSE cells of one subset ("all" or "accepted") of an object of report.json's per_object.
std::string fit_cells(const store::ReportFit* f) {
  if (!f || f->n == 0) {
    std::string s = "<td>0</td>";
    for (int k = 0; k < 6; ++k) s += "<td class=\"na\">–</td>";
    return s;
  }
  const Eigen::Vector3d& p = f->pos_rmse_m;
  const Eigen::Vector3d& e = f->rpy_rmse_deg;
  return fmt::format("<td>{}</td><td>{:.3f}</td><td>{:.3f}</td><td>{:.3f}</td><td>{:.2f}</td><td>{:.2f}</td>"
                     "<td>{:.2f}</td>",
                     f->n, p.x(), p.y(), p.z(), e.x(), e.y(), e.z());
}

/// Detections per object by status (run.json) and, as roe eval prints them, the RMSE of the object's
/// reprojected raw detections on two rows: all of them (the rejected outliers included) and the accepted
/// ones alone; a last row with the totals run.json counts.
std::string section_objects(const store::EvalReportFile& ev, const store::RunRecord* run) {
  std::string s = "<section id=\"objects\"><h2>Objects</h2>\n";
  const char* statuses[] = {"detections", "accepted", "initialized", "rejected_chi2", "rejected_no_main",
                            "rejected_score", "rejected_no_imu", "pending_init"};
  s += "<table class=\"num\" id=\"counts\"><caption>Detections per object (run.json";
  s += run ? fmt::format("; anchor object {}", run->anchor_id) : std::string();
  s += ") and the RMSE of each object's reprojected raw detections against the ground truth (same alignment): "
       "<i>all</i> includes the detections the filter rejected as outliers, <i>accepted</i> only those it used"
       "</caption>\n<tr><th rowspan=\"2\">object</th><th colspan=\"8\">detections by status</th>"
       "<th rowspan=\"2\">subset</th><th rowspan=\"2\">n</th><th colspan=\"3\">RMSE [m]</th>"
       "<th colspan=\"3\">RMSE [°]</th></tr>\n<tr>";
  const char* shown[] = {"all", "accepted", "initialized", "χ² rejected", "no anchor", "score", "no IMU", "pending"};
  for (std::size_t i = 0; i < std::size(statuses); ++i)
    s += fmt::format("<th title=\"{}\">{}</th>", statuses[i], shown[i]);
  s += "<th>x</th><th>y</th><th>z</th><th>roll</th><th>pitch</th><th>yaw</th></tr>\n";
  std::map<int, const store::ReportObject*> eval_obj;
  for (const store::ReportObject& o : ev.per_object) eval_obj[o.object_id] = &o;
  std::set<int> ids;
  for (const auto& [k, v] : eval_obj) ids.insert(k);
  if (run)
    for (const auto& [k, v] : run->counts.per_object) ids.insert(k);
  // The counts in the order of `statuses`.
  const auto by_status = [](const ekf::DetectionCounts& c) {
    return std::array<std::size_t, 8>{c.detections,     c.accepted,       c.initialized,     c.rejected_chi2,
                                      c.rejected_no_main, c.rejected_score, c.rejected_no_imu, c.pending_init};
  };
  const auto count_cells = [&](const ekf::DetectionCounts* c) {
    std::string t;
    for (std::size_t i = 0; i < std::size(statuses); ++i)
      t += c ? fmt::format("<td rowspan=\"2\">{}</td>", by_status(*c)[i]) : "<td rowspan=\"2\" class=\"na\">–</td>";
    return t;
  };
  for (int id : ids) {
    const store::ReportObject* o = eval_obj.count(id) ? eval_obj[id] : nullptr;
    s += fmt::format("<tr class=\"subset-all\" data-object=\"{}\"><th rowspan=\"2\">{}</th>", id, id);
    const ekf::DetectionCounts* counts = nullptr;
    if (run)
      if (const auto it = run->counts.per_object.find(id); it != run->counts.per_object.end()) counts = &it->second;
    s += count_cells(counts);
    s += "<th>all</th>" + fit_cells(o ? &o->all : nullptr) + "</tr>\n";
    s += fmt::format("<tr class=\"subset-accepted\" data-object=\"{}\"><th>accepted</th>{}</tr>\n", id,
                     fit_cells(o ? &o->accepted : nullptr));
  }
  if (run) {
    s += "<tr class=\"total\"><th>total</th>";
    for (const std::size_t n : by_status(run->counts.detections)) s += fmt::format("<td>{}</td>", n);
    s += "<td colspan=\"8\"></td></tr>\n";
  }
  return s + "</table></section>\n";
}

std::string section_calib(const ReportCalib& calib) {
  std::string s = "<section id=\"calib-check\"><h2>Calibration checks</h2>\n";
  if (!calib.result)
    return s + fmt::format("<p class=\"fail\">calib-check could not run: {}</p></section>\n", esc(calib.error));
  const CalibCheckResult& c = *calib.result;
  s += fmt::format("<p>Verdict: <b class=\"{}\">{}</b> (dataset: {}). Thresholds and definitions: "
                   "docs/calib-check.md.</p>\n",
                   c.passed() ? "pass" : "fail", c.passed() ? "PASS" : "FAIL",
                   esc(c.dataset.empty() ? "null" : c.dataset));
  s += "<table id=\"calib-checks\"><tr><th>check</th><th>status</th><th>message</th></tr>\n";
  for (const calib::CheckResult& k : c.report.checks) {
    const std::string st = calib::to_string(k.status);
    s += fmt::format("<tr><th>{}</th><td class=\"{}\">{}</td><td>{}</td></tr>\n", esc(k.name), esc(st), esc(st),
                     esc(k.message));
  }
  return s + "</table></section>\n";
}

/// What the figure was asked to draw and did not (figures.json `skipped_layers`), as a sentence.
std::string skipped_layers_html(const std::string& name, const json& manifest) {
  std::string s;
  for (const json& f : manifest.value("figures", json::array())) {
    if (f.value("name", "") != name) continue;
    for (const json& k : f.value("skipped_layers", json::array()))
      s += fmt::format(" <span class=\"na skipped-layer\">Not drawn: {} ({}).</span>",
                       esc(k.value("layer", "")), esc(k.value("reason", "")));
  }
  return s;
}

std::string section_figures(const FigureSet& figs, const fs::path& dir) {
  std::string s = "<section id=\"figures\"><h2>Figures</h2>\n";
  for (const Figure& f : figs.figures) {
    const std::string png = io::read_file(dir / f.files.at("png"));
    // The alt text is plain (marks dropped), the caption HTML (sub- and superscripts).
    std::string alt = f.title;
    for (const char* m : {"_{", "^{", "}"})
      for (std::size_t p; (p = alt.find(m)) != std::string::npos;) alt.erase(p, std::string(m).size());
    s += fmt::format(
        "<figure id=\"fig-{}\"><img alt=\"{}\" src=\"data:image/png;base64,{}\">\n<figcaption><b>{}</b> {}"
        "{}</figcaption></figure>\n",
        esc(f.name), esc(alt), base64(png), caption_html(f.title), caption_html(f.caption),
        skipped_layers_html(f.name, figs.manifest));
  }
  for (const auto& [name, why] : figs.skipped) s += fmt::format("<p class=\"na\">{} not drawn: {}</p>\n", esc(name), esc(why));
  return s + "</section>\n";
}

std::string section_table(const char* id, const char* title, const json& j, bool open) {
  std::string rows;
  flatten_rows(j, "", rows);
  return fmt::format("<section id=\"{}\"><details{}><summary><h2>{}</h2></summary><table class=\"kv\">\n{}"
                     "</table></details></section>\n",
                     id, open ? " open" : "", title, rows);
}

constexpr const char* kStyle = R"css(
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",sans-serif;max-width:1180px;margin:1.5em auto;padding:0 1em;color:#222}
h1{font-size:1.5em;margin:.2em 0}h2{font-size:1.2em;margin:1.2em 0 .4em;display:inline-block}
table{border-collapse:collapse;margin:.6em 0 1em}caption{text-align:left;color:#555;padding:.2em 0}
th,td{border:1px solid #ddd;padding:.25em .6em;text-align:left}#counts th,#counts td{font-size:13px;white-space:nowrap}table.num td{text-align:right;font-variant-numeric:tabular-nums}
table.kv th{font-weight:normal;color:#444;font-family:ui-monospace,monospace;font-size:12px}
figure{margin:1.2em 0}figure img{max-width:100%;height:auto;border:1px solid #eee}figcaption{color:#444;font-size:13px}
.pass{color:#17803d}.fail{color:#b3261e}.inconclusive{color:#a15c00}.skipped,.na{color:#888}
summary{cursor:pointer}.meta{color:#555}
)css";


/// The blocks of run.json the report shows as key/value tables, as the file spells them (the store's one
/// mapping, store::run_record_to_json): health (open), then config, inputs, init, nis and timing_s.
void run_sections(const store::RunRecord& run, std::string& h) {
  const json doc = store::run_record_to_json(run);
  json health, cfg = json::object();
  for (const auto& [key, value] : doc.items()) {
    if (key == "health") health = value;
    if (key == "config" || key == "inputs" || key == "init" || key == "nis" || key == "timing_s") cfg[key] = value;
  }
  if (!health.is_null()) h += section_table("health", "Health", health, true);
  h += section_table("configuration", "Configuration (run.json)", cfg, false);
}

}  // namespace

std::string report_html(const store::EvalReportFile& ev, const store::RunRecord* run, const ReportCalib& calib,
                        const FigureSet& figures, const fs::path& figures_dir) {
  const std::string& label = ev.label;
  std::string h = "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n";
  h += "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n";
  h += fmt::format("<title>roe report: {}</title>\n<style>{}</style></head><body>\n", esc(label), kStyle);
  h += fmt::format("<h1>roe report: {}</h1>\n<p class=\"meta\">run {} · ground truth {} · roe {}</p>\n", esc(label),
                   esc(ev.est.path), esc(ev.gt.path), kVersion);
  h += "<nav><a href=\"#evaluation\">Evaluation</a> · <a href=\"#objects\">Objects</a> · <a href=\"#calib-check\">Calibration checks</a> · <a href=\"#figures\">Figures</a> · <a href=\"#configuration\">Configuration</a> · <a href=\"#warnings\">Warnings</a></nav>\n";
  h += section_summary(ev);
  h += section_objects(ev, run);
  h += section_calib(calib);
  h += section_figures(figures, figures_dir);
  if (run) run_sections(*run, h);
  h += section_table("eval-options", "Evaluation options", ev.options, false);
  std::vector<std::string> warnings;
  for (const std::string& w : ev.warnings) warnings.push_back("eval: " + w);
  if (run)
    for (const std::string& w : run->warnings) warnings.push_back("run: " + w);
  h += "<section id=\"warnings\"><h2>Warnings</h2>\n";
  if (warnings.empty()) h += "<p class=\"na\">none</p>\n";
  for (const std::string& w : warnings) h += "<p>" + esc(w) + "</p>\n";
  h += "</section>\n";
  // The evaluation report itself, for scripts (a data block: browsers do not execute it). <, > and & only
  // occur inside JSON strings, where \u003c, \u003e and \u0026 mean the same: no label can close the block
  // (`</script>`) or open a comment (`<!--`) that swallows the closing tag, and JSON.parse reads it back.
  std::string data;
  for (const char c : io::dump_json(store::to_json(ev))) {
    if (c == '<')
      data += "\\u003c";
    else if (c == '>')
      data += "\\u003e";
    else if (c == '&')
      data += "\\u0026";
    else
      data += c;
  }
  h += "<script type=\"application/json\" id=\"roe-eval-report\">" + data + "</script>\n";
  h += "</body></html>\n";
  return h;
}

}  // namespace roe::app
