// roe run: dataset → measurement stream → multi-object EKF → RUN_DIR (DESIGN §4).
#include "roe/core/clock.hpp"
#include "roe/app/run.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <optional>
#include <set>

#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/core/parallel.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/output.hpp"
#include "roe/io/pose_json.hpp"
#include "roe/store/run_record.hpp"
#include "roe/io/trajectory_io.hpp"
#include "roe/version.hpp"

namespace roe::app {
namespace {

using io::json;
using Clock = SteadyClock;

}  // namespace

namespace {

// Writers of trajectory.csv and trajectory.tum (with a suffix: trajectory_filter.csv, ...) from state rows,
// read in place.
void add_trajectory_writers(const std::vector<RecordedState>& rows, const io::OutputDir& dir, const std::string& suffix,
                            std::vector<std::function<void()>>& writers) {
  for (const auto format : {io::TrajectoryFormat::kCsv, io::TrajectoryFormat::kTum})
    writers.push_back([&rows, &dir, suffix, format] {
      const std::string ext = format == io::TrajectoryFormat::kCsv ? ".csv" : ".tum";
      io::write_trajectory(dir.file("trajectory" + suffix + ext), rows.size(),
                           [&rows](std::size_t i) { return StampedPose{rows[i].t_ns, Pose(rows[i].x.q_W_I, rows[i].x.p_W_I)}; },
                           format);
    });
}

// The run's files, independent of each other, written by as many threads as the process may use, the
// largest (the states tables) first: the same bytes as one after the other.
// `main_files` false: the batch estimator writes the main files (states.csv, objects.csv, reprojection.csv,
// trajectory.csv/.tum), only the filter's _filter files are written here.
void write_outputs(const RunOutput& r, const RunConfig& config, const io::OutputDir& dir, bool main_files) {
  std::vector<std::function<void()>> writers;
  const auto has = [&](const char* file) { return store::run_folder_has(config, file); };
  if (main_files && has("states.csv"))
    writers.push_back([&] { store::write_states_csv(dir.file("states.csv"), r.states); });
  if (r.smoothed && has("states_filter.csv"))
    writers.push_back([&] { store::write_states_csv(dir.file("states_filter.csv"), r.filter_states); });
  if (main_files && has("objects.csv"))
    writers.push_back([&] { store::write_objects_csv(dir.file("objects.csv"), r.objects); });
  if (main_files) add_trajectory_writers(r.states, dir, "", writers);
  if (r.smoothed && has("trajectory_filter.csv")) add_trajectory_writers(r.filter_states, dir, "_filter", writers);
  if (main_files && has("reprojection.csv"))
    writers.push_back([&] { store::write_reprojection_csv(dir.file("reprojection.csv"), r.reprojection); });
  run_all(writers, available_cpus());
}

BatchEstimator g_batch_estimator = nullptr;

// The temporary files in the run's temporary folder (hidden names; neither reaches the committed run folder):
// the smoothed rows until they are written in time order, the filter's recording until it is smoothed.
constexpr const char* kSmoothedRowsTemporary = ".smoothed-states.tmp";
constexpr const char* kRecordingTemporary = ".filter-recording.tmp";

// What run.json records of a run (store/run_record.hpp); the inputs and the timings are the caller's.
store::RunRecord run_record(const RunOutput& r, const Dataset& dataset, const RunConfig& config) {
  store::RunRecord rec;
  rec.roe_version = kVersion;
  rec.command = "run";
  rec.config = config;
  rec.anchor_id = r.summary.anchor.id;
  store::RunCounts& c = rec.counts;
  c.imu_samples = dataset.imu.size();
  c.camera_frames = dataset.frames.size();
  c.images_with_detections = r.images_with_detections;
  c.updates = r.summary.updates;
  c.trajectory_rows = r.state_rows;
  c.per_object = r.summary.counts;  // every status per object, so that the totals add up to the detections
  for (const auto& [id, n] : r.summary.counts) c.detections += n;
  rec.nis = r.health.nis;
  const Timestamp t0 = r.summary.t_first_ns;
  const ekf::RunHealth& h = r.health;
  rec.health = {h.problems, h.duration_s, h.accepted_updates, h.supported_fraction, h.longest_dead_reckoning_s,
                to_seconds(h.dead_reckoning_from_ns - t0), to_seconds(h.dead_reckoning_to_ns - t0),
                h.nis.median_ratio, config.health};
  // Where the estimate was declared lost and re-locked (FilterOptions::relock_after_s).
  for (const auto& e : r.summary.relocks)
    rec.relocks.push_back({to_seconds(e.t_ns - t0), to_seconds(e.what.since_ns - t0), e.what.offset,
                           e.what.drift_per_s, e.what.residual_sigma, e.what.detections, e.what.objects});
  rec.detection_sigmas = {r.summary.detection_sigmas_present,
                          config.filter.use_detection_sigmas && r.summary.detection_sigmas_present,
                          r.summary.detection_sigma_scale};
  // The initial state: the extrinsics prior, the init window and where the gyro bias came from.
  const ekf::FilterRunSummary& s = r.summary;
  rec.init = {r.prior_T_I_C,          s.init.samples,   s.init.duration_s, s.init.mean_accel,
              s.init.std_accel,       s.init.mean_gyro, s.init.std_gyro,   s.init_gyro_bias,
              s.gyro_bias_from_rest ? "rest" : "config", s.gyro_bias_rest_refused};
  rec.imu_noise = r.imu_noise;
  rec.imu_noise_from = r.imu_noise_from;
  rec.final_T_I_C = s.final_T_I_C;
  rec.final_time_offset = store::FinalTimeOffset{config.filter.estimate_time_offset, s.prior_time_offset_s,
                                                 s.final_time_offset_s, s.final_sigma_time_offset_s};
  for (const auto& [id, T_O_W] : s.final_T_O_W) rec.final_objects.push_back({id, id == s.anchor.id, T_O_W});
  rec.warnings = r.warnings;
  return rec;
}

// run_dataset names files relative to the dataset ("roe.json", "mav0/imu0/data.csv") and the config
// as "config": over many sequences a message must say which dataset and which config file.
ErrorContext located(const ErrorContext& c, const std::filesystem::path& dataset_dir, const std::string& config_file) {
  ErrorContext out = c;
  if (c.file == "config")
    out.file = config_file.empty() ? "the default config (no --config)" : config_file;
  else if (!c.file.empty() && std::filesystem::path(c.file).is_relative())
    out.file = (dataset_dir / c.file).string();
  return out;
}

RunOutput run_dataset_located(const Dataset& dataset, const std::filesystem::path& dataset_dir,
                              const RunOptions& options, const RunConfig& config, const pipeline::RunSinks& sinks) {
  const auto at = [&](const Error& e) { return located(e.context(), dataset_dir, options.config_file); };
  try {
    return run_dataset(dataset, options.detections, config, sinks);
  } catch (const ConfigError& e) {
    throw ConfigError(e.bare_message(), at(e));
  } catch (const InputError& e) {
    throw InputError(e.bare_message(), at(e));
  } catch (const NumericError& e) {
    throw NumericError(e.bare_message(), at(e));
  } catch (const DataError& e) {
    throw DataError(e.bare_message(), at(e));
  }
}

}  // namespace

void set_batch_estimator(BatchEstimator f) { g_batch_estimator = f; }
bool has_batch_estimator() { return g_batch_estimator != nullptr; }

RunConfig effective_run_config(const RunOptions& options) {
  RunConfig config;
  if (!options.config_file.empty()) config = run_config_from_file(options.config_file);
  // --output and --estimator over the config, parsed here (the CLI's words) as the config's are by its reader.
  if (!options.output_level.empty() && !store::parse(options.output_level, config.output_level))
    throw InputError(fmt::format("--output must be full, standard or minimal, got '{}'", options.output_level),
                     {"roe run"});
  if (!options.estimator.empty() && !store::parse(options.estimator, config.estimator))
    throw InputError(fmt::format("--estimator must be filter, smoother or batch, got '{}'", options.estimator),
                     {"roe run"});
  return config;
}

RunResult run(const std::filesystem::path& dataset_dir, const std::filesystem::path& out_dir,
              const RunOptions& options) {
  const auto t_start = Clock::now();
  RunConfig config = effective_run_config(options);
  if (config.estimator == store::Estimator::kBatch && !has_batch_estimator())
    throw InputError("the batch estimator (\"estimator\": \"batch\") runs in the helper roe-refine (Ceres), and "
                     "this executable has none: `roe run` hands such a run to roe-refine itself (docs/refine.md §8)",
                     {options.config_file.empty() ? std::string("--estimator") : options.config_file, 0, 0, "estimator"});
  // Refuses a non-empty RUN_DIR, and one that is or contains the dataset or the config, before any work.
  io::OutputDir dir(out_dir, options.force, {dataset_dir, options.config_file});

  store::DatasetParts parts;
  parts.mocap = false;
  parts.groundtruth = false;
  if (!options.detections.empty()) parts.detection_names = {options.detections};
  log::info("config: {}", options.config_file.empty() ? "roe's defaults (no --config)" : options.config_file);
  const Dataset dataset = store::read_dataset(dataset_dir, parts);
  const double read_s = seconds_since(t_start);
  {
    std::size_t n_det = 0;
    for (const auto& kv : dataset.detections) n_det += kv.second.size();
    log::info("read {} in {:.2f} s: {} IMU samples, {} camera frames, {} detection set(s) with {} detections",
              dataset_dir.string(), read_s, dataset.imu.size(), dataset.frames.size(), dataset.detections.size(),
              n_det);
  }

  RunResult res;
  res.out = out_dir;
  // The filter alone and the smoother: the filter's rows go straight into the run folder's files as they are
  // produced (with the smoother its state rows are states_filter.csv and trajectory_filter.*), the smoothed
  // rows into a temporary file in the run's temporary folder as the backward pass gives them, from the last to
  // the first; the batch revises the rows in memory.
  const auto path_of = [&dir](const std::string& file) { return dir.file(file); };
  // The filter's recording for the smoother goes into a temporary file there too, removed once smoothed.
  std::optional<store::RunFolderWriter> stream;
  std::optional<store::SpilledStateRows> smoothed_rows;
  std::optional<store::RecordingFile> recording;
  if (pipeline::streams_rows(config)) {
    stream.emplace(config, path_of, store::RunFolderRows{true, config.smoothed() ? "_filter" : "", true});
    if (config.smoothed()) smoothed_rows.emplace(dir.file(kSmoothedRowsTemporary));
  }
  if (config.smoothed()) recording.emplace(dir.file(kRecordingTemporary));
  res.output =
      run_dataset_located(dataset, dataset_dir, options, config,
                          {stream ? &*stream : nullptr, smoothed_rows ? &*smoothed_rows : nullptr,
                           recording ? &*recording : nullptr});
  recording.reset();
  const RunOutput& r = res.output;
  for (const auto& w : r.warnings) log::warn("{}", w);
  log::info("filter: {} updates, anchor object {}, {:.3f} s; IMU noise gyro {:g} ({}), accel {:g} ({})",
            r.summary.updates, r.summary.anchor.id, r.filter_wall_s, r.imu_noise.gyro_noise_density, r.imu_noise_from[0],
            r.imu_noise.accel_noise_density, r.imu_noise_from[2]);

  const auto t_write = Clock::now();
  const std::string set = pipeline::choose_detections(dataset, options.detections);
  // The batch starts from the smoother's estimate and the run's anchor; without an anchor there is nothing to
  // refine against, and the smoother's estimate is the run's (said in run.json's config and warnings).
  const bool batch = config.estimator == store::Estimator::kBatch && r.summary.anchor.id >= 0;
  if (config.estimator == store::Estimator::kBatch && !batch) {
    config.estimator = store::Estimator::kSmoother;
    res.output.warnings.push_back("the batch estimator was not run: the run has no anchor (no usable detection), "
                                  "so the files hold the smoother's estimate");
    log::warn("{}", res.output.warnings.back());
  }
  if (stream) {
    stream->commit();
    if (smoothed_rows) {  // states.csv and trajectory.*, in time order; the temporary file goes
      store::RunFolderWriter smoothed(config, path_of, store::RunFolderRows{true, "", false});
      smoothed_rows->replay(smoothed);
      smoothed.commit();
      smoothed_rows.reset();
    }
  } else {
    write_outputs(r, config, dir, !batch);
  }
  // Who produced the set (its meta.json, when it has one): in the log, and a malformed one is an input error.
  res.detections_meta = store::read_detection_set_meta(dataset_dir, set);
  if (res.detections_meta)
    log::info("detection set {}: by {}{}, {} frames processed", set, res.detections_meta->producer,
              res.detections_meta->roe_version.empty() ? "" : " " + res.detections_meta->roe_version,
              res.detections_meta->frames_processed);

  store::RunRecord& rec = res.record;
  rec = run_record(r, dataset, config);
  rec.inputs.dataset = dataset_dir.string();
  rec.inputs.dataset_abs = io::provenance_path(dataset_dir);
  rec.inputs.detections = set;
  rec.inputs.sha256 = {
      {"roe.json", io::sha256_file(store::manifest_path(dataset_dir))},
      {"mav0/imu0/data.csv", io::sha256_file(store::imu_csv_path(dataset_dir))},
      {"detections/" + set + "/detections.csv", io::sha256_file(store::detections_dir(dataset_dir, set) / "detections.csv")}};
  if (!options.config_file.empty()) {
    rec.inputs.config = options.config_file;
    rec.inputs.config_abs = io::provenance_path(options.config_file);
  }
  rec.timing_s = {{"read", read_s}, {"filter", r.filter_wall_s}, {"smoother", r.smoother_wall_s}};
  if (batch) {
    const auto t_batch = Clock::now();
    g_batch_estimator(dataset, set, r, dir, rec);  // the main files, rec's final, refine block and warnings
    rec.timing_s["batch"] = seconds_since(t_batch);
    res.output.warnings = rec.warnings;
  }
  rec.timing_s["write"] = seconds_since(t_write) - (batch ? rec.timing_s.at("batch") : 0.0);
  rec.timing_s["total"] = seconds_since(t_start);
  store::write_run_json(dir.file("run.json"), rec);
  dir.commit();
  log::info("wrote {} ({} trajectory rows)", out_dir.string(), r.state_rows);
  return res;
}
json RunResult::to_json() const {
  const json j = store::run_record_to_json(record);
  return {
      {"out", out.string()},       {"anchor_id", output.summary.anchor.id}, {"updates", output.summary.updates},
      {"counts", j.at("counts")}, {"nis", j.at("nis")},                    {"timing_s", j.at("timing_s")},
      {"health", j.at("health")}, {"warnings", output.warnings}};
}

std::string RunResult::to_text() const {
  const store::RunCounts& c = record.counts;
  const ekf::DetectionCounts& d = c.detections;
  std::string s = fmt::format("roe run → {}\n", out.string());
  s += fmt::format("  IMU samples {}, images with detections {}, updates {}, anchor object {}\n", c.imu_samples,
                   c.images_with_detections, output.summary.updates, output.summary.anchor.id);
  s += fmt::format("  detections {}: accepted {}, initialised {}, rejected χ² {}, rejected without anchor {}",
                   d.detections, d.accepted, d.initialized, d.rejected_chi2, d.rejected_no_main);
  // The rarer statuses only when they occur.
  for (const auto& [n, text] : {std::pair{d.rejected_score, "below min_score"},
                                std::pair{d.rejected_no_imu, "outside the IMU stream"},
                                std::pair{d.pending_init, "awaiting initialisation"}})
    if (n > 0) s += fmt::format(", {} {}", text, n);
  s += "\n";
  const ekf::NisStats& n = record.nis;
  if (n.count > 0)
    // The 6-dof NIS against the one 6-dof gate is a diagnostic: the filter gates the position and the rotation
    // parts apart, so the share it rejected is said beside it, not implied by it.
    s += fmt::format("  NIS (6 dof): median {:.2f} (quartiles {:.2f}, {:.2f}; χ²₆ median 5.35), p95 {:.2f}, "
                     "{:.1f} % above the 6-dof gate {:.2f}; rejected by the filter's χ² gates (position and rotation "
                     "apart): {:.1f} % of the detections\n",
                     n.median, n.p25, n.p75, n.p95, 100.0 * n.fraction_above_gate, n.gate,
                     d.detections ? 100.0 * static_cast<double>(d.rejected_chi2) / static_cast<double>(d.detections) : 0.0);
  const store::RunHealthRecord& h = record.health;
  s += fmt::format("  health: {} — {:.1f} % of the {:.1f} s within {:g} s after an accepted update, longest "
                   "dead reckoning {:.2f} s\n",
                   h.healthy() ? "healthy" : "UNHEALTHY", 100.0 * h.supported_fraction, h.duration_s,
                   h.limits.support_window_s, h.longest_dead_reckoning_s);
  for (const auto& p : h.problems) s += "    " + p + "\n";
  s += fmt::format("  filter {:.3f} s, total {:.3f} s\n", record.timing_s.at("filter"), record.timing_s.at("total"));
  return s;
}

}  // namespace roe::app
