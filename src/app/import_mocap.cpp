// roe import mocap: Motive / Vicon / EuRoC / TUM / cnspy / ROS bag poses → DATASET/mav0/mocap0.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "roe/app/import.hpp"
#include "roe/calib/mocap_time_offset.hpp"
#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/io/ros/message_bag.hpp"
#include "roe/io/csv.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/mocap_formats.hpp"
#include "roe/io/ros/bag_poses.hpp"
#include "roe/io/output.hpp"
#include "roe/io/trajectory_io.hpp"
#include "roe/math/so3.hpp"

namespace roe::app {
namespace {

std::string first_line(const fs::path& file) {
  std::string line = io::read_file_head(file, 4096);  // a format's first line is short
  line = line.substr(0, line.find('\n'));
  line = line.substr(io::utf8_bom_length(line));
  return line;
}

std::string detect_format(const fs::path& file) {
  if (!io::detect_bag_kind(file).empty()) return "rosbag";  // ROS 1 or ROS 2, by content
  const std::string l = first_line(file);
  if (l.rfind("Format Version", 0) == 0) return "motive";
  const std::string cell0 = l.substr(0, l.find(','));
  auto trimmed = cell0;
  while (!trimmed.empty() && (trimmed.back() == '\r' || trimmed.back() == ' ')) trimmed.pop_back();
  if (trimmed == "Objects" || trimmed == "Segments" || trimmed == "Trajectories" || trimmed == "Devices" ||
      trimmed == "Joints" || trimmed == "Model Outputs")
    return "vicon";
  return "auto-trajectory";
}

double median_rate(const std::vector<StampedPose>& p) {
  return median_rate_hz(p, [](const StampedPose& x) { return x.t_ns; });
}

std::string source_kind(const std::string& format) {
  if (format == "motive") return "motive-csv";
  if (format == "vicon") return "vicon-csv";
  if (format == "rosbag") return "ros1-bag";
  if (format == "rosbag2") return "ros2-bag";
  if (format == "euroc") return "euroc-csv";
  if (format == "tum") return "tum";
  return "cnspy-csv";
}

}  // namespace

void begin_dataset_change(io::StagedFiles& staged, const fs::path& dataset) {
  io::refuse_special_output(dataset, io::OutputKind::folder, "dataset folder");
  staged.ensure_folder(dataset);
  staged.lock(dataset);
}

DatasetManifest open_or_create_manifest(const fs::path& dataset, bool& created) {
  created = false;
  if (io::path_exists(store::manifest_path(dataset))) return store::read_manifest(dataset);
  if (!io::is_folder(dataset))
    throw InputError(io::path_exists(dataset) ? "dataset path exists and is not a folder" : "no such dataset folder",
                     {dataset.string()});
  DatasetManifest m;
  m.name = fs::absolute(dataset).lexically_normal().filename().string();
  if (m.name.empty()) m.name = fs::absolute(dataset).lexically_normal().parent_path().filename().string();
  created = true;
  return m;
}

io::MocapData read_mocap(const fs::path& file, const ImportMocapOptions& opt) {
  std::string format = opt.format;
  if (format == "auto") format = detect_format(file);
  io::MocapData d;
  if (format == "motive") {
    d = io::read_motive_csv(file, opt.body);
  } else if (format == "vicon") {
    d = io::read_vicon_csv(file, opt.body);
  } else if (format == "rosbag" || format == "rosbag2") {
    if (!opt.child.empty() && !opt.body.empty() && opt.child != opt.body)
      throw InputError("--child \"" + opt.child + "\" and --body \"" + opt.body + "\" disagree (they are the same option)");
    // An empty topic throws, listing the pose topics.
    d = io::read_bag_poses(file, opt.topic, opt.child.empty() ? opt.body : opt.child, opt.salvage, opt.parent);
  } else if (format == "tum" || format == "euroc" || format == "csv" || format == "cnspy" || format == "csv-ns" ||
             format == "auto-trajectory") {
    const io::TrajectoryFormat tf = format == "auto-trajectory" ? io::TrajectoryFormat::kAuto
                                                                : io::parse_trajectory_format(format);
    io::Trajectory t = io::read_trajectory(file, tf);
    d.format = io::to_string(t.format);
    if (d.format == "csv-ns") d.format = "csv";
    d.rows = t.size();
    d.length_unit = "m";
    d.rotation_type = "Quaternion";
    for (std::size_t i = 0; i < t.size(); ++i) {
      // A stamp before 1970 (or before the recording's start) is a damaged cell, not a clock: refused
      // here, where the line is known (docs/import.md, "Timestamps"). --time-offset may still shift
      // valid stamps anywhere.
      if (t.t_ns[i] < 0)
        throw InputError(fmt::format("negative timestamp ({} ns): mocap stamps count from an epoch or the "
                                     "recording's start",
                                     t.t_ns[i]),
                         {file.string(), i < t.lines.size() ? t.lines[i] : 0});
      if (!d.poses.empty() && t.t_ns[i] == d.poses.back().t_ns) {
        ++d.duplicates;  // a repeated stamp: keep the first pose
        continue;
      }
      d.poses.push_back({t.t_ns[i], t.poses[i]});
    }
    if (d.duplicates) d.warnings.push_back(fmt::format("{} pose(s) with a repeated stamp dropped", d.duplicates));
  } else {
    throw InputError("unknown mocap format \"" + opt.format +
                     "\" (auto, motive, vicon, euroc, tum, csv, csv-ns, rosbag, rosbag2)");
  }
  if (d.rate_hz <= 0) d.rate_hz = median_rate(d.poses);
  return d;
}

nlohmann::json ImportMocapSummary::to_json() const {
  nlohmann::json j = {{"command", "import mocap"},
                      {"dataset", dataset.string()},
                      {"csv", csv.string()},
                      {"format", format},
                      {"body", body},
                      {"topic", topic},
                      {"up", up},
                      {"rows", rows},
                      {"poses", poses},
                      {"occluded", occluded},
                      {"duplicate_stamps", duplicates},
                      {"rate_hz", rate_hz},
                      {"length_unit", length_unit},
                      {"rotation_type", rotation_type},
                      {"time_offset_s", time_offset_s},
                      {"created_manifest", created_manifest},
                      {"warnings", warnings}};
  if (estimate)
    j["offset_estimate"] = {{"offset_s", estimate->offset_s},
                            {"correlation", estimate->correlation},
                            {"peak_ratio", std::isfinite(estimate->peak_ratio) ? nlohmann::json(estimate->peak_ratio)
                                                                               : nlohmann::json(nullptr)},
                            {"samples", estimate->samples},
                            {"grid_dt_s", estimate->grid_dt_s},
                            {"peak_at_edge", estimate->peak_at_edge}};
  return j;
}

namespace {
/// --estimate-offset on a dataset without an IMU stream: what the estimate needs and the two ways on.
InputError no_imu_for_offset(const fs::path& dataset, const fs::path& imu_csv) {
  return InputError(fmt::format("--estimate-offset correlates the mocap's angular rate with the gyro, but {} has no "
                                "IMU recording ({} is missing{}): import the recording with its IMU first "
                                "(`roe import realsense BAG --out {}`, a bag with the IMU streams enabled), or give "
                                "the offset with --time-offset S (0 for clocks synchronised in hardware)",
                                dataset.string(), imu_csv.string(),
                                fs::exists(store::manifest_path(dataset)) ? "" : "; the dataset does not exist yet",
                                dataset.string()),
                    {imu_csv.string()});
}
}  // namespace

namespace {

/// The options and paths, checked before the take is read: a bad folder name, --up, offsets out of
/// range, a missing file, an existing mocap folder without --force, an offset estimate without an IMU.
void check_import(const fs::path& file, const fs::path& dataset, const ImportMocapOptions& opt, const fs::path& csv) {
  // "mocap" + letters, digits, '_' or '-': never one of the dataset's other streams (imu0, cam0,
  // state_groundtruth_estimate0), which a forced import would otherwise overwrite.
  const bool name_ok =
      opt.mocap_name.rfind("mocap", 0) == 0 &&
      std::all_of(opt.mocap_name.begin(), opt.mocap_name.end(),
                  [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-'; });
  if (!name_ok)
    throw InputError("invalid mocap folder name \"" + opt.mocap_name +
                         "\": it must start with \"mocap\" and have only letters, digits, '_' and '-' (mocap0, "
                         "mocap1, mocap_box)",
                     {"", 0, 0, "name"});
  if (opt.up != "auto" && opt.up != "y" && opt.up != "z") throw InputError("--up must be auto, y or z");
  // Up to ~127 years: enough to move a take's relative clock onto epoch time, and stamps stay in int64 ns.
  constexpr double kMaxOffsetS = 4e9;
  if (opt.time_offset_s && !(std::abs(*opt.time_offset_s) <= kMaxOffsetS))
    throw InputError(fmt::format("--time-offset must be a finite number of seconds within ±{:g}, got {}", kMaxOffsetS,
                                 *opt.time_offset_s));
  if (!(opt.max_offset_s > 0.0 && opt.max_offset_s <= 60.0))
    throw InputError(fmt::format("--max-offset must be in (0, 60] seconds, got {} (give a coarse shift with --time-offset)",
                                 opt.max_offset_s));
  // A regular file, or a rosbag2 folder (metadata.yaml + its storage files).
  if (!io::is_folder(file) || io::detect_bag_kind(file) != "rosbag2-folder")
    (void)io::require_regular_file(file, "mocap file");
  io::refuse_special_output(csv, io::OutputKind::file);
  if (io::path_exists(csv) && !opt.force)
    throw InputError("the dataset already has mocap data (use --force to replace it)", {csv.string()});
  if (opt.estimate_offset && !io::path_exists(store::imu_csv_path(dataset)))  // before reading the take
    throw no_imu_for_offset(dataset, store::imu_csv_path(dataset));
}

/// Y-up world (Motive) → Z-up: x stays, y_Z = −z_Y, z_Z = y_Y (a +90° rotation about x).
void to_z_up(std::vector<StampedPose>& poses) {
  Eigen::Matrix3d R_Z_Y;
  R_Z_Y << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  const Pose T_Z_Y(R_Z_Y, Eigen::Vector3d::Zero());
  for (auto& p : poses) p.T = T_Z_Y * p.T;
}

/// --estimate-offset: the mocap clock against the dataset's IMU (around --time-offset when given too),
/// with warnings when the estimate is weak or at the edge of the search.
calib::MocapOffsetEstimate estimate_offset(const fs::path& dataset, const std::vector<StampedPose>& poses,
                                           const ImportMocapOptions& opt, std::vector<std::string>& warnings) {
  const fs::path imu_csv = store::imu_csv_path(dataset);
  if (!io::path_exists(imu_csv)) throw no_imu_for_offset(dataset, imu_csv);
  const auto imu = store::read_imu_csv(imu_csv);
  std::vector<StampedPose> shifted = poses;
  if (opt.time_offset_s)
    for (auto& p : shifted) p.t_ns += from_seconds(*opt.time_offset_s);
  calib::MocapOffsetEstimate e = calib::estimate_mocap_time_offset(imu, shifted, opt.max_offset_s);
  e.offset_s += opt.time_offset_s.value_or(0.0);
  if (e.correlation < 0.5)
    warnings.push_back(fmt::format("time-offset estimate is weak (correlation {:.3f}): check it", e.correlation));
  if (e.peak_at_edge)
    warnings.push_back(fmt::format(
        "time-offset estimate: the peak is at the edge of the ±{} s search range; widen --max-offset",
        opt.max_offset_s));
  return e;
}

/// The import's record in roe.json's sources.
SourceRecord source_record(const fs::path& file, const io::MocapData& d, const ImportMocapOptions& opt,
                           const ImportMocapSummary& S, bool y_up, double offset) {
  SourceRecord src;
  src.kind = source_kind(d.format);
  src.path = io::provenance_path(file);
  src.sha256 = io::bag_sha256(file);  // a file, or a rosbag2 folder
  src.options["format"] = d.format;
  src.options["folder"] = "mav0/" + opt.mocap_name;
  if (!d.body.empty()) src.options["body"] = d.body;
  if (!opt.topic.empty()) src.options["topic"] = opt.topic;
  if (!d.parent_frame.empty()) src.options["parent_frame"] = d.parent_frame;
  src.options["up"] = S.up;
  if (y_up) src.options["axis_conversion"] = "Y-up to Z-up: x_Z = x_Y, y_Z = -z_Y, z_Z = y_Y";
  src.options["time_offset_s"] = io::format_double(offset);
  src.options["time_offset_source"] = S.estimate ? "estimated" : opt.time_offset_s ? "given" : "none";
  if (S.estimate) src.options["offset_correlation"] = io::format_double(S.estimate->correlation);
  src.options["rows"] = std::to_string(d.rows);
  src.options["occluded"] = std::to_string(d.occluded);
  src.options["duplicate_stamps"] = std::to_string(d.duplicates);
  if (!d.length_unit.empty()) src.options["length_unit"] = d.length_unit;
  if (!d.rotation_type.empty()) src.options["rotation_type"] = d.rotation_type;
  if (!d.capture_start_time.empty())  // Motive: the take's wall-clock start, local time without a zone
    src.options["capture_start_time"] = d.capture_start_time;
  return src;
}

/// roe.json's mocap section after importing into mav0/mocap0 (other folders leave it alone).
void update_mocap_info(DatasetManifest& m, const io::MocapData& d, double offset, std::vector<std::string>& warnings) {
  MocapInfo mi = m.mocap.value_or(MocapInfo{});
  // T_B_I belongs to one body: a re-import of another body starts again from identity.
  if (m.mocap && mi.body != d.body && (mi.T_B_I.p != Eigen::Vector3d::Zero() || math::angle_between(mi.T_B_I.q, Eigen::Quaterniond::Identity()) > 0.0)) {
    warnings.push_back(fmt::format("mocap.T_B_I was set for body \"{}\"; the body is now \"{}\", so T_B_I is reset "
                                   "to identity (set it again for the new body)",
                                   mi.body, d.body));
    mi.T_B_I = Pose();
  }
  mi.body = d.body;
  mi.time_offset_s = offset;
  m.mocap = mi;
}

}  // namespace

ImportMocapSummary import_mocap(const fs::path& file, const fs::path& dataset, const ImportMocapOptions& opt) {
  ImportMocapSummary S;
  S.dataset = dataset;
  S.csv = dataset / "mav0" / opt.mocap_name / "data.csv";
  check_import(file, dataset, opt, S.csv);
  io::MocapData d = read_mocap(file, opt);
  S.format = d.format;
  S.body = d.body;
  S.topic = opt.topic;
  S.rows = d.rows;
  S.occluded = d.occluded;
  S.duplicates = d.duplicates;
  S.rate_hz = d.rate_hz;
  S.length_unit = d.length_unit;
  S.rotation_type = d.rotation_type;
  S.warnings = d.warnings;
  if (d.poses.empty())
    throw InputError(fmt::format("no pose to import: all {} frame(s) occluded or empty", d.rows), {file.string()});
  const bool y_up = opt.up == "y" || (opt.up == "auto" && d.y_up);
  S.up = y_up ? "y" : "z";
  if (y_up) to_z_up(d.poses);
  // From here on the dataset is changed as one, under its lock.
  io::StagedFiles staged;
  begin_dataset_change(staged, dataset);
  std::error_code ec;
  if (fs::exists(S.csv, ec) && !opt.force)
    throw InputError("the dataset already has mocap data (use --force to replace it)", {S.csv.string()});
  bool created = false;
  DatasetManifest m = open_or_create_manifest(dataset, created);
  S.created_manifest = created;
  double offset = opt.time_offset_s.value_or(0.0);
  if (opt.estimate_offset) {
    S.estimate = estimate_offset(dataset, d.poses, opt, S.warnings);
    offset = S.estimate->offset_s;
  }
  S.time_offset_s = offset;
  S.poses = d.poses.size();

  // Write the poses (file clock; the offset goes into roe.json) and the manifest.
  store::write_mocap_csv(staged.stage(S.csv), d.poses);
  const SourceRecord src = source_record(file, d, opt, S, y_up, offset);
  // A forced re-import replaces the record of the same folder.
  m.sources.erase(std::remove_if(m.sources.begin(), m.sources.end(),
                                 [&](const SourceRecord& r) {
                                   auto it = r.options.find("folder");
                                   return it != r.options.end() && it->second == "mav0/" + opt.mocap_name;
                                 }),
                  m.sources.end());
  m.sources.push_back(src);
  if (opt.mocap_name == "mocap0") update_mocap_info(m, d, offset, S.warnings);
  store::write_manifest(m, staged.stage(store::manifest_path(dataset)));
  staged.commit();
  for (const auto& w : S.warnings) log::warn("{}", w);
  return S;
}

}  // namespace roe::app
