// roe eval: loading the estimate (run folder or file) and the ground truth (dataset folder or file).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "roe/app/eval.hpp"
#include "roe/core/error.hpp"
#include "roe/io/input.hpp"
#include "roe/io/csv.hpp"
#include "roe/io/ros/message_bag.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/mocap_formats.hpp"
#include "roe/io/ros/bag_poses.hpp"
#include "roe/store/run_files.hpp"

namespace roe::app {

namespace fs = std::filesystem;

std::vector<ReprojectionCsvRow> read_reprojection_csv(const fs::path& file) {
  return store::read_reprojection_csv(file);
}

std::vector<std::optional<eval::PoseCovariance>> read_states_covariance(const fs::path& file,
                                                                        const std::vector<Timestamp>& t_ns,
                                                                        std::string* why) {
  store::RunFileRead read;
  read.columns = {"timestamp_ns"};
  for (const char* g : {"sigma_p_W_I", "sigma_theta_W_I"})
    for (const char* a : {"_x", "_y", "_z"}) read.columns.push_back(std::string(g) + a);
  read.allow_nonfinite = true;
  // Each trajectory stamp takes the σ of the first states.csv row with σ at or after it − 1 µs, when that row
  // is within 1 µs (trajectory.csv stores seconds with 9 decimals, states.csv ns). Both files are in time
  // order, so the rows are matched as they stream by: no copy of states.csv is held (an hour at IMU rate
  // is 1.4 M rows).
  std::vector<std::size_t> order(t_ns.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  if (!std::is_sorted(t_ns.begin(), t_ns.end()))
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return t_ns[a] < t_ns[b]; });
  std::vector<std::optional<eval::PoseCovariance>> out(t_ns.size());
  std::size_t next = 0, found = 0;
  std::string missing;
  const bool have = store::for_each_state_row(
      file, read,
      [&](const store::RecordedState& s) {
        if (std::isnan(s.sigma(0)) || std::isnan(s.sigma(6))) return;  // σ not recorded at this row (level standard)
        for (; next < order.size() && t_ns[order[next]] - 1000 <= s.t_ns; ++next) {
          if (std::llabs(s.t_ns - t_ns[order[next]]) > 1000) continue;
          eval::PoseCovariance& c = out[order[next]].emplace();
          c.P_p.diagonal() = s.sigma.head<3>().cwiseAbs2();
          c.P_theta.diagonal() = s.sigma.segment<3>(6).cwiseAbs2();
          ++found;
        }
      },
      &missing);
  if (!have) {
    if (why) *why = missing;
    return {};
  }
  if (found == 0) {
    if (why) *why = "no states.csv stamp with σ matches a trajectory.csv stamp";
    return {};
  }
  return out;
}

std::optional<EvalInput> load_bag_trajectory(const std::string& spec, std::vector<std::string>& warnings) {
  std::error_code ec;
  if (spec.empty() || fs::exists(spec, ec)) return std::nullopt;  // a real path is never BAG:TOPIC
  // The longest prefix before a ':' that is a bag (by content): "run.mcap:/odom", "rec/:/tf:map.base".
  for (std::size_t colon = spec.rfind(':'); colon != std::string::npos && colon > 0;
       colon = spec.rfind(':', colon - 1)) {
    const fs::path bag = spec.substr(0, colon);
    if (!fs::exists(bag, ec) || io::detect_bag_kind(bag).empty()) continue;
    std::string topic = spec.substr(colon + 1), parent, child;
    // tf topics as evo writes them: /tf:PARENT.CHILD
    if (const std::size_t c = topic.find(':'); c != std::string::npos) {
      const std::string frames = topic.substr(c + 1);
      topic = topic.substr(0, c);
      const std::size_t dot = frames.find('.');
      if (dot == std::string::npos || dot == 0 || dot + 1 == frames.size())
        throw InputError("a tf topic is given as BAG:TOPIC:PARENT.CHILD (e.g. run.mcap:/tf:map.base_link), got \"" +
                         spec + "\"");
      parent = frames.substr(0, dot);
      child = frames.substr(dot + 1);
    }
    const io::MocapData d = io::read_bag_poses(bag, topic, child, false, parent);
    EvalInput in;
    in.kind = "bag";
    in.path = bag;
    for (const auto& p : d.poses) {
      in.traj.t_ns.push_back(p.t_ns);
      in.traj.poses.push_back(p.T);
      in.traj.lines.push_back(0);
    }
    in.traj.source = spec;
    in.topic = spec.substr(colon + 1);
    in.description = fmt::format("{} topic {} ({} poses{}{})", bag.string(), topic, d.poses.size(),
                                 d.parent_frame.empty() ? "" : ", frame " + d.parent_frame,
                                 child.empty() ? "" : " -> " + child);
    for (const auto& w : d.warnings) warnings.push_back(bag.string() + ": " + w);
    return in;
  }
  return std::nullopt;
}

EvalInput load_ground_truth(const EvalOptions& o, std::vector<std::string>& warnings) {
  if (auto bag = load_bag_trajectory(o.gt, warnings)) return std::move(*bag);
  EvalInput in;
  in.path = o.gt;
  if (o.gt.empty()) throw InputError("--gt DATASET|GT_FILE is required", {"roe eval"});
  if (!io::path_exists(in.path)) throw InputError("ground truth not found", {o.gt});
  if (!io::is_folder(in.path)) {
    if (o.gt_source != "auto")
      warnings.push_back(
          fmt::format("--gt-source {} is ignored: the ground truth is a file, not a dataset", o.gt_source));
    in.kind = "file";
    in.traj = io::read_trajectory(in.path, io::parse_trajectory_format(o.gt_format));
    if (!o.gt_times.empty()) io::apply_kitti_times(in.traj, o.gt_times);
    in.description = fmt::format("{} ({})", in.path.string(), io::to_string(in.traj.format));
    return in;
  }
  if (o.gt_source != "auto" && o.gt_source != "groundtruth" && o.gt_source != "mocap") {
    throw InputError(
        fmt::format("unknown --gt-source '{}' (expected auto, groundtruth or mocap)", o.gt_source),
        {"", 0, 0, "gt-source"});
  }
  in.kind = "dataset";
  if (o.gt_format != "auto")
    warnings.push_back(
        fmt::format("--gt-format {} is ignored for a dataset folder (its EuRoC csv files are "
                    "read as such)",
                    o.gt_format));
  // A roe dataset (roe.json + mav0/...), an EuRoC sequence folder (mav0/...) or a mav0 folder itself.
  const bool has_manifest = io::path_exists(store::manifest_path(in.path));
  fs::path mav0 = in.path / "mav0";
  if (!io::is_folder(mav0) && io::path_exists(in.path / "state_groundtruth_estimate0")) mav0 = in.path;
  const fs::path gt_csv = mav0 / "state_groundtruth_estimate0" / "data.csv";
  const fs::path mocap_csv = mav0 / "mocap0" / "data.csv";
  const bool want_gt = o.gt_source != "mocap", want_mocap = o.gt_source != "groundtruth";
  if (want_gt && io::path_exists(gt_csv)) {
    in.traj = io::read_trajectory(gt_csv, io::TrajectoryFormat::kEuroc);
    in.description = fmt::format("{} (true IMU pose T_W_I)", gt_csv.string());
    in.truth_world = true;
    return in;
  }
  if (want_mocap && io::path_exists(mocap_csv)) {
    io::Trajectory m = io::read_trajectory(mocap_csv, io::TrajectoryFormat::kEuroc);
    Pose T_B_I;
    double offset_s = 0.0;
    if (has_manifest) {
      const DatasetManifest man = store::read_manifest(in.path);
      if (man.mocap) {
        T_B_I = man.mocap->T_B_I;
        offset_s = man.mocap->time_offset_s;
      } else {
        warnings.push_back("roe.json has no mocap section: using T_B_I = identity and no time offset");
      }
    } else {
      warnings.push_back(
          "no roe.json: mocap0 poses are used as the IMU pose (T_B_I = identity, no time offset)");
    }
    const Timestamp off = from_seconds(offset_s);
    for (std::size_t i = 0; i < m.size(); ++i) {
      m.poses[i] = m.poses[i] * T_B_I;  // T_M_I = T_M_B · T_B_I
      m.t_ns[i] += off;                 // t_imu = t_mocap + time_offset_s
    }
    in.traj = std::move(m);
    in.description = fmt::format("{} with T_B_I (p = [{:.4f}, {:.4f}, {:.4f}]) and time offset {} s",
                                 mocap_csv.string(), T_B_I.p.x(), T_B_I.p.y(), T_B_I.p.z(), offset_s);
    return in;
  }
  throw InputError(fmt::format("no ground truth in this folder: expected {}{}{}",
                               want_gt ? gt_csv.string() : std::string(), want_gt && want_mocap ? " or " : "",
                               want_mocap ? mocap_csv.string() : std::string()),
                   {o.gt});
}

}  // namespace roe::app
