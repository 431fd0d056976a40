#pragma once
/// @file
/// The tables of a run folder (`roe run`, DESIGN §4), each defined once by a column table that both its
/// writer and its reader use:
///   states.csv        timestamp_ns, p_W_I, v_W_I, q_W_I (x y z w), b_g, b_a, p_I_C, q_I_C, then one σ
///                     per error-state component [δp δv δθ δb_g δb_a δp_I_C δθ_I_C] (sigma_*; rad for
///                     angles), then time_offset_s and sigma_time_offset_s (optional when read); states_filter.csv the same (the filter's estimate beside a smoothed one)
///   objects.csv       timestamp_ns, object_id, anchor (0/1), T_O_W (p, q x y z w), its six σ, the six σ
///                     of T_W_O (sigma_*_W_O_*) and of T_A_O relative to the anchor (sigma_*_A_O_*)
///   reprojection.csv  timestamp_ns, object_id, T_W_I implied by the raw detection (tx..qw; nan when the
///                     object has no object-world yet), status, nis
/// (trajectory.csv / .tum are trajectory files: io/trajectory_io.hpp.)
///
/// Writing: numbers in the shortest round-trip form (CsvWriter), quaternions in the canonical
/// hemisphere (w ≥ 0), one atomic write per file. Reading: columns are matched by their exact names in
/// any order (extra columns are ignored), every error is a roe::InputError with file, line and column:
/// a missing column (at the header line, naming it), a value that is not a number, a non-finite number
/// where the writer never writes one, a quaternion that is not unit (|‖q‖ − 1| > tolerance), a negative
/// σ, decreasing stamps. A σ cell of states.csv may be empty: the run did not record σ at that row (output
/// level "standard": σ at the first row and the first row after each image only); it reads as nan.
/// write → read gives the rows back: numbers exactly (an unrecorded σ as nan), quaternions in the canonical
/// hemisphere and normalised (to an ulp or two); states.csv does not hold RecordedState::pose_cov (reads as 0).
///
/// Adding a column to a file is one line in its table in run_files.cpp (name, how to write it, how to
/// read it; `optional` when older files without it must still be read).

#include <Eigen/Core>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/ekf/filter.hpp"
#include "roe/ekf/images.hpp"
#include "roe/ekf/imu.hpp"
#include "roe/ekf/smoother.hpp"
#include "roe/eval/evaluate.hpp"
#include "roe/store/run_config.hpp"

namespace roe::io {
class TrajectoryWriter;  // io/trajectory_io.hpp
}  // namespace roe::io

namespace roe::store {

namespace fs = std::filesystem;

/// The filter's state at one time as a run records it (named for that, not "a row": it carries more than the
/// file): what a row of states.csv holds (t, x, T_I_C, sigma; trajectory.csv
/// holds t, p_W_I, q_W_I of it) plus pose_cov, which the run keeps in memory for the consistency tests and
/// no file carries (read_states_csv leaves it zero).
struct RecordedState {
  Timestamp t_ns = 0;
  ekf::CoreState x;
  Pose T_I_C;
  /// σ of [δp, δv, δθ, δb_g, δb_a, δp_I_C, δθ_I_C] (0 for the extrinsics when they are held fixed).
  Eigen::Matrix<double, 21, 1> sigma = Eigen::Matrix<double, 21, 1>::Zero();
  /// The camera–IMU time offset t_d (s; t_imu = t_cam + t_d) and its σ (0: held at the declared value; nan:
  /// not recorded at this row). Files written before issue 49 lack both columns: they read as nan.
  double time_offset_s = 0.0;
  double sigma_time_offset_s = 0.0;
  /// Covariance of the IMU pose error [δp_W_I; δθ_W_I] (consistency tests, eval's NEES). Not in the file.
  Eigen::Matrix<double, 6, 6> pose_cov = Eigen::Matrix<double, 6, 6>::Zero();
};

/// One row of objects.csv: an object's estimate after an image.
struct ObjectRow {
  Timestamp t_ns = 0;
  int object_id = 0;
  bool anchor = false;
  Pose T_O_W;
  Eigen::Matrix<double, 6, 1> sigma = Eigen::Matrix<double, 6, 1>::Zero();  ///< [δp_O_W; δθ_O_W]; 0 for components held fixed (anchor)
  /// [δp_W_O; δθ_W_O]: the same uncertainty for the object's pose in W (Filter::object_covariance_in_world)
  Eigen::Matrix<double, 6, 1> sigma_W_O = Eigen::Matrix<double, 6, 1>::Zero();
  /// [δp_A_O; δθ_A_O]: the object's pose relative to the anchor A, T_A_O (gauge-free; 0 for the anchor)
  /// (Filter::object_covariance_relative_to_anchor)
  Eigen::Matrix<double, 6, 1> sigma_A_O = Eigen::Matrix<double, 6, 1>::Zero();
};

/// One row of reprojection.csv as the filter produced it.
struct ReprojectionRow {
  Timestamp t_ns = 0;
  int object_id = 0;
  ekf::DetectionOutcome outcome;
};

/// The column names of each file, in the order written.
const std::vector<std::string>& states_csv_columns();
const std::vector<std::string>& objects_csv_columns();
const std::vector<std::string>& reprojection_csv_columns();

/// The text of each file (header + rows), and the same written atomically (io/output.hpp).
std::string format_states_csv(const std::vector<RecordedState>& rows);
std::string format_objects_csv(const std::vector<ObjectRow>& rows);
std::string format_reprojection_csv(const std::vector<ReprojectionRow>& rows);
void write_states_csv(const fs::path& file, const std::vector<RecordedState>& rows);
void write_objects_csv(const fs::path& file, const std::vector<ObjectRow>& rows);
void write_reprojection_csv(const fs::path& file, const std::vector<ReprojectionRow>& rows);

/// One run file written a row at a time, as the rows are produced, through the file's column table: the same
/// bytes as write_*_csv of the same rows (which are this writer over a vector). The header is written at
/// construction; the text goes into an io::AtomicFile in pieces of CsvWriter::kFlushBytes, so memory does not
/// grow with the rows; nothing is at `file` until commit(), and a writer destroyed uncommitted (an exception)
/// or a signal removes the temporary. Instantiated for RecordedState, ObjectRow and ReprojectionRow.
template <class Row>
class RunFileWriter {
 public:
  explicit RunFileWriter(const fs::path& file);
  ~RunFileWriter();
  RunFileWriter(const RunFileWriter&) = delete;
  RunFileWriter& operator=(const RunFileWriter&) = delete;
  void add(const Row& row);
  void commit();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Where the filter's rows go as they are produced (pipeline::run_dataset): into vectors in memory, or
/// straight into the run folder's files (RunFolderWriter).
class RunRowSink {
 public:
  virtual ~RunRowSink() = default;
  virtual void state(const RecordedState& row) = 0;
  virtual void object(const ObjectRow& row) = 0;
  virtual void reprojection(const ReprojectionRow& row) = 0;
};

/// Which row files a RunFolderWriter writes (each only where run_folder_has(config, it)).
struct RunFolderRows {
  /// The state rows into states<suffix>.csv and trajectory<suffix>.csv/.tum ("_filter": the filter's
  /// estimate beside a smoothed one); none with `states` false.
  bool states = true;
  std::string states_suffix;
  bool objects = true;  ///< the object and reprojection rows into objects.csv and reprojection.csv
};

/// The row files of a run folder written as the rows come (roe run: the filter's rows, final when produced, as
/// the filter runs; the smoothed state rows after the backward pass): states.csv, objects.csv,
/// reprojection.csv and trajectory.csv/.tum (of the state rows), those `rows` selects and only where
/// run_folder_has(config, it). `path_of(name)` is where file `name` is written (the run's io::OutputDir::file).
/// A row of a kind not selected is a programming error. commit() commits every file; destroyed without it,
/// nothing is left.
class RunFolderWriter : public RunRowSink {
 public:
  RunFolderWriter(const RunConfig& config, const std::function<fs::path(const std::string&)>& path_of,
                  const RunFolderRows& rows = {});
  ~RunFolderWriter() override;
  void state(const RecordedState& row) override;
  void object(const ObjectRow& row) override;
  void reprojection(const ReprojectionRow& row) override;
  void commit();

 private:
  RunFolderRows rows_;
  std::optional<RunFileWriter<RecordedState>> states_;
  std::optional<RunFileWriter<ObjectRow>> objects_;
  std::optional<RunFileWriter<ReprojectionRow>> reprojection_;
  std::vector<std::unique_ptr<io::TrajectoryWriter>> trajectories_;
};

/// State rows handed over from the last to the first in blocks, each block in time order (the smoother's
/// backward pass: pipeline::run_dataset).
class BackwardStateRows {
 public:
  virtual ~BackwardStateRows() = default;
  virtual void block(const std::vector<RecordedState>& rows) = 0;
};

/// BackwardStateRows kept in a temporary file until the last block, then handed on in time order (replay),
/// so that memory does not grow with the rows (roe run's smoothed rows: the file lies in the run's
/// io::OutputDir temporary folder, beside --out). The file holds every field of RecordedState but pose_cov,
/// which no run file holds (it reads back zero), as the bits of the doubles. It is removed by the destructor
/// (also after an exception) and, while the object lives, on SIGINT/SIGTERM/SIGHUP (io::SignalCleanup).
/// A failed write or read (disk full) is a roe::InputError naming the file (as RecordingFile).
class SpilledStateRows : public BackwardStateRows {
 public:
  explicit SpilledStateRows(const fs::path& file);
  ~SpilledStateRows() override;
  SpilledStateRows(const SpilledStateRows&) = delete;
  SpilledStateRows& operator=(const SpilledStateRows&) = delete;
  void block(const std::vector<RecordedState>& rows) override;
  /// Every row given, in time order (the last block given first), to sink.state().
  void replay(RunRowSink& sink);
  std::size_t rows() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// ekf::RecordingSpill in a temporary file (roe run with the smoother: the filter's recording, in the run's
/// io::OutputDir temporary folder beside --out), so that the recording (0.8 GB an hour of a 400 Hz IMU, and one
/// dense covariance per update) is not held in memory. Removed by the destructor (also after an exception) and,
/// while the object lives, on SIGINT/SIGTERM/SIGHUP (io::SignalCleanup). A failed write or read (disk full) is
/// a roe::InputError naming the file.
class RecordingFile : public ekf::RecordingSpill {
 public:
  explicit RecordingFile(const fs::path& file);
  ~RecordingFile() override;
  RecordingFile(const RecordingFile&) = delete;
  RecordingFile& operator=(const RecordingFile&) = delete;
  std::uint64_t append(const void* data, std::size_t n) override;
  void read(std::uint64_t offset, void* data, std::size_t n) const override;
  std::uint64_t size() const;  ///< the bytes written

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Which columns a reader reads.
struct RunFileRead {
  /// The columns to read, by name (each must be one of the file's); empty = all of them. Every listed
  /// column is required: one missing from the header is an InputError at the header line that names it.
  /// Columns not listed are neither read nor checked; fields of the row they would fill keep their
  /// defaults.
  std::vector<std::string> columns;
  /// Accept nan/inf (roe eval's NEES reads σ columns others may have left nan); otherwise every number
  /// must be finite, as roe run writes them.
  bool allow_nonfinite = false;
};

/// states.csv (or states_filter.csv). Stamps must not decrease; quaternions unit within 1e-3; σ ≥ 0.
std::vector<RecordedState> read_states_csv(const fs::path& file, const RunFileRead& read = {});
/// The same row by row, nothing kept (a 60 s run at the IMU rate is 24,000 rows of 600 bytes): fn(row)
/// for each data row in order. With `missing` non-null, a listed column that the header lacks is not an
/// error: *missing says which and the result is false (eval then skips its NEES with that reason).
bool for_each_state_row(const fs::path& file, const RunFileRead& read, const std::function<void(const RecordedState&)>& fn,
                        std::string* missing = nullptr);
/// objects.csv. Stamps must not decrease; anchor 0 or 1; quaternions unit within 1e-3; σ ≥ 0.
std::vector<ObjectRow> read_objects_csv(const fs::path& file);
/// reprojection.csv as roe eval reads it: any status text; the pose fields may be empty or nan (the
/// detection had no object-world: T_W_I.p is then nan), otherwise the quaternion must be unit within
/// 0.05; nis may be empty, nan, or its column absent (nan). Stamps must not decrease.
std::vector<eval::DetectionPose> read_reprojection_csv(const fs::path& file);

/// The rows of a run's reprojection.csv against the detections the run read (grouped per image in the IMU
/// clock, ekf::group_images): roe run writes exactly one row per detection, so a detection without its row or
/// a row without its detection means the file is not this run's (shifted, truncated, header only, another
/// run's). roe::InputError naming `file`, the first such (time, object) and how many there are.
void check_reprojection_rows(const std::vector<eval::DetectionPose>& rows,
                             const std::vector<ekf::ImageDetections>& images, const fs::path& file);

}  // namespace roe::store
