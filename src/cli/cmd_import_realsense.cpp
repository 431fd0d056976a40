// roe import realsense BAG --out DATASET
#include <fmt/format.h>

#include <memory>

#include "command.hpp"
#include "roe/app/import.hpp"

namespace roe::cli {
namespace {

struct Args {
  std::string bag, out;
  app::ImportRealsenseOptions opt;
  bool no_undistort = false, no_images = false;
};

RunFn setup(CLI::App& sub) {
  auto a = std::make_shared<Args>();
  sub.add_option("BAG", a->bag, "RealSense Viewer/rs-record .bag, or a realsense-ros ROS 1 bag or ROS 2 bag (.mcap, .db3, bag folder)")->required();
  sub.add_option("--out", a->out, "New dataset folder (refused if non-empty unless --force)")->required();
  sub.add_option("--crop-width", a->opt.crop_width, "Centred crop of the undistorted image (0 = full width)")
      ->capture_default_str()->check(number_in("integer>=0"));
  sub.add_option("--crop-height", a->opt.crop_height, "Centred crop height (0 = full height)")
      ->capture_default_str()->check(number_in("integer>=0"));
  sub.add_option("--out-width", a->opt.out_width, "Resize the crop to this width (0 = no resize)")
      ->capture_default_str()->check(number_in("integer>=0"));
  sub.add_option("--out-height", a->opt.out_height, "Resize the crop to this height (0 = no resize)")
      ->capture_default_str()->check(number_in("integer>=0"));
  sub.add_flag("--no-undistort", a->no_undistort, "Keep the lens distortion (crop/resize only)");
  sub.add_flag("--no-images", a->no_images, "Import IMU and calibration only");
  sub.add_flag("--salvage", a->opt.salvage, "Import the intact part of a truncated/corrupt bag (else exit 2)");
  sub.add_option("--color-topic", a->opt.color_topic, "Colour image topic (default: found automatically)");
  sub.add_option("--accel-topic", a->opt.accel_topic,
                 "Accelerometer sensor_msgs/Imu topic (default: found by type and name, e.g. <ns>/accel/sample)");
  sub.add_option("--gyro-topic", a->opt.gyro_topic,
                 "Gyroscope sensor_msgs/Imu topic (default: found by type and name, e.g. <ns>/gyro/sample)");
  sub.add_option("--imu-topic", a->opt.imu_topic,
                 "United IMU topic, gyro and accel in every message (default: found by type and name, e.g. <ns>/imu)");
  sub.add_option("--max-frames", a->opt.max_frames, "Import at most N frames (0 = all)")->capture_default_str();
  sub.add_option("--png-compression", a->opt.png_compression, "PNG compression level 0-9")
      ->capture_default_str()->check(CLI::Range(0, 9));
  sub.add_option("--name", a->opt.name, "Dataset name in roe.json (default: the bag's file name)");
  return [a]() {
    a->opt.force = globals().force;
    a->opt.undistort = !a->no_undistort;
    a->opt.images = !a->no_images;
    Progress bar("import realsense", 0);
    const auto s = app::import_realsense(a->bag, a->out, a->opt, bar.callback());
    bar.finish();
    std::string human = fmt::format("imported {} ({} layout) into {}\n", a->bag, s.layout, s.dataset.string());
    if (!s.color_topic.empty())
      human += fmt::format(
          "  colour: {} frame(s) from {}\n"
          "    source {}x{} fx={} fy={} cx={} cy={} model \"{}\"\n"
          "    output {}x{} fx={:.3f} fy={:.3f} cx={:.3f} cy={:.3f} distortion {}\n"
          "    timestamps: header.stamp, domain \"{}\"\n",
          s.frames, s.color_topic, s.source_width, s.source_height, s.source_fx, s.source_fy, s.source_cx,
          s.source_cy, s.source_distortion, s.camera.width, s.camera.height, s.camera.fx, s.camera.fy, s.camera.cx,
          s.camera.cy, s.camera.distortion_model, s.timestamp_domain.empty() ? "unknown" : s.timestamp_domain);
    const std::string imu_domain = s.imu_timestamp_domain.empty() ? "unknown" : s.imu_timestamp_domain;
    if (s.imu_samples && s.accel_samples == 0 && s.gyro_samples == 0)
      human += fmt::format("  imu0: {} samples from the united topic {} @ {} Hz, domain \"{}\"\n", s.imu_samples,
                           s.imu_topic, s.gyro_rate_hz, imu_domain);
    else if (s.imu_samples)
      human += fmt::format(
          "  imu0: {} samples (accel {} @ {} Hz, gyro {} @ {} Hz, {} gyro sample(s) outside the accel range), domain "
          "\"{}\"\n",
          s.imu_samples, s.accel_samples, s.accel_rate_hz, s.gyro_samples, s.gyro_rate_hz, s.gyro_outside_accel,
          imu_domain);
    for (const auto& [k, T] : s.extrinsics)
      human += fmt::format("  tf/0 {}: p=[{:.6f} {:.6f} {:.6f}] q_xyzw=[{:.6f} {:.6f} {:.6f} {:.6f}]\n", k, T.p.x(),
                           T.p.y(), T.p.z(), T.q.x(), T.q.y(), T.q.z(), T.q.w());
    if (!s.warnings.empty()) human += fmt::format("  {} warning(s) (see stderr)\n", s.warnings.size());
    emit(s.to_json(), human);
    return 0;
  };
}

const Registrar reg(kImportRealsenseCommand.parent, kImportRealsenseCommand.name, kImportRealsenseCommand.description, kImportRealsenseCommand.order,
                    &setup);

}  // namespace
}  // namespace roe::cli
