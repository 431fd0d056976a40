#pragma once
/// @file
/// `roe sweep`: a study (datasets × seeds × configs × config overrides × detection sets) planned into a
/// folder of jobs with content-derived ids, run idempotently by index or shard by whatever scheduler the
/// user has (Slurm arrays, GNU parallel), and aggregated into tables with confidence intervals and
/// paired comparisons (DESIGN §8, docs/sweep.md). roe never schedules.
///
/// The spec model, its expansion into jobs and the aggregation's statistics are decisions about data:
/// they take and return JSON/typed values without touching files (plan_sweep, aggregate_results), so
/// tests reach them directly. The functions named after the subcommands read and write the folder.

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "roe/app/eval.hpp"
#include "roe/app/shipped_configs.hpp"
#include "roe/eval/stats.hpp"
#include "roe/store/sweep_files.hpp"

namespace roe::app {

/// Version of a spec file ("format" key, optional).
inline constexpr const char* kSweepSpecFormat = "roe-sweep-spec/1";

/// The most jobs `roe sweep plan` expands a spec to unless --max-jobs raises it (docs/sweep.md).
inline constexpr std::size_t kDefaultMaxSweepJobs = 100000;

/// One job: everything needed to run it, independent of the machine that planned it (store/sweep_files.hpp:
/// its id, axis values and content, as jobs.jsonl holds them).
using SweepJob = store::SweepJob;

/// The eval options of a sweep's "eval" block (a spec's, or a job's in jobs.jsonl, where every default is
/// filled in), read strictly by the spec's own rules: the settings of for_each_sweep_eval_setting, each
/// checked as run_eval checks it. ConfigError naming `source` and the key path (`eval.align`).
EvalOptions sweep_eval_options(const nlohmann::json& block, const std::string& source);

/// A spec expanded into jobs: their ids in order, each job made from the spec on demand by job(i). A job holds
/// its whole run config (a few KB of JSON), so 100 000 jobs (the default limit) are never all in memory: roe
/// sweep plan streams them into jobs.jsonl (issue 51: its own limit within 300 MB).
struct SweepPlan {
  nlohmann::json spec;                  ///< the spec as read
  std::vector<std::string> axis_names;  ///< in table order
  std::vector<std::string> ids;         ///< the jobs' ids: in spec order, duplicates (same id) removed
  std::size_t size() const { return ids.size(); }
  /// Job `i` (its id is ids[i]).
  SweepJob job(std::size_t i) const;

  struct Expansion;  ///< what the jobs are made from (plan_sweep's source file)
  /// Job k is made from block `block`: dataset, seed (when `has_seed`), config variant and detection set.
  struct Recipe {
    std::uint32_t block = 0, dataset = 0, variant = 0, detections = 0;
    std::int64_t seed = 0;
    bool has_seed = false;
  };
  std::shared_ptr<const Expansion> expansion;
  std::vector<Recipe> recipes;  ///< parallel to ids
};

/// Expands a spec (JSON as parsed) into jobs. `spec_dir` resolves relative dataset and config paths;
/// `source` names the spec in errors. ConfigError (exit 2) naming the spec path (`axes.configs[2]`)
/// for unknown keys, empty axes, unknown presets or shipped configs, missing dataset or config paths,
/// and config overrides of keys a run config does not have or with values it refuses.
/// A spec that expands to more than `max_jobs` jobs is refused (ConfigError at `axes`) from the sizes of its
/// axes, before anything is expanded: bounded memory whatever the spec claims.
SweepPlan plan_sweep(const nlohmann::json& spec, const std::filesystem::path& spec_dir, const std::string& source,
                     std::size_t max_jobs = kDefaultMaxSweepJobs);

/// The spec file `spec` (JSON; a syntax error names its line and column) expanded by plan_sweep, its errors
/// located in the file by line and column.
SweepPlan plan_sweep_file(const std::filesystem::path& spec, std::size_t max_jobs = kDefaultMaxSweepJobs);

// The shipped run configs a spec names ("configs": ["paper"]): app/shipped_configs.hpp, the one source.

/// Orders `plan`'s jobs for a folder that already holds `existing_ids` (index order): the jobs already
/// there keep their index, new ones are appended. Returns the ids of the folder that the plan no longer
/// has (the caller refuses them unless forced).
std::vector<std::string> keep_indices(SweepPlan& plan, const std::vector<std::string>& existing_ids);

/// The jobs of shard `shard` of `count` (0-based, round-robin by index: k % count == shard).
std::vector<std::size_t> shard_indices(std::size_t n_jobs, std::size_t shard, std::size_t count);
/// Parses "i/N" (0 <= i < N); InputError naming `option` otherwise.
std::pair<std::size_t, std::size_t> parse_shard(const std::string& text, const std::string& option);

// ---- The folder ----------------------------------------------------------------------------------

struct SweepPlanOptions {
  std::string spec;  ///< SPEC file
  std::string out;   ///< SWEEP_DIR
  bool force = false;  ///< re-plan dropping jobs the spec no longer has
  std::size_t max_jobs = kDefaultMaxSweepJobs;  ///< --max-jobs
};
struct SweepPlanResult {
  std::filesystem::path out;
  std::size_t n_jobs = 0, n_new = 0, n_dropped = 0;
  std::vector<std::string> axis_names;
  nlohmann::json to_json() const;
  std::string to_text() const;
};
/// `roe sweep plan`: writes SWEEP_DIR/sweep.json and SWEEP_DIR/jobs.jsonl (atomically). Planning into an
/// existing sweep keeps its jobs' indices and appends new ones.
SweepPlanResult sweep_plan(const SweepPlanOptions& o);

/// A sweep folder as read back: the manifest and its jobs in index order.
struct SweepFolder {
  std::filesystem::path dir;
  store::SweepManifest manifest;  ///< sweep.json
  std::vector<std::string> axis_names;
  std::vector<SweepJob> jobs;
};
/// Reads SWEEP_DIR (store::read_sweep_manifest, store::read_sweep_jobs, each job's eval block checked with
/// sweep_eval_options); InputError for a folder that is not a sweep, or one written by another format
/// version (the message says which and what to do).
SweepFolder read_sweep(const std::filesystem::path& dir);

enum class JobState { kPending, kRunning, kDone, kFailed };
const char* to_string(JobState s);
/// The state of one job in the folder (kRunning: another process holds its lock).
JobState job_state(const SweepFolder& sweep, const SweepJob& job);

struct SweepRunOptions {
  std::string dir;
  std::optional<std::size_t> index;                          ///< --index I
  std::optional<std::pair<std::size_t, std::size_t>> shard;  ///< --shard i/N
  bool retry_failed = false;                                 ///< --retry-failed
};
struct JobOutcome {
  std::size_t index = 0;
  std::string id;
  std::string action;  ///< "done", "failed", "skipped-done", "skipped-failed", "busy"
  int exit_code = 0;
  std::string message;
  double wall_s = 0.0;
};
struct SweepRunResult {
  std::filesystem::path dir;
  std::vector<JobOutcome> jobs;
  std::size_t failed() const;
  nlohmann::json to_json() const;
  std::string to_text() const;
};
/// `roe sweep run`: runs the selected jobs one after the other (all without --index/--shard). Each job
/// runs under an exclusive lock (locks/ID.lock) in work/ID and is renamed to jobs/ID when it ends; a job
/// that fails records its exit code and message there and the next job runs.
SweepRunResult sweep_run(const SweepRunOptions& o);

struct SweepStatusResult {
  std::filesystem::path dir;
  std::size_t total = 0, done = 0, failed = 0, running = 0, pending = 0;
  std::vector<std::pair<std::size_t, std::string>> failures;  ///< index, message
  nlohmann::json to_json() const;
  std::string to_text() const;
};
SweepStatusResult sweep_status(const std::string& dir);

// ---- Aggregation ----------------------------------------------------------------------------------

/// One finished job's numbers as aggregation reads them (from jobs/ID/result.json).
struct JobResult {
  std::string id;
  nlohmann::json axes;
  std::map<std::string, double> metrics;
};

/// The metrics aggregated, in table order (eval report's per-axis RMSE and APE RMSE).
const std::vector<std::string>& sweep_metric_names();

struct AggregateOptions {
  std::vector<std::string> group_by;  ///< axes defining a group; empty: every axis except seed
  double confidence = 0.95;
};

struct GroupStats {
  nlohmann::json key;  ///< axis -> value of the group
  std::size_t n = 0;
  std::map<std::string, eval::SampleSummary> metrics;
};
struct Comparison {
  std::string a, b;    ///< variant labels (config + overrides); differences are b − a
  nlohmann::json key;  ///< the group (non-variant group-by axes), {} pooled over all
  std::size_t n_pairs = 0;
  std::map<std::string, eval::PairedComparison> metrics;
};
struct Aggregate {
  std::vector<std::string> group_by, variant_axes, axis_names;
  std::vector<GroupStats> groups;
  std::vector<Comparison> comparisons;
  std::size_t n_jobs = 0, n_failed = 0, n_missing = 0;
  double confidence = 0.95;
  nlohmann::json to_json() const;
  std::string markdown() const;
  std::string latex() const;
  std::string csv() const;
  std::string comparisons_csv() const;
};
/// Groups and compares finished jobs (I/O-free). InputError when a group-by name is not an axis.
Aggregate aggregate_results(const std::vector<JobResult>& results, const std::vector<std::string>& axis_names,
                            const AggregateOptions& options);

struct SweepAggregateOptions {
  std::string dir, out;
  AggregateOptions aggregate;
  bool plot = false;
  bool force = false;
};
struct SweepAggregateResult {
  std::filesystem::path out;
  Aggregate aggregate;
  std::string plot_status;
  nlohmann::json to_json() const;
  std::string to_text() const;
};
/// `roe sweep aggregate`: writes DIR (atomically) with summary.{md,tex,csv,json}, comparisons.csv,
/// jobs.csv and, with --plot, plots/box_<metric>.png.
SweepAggregateResult sweep_aggregate(const SweepAggregateOptions& o);

// ---- Emit ------------------------------------------------------------------------------------------

struct SweepEmitOptions {
  std::string engine;  ///< "slurm" or "parallel"
  std::string dir;
  std::string roe;                ///< the roe executable the script calls (one word, quoted); empty: this one
  std::size_t max_parallel = 0;   ///< slurm %K / parallel -j (0: slurm unlimited, parallel one per core)
  std::string partition, time = "01:00:00", mem = "2G", account, job_name = "roe-sweep";
  int cpus_per_task = 1;
  std::string sshloginfile;       ///< parallel --sshloginfile
  bool retry_failed = false;
};
/// The script text (pure: no file read beyond the job count the caller passes). `sweep_abs` is the
/// sweep folder's absolute path (the scheduler's jobs may start elsewhere).
std::string emit_script(const SweepEmitOptions& o, std::size_t n_jobs, const std::filesystem::path& sweep_abs);

struct SweepEmitResult {
  std::string script;
  std::filesystem::path out;  ///< empty: for stdout
  std::size_t n_jobs = 0;
  nlohmann::json to_json() const;
  std::string to_text() const;
};
/// `roe sweep emit`: reads the sweep, creates SWEEP_DIR/logs (where the jobs' logs go) and writes the
/// script to `out` (executable; refused when it exists unless `force`), or returns it for stdout.
SweepEmitResult sweep_emit(const SweepEmitOptions& o, const std::string& out, bool force);

}  // namespace roe::app
