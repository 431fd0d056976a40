#pragma once
/// @file
/// Motion-capture exports (notes/formats.md §3): OptiTrack Motive CSV (format 1.2x–3.x), Vicon
/// Nexus/Tracker CSV, and pose topics of ROS bags (io/ros/bag_poses.hpp: geometry_msgs/PoseStamped, TransformStamped,
/// PoseWithCovarianceStamped, nav_msgs/Odometry, tf2_msgs/TFMessage). TUM, EuRoC and cnspy files
/// are read with io/trajectory_io.hpp.
///
/// All readers return T_M_B (the body in the file's world M) in metres with int64 ns stamps of the
/// file's clock, and throw roe::InputError with file:line:column on malformed content: non-numbers,
/// non-finite values, non-unit quaternions (|‖q‖ − 1| > 1e-3; others are normalised), decreasing
/// time, unknown units or rotation types, a body that is not in the file. Frames where the body was
/// not tracked (empty cells) are skipped and counted, not errors.

#include <filesystem>
#include <string>
#include <vector>

#include "roe/core/types.hpp"

namespace roe::io {

namespace fs = std::filesystem;

struct MocapData {
  std::string format;              ///< motive | vicon | rosbag (ROS 1) | rosbag2 | tum | euroc | csv
  std::string body;                ///< rigid body / topic / child frame actually read
  std::string parent_frame;        ///< bags: header.frame_id of the poses read (the tf parent)
  std::vector<std::string> bodies; ///< every rigid body in the file (Motive/Vicon)
  std::vector<StampedPose> poses;  ///< T_M_B, metres, ns of the file's clock
  std::size_t rows = 0;            ///< frames (rows/messages) read
  std::size_t occluded = 0;        ///< frames without a pose of the body
  std::size_t duplicates = 0;      ///< poses dropped because their stamp repeats the previous one
  double rate_hz = 0.0;            ///< from the header (Motive export rate, Vicon rate), 0 if none
  bool y_up = false;               ///< world M is Y-up (Motive's default world)
  std::string length_unit;         ///< as given in the file
  std::string rotation_type;       ///< "Quaternion", an Euler order ("XYZ", degrees), "helical"
  std::string capture_start_time;  ///< Motive's "Capture Start Time" as written (local time, no zone)
  std::vector<std::string> warnings;
};

/// Quaternion tolerance used by the mocap readers: |‖q‖ − 1| above this is an error.
inline constexpr double kMocapUnitQuatTolerance = 1e-3;

/// OptiTrack Motive CSV. Line 1: key,value pairs (Format Version, Export Frame Rate, Rotation Type,
/// Length Units, ...). Then the Type/Name/ID/property/axis header rows located by the axis row that
/// starts with "Frame" (labels in the first column for ≥ 1.22, empty for 1.21), then data rows.
/// Columns of the rigid body are found by name through the header rows (never by offset): property
/// "Rotation" (X,Y,Z,W quaternion, or three Euler angles in degrees of the "Rotation Type" order,
/// composed intrinsically: "XYZ" → R = Rx·Ry·Rz) and "Position" (X,Y,Z). `body` empty = the only
/// rigid body (InputError listing them when there are several).
MocapData read_motive_csv(const fs::path& file, const std::string& body = "");

/// Vicon CSV export: the first "Objects" (Tracker) or "Segments" (Nexus) section: section name row,
/// rate row, names row ("Global Angle obj:obj" / "Subject:Segment", spanning six columns), column
/// row (Frame, Sub Frame, RX, RY, RZ, TX, TY, TZ), units row (mm, deg/rad), data up to the next
/// section. The rotation (RX, RY, RZ) is a helical (axis-angle) vector in the unit of the units row;
/// time = (Frame − first Frame) / rate. The Vicon world is Z up.
MocapData read_vicon_csv(const fs::path& file, const std::string& body = "");

}  // namespace roe::io
