#pragma once
/// @file
/// A sweep folder's own files, typed (docs/sweep.md §4): sweep.json (the manifest), jobs.jsonl (one job per
/// line) and jobs/ID/result.json (a job's outcome). Each has one field list (src/store/sweep_files.cpp, on the
/// store's JSON walker) that the writer and the strict reader both walk, so every key is spelled once; every
/// sweep subcommand (plan, run, status, emit, aggregate) reads and writes them here and none by key.
///
/// Reading is strict: a missing key, a value of the wrong type or an unknown key is an InputError (exit 2)
/// naming the file, the line (jobs.jsonl) or the line and column (sweep.json, result.json), and the key path.
/// Writing gives today's bytes: a file roe wrote reads back to the same value and is written again byte for
/// byte (tests/store/test_sweep_files.cpp, with files written by main 8a5e53d).
///
/// What stays JSON inside the typed values is what roe does not own or what a room above the store owns: the
/// spec as the user wrote it (sweep.json "spec"), the axes' values (an override's value is any JSON value),
/// and the eval settings of a job (app::for_each_sweep_eval_setting is their one field list).

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "roe/store/run_config.hpp"

namespace roe::store {

/// Version of the sweep folder layout (sweep.json "format"); a folder with another one is refused.
inline constexpr const char* kSweepFormat = "roe-sweep/1";
/// Version of a job's result.json ("format").
inline constexpr const char* kSweepJobFormat = "roe-sweep-job/1";

/// sweep.json.
struct SweepManifest {
  std::string roe_version;
  std::string spec_file;           ///< the spec's path (absolute, io::provenance_path)
  nlohmann::json spec;             ///< the spec as read: the user's document, kept as written (an object)
  std::vector<std::string> axes;   ///< the axis names, in table order
  std::size_t n_jobs = 0;          ///< the lines of jobs.jsonl
};

/// A job's dataset: a simulator preset (with its text's SHA-256, the seed and the duration) or a folder.
struct SweepDataset {
  std::string preset;                 ///< "" for a folder
  std::string preset_sha256;          ///< the preset's text when planned (a job refuses another)
  std::optional<double> duration_s;   ///< written as null when unset: the preset's own duration
  std::optional<std::int64_t> seed;   ///< key absent when unset (no seed axis for the dataset)
  std::string path;                   ///< the folder (absolute), "" for a preset
};

/// A job's content (jobs.jsonl "job"): its id is the first 16 hex digits of the SHA-256 of its JSON
/// (sweep_job_id).
struct SweepJobContent {
  SweepDataset dataset;
  std::string config;    ///< the config's label in the spec (a shipped name or a file path)
  RunConfig run_config;  ///< the effective run config (overrides applied), written as run_config_to_json does
  std::string detections;  ///< the detection set ("" = the dataset's only set): one folder name
  /// roe eval's settings for the job, every default filled in: app::for_each_sweep_eval_setting's keys (the
  /// app reads them with its spec reader, app::sweep_eval_options). An object.
  nlohmann::json eval = nlohmann::json::object();
};

/// One job: its id, its axis values (axis name -> value; null where a block has no such axis) and content.
struct SweepJob {
  std::string id;
  nlohmann::json axes = nlohmann::json::object();
  SweepJobContent content;
};

/// The canonical JSON of a job's content (sorted keys): what its id hashes and jobs.jsonl's "job" holds.
nlohmann::json sweep_job_content_json(const SweepJobContent& c);
/// The first 16 hex digits of the SHA-256 of sweep_job_content_json(c), one line.
std::string sweep_job_id(const SweepJobContent& c);
/// True for an id as sweep_job_id makes them (16 lower-case hex digits): read_sweep_jobs refuses any other, so
/// a hand-edited jobs.jsonl can never make a job folder path leave the sweep.
bool is_sweep_job_id(const std::string& id);

/// One line of jobs.jsonl, "\n" included: {"axes", "id", "index", "job"} on one line.
std::string format_sweep_job_line(const SweepJob& job, std::size_t index);
/// jobs.jsonl, every line checked (exit 2 naming `file`, the line and the key): the indices in order from 0,
/// each id 16 lower-case hex digits and unique, the detection set one folder name, the dataset one preset or
/// one non-empty path, the run config a run config (store::run_config_from_json).
std::vector<SweepJob> read_sweep_jobs(const std::filesystem::path& file);

/// sweep.json's text (two-space indent, final newline; "format" is kSweepFormat).
std::string format_sweep_manifest(const SweepManifest& m);
/// Reads sweep.json. A folder of another format version (an older or newer roe) is refused, naming it and
/// saying to plan again, before anything else is read.
SweepManifest read_sweep_manifest(const std::filesystem::path& file);

/// A job's result.json: what `roe sweep run` recorded when the job ended.
struct SweepJobResult {
  std::string id;
  nlohmann::json axes = nlohmann::json::object();
  std::string roe_version;
  std::string status = "done";        ///< "done" or "failed" (the reader refuses anything else)
  bool done() const { return status == "done"; }
  int exit_code = 0;                  ///< 0 done; 1 data, 2 input, 3 internal (DESIGN §1)
  std::optional<std::string> message;  ///< failed: why (key absent when done)
  /// done: the evaluation's headline metrics (store::headline_metric_names, each present; NaN written as
  /// null) and the job's warnings; keys absent when failed.
  std::optional<std::map<std::string, double>> metrics;
  std::optional<std::vector<std::string>> warnings;
  std::map<std::string, double> timing_s;  ///< wall seconds: simulate, run, eval (done), total
};

/// result.json's text (two-space indent, final newline).
std::string format_sweep_result(const SweepJobResult& r);
/// Reads a result.json (strict; a "done" result needs its metrics and warnings).
SweepJobResult read_sweep_result(const std::filesystem::path& file);

}  // namespace roe::store
