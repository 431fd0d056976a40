// roe sweep plan SPEC --out SWEEP_DIR | run SWEEP_DIR [--index I | --shard i/N] | status SWEEP_DIR |
// emit slurm|parallel SWEEP_DIR | aggregate SWEEP_DIR --out DIR [--group-by AXES]
#include <memory>

#include "command.hpp"
#include "roe/app/sweep.hpp"
#include "roe/core/error.hpp"
#include "roe/io/output.hpp"

namespace roe::cli {
namespace {

RunFn setup_plan(CLI::App& sub) {
  auto o = std::make_shared<app::SweepPlanOptions>();
  sub.add_option("SPEC", o->spec, "Sweep spec (JSON; docs/sweep.md, configs/sweeps/)")->required();
  sub.add_option("--out", o->out, "Sweep folder (new, or an existing sweep: its jobs keep their indices)");
  sub.add_option("--max-jobs", o->max_jobs, "Refuse a spec that expands to more jobs than this")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  return [o]() {
    o->force = globals().force;
    const auto r = app::sweep_plan(*o);
    emit(r.to_json(), r.to_text());
    return 0;
  };
}

RunFn setup_run(CLI::App& sub) {
  auto o = std::make_shared<app::SweepRunOptions>();
  auto index = std::make_shared<std::size_t>(0);
  auto shard = std::make_shared<std::string>();
  sub.add_option("SWEEP_DIR", o->dir, "Sweep folder made by roe sweep plan")->required();
  auto* i = sub.add_option("--index", *index, "Run job I (0-based; a Slurm array task's $SLURM_ARRAY_TASK_ID)")
                ->check(number_in("integer>=0"));
  sub.add_option("--shard", *shard, "Run shard i of N (0-based: jobs k with k % N == i)")->excludes(i);
  sub.add_flag("--retry-failed", o->retry_failed, "Run failed jobs again (by default they are skipped)");
  return [o, i, index, shard]() {
    if (i->count() > 0) o->index = *index;
    if (!shard->empty()) o->shard = app::parse_shard(*shard, "--shard");
    const auto r = app::sweep_run(*o);
    emit(r.to_json(), r.to_text());
    return r.failed() > 0 ? 1 : 0;
  };
}

RunFn setup_status(CLI::App& sub) {
  auto dir = std::make_shared<std::string>();
  sub.add_option("SWEEP_DIR", *dir, "Sweep folder")->required();
  return [dir]() {
    const auto r = app::sweep_status(*dir);
    emit(r.to_json(), r.to_text());
    return 0;
  };
}

RunFn setup_emit(CLI::App& sub) {
  auto o = std::make_shared<app::SweepEmitOptions>();
  auto out = std::make_shared<std::string>();
  sub.add_option("ENGINE", o->engine, "slurm (an sbatch array script) or parallel (GNU parallel)")
      ->required()
      ->check(CLI::IsMember({"slurm", "parallel"}));
  sub.add_option("SWEEP_DIR", o->dir, "Sweep folder")->required();
  sub.add_option("--out", *out, "Write the script to FILE (executable) instead of stdout");
  sub.add_option("--roe", o->roe, "The roe executable the script runs, one path (default: this roe's absolute path)");
  sub.add_option("--max-parallel,-j", o->max_parallel, "Slurm array %K / parallel --jobs (0: no limit / one per core)");
  sub.add_option("--partition", o->partition, "Slurm partition")->group("Slurm");
  sub.add_option("--time", o->time, "Slurm time limit per job")->capture_default_str()->group("Slurm");
  sub.add_option("--mem", o->mem, "Slurm memory per job")->capture_default_str()->group("Slurm");
  sub.add_option("--cpus-per-task", o->cpus_per_task, "Slurm CPUs per job")->capture_default_str()->group("Slurm");
  sub.add_option("--account", o->account, "Slurm account")->group("Slurm");
  sub.add_option("--job-name", o->job_name, "Slurm job name")->capture_default_str()->group("Slurm");
  sub.add_option("--sshloginfile", o->sshloginfile, "GNU parallel: run on the hosts of this file")->group("GNU parallel");
  sub.add_flag("--retry-failed", o->retry_failed, "The script runs failed jobs again");
  return [o, out]() {
    const auto r = app::sweep_emit(*o, *out, globals().force);
    if (out->empty()) {
      if (globals().json) emit(r.to_json(), "");
      else std::fwrite(r.script.data(), 1, r.script.size(), stdout);
    } else {
      emit(r.to_json(), r.to_text());
    }
    return 0;
  };
}

RunFn setup_aggregate(CLI::App& sub) {
  auto o = std::make_shared<app::SweepAggregateOptions>();
  sub.add_option("SWEEP_DIR", o->dir, "Sweep folder")->required();
  sub.add_option("--out", o->out, "Output folder (summary.{md,tex,csv,json}, comparisons.csv, jobs.csv, plots/)");
  sub.add_option("--group-by", o->aggregate.group_by, "Axes that define a group (default: every axis but seed)")
      ->delimiter(',');
  sub.add_option("--confidence", o->aggregate.confidence, "Confidence level of the intervals")
      ->capture_default_str()
      ->check(number_in("confidence"));
  sub.add_flag("--plot", o->plot, "Box plots per configuration (python3 + matplotlib, scripts/plot_sweep.py)");
  return [o]() {
    o->force = globals().force;
    const auto r = app::sweep_aggregate(*o);
    emit(r.to_json(), r.to_text());
    return 0;
  };
}

const Registrar plan("sweep", "plan", "Expand a sweep spec into a folder of jobs", 90, &setup_plan);
const Registrar run("sweep", "run", "Run a sweep's jobs (all, --index I or --shard i/N); done jobs are skipped", 91,
                    &setup_run);
const Registrar status("sweep", "status", "Count a sweep's done, failed, running and pending jobs", 92, &setup_status);
const Registrar emit_reg("sweep", "emit", "Write the Slurm array script or GNU parallel command that runs a sweep", 93,
                         &setup_emit);
const Registrar aggregate("sweep", "aggregate",
                          "Tables (Markdown, LaTeX, CSV, JSON) with confidence intervals and paired comparisons", 94,
                          &setup_aggregate);

}  // namespace
}  // namespace roe::cli
