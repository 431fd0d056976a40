#include "roe/store/dataset.hpp"
#include "roe/io/models_info.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "roe/io/csv.hpp"
#include "roe/io/input.hpp"
#include "roe/io/output.hpp"
#include "roe/io/pose_json.hpp"
#include "roe/io/trajectory_io.hpp"

namespace roe::store {

// store reads and writes through io's primitives.
using io::CsvOptions;
using io::CsvReader;
using io::CsvWriter;
using io::JsonObject;
using io::OutputDir;
using io::StampKind;
using io::StampOrder;
using io::Trajectory;
using io::TrajectoryFormat;
using io::dump_json;
using io::imu_noise_to_json;
using io::is_folder;
using io::json;
using io::optional_regular_file;
using io::path_exists;
using io::pose_from_json;
using io::pose_to_json;
using io::read_file_head;
using io::read_imu_noise;
using io::read_json_file;
using io::read_models_info;
using io::read_trajectory;
using io::unit_quaternion;
using io::write_file_atomic;
namespace {

using Eigen::Quaterniond;
using Eigen::Vector3d;

// ---------------------------------------------------------------------------------------------
// Shared helpers
// ---------------------------------------------------------------------------------------------

// Tolerance on |‖q‖ − 1| in CSV streams: EuRoC writes 6 decimals, network outputs may be loosely
// normalised; anything further off is a wrong column or a corrupt row, not rounding.
constexpr double kCsvQuatTol = 1e-3;

Pose make_pose(const Quaterniond& q, const Vector3d& p) {
  Pose T;
  T.q = unit_quaternion(q);
  T.p = p;
  return T;
}

// Reads a quaternion from columns (in the given order of x,y,z,w file columns) and checks its norm.
Quaterniond read_quat(const CsvReader& r, std::size_t cx, std::size_t cy, std::size_t cz, std::size_t cw) {
  const Quaterniond q(r.get_double(cw), r.get_double(cx), r.get_double(cy), r.get_double(cz));
  const double n = q.norm();
  if (!(std::abs(n - 1.0) <= kCsvQuatTol))
    throw r.error(std::min({cx, cy, cz, cw}),
                  fmt::format("quaternion is not unit norm (|q| = {:.9g}); check the column order", n));
  return q;
}

Vector3d read_vec3(const CsvReader& r, std::size_t c0) {
  return Vector3d(r.get_double(c0), r.get_double(c0 + 1), r.get_double(c0 + 2));
}

// Every stream file starts its header with the stamp column; EuRoC spells it two ways.
constexpr const char* kStampNs = "timestamp [ns]|timestamp";

CsvOptions stream_options(std::vector<std::string> header,
                          StampOrder order = StampOrder::kStrictlyIncreasing) {
  CsvOptions o;
  o.expected_header = std::move(header);
  o.stamp_column = 0;
  o.stamp_kind = StampKind::kNanoseconds;
  o.stamp_order = order;
  return o;
}

void check_finite(const Vector3d& v, const char* what) {
  ROE_CHECK(v.allFinite(), std::string("non-finite ") + what + " cannot be written");
}

// Writers refuse unsorted or non-finite data: the readers would reject the file, so writing it
// is a bug in the producer.
template <typename T>
void check_sorted(const std::vector<T>& v, const fs::path& file, bool strict) {
  for (std::size_t i = 1; i < v.size(); ++i) {
    const bool ok = strict ? v[i].t_ns > v[i - 1].t_ns : v[i].t_ns >= v[i - 1].t_ns;
    ROE_CHECK(ok, fmt::format("{}: stamps not {} at element {}", file.string(),
                              strict ? "strictly increasing" : "sorted", i));
  }
}

void add_quat_wxyz(CsvWriter& w, const Quaterniond& q) { w.add(q.w()).add(q.x()).add(q.y()).add(q.z()); }
void add_vec3(CsvWriter& w, const Vector3d& v) { w.add(v.x()).add(v.y()).add(v.z()); }

// The stamp-ordered loaders share "absent file → empty stream"; a folder, a FIFO or a symlink loop
// where the file should be is an input error (not an empty stream).
bool present(const fs::path& file) { return optional_regular_file(file, "data file"); }

const std::vector<std::string>& imu_header() {
  static const std::vector<std::string> h = {
      "timestamp [ns]",    "w_RS_S_x [rad s^-1]", "w_RS_S_y [rad s^-1]", "w_RS_S_z [rad s^-1]",
      "a_RS_S_x [m s^-2]", "a_RS_S_y [m s^-2]",   "a_RS_S_z [m s^-2]"};
  return h;
}
const std::vector<std::string>& mocap_header() {
  static const std::vector<std::string> h = {"timestamp [ns]", "p_RS_R_x [m]", "p_RS_R_y [m]", "p_RS_R_z [m]",
                                             "q_RS_w []",      "q_RS_x []",    "q_RS_y []",    "q_RS_z []"};
  return h;
}
// Exactly the EuRoC ground-truth header (state_groundtruth_estimate0), including its "#timestamp"
// without unit; written with ", " separators like the original files.
const std::vector<std::string>& groundtruth_header() {
  static const std::vector<std::string> h = {"timestamp",
                                             "p_RS_R_x [m]",
                                             "p_RS_R_y [m]",
                                             "p_RS_R_z [m]",
                                             "q_RS_w []",
                                             "q_RS_x []",
                                             "q_RS_y []",
                                             "q_RS_z []",
                                             "v_RS_R_x [m s^-1]",
                                             "v_RS_R_y [m s^-1]",
                                             "v_RS_R_z [m s^-1]",
                                             "b_w_RS_S_x [rad s^-1]",
                                             "b_w_RS_S_y [rad s^-1]",
                                             "b_w_RS_S_z [rad s^-1]",
                                             "b_a_RS_S_x [m s^-2]",
                                             "b_a_RS_S_y [m s^-2]",
                                             "b_a_RS_S_z [m s^-2]"};
  return h;
}
const std::vector<std::string>& detections_header(bool with_sigma) {
  static const std::vector<std::string> base = {"timestamp_ns", "object_id", "tx", "ty", "tz",
                                                "qx",           "qy",        "qz", "qw", "score"};
  static const std::vector<std::string> full = [] {
    auto h = base;
    for (const char* s : {"sigma_tx", "sigma_ty", "sigma_tz", "sigma_rx", "sigma_ry", "sigma_rz"})
      h.push_back(s);
    return h;
  }();
  return with_sigma ? full : base;
}

// The ground-truth header as read: EuRoC's names, or OpenVINS's (vicon2gt / ov_eval:
// `#time(ns),px,py,pz,qw,qx,qy,qz,vx,vy,vz,bwx,bwy,bwz,bax,bay,baz`, the same columns in the same order).
std::vector<std::string> groundtruth_header_read() {
  static const char* const ov[] = {"time(ns)", "px", "py", "pz", "qw", "qx", "qy", "qz", "vx",
                                   "vy",       "vz", "bwx", "bwy", "bwz", "bax", "bay", "baz"};
  std::vector<std::string> h = groundtruth_header();
  h[0] = std::string("timestamp [ns]|") + h[0];
  for (std::size_t i = 0; i < h.size(); ++i) h[i] += std::string("|") + ov[i];
  return h;
}

// Header with the first column's accepted spellings.
std::vector<std::string> with_stamp_alternatives(std::vector<std::string> h) {
  h[0] = kStampNs;
  return h;
}

}  // namespace

// -------------------------------------------------------------------------------------------------
// Paths
// -------------------------------------------------------------------------------------------------

fs::path manifest_path(const fs::path& d) { return d / "roe.json"; }
fs::path imu_csv_path(const fs::path& d) { return d / "mav0" / "imu0" / "data.csv"; }
fs::path cam_csv_path(const fs::path& d) { return d / "mav0" / "cam0" / "data.csv"; }
fs::path cam_image_dir(const fs::path& d) { return d / "mav0" / "cam0" / "data"; }
fs::path mocap_csv_path(const fs::path& d) { return d / "mav0" / "mocap0" / "data.csv"; }
fs::path groundtruth_csv_path(const fs::path& d) {
  return d / "mav0" / "state_groundtruth_estimate0" / "data.csv";
}
fs::path detections_dir(const fs::path& d, const std::string& name) { return d / "detections" / name; }

// -------------------------------------------------------------------------------------------------
// Streams
// -------------------------------------------------------------------------------------------------

std::vector<ImuSample> read_imu_csv(const fs::path& file) {
  CsvReader r(file, stream_options(with_stamp_alternatives(imu_header())));
  std::vector<ImuSample> out;
  // Readings no MEMS IMU can give (a corrupt cell, a unit mix-up by 10⁶) are input errors here,
  // not a filter divergence later: the limits are ~30× the largest ranges of consumer and tactical
  // IMUs (±2000 °/s = 35 rad/s, ±16 g = 157 m/s²; 1000 rad/s, 5000 m/s²).
  constexpr double kMaxGyro = 1000.0, kMaxAccel = 5000.0;
  while (r.next()) {
    ImuSample s;
    s.t_ns = r.get_int64(0);
    s.gyro = read_vec3(r, 1);
    s.accel = read_vec3(r, 4);
    for (int k = 0; k < 3; ++k) {
      if (std::abs(s.gyro(k)) > kMaxGyro)
        throw r.error(1 + k, fmt::format("angular rate {} rad/s is beyond any IMU's range (|w| <= {})", s.gyro(k), kMaxGyro));
      if (std::abs(s.accel(k)) > kMaxAccel)
        throw r.error(4 + k, fmt::format("acceleration {} m/s^2 is beyond any IMU's range (|a| <= {})", s.accel(k), kMaxAccel));
    }
    out.push_back(s);
  }
  return out;
}

void write_imu_csv(const fs::path& file, const std::vector<ImuSample>& imu) {
  check_sorted(imu, file, true);
  CsvWriter w;
  w.header(imu_header(), "#");
  for (const auto& s : imu) {
    check_finite(s.gyro, "gyro");
    check_finite(s.accel, "accel");
    w.add(s.t_ns);
    add_vec3(w, s.gyro);
    add_vec3(w, s.accel);
    w.end_row();
  }
  w.write(file);
}

std::vector<CameraFrame> read_cam_csv(const fs::path& file) {
  CsvReader r(file, stream_options({kStampNs, "filename"}));
  std::vector<CameraFrame> out;
  while (r.next()) {
    CameraFrame f;
    f.t_ns = r.get_int64(0);
    f.filename = r.get_string(1);
    if (f.filename.find('/') != std::string::npos || f.filename == "." || f.filename == "..")
      throw r.error(1, "filename must be a plain name inside cam0/data/: '" + f.filename + "'");
    out.push_back(std::move(f));
  }
  return out;
}

void write_cam_csv(const fs::path& file, const std::vector<CameraFrame>& frames) {
  check_sorted(frames, file, true);
  CsvWriter w;
  w.header({"timestamp [ns]", "filename"}, "#");
  for (const auto& f : frames) w.add(f.t_ns).add(f.filename).end_row();
  w.write(file);
}

std::vector<StampedPose> read_mocap_csv(const fs::path& file) {
  CsvReader r(file, stream_options(with_stamp_alternatives(mocap_header())));
  std::vector<StampedPose> out;
  while (r.next()) {
    StampedPose s;
    s.t_ns = r.get_int64(0);
    s.T = make_pose(read_quat(r, 5, 6, 7, 4), read_vec3(r, 1));
    out.push_back(s);
  }
  return out;
}

void write_mocap_csv(const fs::path& file, const std::vector<StampedPose>& poses) {
  check_sorted(poses, file, true);
  CsvWriter w;
  w.header(mocap_header(), "#");
  for (const auto& s : poses) {
    check_finite(s.T.p, "position");
    w.add(s.t_ns);
    add_vec3(w, s.T.p);
    add_quat_wxyz(w, s.T.q);
    w.end_row();
  }
  w.write(file);
}

std::vector<ImuState> read_groundtruth_csv(const fs::path& file) {
  CsvReader r(file, stream_options(groundtruth_header_read()));
  std::vector<ImuState> out;
  while (r.next()) {
    ImuState s;
    s.t_ns = r.get_int64(0);
    s.T_W_I = make_pose(read_quat(r, 5, 6, 7, 4), read_vec3(r, 1));
    s.v_W_I = read_vec3(r, 8);
    s.b_g = read_vec3(r, 11);
    s.b_a = read_vec3(r, 14);
    out.push_back(s);
  }
  return out;
}

GroundTruthFile read_groundtruth_file(const fs::path& file) {
  // The first line that is not blank decides: 17 comma-separated cells are EuRoC's state.
  const std::string head = read_file_head(file, 1 << 16);
  std::size_t pos = head.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;
  while (pos < head.size() && (head[pos] == '\n' || head[pos] == '\r' || head[pos] == ' ')) ++pos;
  const std::string first = head.substr(pos, head.find('\n', pos) - pos);
  GroundTruthFile out;
  if (std::count(first.begin(), first.end(), ',') + 1 == static_cast<std::ptrdiff_t>(groundtruth_header().size())) {
    out.states = read_groundtruth_csv(file);
    out.layout = "euroc-state";
    return out;
  }
  const Trajectory tr = read_trajectory(file, TrajectoryFormat::kAuto);
  for (std::size_t i = 0; i < tr.size(); ++i) out.poses.push_back({tr.t_ns[i], tr.poses[i]});
  // Sorted; a repeated stamp keeps its first pose (as every roe reader of pose files).
  std::stable_sort(out.poses.begin(), out.poses.end(), [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });
  const std::size_t n = out.poses.size();
  out.poses.erase(std::unique(out.poses.begin(), out.poses.end(),
                              [](const auto& a, const auto& b) { return a.t_ns == b.t_ns; }),
                  out.poses.end());
  out.duplicate_stamps = n - out.poses.size();
  out.layout = to_string(tr.format);
  return out;
}

void write_groundtruth_csv(const fs::path& file, const std::vector<ImuState>& states) {
  check_sorted(states, file, true);
  // The EuRoC spelling: "#timestamp, p_RS_R_x [m], ..." (", " between names).
  CsvWriter w;
  const auto& h = groundtruth_header();
  std::vector<std::string> spaced = h;
  for (std::size_t i = 1; i < spaced.size(); ++i) spaced[i] = " " + spaced[i];
  w.header(spaced, "#");
  for (const auto& s : states) {
    check_finite(s.T_W_I.p, "position");
    check_finite(s.v_W_I, "velocity");
    check_finite(s.b_g, "gyro bias");
    check_finite(s.b_a, "accel bias");
    w.add(s.t_ns);
    add_vec3(w, s.T_W_I.p);
    add_quat_wxyz(w, s.T_W_I.q);
    add_vec3(w, s.v_W_I);
    add_vec3(w, s.b_g);
    add_vec3(w, s.b_a);
    w.end_row();
  }
  w.write(file);
}

std::vector<Detection> read_detections_csv(const fs::path& file) {
  // The header decides whether the six sigma columns are present.
  CsvOptions o;
  o.stamp_column = 0;
  o.stamp_order = StampOrder::kNonDecreasing;
  CsvReader r(file, o);
  const bool with_sigma = r.header().size() == detections_header(true).size();
  const auto& expected = detections_header(with_sigma);
  for (std::size_t c = 0; c < std::min(expected.size(), r.header().size()); ++c) {
    if (r.header()[c] != expected[c])
      throw InputError(
          fmt::format("unexpected header: column is '{}', expected '{}'", r.header()[c], expected[c]),
          {file.string(), r.header_line(), static_cast<std::int64_t>(c + 1)});
  }
  if (r.header().size() != expected.size())
    throw InputError(
        fmt::format("unexpected header: {} columns, expected {} (or {} with the six sigma columns)",
                    r.header().size(), detections_header(false).size(), detections_header(true).size()),
        {file.string(), r.header_line(),
         static_cast<std::int64_t>(std::min(r.header().size(), expected.size()) + 1)});

  std::vector<Detection> out;
  std::set<int> ids_at_stamp;
  Timestamp stamp = 0;
  while (r.next()) {
    Detection d;
    d.t_ns = r.get_int64(0);
    d.object_id = r.get_int(1);
    if (d.object_id < 0) throw r.error(1, "object_id must be >= 0");
    if (out.empty() || d.t_ns != stamp) {
      ids_at_stamp.clear();
      stamp = d.t_ns;
    }
    if (!ids_at_stamp.insert(d.object_id).second)
      throw r.error(1, fmt::format("duplicate detection of object {} at timestamp {}", d.object_id, d.t_ns));
    d.T_C_O = make_pose(read_quat(r, 5, 6, 7, 8), read_vec3(r, 2));
    d.score = r.get_double_or_nan(9);
    if (with_sigma) {
      std::size_t empty = 0;
      for (std::size_t c = 10; c < 16; ++c) empty += r.is_empty(c) ? 1 : 0;
      if (empty != 0 && empty != 6) throw r.row_error("sigma columns must be all empty or all given");
      if (empty == 0) {
        Vector6d s;
        for (int k = 0; k < 6; ++k) {
          s[k] = r.get_double(10 + k);
          if (!(s[k] > 0.0)) throw r.error(10 + k, "sigma must be > 0");
        }
        d.sigma = s;
      }
    }
    out.push_back(d);
  }
  return out;
}

void write_detections_csv(const fs::path& file, const std::vector<Detection>& detections) {
  check_sorted(detections, file, false);
  const bool with_sigma = std::any_of(detections.begin(), detections.end(),
                                      [](const Detection& d) { return d.sigma.has_value(); });
  CsvWriter w;
  w.header(detections_header(with_sigma));
  for (std::size_t i = 0; i < detections.size(); ++i) {
    const auto& d = detections[i];
    for (std::size_t k = 0; k < i && detections[i - 1 - k].t_ns == d.t_ns; ++k)
      ROE_CHECK(
          detections[i - 1 - k].object_id != d.object_id,
          fmt::format("{}: duplicate detection of object {} at {}", file.string(), d.object_id, d.t_ns));
    check_finite(d.T_C_O.p, "translation");
    ROE_CHECK(!std::isinf(d.score), "infinite detection score");
    w.add(d.t_ns).add(d.object_id);
    add_vec3(w, d.T_C_O.p);
    w.add(d.T_C_O.q.x()).add(d.T_C_O.q.y()).add(d.T_C_O.q.z()).add(d.T_C_O.q.w());
    if (std::isnan(d.score))
      w.add_empty();
    else
      w.add(d.score);
    if (with_sigma) {
      for (int k = 0; k < 6; ++k) {
        if (d.sigma) {
          ROE_CHECK(std::isfinite((*d.sigma)[k]) && (*d.sigma)[k] > 0.0, "sigma must be finite and > 0");
          w.add((*d.sigma)[k]);
        } else {
          w.add_empty();
        }
      }
    }
    w.end_row();
  }
  w.write(file);
}

// -------------------------------------------------------------------------------------------------
// Whole folder
// -------------------------------------------------------------------------------------------------

Dataset read_dataset(const fs::path& dataset, const DatasetParts& parts) {
  std::error_code ec;
  if (!is_folder(dataset))
    throw InputError(path_exists(dataset) ? "not a folder, expected a dataset folder" : "dataset folder not found",
                     {dataset.string()});
  Dataset d;
  d.manifest = read_manifest(dataset);
  if (parts.imu && present(imu_csv_path(dataset))) d.imu = read_imu_csv(imu_csv_path(dataset));
  if (parts.frames && present(cam_csv_path(dataset))) d.frames = read_cam_csv(cam_csv_path(dataset));
  if (parts.mocap && present(mocap_csv_path(dataset))) d.mocap = read_mocap_csv(mocap_csv_path(dataset));
  if (parts.groundtruth && present(groundtruth_csv_path(dataset)))
    d.groundtruth = read_groundtruth_csv(groundtruth_csv_path(dataset));
  if (parts.detections) {
    std::vector<std::string> available;
    const fs::path root = dataset / "detections";
    if (is_folder(root)) {
      for (const auto& e : fs::directory_iterator(root, ec))
        if (is_folder(e.path()) && present(e.path() / "detections.csv"))
          available.push_back(e.path().filename().string());
    }
    std::sort(available.begin(), available.end());  // deterministic order
    std::vector<std::string> names = parts.detection_names.empty() ? available : parts.detection_names;
    for (const auto& n : names) {
      if (std::find(available.begin(), available.end(), n) == available.end()) {
        std::string list;
        for (const auto& a : available) list += (list.empty() ? "" : ", ") + a;
        throw InputError(fmt::format("no detections named '{}' in this dataset (available: {})", n,
                                     list.empty() ? "none" : list),
                         {detections_dir(dataset, n).string()});
      }
      d.detections[n] = read_detections_csv(detections_dir(dataset, n) / "detections.csv");
    }
  }
  return d;
}

void write_dataset_files(const Dataset& d, const fs::path& root) {
  if (!d.imu.empty()) write_imu_csv(imu_csv_path(root), d.imu);
  if (!d.frames.empty()) write_cam_csv(cam_csv_path(root), d.frames);
  if (!d.mocap.empty()) write_mocap_csv(mocap_csv_path(root), d.mocap);
  if (!d.groundtruth.empty()) write_groundtruth_csv(groundtruth_csv_path(root), d.groundtruth);
  for (const auto& [name, dets] : d.detections) {
    ROE_CHECK(!name.empty() && name.find('/') == std::string::npos && name != "." && name != "..",
              "invalid detection set name '" + name + "'");
    // An empty set is still written (header only): "ran, found nothing" differs from "not run".
    write_detections_csv(detections_dir(root, name) / "detections.csv", dets);
  }
  write_manifest(d.manifest, manifest_path(root));
}

void write_dataset(const Dataset& d, const fs::path& dataset, bool force) {
  OutputDir out(dataset, force);
  write_dataset_files(d, out.tmp());
  out.commit();
}

// -------------------------------------------------------------------------------------------------
// detections/<name>/meta.json

fs::path detection_set_meta_path(const fs::path& dataset, const std::string& name) {
  return detections_dir(dataset, name) / "meta.json";
}

std::optional<DetectionSetMeta> read_detection_set_meta(const fs::path& dataset, const std::string& name) {
  const fs::path file = detection_set_meta_path(dataset, name);
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) return std::nullopt;
  return io::read_json_file(file, detection_set_meta_from_json);
}

}  // namespace roe::store
