// A sweep folder's own files (store/sweep_files.hpp): one field list per file, walked by the writer and by
// the strict reader (store/json_fields.hpp), so each key of sweep.json, jobs.jsonl and result.json is spelled
// once, here.
#include "roe/store/sweep_files.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <set>

#include "json_fields.hpp"
#include "roe/core/error.hpp"
#include "roe/io/input.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"
#include "roe/store/eval_report.hpp"
#include "roe/version.hpp"

namespace roe::store {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using json_fields::Problem;

/// The dialect of the sweep's files: strict keys (a key no field list has is an error), null is a value.
struct SweepDialect {
  static constexpr bool kStrictKeys = true;
  static constexpr bool kNullIsAbsent = false;
  [[noreturn]] static void fail(const std::string& file, const std::string& path, Problem p,
                                const std::string& detail) {
    throw InputError(fmt::format("not a file of roe sweep: {} {}", path.empty() ? "the document" : path,
                                 json_fields::phrase(p, detail)),
                     {file, 0, 0, path});
  }
};

// ---- the field lists: one per file block, used by both walkers -------------------------------------

/// A preset's dataset or a folder's: the two forms have different keys ("path" alone for a folder).
template <class A>
void fields(A& a, SweepDataset& d) {
  bool folder = !d.path.empty();
  if constexpr (A::kReading) folder = a.peek("path") != nullptr;
  if (folder) {
    a("path", d.path);
    a.check("path", !d.path.empty(), "is empty (a dataset folder's path)");
    return;
  }
  a("preset", d.preset), a("preset_sha256", d.preset_sha256), a("duration_s", d.duration_s);
  a.omittable("seed", d.seed);
  a.check("preset", !d.preset.empty(), "is empty (a simulator preset's name)");
  a.check("seed", d.seed.has_value(), "is missing (a preset's job has its seed)");
}

template <class A>
void fields(A& a, SweepJobContent& c) {
  a("dataset", c.dataset), a("config", c.config), a("detections", c.detections), a("eval", c.eval);
  // The run config has its own mapping (store/run_config.hpp), strict on its own.
  a.custom(
      "run_config", [&] { return run_config_to_json(c.run_config); },
      [&](const json* x, const std::string& file, const std::string& path) {
        if (!x) SweepDialect::fail(file, path, Problem::kMissing, {});
        try {
          c.run_config = run_config_from_json(*x, file);
        } catch (const InputError& e) {
          const std::string& key = e.context().key;
          throw InputError(e.bare_message(), {file, 0, 0, key.empty() ? path : path + "." + key});
        }
      });
}

/// A line of jobs.jsonl: the job and its index.
struct JobLine {
  std::size_t index = 0;
  SweepJob job;
};

template <class A>
void fields(A& a, JobLine& l) {
  a("index", l.index), a("id", l.job.id), a("axes", l.job.axes), a("job", l.job.content);
}

template <class A>
void fields(A& a, SweepManifest& m) {
  a.fixed("format", kSweepFormat);
  a("roe_version", m.roe_version), a("spec_file", m.spec_file), a("spec", m.spec), a("axes", m.axes);
  a("n_jobs", m.n_jobs);
}

template <class A>
void fields(A& a, SweepJobResult& r) {
  a.fixed("format", kSweepJobFormat);
  a("id", r.id), a("axes", r.axes), a("roe_version", r.roe_version), a("status", r.status);
  a.check("status", r.status == "done" || r.status == "failed", "is not \"done\" or \"failed\"");
  a("exit_code", r.exit_code);
  // A failed job has its message, a finished one its metrics and warnings (and neither has the others).
  a.omittable("message", r.message, !r.done());
  a.omittable("metrics", r.metrics, r.done()), a.omittable("warnings", r.warnings, r.done());
  a("timing_s", r.timing_s);
  if (r.metrics)
    for (const std::string& m : headline_metric_names())
      a.check("metrics", r.metrics->count(m) > 0, "has no " + m);
}

template <class T>
json write(const T& v) {
  return json_fields::write<SweepDialect>(v);
}

template <class T>
T read(const json& j, const std::string& file) {
  T v;
  json_fields::read<SweepDialect>(j, v, file);
  return v;
}

/// A document written by another format version: refused before anything else is read.
void check_format(const json& j, const char* expected, const std::string& file, const char* what,
                  const char* advice) {
  const auto it = j.is_object() ? j.find("format") : j.end();
  const json v = j.is_object() && it != j.end() ? *it : json(nullptr);
  if (v != expected)
    throw InputError(fmt::format("{} format {} is not the one this roe {} reads (\"{}\"): {}", what,
                                 io::dump_json(v), kVersion, expected, advice),
                     {file, 0, 0, "format"});
}

}  // namespace

json sweep_job_content_json(const SweepJobContent& c) { return write(c); }

std::string sweep_job_id(const SweepJobContent& c) {
  return io::sha256_hex(io::dump_json(sweep_job_content_json(c))).substr(0, 16);
}

bool is_sweep_job_id(const std::string& id) {
  return id.size() == 16 && std::all_of(id.begin(), id.end(), [](char c) {
           return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
         });
}

std::string format_sweep_job_line(const SweepJob& job, std::size_t index) {
  return io::dump_json(write(JobLine{index, job})) + "\n";
}

namespace {

/// What a job steers on the file system, checked when the folder is read: its id names its folders (work/ID,
/// jobs/ID, locks/ID.lock, which a run replaces), its detection set one folder under detections/, its dataset
/// folder a path.
void check_job(const JobLine& l, std::size_t expected_index, std::set<std::string>& ids, const ErrorContext& at) {
  const auto bad = [&](const std::string& key, const std::string& what) {
    throw InputError(what + " (plan the sweep again instead of editing jobs.jsonl)", {at.file, at.line, 0, key});
  };
  if (l.index != expected_index) bad("index", fmt::format("job index {} out of order (expected {})", l.index, expected_index));
  if (!is_sweep_job_id(l.job.id))
    bad("id", fmt::format("job id {} is not 16 lower-case hex digits (ids are made by roe sweep plan)",
                          io::dump_json(l.job.id)));
  if (!ids.insert(l.job.id).second) bad("id", "job id " + l.job.id + " appears twice (two jobs would share one folder)");
  const SweepJobContent& c = l.job.content;
  if (!c.detections.empty() && !io::is_plain_name(c.detections))
    bad("job.detections", "not a detection set name (one folder name under detections/, no '/' or '..')");
}

}  // namespace

std::vector<SweepJob> read_sweep_jobs(const fs::path& file) {
  const std::string text = io::read_file(file), source = file.string();
  std::vector<SweepJob> jobs;
  std::set<std::string> ids;
  std::size_t line_no = 0;
  for (std::size_t start = 0; start < text.size();) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    ++line_no;
    const ErrorContext at{source, static_cast<std::int64_t>(line_no)};
    JobLine l;
    try {
      l = read<JobLine>(io::parse_json_text(text.substr(start, end - start), source), source);
    } catch (const InputError& e) {  // the key path's line is the line of the file
      const ErrorContext& x = e.context();
      throw InputError(e.bare_message() + " (plan the sweep again instead of editing jobs.jsonl)",
                       {source, at.line, x.line == 1 ? x.column : 0, x.key});
    }
    check_job(l, jobs.size(), ids, at);
    jobs.push_back(std::move(l.job));
    start = end + 1;
  }
  return jobs;
}

std::string format_sweep_manifest(const SweepManifest& m) { return io::dump_json(write(m), 2) + "\n"; }

SweepManifest read_sweep_manifest(const fs::path& file) {
  const std::string text = io::read_file(file), source = file.string();
  return io::with_json_locations(text, source, [&] {
    const json j = io::parse_json_text(text, source);
    check_format(j, kSweepFormat, source, "sweep folder",
                 "plan the sweep again into a new folder with this roe, or use the roe that made it");
    return read<SweepManifest>(j, source);
  });
}

std::string format_sweep_result(const SweepJobResult& r) { return io::dump_json(write(r), 2) + "\n"; }

SweepJobResult read_sweep_result(const fs::path& file) {
  const std::string text = io::read_file(file), source = file.string();
  return io::with_json_locations(text, source, [&] {
    const json j = io::parse_json_text(text, source);
    check_format(j, kSweepJobFormat, source, "job result", "run the job again with this roe (--retry-failed)");
    return read<SweepJobResult>(j, source);
  });
}

}  // namespace roe::store
