// roe import mocap FILE --into DATASET [--format ...] [--body NAME] [--topic T] [--time-offset S | --estimate-offset]
#include <fmt/format.h>

#include <memory>

#include "command.hpp"
#include "roe/app/import.hpp"

namespace roe::cli {
namespace {

struct MocapArgs {
  std::string file, dataset;
  app::ImportMocapOptions opt;
  double offset = 0.0;
  CLI::Option* offset_opt = nullptr;
};

RunFn setup_mocap(CLI::App& sub) {
  auto a = std::make_shared<MocapArgs>();
  sub.add_option("FILE", a->file, "Motive/Vicon CSV, EuRoC/TUM-VI ground truth, TUM, cnspy CSV, or a ROS bag")
      ->required();
  sub.add_option("--into", a->dataset, "Dataset folder (roe.json is created when missing)")->required();
  sub.add_option("--format", a->opt.format, "File format")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "motive", "vicon", "euroc", "tum", "csv", "cnspy", "csv-ns", "rosbag"}));
  sub.add_option("--body", a->opt.body, "Rigid body (Motive/Vicon) or child frame (tf topics)");
  sub.add_option("--topic", a->opt.topic, "ROS 1/ROS 2 bag: PoseStamped/TransformStamped/Odometry/TFMessage topic");
  sub.add_option("--parent", a->opt.parent, "ROS bag tf topics: parent frame of the transform (header.frame_id)");
  sub.add_option("--child", a->opt.child, "ROS bag tf topics: child frame of the transform (same as --body)");
  sub.add_option("--up", a->opt.up, "Up axis of the file's world: auto (y for Motive), y or z")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "y", "z"}));
  a->offset_opt = sub.add_option("--time-offset", a->offset, "Clock offset in s: t_imu = t_mocap + S");
  sub.add_flag("--estimate-offset", a->opt.estimate_offset,
               "Estimate the offset by correlating |gyro| with the mocap angular rate (needs mav0/imu0)");
  sub.add_option("--max-offset", a->opt.max_offset_s, "Search range of --estimate-offset in s")
      ->capture_default_str()
      ->check(number_in("positive"));
  sub.add_flag("--salvage", a->opt.salvage, "ROS bag: import the intact part of a truncated/corrupt bag");
  sub.add_option("--name", a->opt.mocap_name, "Folder under mav0/ (mocap0 = the camera body)")->capture_default_str();
  return [a]() {
    a->opt.force = globals().force;
    if (a->offset_opt->count()) a->opt.time_offset_s = a->offset;
    const auto s = app::import_mocap(a->file, a->dataset, a->opt);
    std::string human = fmt::format("imported {} pose(s) of \"{}\" ({} format) into {}\n", s.poses, s.body, s.format,
                                    s.csv.string());
    human += fmt::format("  rows {}, occluded {}, repeated stamps {}, rate {:.3f} Hz, up axis of the file: {}{}\n",
                         s.rows, s.occluded, s.duplicates, s.rate_hz, s.up, s.up == "y" ? " (converted to Z up)" : "");
    if (s.estimate)
      human += fmt::format("  estimated time offset {:.6f} s (t_imu = t_mocap + offset), correlation {:.3f}, "
                           "peak ratio {:.2f}, {} samples\n",
                           s.estimate->offset_s, s.estimate->correlation, s.estimate->peak_ratio, s.estimate->samples);
    else if (s.csv.parent_path().filename() == "mocap0")
      human += fmt::format("  time offset {} s recorded in roe.json (mocap.time_offset_s)\n", s.time_offset_s);
    else  // only mocap0 (the camera body) has the mocap section
      human += fmt::format("  time offset {} s recorded in roe.json (this import's sources[].options.time_offset_s)\n",
                           s.time_offset_s);
    if (s.created_manifest) human += "  created a new roe.json\n";
    emit(s.to_json(), human);
    return 0;
  };
}

const Registrar reg_mocap("import", "mocap",
                          "Import motion-capture poses (Motive, Vicon, EuRoC, TUM, cnspy, ROS bag)", 20,
                          &setup_mocap);

}  // namespace
}  // namespace roe::cli
