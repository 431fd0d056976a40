// roe sweep plan | run | status: the sweep folder, its per-job locks and the job runner (in-process
// simulate + run + eval, each job built in work/ID and renamed to jobs/ID when it ends).
#include <type_traits>
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <set>

#include "roe/core/clock.hpp"
#include "roe/app/eval.hpp"
#include "roe/app/run.hpp"
#include "roe/app/simulate.hpp"
#include "roe/app/sweep.hpp"
#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"
#include "roe/version.hpp"

namespace roe::app {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using Clock = SteadyClock;

fs::path manifest_file(const fs::path& d) { return d / "sweep.json"; }
fs::path jobs_file(const fs::path& d) { return d / "jobs.jsonl"; }
fs::path job_dir(const fs::path& d, const std::string& id) { return d / "jobs" / id; }
fs::path work_dir(const fs::path& d, const std::string& id) { return d / "work" / id; }
fs::path lock_file(const fs::path& d, const std::string& id) { return d / "locks" / (id + ".lock"); }

void make_dirs(const fs::path& p) {
  std::error_code ec;
  if (fs::is_symlink(p, ec))
    throw InputError("is a symbolic link: a sweep's own folders (jobs, work, locks) must be real folders, so that "
                     "replacing a job's files never reaches outside the sweep",
                     {p.string()});
  fs::create_directories(p, ec);
  if (ec) throw InputError("cannot create folder: " + ec.message(), {p.string()});
}

/// jobs/ID/result.json, or null when the job has not finished.
json read_result(const fs::path& sweep, const std::string& id) {
  const fs::path f = job_dir(sweep, id) / "result.json";
  if (!fs::exists(f)) return nullptr;
  return io::parse_json_file(f);
}

/// Files a finished job keeps (the rest of its run and eval folders and a simulated dataset are large
/// and reproducible from the manifest): result.json, config.json, run/run.json, run/trajectory.csv,
/// run/eval/report.json, run/eval/summary.csv.
void prune(const fs::path& work) {
  static const std::set<std::string> keep = {"result.json",        "config.json",          "run/run.json",
                                             "run/trajectory.csv", "run/eval/report.json", "run/eval/summary.csv"};
  std::vector<fs::path> remove;
  for (auto it = fs::recursive_directory_iterator(work); it != fs::recursive_directory_iterator(); ++it) {
    const std::string rel = fs::relative(it->path(), work).generic_string();
    if (it->is_directory()) {
      bool needed = false;
      for (const auto& k : keep) needed = needed || k.rfind(rel + "/", 0) == 0;
      if (!needed) {
        remove.push_back(it->path());
        it.disable_recursion_pending();
      }
    } else if (!keep.count(rel)) {
      remove.push_back(it->path());
    }
  }
  for (const auto& p : remove) fs::remove_all(p);  // path-checked: entries found inside work/ID (no symlink followed)
}

/// Simulate (a preset) + run + eval of one job in `work`; returns the metrics and fills `out`.
void execute(const SweepJob& job, const fs::path& work, json& out) {
  const json& c = job.content;
  const json& d = c["dataset"];
  json timing = json::object();
  fs::path dataset;
  auto t0 = Clock::now();
  if (d.contains("preset")) {
    const std::string preset = d["preset"];
    if (io::sha256_hex(preset_text(preset)) != d["preset_sha256"])
      throw InputError(fmt::format("simulator preset '{}' is not the one the sweep was planned with (this roe "
                                   "build ships another version): plan the sweep again into a new folder",
                                   preset));
    SimulateOptions so;
    so.preset = preset;
    so.seed = d["seed"].get<std::uint64_t>();
    if (!d["duration_s"].is_null()) so.duration_s = d["duration_s"].get<double>();
    dataset = work / "dataset";
    (void)simulate(so, dataset);
    timing["simulate"] = seconds_since(t0);
  } else {
    dataset = d["path"].get<std::string>();
  }
  io::write_file_atomic(work / "config.json", io::dump_json(c["run_config"], 2) + "\n");
  RunOptions ro;
  ro.config_file = (work / "config.json").string();
  ro.detections = c["detections"];
  t0 = Clock::now();
  const RunResult rr = run(dataset, work / "run", ro);
  timing["run"] = seconds_since(t0);
  EvalOptions eo;
  const json& e = c["eval"];
  eo.est = (work / "run").string();
  eo.gt = dataset.string();
  eo.out = (work / "run" / "eval").string();
  eo.label = job.id;
  for_each_sweep_eval_setting(eo, [&e](const char* key, auto& value) {
    if (std::string(key) != "t_offset_s") value = e.at(key).get<std::decay_t<decltype(value)>>();
  });
  read_sweep_t_offset(e.at("t_offset_s"), eo);
  t0 = Clock::now();
  const EvalResult er = run_eval(eo);
  timing["eval"] = seconds_since(t0);
  json metrics = json::object();
  for (const auto& [name, value] : store::headline_metrics(er.report)) metrics[name] = value;
  out["metrics"] = metrics;
  out["warnings"] = rr.output.warnings;
  out["timing_s"] = timing;
}

JobOutcome run_job(const SweepFolder& s, std::size_t index, bool retry_failed) {
  const SweepJob& job = s.jobs[index];
  JobOutcome o;
  o.index = index;
  o.id = job.id;
  make_dirs(s.dir / "locks");
  io::FileLock lock(lock_file(s.dir, job.id));
  if (!lock.held()) {
    o.action = "busy";
    o.message = "another process is running this job (its lock is held)";
    return o;
  }
  const json prev = read_result(s.dir, job.id);
  if (!prev.is_null() && prev.value("status", "") == "done") {
    o.action = "skipped-done";
    return o;
  }
  if (!prev.is_null() && !retry_failed) {
    o.action = "skipped-failed";
    o.exit_code = prev.value("exit_code", 0);
    o.message = prev.value("message", "");
    return o;
  }
  const fs::path work = work_dir(s.dir, job.id);
  make_dirs(s.dir / "work");
  make_dirs(s.dir / "jobs");
  fs::remove_all(work);  // path-checked: read_sweep accepts only hex ids. What a killed attempt left: redone
  make_dirs(work);
  const auto t0 = Clock::now();
  // A job's warnings (the run's, the eval's) go to its result.json; on stderr they would repeat for every
  // job. -v still shows them.
  const log::Level level = log::level();
  if (level == log::Level::kWarn) log::set_level(log::Level::kQuiet);
  struct Restore {
    log::Level l;
    ~Restore() { log::set_level(l); }
  } restore{level};
  json result = {{"format", "roe-sweep-job/1"}, {"id", job.id}, {"axes", job.axes}, {"roe_version", kVersion}};
  try {
    execute(job, work, result);
    result["status"] = "done";
    result["exit_code"] = 0;
  } catch (const InputError& e) {
    o.exit_code = 2;
    o.message = e.what();
  } catch (const DataError& e) {
    o.exit_code = 1;
    o.message = e.what();
  } catch (const std::exception& e) {
    o.exit_code = 3;
    o.message = e.what();
  }
  if (o.exit_code != 0) {
    // The job's files move from work/ID to jobs/ID: the message names them where they will be.
    for (std::size_t p = o.message.find(work.string()); p != std::string::npos; p = o.message.find(work.string(), p))
      o.message.replace(p, work.string().size(), job_dir(s.dir, job.id).string());
    result["status"] = "failed";
    result["exit_code"] = o.exit_code;
    result["message"] = o.message;
  }
  o.wall_s = seconds_since(t0);
  if (!result.contains("timing_s")) result["timing_s"] = json::object();
  result["timing_s"]["total"] = o.wall_s;
  prune(work);
  io::write_file_atomic(work / "result.json", io::dump_json(result, 2) + "\n");
  {
    io::DeferSignals defer;  // the old result out and the new one in, not cut in half
    const fs::path final_dir = job_dir(s.dir, job.id), old = work.string() + ".old";
    // path-checked: final_dir, old and work are jobs/ID and work/ID[.old] of an id read_sweep checked.
    fs::remove_all(old);
    if (fs::exists(final_dir)) fs::rename(final_dir, old);
    fs::rename(work, final_dir);
    fs::remove_all(old);  // path-checked: as above
  }
  o.action = o.exit_code == 0 ? "done" : "failed";
  return o;
}

/// What a job's content steers on the file system, checked when the folder is read: a detection set is one
/// folder name under detections/, a simulated dataset a shipped preset, a dataset path a folder (read only).
void check_job_content(const json& c, const ErrorContext& at) {
  const auto bad = [&](const std::string& key, const std::string& what) {
    throw InputError(what + " (plan the sweep again instead of editing jobs.jsonl)", {at.file, at.line, 0, key});
  };
  if (!c.is_object() || !c.contains("dataset") || !c["dataset"].is_object()) bad("job.dataset", "missing or not an object");
  if (!c.contains("detections") || !c["detections"].is_string()) bad("job.detections", "missing or not a string");
  const std::string det = c["detections"].get<std::string>();
  if (!det.empty() && !io::is_plain_name(det))
    bad("job.detections", "not a detection set name (one folder name under detections/, no '/' or '..')");
  for (const char* k : {"run_config", "eval"})
    if (!c.contains(k) || !c[k].is_object()) bad(std::string("job.") + k, "missing or not an object");
  const json& d = c["dataset"];
  if (d.contains("path") == d.contains("preset")) bad("job.dataset", "needs exactly one of path and preset");
  if (d.contains("path") && (!d["path"].is_string() || d["path"].get<std::string>().empty()))
    bad("job.dataset.path", "not a path");
  if (d.contains("preset") && !d["preset"].is_string()) bad("job.dataset.preset", "not a preset name");
}

json job_line(const SweepJob& j, std::size_t index) {
  return {{"index", index}, {"id", j.id}, {"axes", j.axes}, {"job", j.content}};
}

}  // namespace

SweepPlanResult sweep_plan(const SweepPlanOptions& o) {
  if (o.spec.empty()) throw InputError("a spec file is required: roe sweep plan SPEC --out SWEEP_DIR");
  if (o.out.empty()) throw InputError("--out SWEEP_DIR is required", {"roe sweep plan"});
  const fs::path spec_path = o.spec;
  const std::string text = io::read_file(spec_path);
  const json spec = io::parse_json_text(text, spec_path.string());
  SweepPlan plan = io::with_json_locations(text, spec_path.string(), [&] {
    return plan_sweep(spec, spec_path.parent_path(), spec_path.string(), o.max_jobs);
  });
  const fs::path out = io::without_trailing_separator(o.out);
  io::refuse_special_output(out, io::OutputKind::folder, "sweep folder");
  SweepPlanResult res;
  res.out = out;
  std::size_t n_before = 0;
  if (fs::exists(manifest_file(out))) {
    const SweepFolder old = read_sweep(out);
    std::vector<std::string> ids;
    for (const auto& j : old.jobs) ids.push_back(j.id);
    n_before = ids.size();
    const auto dropped = keep_indices(plan, ids);
    if (!dropped.empty() && !o.force)
      throw InputError(fmt::format("the spec no longer has {} of the sweep's {} jobs (first: {}): plan into a new "
                                   "folder, or use --force to drop them from the manifest (their results stay in "
                                   "jobs/ and are not aggregated)",
                                   dropped.size(), ids.size(), dropped.front()),
                       {out.string()});
    res.n_dropped = dropped.size();
  } else if (fs::exists(out) && !fs::is_empty(out)) {
    throw InputError("not a sweep folder (no sweep.json) and not empty: plan into a new folder", {out.string()});
  }
  io::refuse_overwriting_inputs(out, {spec_path}, "sweep folder");
  make_dirs(out);
  // Job by job into the temporary jobs.jsonl: a job's line is a few KB, 100 000 of them are never in memory.
  io::AtomicFile jobs(jobs_file(out));
  std::string lines;
  for (std::size_t i = 0; i < plan.size(); ++i) {
    lines += io::dump_json(job_line(plan.job(i), i)) + "\n";
    if (lines.size() >= (1u << 20) || i + 1 == plan.size()) {
      jobs.append(lines);
      lines.clear();
    }
  }
  const json manifest = {{"format", kSweepFormat},
                         {"roe_version", kVersion},
                         {"spec_file", io::provenance_path(spec_path)},
                         {"spec", spec},
                         {"axes", plan.axis_names},
                         {"n_jobs", plan.size()}};
  {
    io::DeferSignals defer;  // the job list and the manifest that counts it change together
    jobs.commit();
    io::write_file_atomic(manifest_file(out), io::dump_json(manifest, 2) + "\n");
  }
  res.n_jobs = plan.size();
  res.n_new = plan.size() - (n_before - res.n_dropped);
  res.axis_names = plan.axis_names;
  return res;
}

bool is_job_id(const std::string& id) {
  return id.size() == 16 && std::all_of(id.begin(), id.end(), [](char c) {
           return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
         });
}

json SweepPlanResult::to_json() const {
  return {{"command", "sweep plan"}, {"out", out.string()}, {"n_jobs", n_jobs},
          {"n_new", n_new},         {"n_dropped", n_dropped}, {"axes", axis_names}};
}

std::string SweepPlanResult::to_text() const {
  return fmt::format("roe sweep plan: {} jobs ({} new{}) over {} in {}\n", n_jobs, n_new,
                     n_dropped ? fmt::format(", {} dropped", n_dropped) : "", fmt::join(axis_names, " × "),
                     out.string());
}

SweepFolder read_sweep(const fs::path& dir_in) {
  SweepFolder s;
  s.dir = io::without_trailing_separator(dir_in);
  const fs::path mf = manifest_file(s.dir);
  if (!fs::is_regular_file(mf))
    throw InputError("not a sweep folder (no sweep.json; make one with roe sweep plan)", {s.dir.string()});
  s.manifest = io::parse_json_file(mf);
  const json fmt_v = s.manifest.is_object() && s.manifest.contains("format") ? s.manifest["format"] : json(nullptr);
  if (fmt_v != kSweepFormat)
    throw InputError(fmt::format("sweep folder format {} is not the one this roe {} reads (\"{}\"): plan the "
                                 "sweep again into a new folder with this roe, or use the roe that made it",
                                 io::dump_json(fmt_v), kVersion, kSweepFormat),
                     {mf.string(), 0, 0, "format"});
  try {
    s.axis_names = s.manifest.at("axes").get<std::vector<std::string>>();
    const std::string text = io::read_file(jobs_file(s.dir));
    std::size_t line_no = 0, start = 0;
    std::set<std::string> ids;
    while (start < text.size()) {
      std::size_t end = text.find('\n', start);
      if (end == std::string::npos) end = text.size();
      ++line_no;
      const json j = io::parse_json_text(text.substr(start, end - start), jobs_file(s.dir).string());
      const ErrorContext at{jobs_file(s.dir).string(), static_cast<std::int64_t>(line_no)};
      if (j.at("index").get<std::size_t>() != s.jobs.size()) throw InputError("job index out of order", at);
      // The id names the job's folders (work/ID, jobs/ID, locks/ID.lock), which a run replaces: a hand-edited
      // id must never steer that outside the sweep ("../../x", "/abs").
      const std::string id = j.at("id").get<std::string>();
      if (!is_job_id(id))
        throw InputError(fmt::format("job id {} is not 16 lower-case hex digits (ids are made by roe sweep plan; "
                                     "plan again instead of editing jobs.jsonl)",
                                     io::dump_json(j.at("id"))),
                         {at.file, at.line, 0, "id"});
      if (!ids.insert(id).second)
        throw InputError("job id " + id + " appears twice (two jobs would share one folder)", {at.file, at.line, 0, "id"});
      check_job_content(j.at("job"), at);
      s.jobs.push_back({id, j.at("axes"), j.at("job")});
      start = end + 1;
    }
    if (s.jobs.size() != s.manifest.at("n_jobs").get<std::size_t>())
      throw InputError(fmt::format("jobs.jsonl has {} jobs, sweep.json says {}", s.jobs.size(),
                                   s.manifest["n_jobs"].get<std::size_t>()),
                       {jobs_file(s.dir).string()});
  } catch (const json::exception& e) {
    throw InputError("malformed sweep folder (sweep.json or jobs.jsonl; plan the sweep again instead of editing "
                     "them): " + io::json_error_text(e),
                     {s.dir.string()});
  }
  return s;
}

const char* to_string(JobState s) {
  switch (s) {
    case JobState::kPending: return "pending";
    case JobState::kRunning: return "running";
    case JobState::kDone: return "done";
    case JobState::kFailed: return "failed";
  }
  return "?";
}

JobState job_state(const SweepFolder& s, const SweepJob& job) {
  const json r = read_result(s.dir, job.id);
  if (!r.is_null()) return r.value("status", "") == "done" ? JobState::kDone : JobState::kFailed;
  if (fs::exists(lock_file(s.dir, job.id))) {
    io::FileLock probe(lock_file(s.dir, job.id));
    if (!probe.held()) return JobState::kRunning;
  }
  return JobState::kPending;
}

SweepRunResult sweep_run(const SweepRunOptions& o) {
  if (o.index && o.shard) throw InputError("--index and --shard exclude each other", {"roe sweep run"});
  const SweepFolder s = read_sweep(o.dir);
  std::vector<std::size_t> todo;
  if (o.index) {
    if (*o.index >= s.jobs.size())
      throw InputError(fmt::format("--index {} is out of range: the sweep has {} jobs (0..{})", *o.index,
                                   s.jobs.size(), s.jobs.size() - 1),
                       {s.dir.string()});
    todo = {*o.index};
  } else if (o.shard) {
    todo = shard_indices(s.jobs.size(), o.shard->first, o.shard->second);
  } else {
    for (std::size_t i = 0; i < s.jobs.size(); ++i) todo.push_back(i);
  }
  SweepRunResult res;
  res.dir = s.dir;
  for (std::size_t i : todo) {
    res.jobs.push_back(run_job(s, i, o.retry_failed));
    const JobOutcome& j = res.jobs.back();
    if (j.action == "failed") log::warn("sweep job {} ({}) failed with exit code {}: {}", j.index, j.id, j.exit_code, j.message);
    else log::info("sweep job {} ({}): {}", j.index, j.id, j.action);
  }
  return res;
}

std::size_t SweepRunResult::failed() const {
  std::size_t n = 0;
  for (const auto& j : jobs) n += j.action == "failed";
  return n;
}

json SweepRunResult::to_json() const {
  json js = json::array();
  for (const auto& j : jobs)
    js.push_back({{"index", j.index}, {"id", j.id}, {"action", j.action}, {"exit_code", j.exit_code},
                  {"message", j.message}, {"wall_s", j.wall_s}});
  return {{"command", "sweep run"}, {"out", dir.string()}, {"jobs", js}, {"failed", failed()}};
}

std::string SweepRunResult::to_text() const {
  std::map<std::string, std::size_t> count;
  for (const auto& j : jobs) ++count[j.action];
  std::string s = fmt::format("roe sweep run: {} job(s) in {}:", jobs.size(), dir.string());
  for (const auto& [a, n] : count) s += fmt::format(" {} {}", n, a);
  return s + "\n";
}

SweepStatusResult sweep_status(const std::string& dir) {
  const SweepFolder s = read_sweep(dir);
  SweepStatusResult r;
  r.dir = s.dir;
  r.total = s.jobs.size();
  for (std::size_t i = 0; i < s.jobs.size(); ++i) {
    switch (job_state(s, s.jobs[i])) {
      case JobState::kDone: ++r.done; break;
      case JobState::kRunning: ++r.running; break;
      case JobState::kPending: ++r.pending; break;
      case JobState::kFailed:
        ++r.failed;
        r.failures.push_back({i, read_result(s.dir, s.jobs[i].id).value("message", "")});
        break;
    }
  }
  return r;
}

json SweepStatusResult::to_json() const {
  json f = json::array();
  for (const auto& [i, m] : failures) f.push_back({{"index", i}, {"message", m}});
  return {{"command", "sweep status"}, {"out", dir.string()}, {"total", total}, {"done", done},
          {"failed", failed}, {"running", running}, {"pending", pending}, {"failures", f}};
}

std::string SweepStatusResult::to_text() const {
  std::string s = fmt::format("{}: {} jobs: {} done, {} failed, {} running, {} pending\n", dir.string(), total, done,
                              failed, running, pending);
  for (const auto& [i, m] : failures) s += fmt::format("  job {} failed: {}\n", i, m);
  return s;
}

}  // namespace roe::app
