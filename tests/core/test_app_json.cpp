// No app or cli file parses JSON itself (issue 52 item 6): roe's own files are read through their typed readers
// in store (run.json, report.json, roe.json, meta.json, the sweep's files) and handed on typed, never parsed
// again or read back by key. Checked on the sources of src/app, src/cli and include/roe/app, as
// tests/core/test_layering.cpp checks the includes: every call that turns JSON text into a value (io's parsers
// and strict readers, nlohmann's parse), and every read by key of a store writer's JSON (`store::X_to_json(v)`
// subscripted, or kept in a variable that is subscripted), is a finding, apart from the readers named in
// kAllowed below with the reason each may parse. The probes add a parse to a scratch copy of a file and see the
// check fail.
#include <algorithm>
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "support/test_util.hpp"

namespace fs = std::filesystem;

namespace {

using roe::test::read_text;

/// The app and cli files that may parse JSON, and why: the readers of files a user writes (configs, specs,
/// presets) and the figures manifest.
const std::map<std::string, std::string>& allowed() {
  static const std::map<std::string, std::string> a = {
      {"src/app/run_config.cpp", "the run config reader (--config FILE, configs/*.json)"},
      {"src/app/shipped_configs.cpp", "the shipped run configs (configs/*.json compiled into roe)"},
      {"src/app/simulate.cpp", "the simulator's config reader (--config FILE and the shipped presets)"},
      {"src/app/sweep_plan.cpp",
       "the sweep spec reader (the spec, the config files it names, its eval block, which each job of jobs.jsonl "
       "carries with every default filled in)"},
      {"src/app/import_poet.cpp", "--class-map FILE, a user's {\"<PoET class>\": object id} map"},
      {"src/app/figures.cpp", "the figures manifest (figures.json, written by scripts/plot_run.py)"},
  };
  return a;
}

/// Reads of a store writer's JSON that wait for the store to write the block on its own (a per-block writer in
/// src/store/run_record.cpp, issue 52 item 1's room): each must still be found here, so that the entry goes
/// when the read does.
const std::map<std::string, std::string>& pending() {
  static const std::map<std::string, std::string> p = {
      {"src/app/run.cpp", "RunResult::to_json picks counts, nis, timing_s and health out of run.json's JSON"},
      {"src/app/refine.cpp", "RefineCommandResult::to_json picks the refine block out of run.json's JSON"},
  };
  return p;
}

/// `text` without its comments (// to the end of the line, /* */) and with its string and character literals
/// emptied (their quotes kept), line breaks kept: what is left is code.
std::string code_of(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  const auto blank = [&](std::size_t from, std::size_t to) {  // keeps the line breaks of [from, to)
    for (std::size_t k = from; k < to && k < text.size(); ++k)
      if (text[k] == '\n') out += '\n';
  };
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == 'R' && text.compare(i, 2, "R\"") == 0) {  // a raw string: up to its )delim"
      const std::size_t open = text.find('(', i);
      const std::string close = ")" + text.substr(i + 2, open - i - 2) + "\"";
      const std::size_t end = text.find(close, open);
      const std::size_t stop = end == std::string::npos ? text.size() : end + close.size();
      out += "R\"\"";
      blank(i, stop);
      i = stop - 1;
    } else if (c == '"' || c == '\'') {
      std::size_t k = i + 1;
      while (k < text.size() && text[k] != c && text[k] != '\n') k += text[k] == '\\' ? 2 : 1;
      out += c;
      out += c;
      i = std::min(k, text.size() - 1);
    } else if (c == '/' && i + 1 < text.size() && text[i + 1] == '/') {
      while (i < text.size() && text[i] != '\n') ++i;
      if (i < text.size()) out += '\n';
    } else if (c == '/' && i + 1 < text.size() && text[i + 1] == '*') {
      const std::size_t end = text.find("*/", i + 2);
      const std::size_t stop = end == std::string::npos ? text.size() : end + 2;
      blank(i, stop);
      i = stop - 1;
    } else {
      out += c;
    }
  }
  return out;
}

std::size_t line_at(const std::string& text, std::size_t pos) {
  return 1 + static_cast<std::size_t>(std::count(text.begin(), text.begin() + static_cast<long>(pos), '\n'));
}

/// Every place of `text` (the file `path`) that parses JSON or reads a store writer's JSON by key, as
/// "PATH:LINE: what".
std::vector<std::string> json_reads(const std::string& path, const std::string& text) {
  static const std::regex parse(
      R"(\b(parse_json_file|parse_json_text|read_json_file|with_json_locations|json_key_location)\s*\(|)"
      R"(\bjson::(parse|accept|from_cbor|from_msgpack|from_bson|from_ubjson)\s*\(|\bJsonObject\b)");
  // A store writer's JSON subscripted where it is made, or kept in a variable.
  static const std::regex read_back(
      R"(\bstore::\w*to_json\s*\(([^()]|\([^()]*\))*\)\s*(\.at\s*\(|\[|\.value\s*\(|\.contains\s*\())");
  static const std::regex kept(R"(\b(\w+)\s*=\s*store::\w*to_json\s*\()");
  const std::string code = code_of(text);
  std::vector<std::string> found;
  const auto add = [&](std::size_t pos, const std::string& what) {
    found.push_back(path + ":" + std::to_string(line_at(code, pos)) + ": " + what);
  };
  for (auto it = std::sregex_iterator(code.begin(), code.end(), parse); it != std::sregex_iterator(); ++it)
    add(static_cast<std::size_t>(it->position()), "parses JSON (" + it->str() + ")");
  for (auto it = std::sregex_iterator(code.begin(), code.end(), read_back); it != std::sregex_iterator(); ++it)
    add(static_cast<std::size_t>(it->position()), "reads a store writer's JSON back by key");
  for (auto it = std::sregex_iterator(code.begin(), code.end(), kept); it != std::sregex_iterator(); ++it) {
    const std::regex use("\\b" + (*it)[1].str() + R"(\s*(\.at\s*\(|\[|\.value\s*\(|\.contains\s*\())");
    std::smatch m;
    const std::string rest = code.substr(static_cast<std::size_t>(it->position()));
    if (std::regex_search(rest, m, use))
      add(static_cast<std::size_t>(it->position() + m.position()),
          "reads a store writer's JSON back by key (" + (*it)[1].str() + ")");
  }
  return found;
}

/// The files the rule covers: src/app, src/cli, include/roe/app, relative to the source root, with their text.
std::map<std::string, std::string> app_files(const fs::path& root) {
  std::map<std::string, std::string> files;
  for (const char* dir : {"src/app", "src/cli", "include/roe/app"})
    for (const auto& e : fs::recursive_directory_iterator(root / dir))
      if (e.is_regular_file() && (e.path().extension() == ".cpp" || e.path().extension() == ".hpp"))
        files[fs::relative(e.path(), root).generic_string()] = read_text(e.path());
  return files;
}

/// The findings in files that are neither allowed nor pending.
std::vector<std::string> check(const std::map<std::string, std::string>& files) {
  std::vector<std::string> bad;
  for (const auto& [path, text] : files) {
    if (allowed().count(path) || pending().count(path)) continue;
    for (const std::string& f : json_reads(path, text)) bad.push_back(f);
  }
  return bad;
}

const std::map<std::string, std::string>& real_files() {
  static const std::map<std::string, std::string> files = app_files(ROE_SOURCE_DIR);
  return files;
}

}  // namespace

TEST_CASE("app and cli: no file parses JSON or reads a store writer's JSON back, but the named readers",
          "[layering][json]") {
  const auto& files = real_files();
  REQUIRE(files.size() > 40);  // the scan found the checkout (src/app, src/cli, include/roe/app)
  REQUIRE(files.count("src/app/sweep_run.cpp"));
  const auto bad = check(files);
  for (const auto& s : bad) UNSCOPED_INFO(s);
  CHECK(bad.empty());
  // Each exception is still needed (a reader that moved or went takes its entry with it).
  for (const auto& table : {allowed(), pending()})
    for (const auto& [path, why] : table) {
      INFO(path << ": " << why);
      REQUIRE(files.count(path));
      CHECK_FALSE(json_reads(path, files.at(path)).empty());
    }
}

TEST_CASE("app and cli JSON rule: a parse or a read-back added to a scratch copy of a file is found",
          "[layering][json]") {
  // The probes, each added to the end of a copy of a file that reads roe's files through their typed readers.
  // The probes, each added to the end of a copy of a file that reads roe's files through their typed readers;
  // the finding is on the probe's line `at` (0: its first).
  struct Probe {
    std::string path, code;
    std::size_t at = 0;
  };
  const std::vector<Probe> probes = {
      {"src/app/sweep_run.cpp", "void probe() { const json r = io::parse_json_file(f); }"},
      {"src/app/sweep_aggregate.cpp", "void probe() { auto j = nlohmann::json::parse(text); }"},
      {"src/app/report.cpp", "void probe() { json j = json::parse(s); }"},
      {"src/app/calib_check.cpp", "void probe() { io::JsonObject r(j, \"run.json\"); }"},
      {"src/app/sweep_emit.cpp", "void probe() { return io::read_json_file(p, from_json); }"},
      {"src/app/report_html.cpp", "void probe() { const double s = store::run_record_to_json(*run).at(\"anchor_id\"); }"},
      {"src/cli/cmd_report.cpp", "void probe() {\n  const json d = store::to_json(r.eval);\n  emit(d[\"label\"]);\n}", 2},
      {"src/cli/cmd_sweep.cpp", "void probe() { auto x = io::parse_json_text(t, \"jobs.jsonl\"); }"},
  };
  for (const Probe& p : probes) {
    INFO(p.path << " + " << p.code);
    auto copy = real_files();
    REQUIRE(copy.count(p.path));
    REQUIRE(copy[p.path].back() == '\n');
    const std::size_t first = line_at(copy[p.path], copy[p.path].size()) + 1;  // after an empty line
    copy[p.path] += "\n" + p.code + "\n";
    const auto bad = check(copy);
    for (const auto& s : bad) UNSCOPED_INFO(s);
    REQUIRE(bad.size() == 1);
    CHECK(bad[0].rfind(p.path + ":" + std::to_string(first + p.at) + ": ", 0) == 0);
  }
  // Comments and strings that name a parser are not calls.
  CHECK(json_reads("x.cpp", "// io::parse_json_file(f) is store's job\nconst char* s = \"json::parse(\";\n").empty());
  CHECK(json_reads("x.cpp", "/* JsonObject */ int x;").empty());
  // A store writer's JSON that is only written out is no read.
  CHECK(json_reads("x.cpp", "out = {{\"per_axis\", store::to_json(ev.per_axis)}};").empty());
}
