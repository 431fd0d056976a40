// roe import mocap: Motive / Vicon / EuRoC / TUM / cnspy / ROS bag poses → DATASET/mav0/mocap0.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "roe/app/import.hpp"
#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/io/ros/message_bag.hpp"
#include "roe/io/csv.hpp"
#include "roe/io/dataset.hpp"
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
  if (io::path_exists(dataset) && !io::is_folder(dataset))
    throw InputError("dataset path exists and is not a folder", {dataset.string()});
  staged.ensure_folder(dataset);
  staged.lock(dataset);
}

DatasetManifest open_or_create_manifest(const fs::path& dataset, bool& created) {
  created = false;
  if (io::path_exists(io::manifest_path(dataset))) return io::read_manifest(dataset);
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

OffsetEstimate estimate_time_offset(const std::vector<ImuSample>& imu, const std::vector<StampedPose>& mocap,
                                    double max_offset_s, double grid_dt_s) {
  if (imu.size() < 10 || mocap.size() < 10)
    throw DataError("time-offset estimate needs at least 10 IMU samples and 10 mocap poses");
  // Mocap angular-rate magnitude at mid-points of consecutive poses (gaps over 3 periods skipped).
  const double mocap_rate = median_rate(mocap);
  const double period = mocap_rate > 0 ? 1.0 / mocap_rate : 0.01;
  if (grid_dt_s <= 0) grid_dt_s = std::min(period, 0.005);
  std::vector<std::pair<double, double>> mrate;  // (t_mocap s relative, |w|)
  const Timestamp m0 = mocap.front().t_ns;
  for (std::size_t k = 0; k + 1 < mocap.size(); ++k) {
    const double dt = dt_seconds(mocap[k].t_ns, mocap[k + 1].t_ns);
    if (!(dt > 0) || dt > 3.0 * period) continue;
    const double w = math::log_quat(mocap[k].T.q.conjugate() * mocap[k + 1].T.q).norm() / dt;
    mrate.emplace_back(dt_seconds(m0, mocap[k].t_ns) + 0.5 * dt, w);
  }
  // Gyro magnitude binned on the grid (IMU clock, relative to the first IMU sample).
  const Timestamp g0 = imu.front().t_ns;
  const double g_len = dt_seconds(g0, imu.back().t_ns);
  const auto ng = static_cast<std::size_t>(g_len / grid_dt_s) + 1;
  std::vector<double> G(ng, 0.0), Gn(ng, 0.0);
  for (const auto& s : imu) {
    const auto i = static_cast<std::size_t>(std::floor(dt_seconds(g0, s.t_ns) / grid_dt_s + 0.5));
    if (i < ng) {
      G[i] += s.gyro.norm();
      Gn[i] += 1.0;
    }
  }
  for (std::size_t i = 0; i < ng; ++i) G[i] = Gn[i] > 0 ? G[i] / Gn[i] : std::numeric_limits<double>::quiet_NaN();
  // Mocap rate linearly interpolated at mocap-clock time tm (relative to m0); NaN outside/gaps.
  auto m_at = [&](double tm) {
    auto it = std::lower_bound(mrate.begin(), mrate.end(), tm,
                               [](const std::pair<double, double>& a, double t) { return a.first < t; });
    if (it == mrate.begin() || it == mrate.end()) return std::numeric_limits<double>::quiet_NaN();
    const auto& b = *it;
    const auto& a = *(it - 1);
    if (b.first - a.first > 3.0 * period) return std::numeric_limits<double>::quiet_NaN();
    const double u = (tm - a.first) / (b.first - a.first);
    return (1.0 - u) * a.second + u * b.second;
  };
  // Search centre: 0 when the clocks overlap, otherwise align the starts.
  const double clock_gap = dt_seconds(m0, g0);  // t_imu_start − t_mocap_start (s)
  const double m_len = dt_seconds(m0, mocap.back().t_ns);
  const bool overlap = clock_gap < m_len && -clock_gap < g_len;
  const double centre = overlap ? 0.0 : clock_gap;
  const auto nlag = static_cast<int>(std::ceil(max_offset_s / grid_dt_s));
  std::vector<double> corr(2 * nlag + 1, std::numeric_limits<double>::quiet_NaN());
  std::vector<std::size_t> used(2 * nlag + 1, 0);
  // Mocap samples on the grid for offset o: M_o[i] = m(t_imu_i − o) with t_imu_i = g0 + i·dt.
  for (int L = -nlag; L <= nlag; ++L) {
    const double o = centre + L * grid_dt_s;
    double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < ng; ++i) {
      if (std::isnan(G[i])) continue;
      const double tm = clock_gap + static_cast<double>(i) * grid_dt_s - o;  // mocap time rel. m0
      const double m = m_at(tm);
      if (std::isnan(m)) continue;
      sx += G[i];
      sy += m;
      sxx += G[i] * G[i];
      syy += m * m;
      sxy += G[i] * m;
      ++n;
    }
    if (n < 20) continue;
    const double cov = sxy - sx * sy / n, vx = sxx - sx * sx / n, vy = syy - sy * sy / n;
    if (vx <= 1e-12 || vy <= 1e-12) continue;
    corr[L + nlag] = cov / std::sqrt(vx * vy);
    used[L + nlag] = n;
  }
  int best = -1;
  for (int k = 0; k < static_cast<int>(corr.size()); ++k)
    if (!std::isnan(corr[k]) && (best < 0 || corr[k] > corr[best])) best = k;
  if (best < 0)
    throw DataError("time-offset estimate failed: the IMU and mocap signals never overlap with rotation within ±" +
                    fmt::format("{}", max_offset_s) + " s of the search centre");
  double delta = 0.0;
  if (best > 0 && best + 1 < static_cast<int>(corr.size()) && !std::isnan(corr[best - 1]) && !std::isnan(corr[best + 1])) {
    const double a = corr[best - 1], b = corr[best], c = corr[best + 1];
    const double den = a - 2 * b + c;
    if (den < 0) delta = std::clamp(0.5 * (a - c) / den, -0.5, 0.5);
  }
  OffsetEstimate e;
  e.offset_s = centre + (best - nlag + delta) * grid_dt_s;
  e.correlation = corr[best];
  e.samples = used[best];
  e.grid_dt_s = grid_dt_s;
  double second = -1.0;
  const int excl = static_cast<int>(std::ceil(0.25 / grid_dt_s));
  for (int k = 0; k < static_cast<int>(corr.size()); ++k)
    if (std::abs(k - best) > excl && !std::isnan(corr[k])) second = std::max(second, corr[k]);
  e.peak_ratio = second > 0 ? corr[best] / second : std::numeric_limits<double>::infinity();
  e.peak_at_edge = best == 0 || best + 1 == static_cast<int>(corr.size());
  return e;
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
                                fs::exists(io::manifest_path(dataset)) ? "" : "; the dataset does not exist yet",
                                dataset.string()),
                    {imu_csv.string()});
}
}  // namespace

ImportMocapSummary import_mocap(const fs::path& file, const fs::path& dataset, const ImportMocapOptions& opt) {
  ImportMocapSummary S;
  S.dataset = dataset;
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
  S.csv = dataset / "mav0" / opt.mocap_name / "data.csv";
  if (io::path_exists(S.csv) && !opt.force)
    throw InputError("the dataset already has mocap data (use --force to replace it)", {S.csv.string()});
  if (opt.estimate_offset && !io::path_exists(io::imu_csv_path(dataset)))  // before reading the take
    throw no_imu_for_offset(dataset, io::imu_csv_path(dataset));
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
  if (y_up) {
    // Y-up world (Motive) → Z-up: x stays, y_Z = −z_Y, z_Z = y_Y (a +90° rotation about x).
    Eigen::Matrix3d R_Z_Y;
    R_Z_Y << 1, 0, 0, 0, 0, -1, 0, 1, 0;
    const Pose T_Z_Y(R_Z_Y, Eigen::Vector3d::Zero());
    for (auto& p : d.poses) p.T = T_Z_Y * p.T;
  }
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
    const fs::path imu_csv = io::imu_csv_path(dataset);
    if (!io::path_exists(imu_csv)) throw no_imu_for_offset(dataset, imu_csv);
    const auto imu = io::read_imu_csv(imu_csv);
    std::vector<StampedPose> shifted = d.poses;
    // With --time-offset given too, it is the centre of the search.
    if (opt.time_offset_s)
      for (auto& p : shifted) p.t_ns += from_seconds(*opt.time_offset_s);
    OffsetEstimate e = estimate_time_offset(imu, shifted, opt.max_offset_s);
    e.offset_s += opt.time_offset_s.value_or(0.0);
    S.estimate = e;
    offset = e.offset_s;
    if (e.correlation < 0.5)
      S.warnings.push_back(fmt::format("time-offset estimate is weak (correlation {:.3f}): check it", e.correlation));
    if (e.peak_at_edge)
      S.warnings.push_back(fmt::format(
          "time-offset estimate: the peak is at the edge of the ±{} s search range; widen --max-offset",
          opt.max_offset_s));
  }
  S.time_offset_s = offset;
  S.poses = d.poses.size();

  // Write the poses (file clock; the offset goes into roe.json) and the manifest.
  io::write_mocap_csv(staged.stage(S.csv), d.poses);
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
  // A forced re-import replaces the record of the same folder.
  m.sources.erase(std::remove_if(m.sources.begin(), m.sources.end(),
                                 [&](const SourceRecord& r) {
                                   auto it = r.options.find("folder");
                                   return it != r.options.end() && it->second == "mav0/" + opt.mocap_name;
                                 }),
                  m.sources.end());
  m.sources.push_back(src);
  if (opt.mocap_name == "mocap0") {
    MocapInfo mi = m.mocap.value_or(MocapInfo{});
    // T_B_I belongs to one body: a re-import of another body starts again from identity.
    if (m.mocap && mi.body != d.body && (mi.T_B_I.p != Eigen::Vector3d::Zero() || math::angle_between(mi.T_B_I.q, Eigen::Quaterniond::Identity()) > 0.0)) {
      S.warnings.push_back(fmt::format("mocap.T_B_I was set for body \"{}\"; the body is now \"{}\", so T_B_I is reset "
                                       "to identity (set it again for the new body)",
                                       mi.body, d.body));
      mi.T_B_I = Pose();
    }
    mi.body = d.body;
    mi.time_offset_s = offset;
    m.mocap = mi;
  }
  io::write_manifest(m, staged.stage(io::manifest_path(dataset)));
  staged.commit();
  for (const auto& w : S.warnings) log::warn("{}", w);
  return S;
}

}  // namespace roe::app
