// The figures of `roe eval --plot` and `roe report` (scripts/plot_run.py): figures.json says what each
// figure drew and what it was asked for and did not draw; no TeX in titles and captions; a symmetric
// object's Fig. 4 sits on the truth without jumps; the extrinsics are the causal filter's; the paper
// style; the decimated lines stay within a pixel of the full ones. Skips when python3 with matplotlib is
// absent.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "roe/app/report.hpp"
#include "support/test_util.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using roe::test::run_roe;
using roe::test::run_shell;
using roe::test::TempDir;

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

bool have_matplotlib() {
  return run_shell("/usr/bin/python3 -c 'import matplotlib, numpy' 2>/dev/null").code == 0;
}

const json* figure(const json& manifest, const std::string& name) {
  for (const json& f : manifest["figures"])
    if (f["name"] == name) return &f;
  return nullptr;
}

bool has_layer(const json& f, const std::string& layer) {
  for (const json& l : f["layers"])
    if (l == layer) return true;
  return false;
}

/// The detections of a run's reprojection.csv that the filter used in part only (status accepted or
/// initialized, `used` position or rotation) with a reprojected pose and a positive NIS: those the NIS
/// panel draws apart (read here with a plain split, independently of plot_run.py).
int part_used_detections(const fs::path& reprojection_csv) {
  std::ifstream f(reprojection_csv);
  std::string line;
  std::getline(f, line);
  std::vector<std::string> head;
  for (std::stringstream ss(line); std::getline(ss, line, ',');) head.push_back(line);
  const auto col = [&](const std::string& name) {
    const auto it = std::find(head.begin(), head.end(), name);
    REQUIRE(it != head.end());
    return static_cast<std::size_t>(it - head.begin());
  };
  const std::size_t status = col("status"), used = col("used"), nis = col("nis"), tx = col("tx"), qw = col("qw");
  int n = 0;
  while (std::getline(f, line)) {
    std::vector<std::string> v;
    for (std::stringstream ss(line); std::getline(ss, line, ',');) v.push_back(line);
    REQUIRE(v.size() == head.size());
    bool pose = true;
    for (std::size_t k = tx; k <= qw; ++k) pose = pose && std::isfinite(std::stod(v[k]));
    const double e = std::stod(v[nis]);
    n += (v[status] == "accepted" || v[status] == "initialized") && (v[used] == "position" || v[used] == "rotation") &&
         pose && std::isfinite(e) && e > 0;
  }
  return n;
}

/// The width of a PNG file in pixels (IHDR).
std::uint32_t png_width(const fs::path& p) {
  const std::string b = slurp(p);
  REQUIRE(b.size() > 24);
  return (std::uint32_t(static_cast<unsigned char>(b[16])) << 24) | (std::uint32_t(static_cast<unsigned char>(b[17])) << 16) |
         (std::uint32_t(static_cast<unsigned char>(b[18])) << 8) | std::uint32_t(static_cast<unsigned char>(b[19]));
}

const std::string kSample = std::string(ROE_SOURCE_DIR) + "/datasets/sample";

/// One run of the sample dataset shared by the test cases of this file (the default configuration:
/// smoother on).
const fs::path& sample_run() {
  static TempDir dir("roe_figures_run");
  static const bool done = run_roe("-q run " + kSample + " --out " + (dir / "run").string()).code == 0;
  REQUIRE(done);
  return dir.path;
}

}  // namespace

TEST_CASE("figures: --plot-mode xyz honours the options and figures.json lists layers drawn and skipped",
          "[cli][report][figures]") {
  if (!have_matplotlib()) {
    WARN("skipped: /usr/bin/python3 without matplotlib/numpy");
    return;
  }
  TempDir t("roe_figures_xyz");
  const fs::path run = sample_run() / "run";
  for (const std::string mode : {"xyz", "xz"}) {
    const fs::path out = t / ("eval-" + mode);
    const auto r = run_roe("-q eval " + run.string() + " --gt " + kSample + " --out " + out.string() +
                           " --plot --plot-mode " + mode + " --color-by-error --objects all --vector none");
    INFO(r.out);
    REQUIRE(r.code == 0);
    const json m = json::parse(slurp(out / "plots/figures.json"));
    CHECK(m["plot_mode"] == mode);
    CHECK(m["color_by_error"] == true);
    const json* tr = figure(m, "trajectory");
    REQUIRE(tr != nullptr);
    INFO(tr->dump());
    CHECK(has_layer(*tr, "estimate coloured by the position error"));
    CHECK(has_layer(*tr, "start"));
    CHECK(has_layer(*tr, "ground truth"));
    for (const json& id : m["chosen_objects"])
      CHECK(has_layer(*tr, "reprojected detections of object " + std::to_string(id.get<int>())));
    CHECK(m["chosen_objects"].size() >= 2);
    CHECK((*tr)["skipped_layers"].empty());
    CHECK((*tr)["caption"].get<std::string>().find("coloured by the position error") != std::string::npos);
    // Every figure lists what it drew.
    for (const json& f : m["figures"]) CHECK_FALSE(f["layers"].empty());
  }
}

TEST_CASE("figures: titles and captions carry no TeX and the report renders sub- and superscripts",
          "[cli][report][figures]") {
  if (!have_matplotlib()) {
    WARN("skipped: /usr/bin/python3 without matplotlib/numpy");
    return;
  }
  TempDir t("roe_figures_tex");
  const fs::path run = sample_run() / "run";
  const auto r = run_roe("-q report " + run.string() + " --out " + (t / "r.html").string() + " --figures " +
                         (t / "figs").string() + " --vector none --rpe-delta 1");
  INFO(r.out);
  REQUIRE(r.code == 0);
  const json m = json::parse(slurp(t / "figs/figures.json"));
  REQUIRE(m["figures"].size() >= 6);
  for (const json& f : m["figures"]) {
    INFO(f["name"]);
    CHECK(f["title"].get<std::string>().find('$') == std::string::npos);
    CHECK(f["caption"].get<std::string>().find('$') == std::string::npos);
    CHECK(f["caption"].get<std::string>().find('\\') == std::string::npos);
  }
  const std::string html = slurp(t / "r.html");
  std::size_t n_sub = 0;
  for (std::size_t p = 0; (p = html.find("<figcaption>", p)) != std::string::npos; ++p) {
    const std::string cap = html.substr(p, html.find("</figcaption>", p) - p);
    CHECK(cap.find('$') == std::string::npos);
    CHECK(cap.find("_{") == std::string::npos);
    n_sub += cap.find("<sub>") != std::string::npos;
  }
  CHECK(n_sub >= 3);  // T_{AO} (Fig. 4), T_{IC} (extrinsics), R_{est} (errors)
  CHECK(html.find("T<sub>IC</sub>") != std::string::npos);
  // --rpe-delta: the table and the figure.
  CHECK(html.find("id=\"rpe\"") != std::string::npos);
  CHECK(figure(m, "rpe") != nullptr);
  // Fig. 3 of a run with detections says so in its title.
  CHECK((*figure(m, "fig3"))["title"].get<std::string>().find("detections") != std::string::npos);
}

TEST_CASE("figures: caption_html turns the marks into HTML and escapes the rest", "[cli][report][figures]") {
  CHECK(roe::app::caption_html("T_{AO} = T_{AW} T_{OW}^{−1}") ==
        "T<sub>AO</sub> = T<sub>AW</sub> T<sub>OW</sub><sup>−1</sup>");
  CHECK(roe::app::caption_html("a < b & p_I_C") == "a &lt; b &amp; p_I_C");
  CHECK(roe::app::caption_html("x_{<i>}") == "x<sub>&lt;i&gt;</sub>");
  CHECK(roe::app::caption_html("open_{ mark") == "open_{ mark");
}

TEST_CASE("figures: Fig. 3 of a trajectory without detections does not mention them", "[cli][report][figures]") {
  if (!have_matplotlib()) {
    WARN("skipped: /usr/bin/python3 without matplotlib/numpy");
    return;
  }
  const fs::path data = fs::path(ROE_SOURCE_DIR) / "../shared/data/eval";
  if (!fs::exists(data / "V102.txt")) {
    WARN("skipped: ../shared/data/eval/V102.txt is absent");
    return;
  }
  TempDir t("roe_figures_v102");
  const auto r = run_roe("-q eval " + (data / "V102.txt").string() + " --gt " + (data / "V102_groundtruth.csv").string() +
                         " --out " + (t / "e").string() + " --plot --vector none");
  INFO(r.out);
  REQUIRE(r.code == 0);
  const json m = json::parse(slurp(t / "e/plots/figures.json"));
  const json* f3 = figure(m, "fig3");
  REQUIRE(f3 != nullptr);
  CHECK((*f3)["title"].get<std::string>().find("detections") == std::string::npos);
  CHECK_FALSE(has_layer(*f3, "reprojected detections of object 0"));
}

TEST_CASE("figures: the extrinsics of a default run are the causal filter's and move", "[cli][report][figures]") {
  if (!have_matplotlib()) {
    WARN("skipped: /usr/bin/python3 without matplotlib/numpy");
    return;
  }
  TempDir t("roe_figures_extr");
  const fs::path run = sample_run() / "run";
  REQUIRE(fs::exists(run / "states_filter.csv"));  // the default configuration smooths
  const auto r = run_roe("-q eval " + run.string() + " --gt " + kSample + " --out " + (t / "e").string() +
                         " --plot --vector none");
  REQUIRE(r.code == 0);
  const json m = json::parse(slurp(t / "e/plots/figures.json"));
  const json* ex = figure(m, "extrinsics");
  REQUIRE(ex != nullptr);
  INFO(ex->dump());
  CHECK((*ex)["data"]["source"] == "states_filter.csv");
  CHECK(has_layer(*ex, "smoothed (final)"));
  double moved = 0.0;
  for (const auto& [k, v] : (*ex)["data"]["span"].items()) moved = std::max(moved, v.get<double>());
  CHECK(moved > 0.1);  // mm or degrees: not a constant
}

TEST_CASE("figures: a symmetric object's Fig. 4 sits on the truth without jumps, its NIS panel marks part use",
          "[cli][report][figures]") {
  if (!have_matplotlib()) {
    WARN("skipped: /usr/bin/python3 without matplotlib/numpy");
    return;
  }
  TempDir t("roe_figures_sym");
  // paper-seq4: object 16 is symmetric (a half turn about z) and a quarter of its detections are flipped.
  for (const std::string with : {"--models-info", ""}) {
    const fs::path ds = t / (with.empty() ? "ds-plain" : "ds-sym");
    const fs::path run = t / (with.empty() ? "run-plain" : "run-sym");
    REQUIRE(run_roe("-q simulate --preset paper-seq4 --seed 3 --duration 25 " + with + " --out " + ds.string()).code == 0);
    const auto rr = run_roe("-q run " + ds.string() + " --out " + run.string());
    INFO(rr.out);
    REQUIRE((rr.code == 0 || rr.code == 1));
    const fs::path figs = t / (with.empty() ? "figs-plain" : "figs-sym");
    const auto r = run_roe("-q report " + run.string() + " --out " + (t / (with.empty() ? "p.html" : "s.html")).string() +
                           " --figures " + figs.string() + " --vector none --objects all");
    INFO(r.out);
    REQUIRE(r.code == 0);
    const json m = json::parse(slurp(figs / "figures.json"));
    const json* f4 = figure(m, "fig4_obj16");
    REQUIRE(f4 != nullptr);
    INFO(f4->dump());
    const json& d = (*f4)["data"];
    CHECK(d["max_angle_step_deg"].get<double>() <= 180.0);
    if (!with.empty()) {
      CHECK(d["symmetry"] == "nearest the truth");
      CHECK((*f4)["caption"].get<std::string>().find("symmetry-equivalent") != std::string::npos);
      for (const auto& [k, v] : d["median_truth_offset_deg"].items()) CHECK(std::abs(v.get<double>()) < 20.0);
    } else {
      // The filter does not know the symmetry: flipped detections are used for their position only, and
      // their 6-dof NIS is not the NIS of what was used: the panel draws them apart and counts them.
      const json* c = figure(m, "consistency");
      REQUIRE(c != nullptr);
      // Every one of them, matched by (timestamp, object) to the run's reprojection.csv: nanosecond stamps
      // that a float64 does not hold exactly included (most of them at 30 Hz).
      CHECK((*c)["data"]["nis_part_used"].get<int>() > 0);
      CHECK((*c)["data"]["nis_part_used"].get<int>() == part_used_detections(run / "reprojection.csv"));
      CHECK((*c)["caption"].get<std::string>().find("used in part only") != std::string::npos);
    }
  }
}

TEST_CASE("figures: --style paper has column widths, no titles, embedded fonts and rasterised scatters",
          "[cli][report][figures]") {
  if (!have_matplotlib()) {
    WARN("skipped: /usr/bin/python3 without matplotlib/numpy");
    return;
  }
  TempDir t("roe_figures_paper");
  const fs::path run = sample_run() / "run";
  const auto r = run_roe("-q eval " + run.string() + " --gt " + kSample + " --out " + (t / "e").string() +
                         " --plot --style paper --objects all");
  INFO(r.out);
  REQUIRE(r.code == 0);
  const fs::path plots = t / "e/plots";
  const json m = json::parse(slurp(plots / "figures.json"));
  CHECK(m["style"] == "paper");
  for (const json& f : m["figures"]) {
    INFO(f["name"]);
    const double w = f["size_in"][0].get<double>();
    CHECK((std::abs(w - 3.5) < 1e-3 || std::abs(w - 7.16) < 1e-3));
    CHECK(png_width(plots / f["files"]["png"].get<std::string>()) == static_cast<std::uint32_t>(std::lround(w * 300)));
    const std::string pdf = slurp(plots / f["files"]["pdf"].get<std::string>());
    CHECK(pdf.find("/FontFile2") != std::string::npos);  // TrueType embedded
    CHECK(pdf.find("/Type3") == std::string::npos);
  }
  CHECK(json::parse(slurp(plots / "figures.json"))["figures"][0]["name"] == "fig3");
  // Fig. 3's detections are an image inside the PDF, its lines vectors.
  CHECK(slurp(plots / "fig3.pdf").find("/Subtype /Image") != std::string::npos);
  // The default style is as before: screen widths.
  const auto d = run_roe("-q eval " + run.string() + " --gt " + kSample + " --out " + (t / "d").string() +
                         " --plot --vector none");
  REQUIRE(d.code == 0);
  const json md = json::parse(slurp(t / "d/plots/figures.json"));
  CHECK(md["style"] == "default");
  CHECK((*figure(md, "fig3"))["size_in"][0].get<double>() == Approx(10.0));
}

TEST_CASE("figures: a decimated line stays within one pixel of the full one", "[cli][report][figures]") {
  if (!have_matplotlib()) {
    WARN("skipped: /usr/bin/python3 without matplotlib/numpy");
    return;
  }
  TempDir t("roe_figures_decimate");
  // Draws a 60 000-point random walk with spikes in full and decimated (plot_run.decimate at the axes'
  // pixel columns) into two same-size images; every inked pixel of each must lie within one pixel of an
  // inked pixel of the other (both directions), and the decimated line must have far fewer points.
  const fs::path py = t.write("check.py", R"py(
import sys, json
sys.path.insert(0, sys.argv[1])
import numpy as np
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import plot_run as P
plt.rcParams.update(P.BASE_RC); plt.rcParams.update(P.STYLES["default"]["rc"])
rng = np.random.default_rng(5)
n = 60000
t = np.linspace(0.0, 300.0, n)
y = np.cumsum(rng.normal(size=n)) * 0.01
y[rng.integers(0, n, 40)] += rng.normal(size=40) * 3.0   # isolated spikes: single-sample extremes
def draw(idx):
    fig, ax = plt.subplots(figsize=(10, 3))
    fig.subplots_adjust(left=0.08, right=0.99, top=0.95, bottom=0.1)
    ax.set_xlim(t[0], t[-1]); ax.set_ylim(y.min() - 0.1, y.max() + 0.1); ax.axis("off")
    ax.plot(t[idx], y[idx], color="k", lw=1.0, antialiased=False)
    cols = P.pixel_columns(ax)
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[:, :, 0] < 128
    plt.close(fig)
    return img, cols
full, cols = draw(np.arange(n))
idx = P.decimate(t, [y], cols)
dec, _ = draw(idx)
def dilate(a):
    b = a.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            b |= np.roll(np.roll(a, dy, 0), dx, 1)
    return b
print(json.dumps({"n_full": int(n), "n_dec": int(len(idx)), "cols": cols, "ink": int(full.sum()),
                  "dec_outside_full": int((dec & ~dilate(full)).sum()),
                  "full_outside_dec": int((full & ~dilate(dec)).sum())}))
)py");
  const auto r = run_shell("/usr/bin/python3 " + py.string() + " " + std::string(ROE_SOURCE_DIR) + "/scripts");
  INFO(r.out);
  REQUIRE(r.code == 0);
  const json j = json::parse(r.out.substr(r.out.find('{')));
  CHECK(j["ink"].get<int>() > 1000);
  CHECK(j["n_dec"].get<int>() < j["n_full"].get<int>() / 5);
  CHECK(j["dec_outside_full"].get<int>() == 0);
  CHECK(j["full_outside_dec"].get<int>() == 0);
}

TEST_CASE("figures: sweep box plots are titled by what they show and give n", "[cli][report][figures]") {
  if (!have_matplotlib()) {
    WARN("skipped: /usr/bin/python3 without matplotlib/numpy");
    return;
  }
  TempDir t("roe_figures_sweep");
  std::string jobs = "job,variant,status,rmse_x_m,rmse_yaw_deg,ate_rmse_m\n";
  for (int i = 0; i < 5; ++i) jobs += "a" + std::to_string(i) + ",default,done,0.01" + std::to_string(i) + ",1.5,0.02\n";
  for (int i = 0; i < 3; ++i) jobs += "b" + std::to_string(i) + ",paper,done,0.03" + std::to_string(i) + ",2.5,0.04\n";
  jobs += "b9,paper,failed,,,\n";
  t.write("agg/jobs.csv", jobs);
  const auto r = run_shell("/usr/bin/python3 " + std::string(ROE_SOURCE_DIR) + "/scripts/plot_sweep.py " + (t / "agg").string());
  INFO(r.out);
  REQUIRE(r.code == 0);
  const json m = json::parse(slurp(t / "agg/plots/plots.json"));
  REQUIRE(m["plots"].size() == 3);
  for (const json& p : m["plots"]) {
    INFO(p.dump());
    const std::string title = p["title"].get<std::string>();
    CHECK(title.find(p["metric"].get<std::string>()) == std::string::npos);  // not the raw key
    CHECK(title.find('_') == std::string::npos);
    CHECK(title.find("n per box") != std::string::npos);  // 5 and 3 jobs: n differs, shown per box
    CHECK(p["n"]["default"] == 5);
    CHECK(p["n"]["paper"] == 3);
    CHECK(fs::exists(t / "agg/plots" / p["file"].get<std::string>()));
  }
  CHECK(m["plots"][0]["title"].get<std::string>().rfind("Position RMSE along x", 0) == 0);
}
