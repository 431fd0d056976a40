// roe sweep plan | run | status: the sweep folder, its per-job locks and the job runner (in-process
// simulate + run + eval, each job built in work/ID and renamed to jobs/ID when it ends).
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

/// jobs/ID/result.json, or nullopt when the job has not finished.
std::optional<store::SweepJobResult> read_result(const fs::path& sweep, const std::string& id) {
  const fs::path f = job_dir(sweep, id) / "result.json";
  if (!fs::exists(f)) return std::nullopt;
  return store::read_sweep_result(f);
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

/// Simulate (a preset) + run + eval of one job in `work`; fills the metrics, warnings and timings of `out`.
void execute(const SweepJob& job, const fs::path& work, store::SweepJobResult& out) {
  const store::SweepJobContent& c = job.content;
  const store::SweepDataset& d = c.dataset;
  std::map<std::string, double> timing;
  fs::path dataset;
  auto t0 = Clock::now();
  if (!d.preset.empty()) {
    if (io::sha256_hex(preset_text(d.preset)) != d.preset_sha256)
      throw InputError(fmt::format("simulator preset '{}' is not the one the sweep was planned with (this roe "
                                   "build ships another version): plan the sweep again into a new folder",
                                   d.preset));
    SimulateOptions so;
    so.preset = d.preset;
    so.seed = static_cast<std::uint64_t>(*d.seed);  // store::read_sweep_jobs: a preset's job has its seed
    if (d.duration_s) so.duration_s = *d.duration_s;
    dataset = work / "dataset";
    (void)simulate(so, dataset);
    timing["simulate"] = seconds_since(t0);
  } else {
    dataset = d.path;
  }
  io::write_file_atomic(work / "config.json", io::dump_json(store::run_config_to_json(c.run_config), 2) + "\n");
  RunOptions ro;
  ro.config_file = (work / "config.json").string();
  ro.detections = c.detections;
  t0 = Clock::now();
  const RunResult rr = run(dataset, work / "run", ro);
  timing["run"] = seconds_since(t0);
  EvalOptions eo = sweep_eval_options(c.eval, "job " + job.id);  // read_sweep checked it
  eo.est = (work / "run").string();
  eo.gt = dataset.string();
  eo.out = (work / "run" / "eval").string();
  eo.label = job.id;
  t0 = Clock::now();
  const EvalResult er = run_eval(eo);
  timing["eval"] = seconds_since(t0);
  std::map<std::string, double> metrics;
  for (const auto& [name, value] : store::headline_metrics(er.report)) metrics[name] = value;
  out.metrics = std::move(metrics);
  out.warnings = rr.output.warnings;
  out.timing_s = std::move(timing);
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
  if (const auto prev = read_result(s.dir, job.id)) {
    if (prev->done()) {
      o.action = "skipped-done";
      return o;
    }
    if (!retry_failed) {
      o.action = "skipped-failed";
      o.exit_code = prev->exit_code;
      o.message = prev->message.value_or("");
      return o;
    }
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
  store::SweepJobResult result;
  result.id = job.id;
  result.axes = job.axes;
  result.roe_version = kVersion;
  try {
    execute(job, work, result);
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
    result.status = "failed";
    result.exit_code = o.exit_code;
    result.message = o.message;
    result.metrics.reset();
    result.warnings.reset();
    result.timing_s.clear();
  }
  o.wall_s = seconds_since(t0);
  result.timing_s["total"] = o.wall_s;
  prune(work);
  io::write_file_atomic(work / "result.json", store::format_sweep_result(result));
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

}  // namespace

SweepPlanResult sweep_plan(const SweepPlanOptions& o) {
  if (o.spec.empty()) throw InputError("a spec file is required: roe sweep plan SPEC --out SWEEP_DIR");
  if (o.out.empty()) throw InputError("--out SWEEP_DIR is required", {"roe sweep plan"});
  const fs::path spec_path = o.spec;
  SweepPlan plan = plan_sweep_file(spec_path, o.max_jobs);
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
    lines += store::format_sweep_job_line(plan.job(i), i);
    if (lines.size() >= (1u << 20) || i + 1 == plan.size()) {
      jobs.append(lines);
      lines.clear();
    }
  }
  store::SweepManifest manifest;
  manifest.roe_version = kVersion;
  manifest.spec_file = io::provenance_path(spec_path);
  manifest.spec = plan.spec;
  manifest.axes = plan.axis_names;
  manifest.n_jobs = plan.size();
  {
    io::DeferSignals defer;  // the job list and the manifest that counts it change together
    jobs.commit();
    io::write_file_atomic(manifest_file(out), store::format_sweep_manifest(manifest));
  }
  res.n_jobs = plan.size();
  res.n_new = plan.size() - (n_before - res.n_dropped);
  res.axis_names = plan.axis_names;
  return res;
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
  s.manifest = store::read_sweep_manifest(mf);
  s.axis_names = s.manifest.axes;
  s.jobs = store::read_sweep_jobs(jobs_file(s.dir));
  // A job's eval block is the spec's, every default filled in: read by the spec's rules (line k is job k-1).
  for (std::size_t i = 0; i < s.jobs.size(); ++i) {
    try {
      (void)sweep_eval_options(s.jobs[i].content.eval, jobs_file(s.dir).string());
    } catch (const InputError& e) {
      throw InputError(e.bare_message() + " (plan the sweep again instead of editing jobs.jsonl)",
                       {jobs_file(s.dir).string(), static_cast<std::int64_t>(i + 1), 0, "job." + e.context().key});
    }
  }
  if (s.jobs.size() != s.manifest.n_jobs)
    throw InputError(fmt::format("jobs.jsonl has {} jobs, sweep.json says {}", s.jobs.size(), s.manifest.n_jobs),
                     {jobs_file(s.dir).string()});
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
  if (const auto r = read_result(s.dir, job.id)) return r->done() ? JobState::kDone : JobState::kFailed;
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
        r.failures.push_back({i, read_result(s.dir, s.jobs[i].id)->message.value_or("")});
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
