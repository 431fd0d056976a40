#pragma once
/// @file
/// Trajectory files read and written by `roe eval` (and usable by any command):
///  - TUM      `t tx ty tz qx qy qz qw`, space-separated, seconds, `#` comment lines (evo, rpg,
///             ov_eval). Exactly 8 fields per row.
///  - EuRoC    ASL csv: `#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],...`
///             (vicon0/mocap0 with 8 columns, state_groundtruth_estimate0 with 17); ns, w first.
///  - CSV      the cnspy/roe comma-separated form with a header of named columns, matched as a SET
///             (any column order): PoseStamped `t,tx,ty,tz,qx,qy,qz,qw` (also `#t,...`, the cnspy
///             "TUM" header), optionally with covariance columns: PosOrientWithCov (+ pxx,pxy,pxz,
///             pyy,pyz,pzz,qrr,qrp,qry,qpp,qpy,qyy), PoseWithCov (+ the 21 upper-triangular entries
///             Txx..Tcc of the 6×6 [x y z roll pitch yaw] covariance), each optionally + est_err_type,
///             err_representation; PoseTypedStamped (+ scale, est_err_type; no covariance). roe's
///             trajectory.csv (DESIGN §4) is PoseStamped. Seconds.
///  - CSV-ns   roe-native: `timestamp_ns,tx,ty,tz,qx,qy,qz,qw` (int64 ns), same set matching.
///  - KITTI    odometry poses: `r11 r12 r13 tx r21 r22 r23 ty r31 r32 r33 tz` per line, no stamp (evo's
///             kitti format). The stamps are the row index in seconds, so two KITTI files associate
///             by index as evo does; apply_kitti_times() takes the stamps from a times file instead.
///  A ROS bag (rosbag v2 or MCAP) is recognised by its magic and refused with how to read it.
/// Seconds are parsed as decimal text straight into int64 nanoseconds (io::parse_seconds_ns, no
/// double rounding), so stamps equal in the file stay equal, and written back exactly with 9 decimals.
/// Readers are strict: every malformed row is a roe::InputError with file:line:column (wrong field
/// count, non-numbers, NaN/inf, zero or far-from-unit quaternions (|‖q‖ − 1| > 0.05; others are
/// normalised), decreasing stamps). Equal consecutive stamps are accepted (evaluation decides).

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "roe/core/types.hpp"

namespace roe::io {

namespace fs = std::filesystem;

enum class TrajectoryFormat { kAuto, kTum, kEuroc, kCsv, kCsvNs, kKitti };

/// "auto", "tum", "euroc", "csv", "csv-ns", "kitti".
std::string to_string(TrajectoryFormat f);
/// Accepts the names of to_string plus the aliases "cnspy" (= csv) and "roe" (= csv-ns);
/// InputError otherwise.
TrajectoryFormat parse_trajectory_format(const std::string& name);

/// A trajectory as read from a file: T_W_X per stamp (the frames are the file's).
struct Trajectory {
  std::vector<Timestamp> t_ns;
  std::vector<Pose> poses;
  std::vector<std::int64_t> lines;  ///< 1-based source line of each pose (0 when not from a file)
  /// Optional 6×6 covariance per pose, order [x y z | roll pitch yaw] (position m², orientation
  /// rad²); empty when the file has none.
  std::vector<Eigen::Matrix<double, 6, 6>> cov;
  /// The position covariance is expressed in the body (estimate) frame, not in the world
  /// (cnspy est_err_type "type1", a local pose error).
  bool cov_position_local = false;
  TrajectoryFormat format = TrajectoryFormat::kAuto;
  std::string source;

  std::size_t size() const { return t_ns.size(); }
  bool empty() const { return t_ns.empty(); }
  /// Stamps equal to their predecessor.
  std::size_t count_duplicate_stamps() const;
};

/// Detects the format from the first non-blank lines of `text` (see the file comment); InputError
/// naming the line when nothing matches (with a hint to pass the format explicitly).
TrajectoryFormat detect_trajectory_format(std::string_view text, const std::string& source);

/// Reads a trajectory file. `format` kAuto detects it from the header.
Trajectory read_trajectory(const fs::path& file, TrajectoryFormat format = TrajectoryFormat::kAuto);
/// Replaces a KITTI trajectory's index stamps by those of a times file (KITTI odometry times.txt: one
/// time in seconds per line, one line per pose). InputError for another format, a count that differs
/// from the poses', or decreasing times.
void apply_kitti_times(Trajectory& tr, const fs::path& times_file);
/// Parses trajectory text; `source` names it in errors.
Trajectory parse_trajectory(std::string text, const std::string& source,
                            TrajectoryFormat format = TrajectoryFormat::kAuto);

/// Text of a trajectory in `format` (kAuto = kCsv): TUM with the header comment
/// `# timestamp tx ty tz qx qy qz qw`; EuRoC with the mocap0 header; CSV `t,tx,ty,tz,qx,qy,qz,qw`
/// (t with 9 decimals); CSV-ns. Numbers are written in the shortest round-trip form.
std::string format_trajectory(const std::vector<Timestamp>& t_ns, const std::vector<Pose>& poses,
                              TrajectoryFormat format);
/// The same for the n poses at(0), at(1), ... (e.g. matched pairs picked by index, without a copy).
std::string format_trajectory(std::size_t n, const std::function<StampedPose(std::size_t)>& at,
                              TrajectoryFormat format);
/// format_trajectory's text written atomically (io::AtomicFile), streamed in pieces of
/// CsvWriter::kFlushBytes: memory does not grow with the trajectory.
void write_trajectory(const fs::path& file, const std::vector<Timestamp>& t_ns,
                      const std::vector<Pose>& poses, TrajectoryFormat format);
void write_trajectory(const fs::path& file, std::size_t n, const std::function<StampedPose(std::size_t)>& at,
                      TrajectoryFormat format);
void write_trajectory(const fs::path& file, const std::vector<StampedPose>& poses, TrajectoryFormat format);

/// write_trajectory one pose at a time, for a trajectory produced as it is written (roe run's filter): the
/// same bytes, through the same io::AtomicFile (nothing at `file` until commit(); the temporary is removed
/// when the writer is destroyed uncommitted, and on signals), in pieces of CsvWriter::kFlushBytes.
class TrajectoryWriter {
 public:
  TrajectoryWriter(const fs::path& file, TrajectoryFormat format);
  ~TrajectoryWriter();
  TrajectoryWriter(const TrajectoryWriter&) = delete;
  TrajectoryWriter& operator=(const TrajectoryWriter&) = delete;
  void add(const StampedPose& pose);
  void commit();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace roe::io
