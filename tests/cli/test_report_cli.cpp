// roe report: the HTML opened in a real browser (headless Chromium): loads without errors, every figure
// present and not blank, the tables hold report.json's numbers. Skips (with the reason) when chromium,
// or python3 with matplotlib, is absent.
#include <catch2/catch.hpp>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "support/test_util.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using roe::test::run_roe;
using roe::test::TempDir;

/// Runs a shell command, returns (exit code, stdout+stderr).
std::pair<int, std::string> sh(const std::string& cmd) {
  const auto r = roe::test::run_shell(cmd);
  return {r.code, r.out};
}

std::string chromium() {
  for (const char* name : {"chromium", "chromium-browser"}) {
    auto [rc, out] = sh(std::string("command -v ") + name);
    if (rc == 0) return out.substr(0, out.find('\n'));
  }
  return "";
}

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

const json& at_path(const json& j, const std::string& path) {
  const json* cur = &j;
  std::size_t start = 0;
  while (start <= path.size()) {
    const std::size_t end = std::min(path.find('.', start), path.size());
    cur = &cur->at(path.substr(start, end - start));
    start = end + 1;
  }
  return *cur;
}

// Injected into a copy of the report: records errors from the start, and on load checks every image
// (decoded size, pixel variance on a canvas) and collects every numeric cell, into <pre id=roe-check>.
const char* kProbe = R"js(<script>
window.__errors = [];
window.addEventListener('error', e => window.__errors.push(String(e.message || (e.target && (e.target.src || e.target.href)) || 'error')), true);
window.addEventListener('load', () => {
  const imgs = [...document.querySelectorAll('figure img')].map(img => {
    const c = document.createElement('canvas');
    c.width = img.naturalWidth; c.height = img.naturalHeight;
    let variance = -1, err = '';
    try {
      const g = c.getContext('2d'); g.drawImage(img, 0, 0);
      const d = g.getImageData(0, 0, c.width, c.height).data;
      let s = 0, s2 = 0, n = 0;
      for (let i = 0; i < d.length; i += 4 * 97) { const v = d[i] + d[i + 1] + d[i + 2]; s += v; s2 += v * v; n++; }
      variance = s2 / n - (s / n) * (s / n);
    } catch (x) { err = String(x); }
    return {id: img.closest('figure').id, w: img.naturalWidth, h: img.naturalHeight, variance, err,
            external: !img.src.startsWith('data:image/png;base64,')};
  });
  const cells = [...document.querySelectorAll('td[data-path]')].map(td =>
      ({path: td.dataset.path, value: td.dataset.value, text: td.textContent}));
  const links = [...document.querySelectorAll('[src],[href]')].map(e => e.getAttribute('src') || e.getAttribute('href'))
      .filter(u => /^(https?:)?\/\//.test(u));
  const caps = [...document.querySelectorAll('figcaption')];
  const parts = {
    captions: caps.length,
    captions_with_tex: caps.filter(c => /[$\\]|_\{|\^\{/.test(c.textContent)).map(c => c.textContent.slice(0, 80)),
    sub_rendered: [...document.querySelectorAll('figcaption sub')].filter(e => {
      const r = e.getBoundingClientRect(), p = e.parentElement.getBoundingClientRect();
      return r.height > 0 && r.bottom > p.top && getComputedStyle(e).verticalAlign === 'sub'; }).length,
    accepted_rows: [...document.querySelectorAll('#counts tr.subset-accepted')].map(tr => tr.dataset.object),
    all_rows: [...document.querySelectorAll('#counts tr.subset-all')].map(tr => tr.dataset.object),
    total_row: document.querySelectorAll('#counts tr.total').length,
    rpe_rows: document.querySelectorAll('#rpe tr').length,
  };
  const pre = document.createElement('pre'); pre.id = 'roe-check';
  pre.textContent = btoa(unescape(encodeURIComponent(JSON.stringify({errors: window.__errors, imgs, cells, links, parts}))));
  document.body.appendChild(pre);
});
</script>)js";

}  // namespace

TEST_CASE("roe report: the HTML in headless Chromium", "[cli][report][browser]") {
  const std::string browser = chromium();
  if (browser.empty()) {
    WARN("skipped: chromium is not installed (Debian: apt install chromium; scripts/install-deps.sh does)");
    return;
  }
  TempDir t("roe_report");
  const std::string sample = std::string(ROE_SOURCE_DIR) + "/datasets/sample";
  REQUIRE(run_roe("-q run " + sample + " --out " + (t / "run").string()).code == 0);
  const auto rep = run_roe("--json report " + (t / "run").string() + " --out " + (t / "r.html").string() +
                               " --objects all --vector none --rpe-delta 1,2",
                           false);
  if (rep.code == 2 && !fs::exists(t / "r.html")) {
    const auto again = run_roe("report " + (t / "run").string() + " --out " + (t / "r.html").string());
    if (again.out.find("cannot draw the figures") != std::string::npos) {
      WARN("skipped: " << again.out);
      return;
    }
  }
  REQUIRE(rep.code == 0);
  const json summary = json::parse(rep.out);
  const std::string html = slurp(t / "r.html");
  REQUIRE(summary["bytes"].get<std::size_t>() == html.size());
  // The numbers to find: an independent `roe eval` of the same run (deterministic).
  REQUIRE(run_roe("-q eval " + (t / "run").string() + " --gt " + sample + " --out " + (t / "eval").string()).code == 0);
  const json report = json::parse(slurp(t / "eval/report.json"));

  std::string probed = html;
  probed.insert(probed.find("<head>") + 6, kProbe);
  std::ofstream(t / "probe.html", std::ios::binary) << probed;
  const std::string flags = " --headless --no-sandbox --disable-gpu --no-first-run --disable-extensions "
                            "--user-data-dir=" + (t / "profile").string() + " --virtual-time-budget=20000 ";
  auto [rc, dom] = sh(browser + flags + "--enable-logging=stderr --v=0 --dump-dom file://" + (t / "probe.html").string());
  INFO(dom.substr(0, 2000));
  REQUIRE(rc == 0);
  // Console errors (JavaScript or resources) would be logged as CONSOLE lines.
  CHECK(dom.find(":CONSOLE(") == std::string::npos);
  const std::size_t a = dom.find("<pre id=\"roe-check\">");
  REQUIRE(a != std::string::npos);
  const std::size_t b = dom.find("</pre>", a);
  const std::string b64 = dom.substr(a + 20, b - a - 20);
  std::ofstream(t / "probe.b64") << b64;
  auto [drc, decoded] = sh("base64 -d " + (t / "probe.b64").string());
  REQUIRE(drc == 0);
  const json probe = json::parse(decoded);
  CHECK(probe["errors"].empty());
  CHECK(probe["links"].empty());  // self-contained: nothing fetched from a network

  // Every figure of the summary is in the page, decoded, and not blank.
  const json& figs = summary["figures"];
  REQUIRE(figs.size() >= 6);  // fig3, fig4 per non-anchor object, extrinsics, consistency, trajectory, errors
  std::set<std::string> seen;
  for (const json& img : probe["imgs"]) {
    INFO(img.dump());
    seen.insert(img["id"].get<std::string>());
    CHECK_FALSE(img["external"].get<bool>());
    CHECK(img["w"].get<int>() >= 600);
    CHECK(img["h"].get<int>() >= 400);
    CHECK(img["err"].get<std::string>().empty());
    CHECK(img["variance"].get<double>() > 100.0);  // a blank (one-colour) image has 0
  }
  for (const json& f : figs) CHECK(seen.count("fig-" + f.get<std::string>()) == 1);
  for (const char* f : {"fig3", "extrinsics", "consistency", "trajectory", "errors"})
    CHECK(std::find(figs.begin(), figs.end(), f) != figs.end());

  // The tables hold report.json's numbers: exactly in data-value, rounded in the text.
  std::set<std::string> paths;
  for (const json& c : probe["cells"]) {
    const std::string path = c["path"].get<std::string>();
    INFO(path << " = " << c["value"] << " shown " << c["text"]);
    paths.insert(path);
    const double want = at_path(report, path).get<double>();
    CHECK(std::stod(c["value"].get<std::string>()) == Approx(want).epsilon(1e-12));
    const std::string text = c["text"].get<std::string>();
    const std::size_t dot = text.find('.');
    const int decimals = dot == std::string::npos ? 0 : static_cast<int>(text.size() - dot - 1);
    CHECK(std::abs(std::stod(text) - want) <= 0.5 * std::pow(10.0, -decimals) + 1e-12);
  }
  for (const char* p : {"per_axis.pos_rmse_m.x", "per_axis.pos_rmse_m.y", "per_axis.pos_rmse_m.z",
                        "per_axis.rpy_rmse_deg.roll", "per_axis.rpy_rmse_deg.pitch", "per_axis.rpy_rmse_deg.yaw",
                        "ape_trans_m.rmse", "ape_trans_m.max", "ape_rot_deg.rmse", "consistency.aligned.anees_p"})
    CHECK(paths.count(p) == 1);

  // The new parts: captions without TeX and with rendered subscripts, the objects table's "accepted" row
  // under each object's "all" row (as roe eval prints them) and the totals, the RPE table and figure.
  const json& parts = probe["parts"];
  INFO(parts.dump());
  CHECK(parts["captions"].get<int>() == static_cast<int>(figs.size()));
  CHECK(parts["captions_with_tex"].empty());
  CHECK(parts["sub_rendered"].get<int>() >= 3);
  CHECK(parts["accepted_rows"].size() >= 2);
  CHECK(parts["accepted_rows"] == parts["all_rows"]);
  CHECK(parts["total_row"] == 1);
  CHECK(parts["rpe_rows"].get<int>() == 3);  // header + two deltas
  CHECK(std::find(figs.begin(), figs.end(), "rpe") != figs.end());

  // A screenshot of the page renders (a blank page compresses to a few kB).
  auto [src, sout] = sh(browser + flags + "--window-size=1200,2400 --screenshot=" + (t / "shot.png").string() +
                        " file://" + (t / "r.html").string());
  INFO(sout);
  REQUIRE(src == 0);
  REQUIRE(fs::exists(t / "shot.png"));
  CHECK(fs::file_size(t / "shot.png") > 60000);
}

TEST_CASE("roe report: usage and output errors", "[cli][report]") {
  TempDir t("roe_report_err");
  std::ofstream(t / "exists.html") << "x";
  const std::string sample = std::string(ROE_SOURCE_DIR) + "/datasets/sample";
  SECTION("an existing report is not replaced without --force") {
    fs::create_directories(t / "run");
    std::ofstream(t / "run/trajectory.csv") << "t,tx,ty,tz,qx,qy,qz,qw\n";
    const auto r = run_roe("report " + (t / "run").string() + " --gt " + sample + " --out " + (t / "exists.html").string());
    CHECK(r.code == 2);
    CHECK(r.out.find("already exists") != std::string::npos);
    CHECK(slurp(t / "exists.html") == "x");
  }
  SECTION("bad figure options are usage errors before any work") {
    const auto r = run_roe("report " + t.path.string() + " --out " + (t / "r.html").string() + " --plot-mode ab");
    CHECK(r.code == 2);
    const auto r2 = run_roe("report " + t.path.string() + " --out " + (t / "r.html").string() + " --objects 1,x");
    CHECK(r2.code == 2);
    CHECK(r2.out.find("--objects") != std::string::npos);
    const auto r3 = run_roe("report " + t.path.string() + " --out " + (t / "r.html").string() + " --style poster");
    CHECK(r3.code == 2);
    const auto r4 = run_roe("report " + t.path.string() + " --out " + (t / "r.html").string() + " --rpe-unit s");
    CHECK(r4.code == 2);
    CHECK(r4.out.find("--rpe-delta") != std::string::npos);
    CHECK_FALSE(fs::exists(t / "r.html"));
  }
  SECTION("the folder of --out must exist") {
    const auto r = run_roe("report " + t.path.string() + " --out " + (t / "no/r.html").string());
    CHECK(r.code == 2);
    CHECK_FALSE(fs::exists(t / "no"));
  }
}

// Ctrl-C (SIGINT) or SIGTERM while the figures are drawn: roe dies of the signal, kills the plotting
// process, and leaves no temporary and no output (the interpreter here is a stand-in that sleeps).
TEST_CASE("roe eval --plot and roe report: a signal during plotting kills the plotter, leaves nothing",
          "[cli][report][signals]") {
  TempDir t("roe_report_sig");
  const std::string sample = std::string(ROE_SOURCE_DIR) + "/datasets/sample";
  REQUIRE(run_roe("-q run " + sample + " --out " + (t / "run").string()).code == 0);
  const fs::path fake = t.write("bin/slowpython", "#!/bin/sh\necho $$ > " + (t / "child.pid").string() +
                                                      "\nexec sleep 60\n");
  fs::permissions(fake, fs::perms::owner_all);
  const auto interrupt = [&](const std::string& args, const char* sig) {
    fs::remove(t / "child.pid");
    // set -m: the background job keeps SIGINT (a non-interactive shell would make it ignore SIGINT).
    const std::string script = "set -m; ROE_PYTHON=" + fake.string() + " " + ROE_BINARY + " " + args +
                               " >/dev/null 2>&1 & pid=$!; for i in $(seq 200); do [ -s " +
                               (t / "child.pid").string() + " ] && break; sleep 0.05; done; kill -" + sig +
                               " $pid; wait $pid; echo rc=$?";
    auto [rc, out] = sh("bash -c '" + script + "'");
    INFO(args << " " << sig << ": " << out);
    REQUIRE(fs::exists(t / "child.pid"));
    CHECK(out.find(std::string("rc=") + (std::string(sig) == "INT" ? "130" : "143")) != std::string::npos);
    const std::string child = slurp(t / "child.pid");
    auto [alive, o2] = sh("kill -0 " + child.substr(0, child.find('\n')));
    CHECK(alive != 0);  // the plotting process is gone
    for (const fs::path& dir : {t.path, t / "run"})
      for (const auto& e : fs::directory_iterator(dir)) {
        INFO(e.path());
        CHECK(e.path().filename().string().find(".tmp") == std::string::npos);
        CHECK(e.path().filename().string().find(".work") == std::string::npos);
      }
  };
  interrupt("eval " + (t / "run").string() + " --gt " + sample + " --plot", "INT");
  CHECK_FALSE(fs::exists(t / "run/eval"));
  interrupt("report " + (t / "run").string() + " --out " + (t / "r.html").string(), "INT");
  interrupt("report " + (t / "run").string() + " --out " + (t / "r.html").string() + " --figures " +
                (t / "figs").string(),
            "TERM");
  CHECK_FALSE(fs::exists(t / "r.html"));
  CHECK_FALSE(fs::exists(t / "figs"));
}

// The plotting process starts before eval (its imports overlap eval); when eval then refuses its input,
// the process is told to stop: roe exits 2 with the eval error, the interpreter is gone and nothing is
// left beside the report (the stand-in interpreter records its pid and runs the real python3).
TEST_CASE("roe report: an eval error stops the plotting process started ahead of it", "[cli][report]") {
  if (sh("/usr/bin/python3 -c 'import matplotlib, numpy' 2>/dev/null").first != 0) {
    WARN("skipped: /usr/bin/python3 with matplotlib and numpy is needed");
    return;
  }
  TempDir t("roe_report_early");
  const std::string sample = std::string(ROE_SOURCE_DIR) + "/datasets/sample";
  REQUIRE(run_roe("-q run " + sample + " --out " + (t / "run").string()).code == 0);
  const fs::path wrapper = t.write("bin/python", "#!/bin/sh\necho $$ > " + (t / "child.pid").string() +
                                                     "\nexec /usr/bin/python3 \"$@\"\n");
  fs::permissions(wrapper, fs::perms::owner_all);
  auto [rc, out] = sh("ROE_PYTHON=" + wrapper.string() + " " + ROE_BINARY + " report " + (t / "run").string() +
                      " --out " + (t / "r.html").string() + " --align bogus 2>&1");
  INFO(out);
  CHECK(rc == 2);
  CHECK(out.find("unknown alignment 'bogus'") != std::string::npos);
  REQUIRE(fs::exists(t / "child.pid"));  // it was started, before eval
  const std::string child = slurp(t / "child.pid");
  CHECK(sh("kill -0 " + child.substr(0, child.find('\n')) + " 2>/dev/null").first != 0);
  for (const auto& e : fs::directory_iterator(t.path)) {
    INFO(e.path());
    CHECK((e.path().filename() == "run" || e.path().filename() == "bin" || e.path().filename() == "child.pid"));
  }
}
