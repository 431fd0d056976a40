#pragma once
/// @file
/// The run pipeline of `roe run`, I/O-free: a dataset in memory and a run configuration in, the filter's
/// (and with "smoother": "rts" the smoother's) rows, summary, health and warnings out. The app reads the
/// dataset and writes the run folder (app/run.hpp); everything decided about the data between is here,
/// where tests reach it without files.

#include <array>
#include <string>
#include <vector>

#include "roe/core/dataset.hpp"
#include "roe/ekf/driver.hpp"
#include "roe/ekf/health.hpp"
#include "roe/ekf/imu.hpp"
#include "roe/store/run_config.hpp"
#include "roe/store/run_files.hpp"

namespace roe::pipeline {

/// The result of a run in memory (what the files hold). With row sinks (run_dataset), `states`,
/// `filter_states`, `objects` and `reprojection` stay empty: the rows went to the sinks, and only their counts
/// are kept.
struct RunOutput {
  std::vector<store::RecordedState> states;  ///< the estimate (smoothed with store::RunConfig::smoother "rts")
  /// With the smoother: the filter's estimate at the same times as `states`; empty otherwise.
  std::vector<store::RecordedState> filter_states;
  bool smoothed = false;
  double smoother_wall_s = 0.0;
  std::vector<store::ObjectRow> objects;
  std::vector<store::ReprojectionRow> reprojection;
  std::size_t state_rows = 0;              ///< the state rows produced (the size of `states` without a sink)
  std::size_t images_with_detections = 0;  ///< images with at least one detection (one reprojection row each)
  /// The anchor, per-object counts, NIS values, update times and the final state (ekf/driver.hpp).
  ekf::FilterRunSummary summary;
  ekf::RunHealth health;  ///< against store::RunConfig::health
  Pose prior_T_I_C;  ///< the extrinsics the filter started from (roe.json camera.T_I_C)
  std::vector<std::string> warnings;
  double filter_wall_s = 0.0;
  /// The IMU noise the filter used (after imu_noise_scale), and where each value came from
  /// ("config" or "dataset"), in the order gyro_noise_density, gyro_random_walk, accel_noise_density,
  /// accel_random_walk.
  ekf::ImuNoiseParams imu_noise;
  std::array<std::string, 4> imu_noise_from;
};

/// Where run_dataset's rows go instead of RunOutput's vectors, and the smoother's recording instead of memory
/// (roe run: into the run folder's files as they are produced and a temporary file, so that memory does not
/// grow with the recording beyond the dataset).
struct RunSinks {
  /// The filter's rows as it produces them: its object and reprojection rows and its state rows (the run's
  /// estimate with the filter alone; with the smoother the filter's own beside it, states_filter.csv).
  store::RunRowSink* filter = nullptr;
  /// With the smoother: the smoothed state rows, handed over by the backward pass from the last to the first
  /// (store::SpilledStateRows puts them back in time order).
  store::BackwardStateRows* smoothed = nullptr;
  /// With the smoother (or the batch): where the filter's recording goes while the filter runs (a temporary
  /// file, store::RecordingFile); nullptr: in memory.
  ekf::RecordingSpill* recording = nullptr;
};

/// Runs the filter on a dataset in memory with the detection set `detections_name` (empty: the only
/// one). Validates the inputs (InputError: no IMU, unknown object ids, bad options; DataError: no
/// detections, configured anchor never detected) and throws NumericError when the filter diverges.
/// With `sinks` (streams_rows(config); both sinks with the smoother: a programming error otherwise), every row
/// goes to them as it is produced and none is kept (RunOutput's row vectors stay empty); without, the rows are
/// collected in RunOutput (the batch's path, and tests).
RunOutput run_dataset(const Dataset& dataset, const std::string& detections_name, const store::RunConfig& config,
                      const RunSinks& sinks = {});

/// Whether `roe run` streams the run's rows into its files (run_dataset with sinks): the filter alone, whose
/// rows are final when produced, and the smoother, whose rows come out of its backward pass; not the batch,
/// which revises the whole history from the rows in memory.
bool streams_rows(const store::RunConfig& config);

/// The detection set a run fuses: `name` when given (InputError naming the available sets when the dataset
/// has no such set), else the dataset's only one (InputError when it has none or several).
std::string choose_detections(const Dataset& dataset, const std::string& name);

}  // namespace roe::pipeline
