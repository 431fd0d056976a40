// roe import realsense: RealSense recorder bags and realsense-ros ROS 1 / ROS 2 bags → dataset folder.
// The bag is read by io/ros/realsense_recording.hpp (discover_realsense_bag, read_realsense_recording);
// this file merges the IMU (merge_imu), builds the camera model
// (make_frame_processor), writes the images (write_images), finds T_I_C (camera_imu_extrinsics) and
// writes the manifest (build_manifest).
#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include <fmt/format.h>

#include "roe/app/import.hpp"
#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/image/frame_processor.hpp"
#include "roe/io/ros/message_bag.hpp"
#include "roe/io/csv.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/output.hpp"
#include "roe/io/pose_json.hpp"
#include "roe/io/ros/imu_streams.hpp"
#include "roe/io/ros/realsense_recording.hpp"
#include "roe/io/ros/msgs.hpp"

namespace roe::app {
namespace {

namespace ros = roe::io::ros;
using Vec3Stamped = std::pair<Timestamp, Eigen::Vector3d>;

std::string fmt_vec(const std::vector<double>& v) {
  std::string s;
  for (std::size_t i = 0; i < v.size(); ++i) s += (i ? "," : "") + io::format_double(v[i]);
  return s;
}

std::string fmt_pose(const Pose& T) {
  return fmt::format("p=[{},{},{}] q_xyzw=[{},{},{},{}]", io::format_double(T.p.x()), io::format_double(T.p.y()),
                     io::format_double(T.p.z()), io::format_double(T.q.x()), io::format_double(T.q.y()),
                     io::format_double(T.q.z()), io::format_double(T.q.w()));
}

/// Sorts by stamp, drops exact duplicates (keeping the first) and counts them.
template <class T, class StampOf>
void sort_unique(std::vector<T>& v, StampOf stamp, std::size_t& dropped) {
  std::stable_sort(v.begin(), v.end(), [&](const T& a, const T& b) { return stamp(a) < stamp(b); });
  const std::size_t n = v.size();
  v.erase(std::unique(v.begin(), v.end(), [&](const T& a, const T& b) { return stamp(a) == stamp(b); }), v.end());
  dropped += n - v.size();
}
Timestamp vec_stamp(const Vec3Stamped& x) { return x.first; }
Timestamp imu_stamp(const ImuSample& x) { return x.t_ns; }

double median_rate(const std::vector<Vec3Stamped>& v) { return median_rate_hz(v, vec_stamp); }

/// "a, b, c", or "none".
std::string join_or_none(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s.empty() ? "none" : s;
}

void write_xyz_csv(const fs::path& file, const std::vector<Vec3Stamped>& v, const char* unit) {
  io::CsvWriter w;
  w.header({"timestamp [ns]", std::string("x [") + unit + "]", std::string("y [") + unit + "]",
            std::string("z [") + unit + "]"},
           "#");
  for (const auto& [t, x] : v) w.add(static_cast<std::int64_t>(t)).add(x.x()).add(x.y()).add(x.z()).end_row();
  w.write(file);
}

/// Without --salvage a damaged bag is refused as soon as the damage is known: right after opening
/// (a truncated bag), after the stream pass, and after the images, never after writing everything.
void fail_if_damaged(const io::MessageBag& bag, bool salvage) {
  if (bag.damaged() && !salvage)
    throw InputError("the bag is damaged (" + bag.damage_summary() + "); use --salvage to import the part that is intact" +
                         bag.damage_listing(),
                     {bag.name()});
}

/// The IMU samples of imu0: the united topic, or accel interpolated at the gyro stamps.
std::vector<ImuSample> merge_imu(io::RealsenseRecording& d, const io::RealsenseStreams& st, const std::string& bag_name,
                                 ImportRealsenseSummary& S) {
  std::vector<ImuSample> imu;
  std::size_t dup = 0;
  sort_unique(d.accel, vec_stamp, dup);
  sort_unique(d.gyro, vec_stamp, dup);
  S.accel_samples = d.accel.size();
  S.gyro_samples = d.gyro.size();
  S.accel_rate_hz = d.accel_fps ? d.accel_fps : median_rate(d.accel);
  S.gyro_rate_hz = d.gyro_fps ? d.gyro_fps : median_rate(d.gyro);
  if (!d.united.empty()) {
    sort_unique(d.united, imu_stamp, dup);
    // The united topic carries the gyro stamps (realsense-ros unite_imu_method): its rate is the gyro's.
    if (d.gyro.empty()) S.gyro_rate_hz = median_rate_hz(d.united, imu_stamp);
    imu = std::move(d.united);
  } else if (!d.accel.empty() && !d.gyro.empty()) {
    imu = io::merge_accel_gyro(d.accel, d.gyro, &S.gyro_outside_accel);
  } else if (!d.accel.empty() || !d.gyro.empty()) {
    S.warnings.push_back("only one of accel/gyro is present: imu0 not written (raw stream kept in imu0_raw)");
  } else if (!st.accel_topic.empty() || !st.gyro_topic.empty() || !st.imu_topic.empty()) {
    std::vector<std::string> v;
    for (const auto* t : {&st.imu_topic, &st.accel_topic, &st.gyro_topic})
      if (!t->empty()) v.push_back(*t);
    S.warnings.push_back(fmt::format(
        "the bag has no IMU stream with samples (no message on {}): imu0 not written, so roe run cannot use this "
        "dataset",
        join_or_none(v)));
  } else if (!st.imu_typed_topics.empty()) {
    S.warnings.push_back(
        "the bag has no IMU stream that roe recognises (realsense-ros <ns>/imu, <ns>/accel/sample and "
        "<ns>/gyro/sample; recorder Accel_N/Gyro_N of the Motion Module); sensor_msgs/Imu topics in the bag: " +
        join_or_none(st.imu_typed_topics) +
        ": choose with --imu-topic or --accel-topic and --gyro-topic; imu0 not written, so roe run cannot use this "
        "dataset");
  } else {
    S.warnings.push_back(
        "the bag has no IMU stream (no sensor_msgs/Imu topic; record with the motion module enabled): imu0 not "
        "written, so roe run cannot use this dataset");
  }
  if (dup) S.warnings.push_back(fmt::format("{} IMU samples with a repeated stamp dropped", dup));
  S.imu_samples = imu.size();
  for (const auto& s : imu)
    if (!s.gyro.allFinite() || !s.accel.allFinite())
      throw InputError(fmt::format("non-finite IMU sample at stamp {} ns", s.t_ns), {bag_name});
  return imu;
}

/// Each stream's timestamp_domain (recorder metadata) and the warnings when the clocks differ.
void check_clocks(const io::RealsenseRecording& d, const io::RealsenseStreams& st, bool have_imu_stream, ImportRealsenseSummary& S) {
  const auto domain = [&](const std::string& t) { return d.domain_of.count(t) ? d.domain_of.at(t) : std::string(); };
  const std::string color_domain = domain(st.metadata_topic);
  const std::string accel_domain = domain(st.accel_meta_topic), gyro_domain = domain(st.gyro_meta_topic);
  S.imu_timestamp_domain = !gyro_domain.empty() ? gyro_domain : accel_domain;
  if (!accel_domain.empty() && !gyro_domain.empty() && accel_domain != gyro_domain)
    S.warnings.push_back(fmt::format("the accelerometer's header.stamp is in \"{}\" but the gyro's in \"{}\": the "
                                     "merged IMU samples mix two clocks",
                                     accel_domain, gyro_domain));
  S.timestamp_domain = !st.color_topic.empty() ? color_domain : S.imu_timestamp_domain;
  if (!st.color_topic.empty() && have_imu_stream && !color_domain.empty() && !S.imu_timestamp_domain.empty() &&
      color_domain != S.imu_timestamp_domain)
    S.warnings.push_back(fmt::format(
        "the colour frames are stamped in \"{}\" and the IMU samples in \"{}\": the two clocks are not comparable, "
        "so camera and IMU are not synchronised in this dataset (record with the same timestamp domain, e.g. "
        "global time, or calibrate the offset)",
        color_domain, S.imu_timestamp_domain));
}

/// The camera model from the CameraInfo and the processing options (nullopt: no camera section).
std::optional<image::FrameProcessor> make_frame_processor(const io::RealsenseRecording& d, const io::RealsenseStreams& st,
                                                          const ImportRealsenseOptions& opt,
                                                          const io::MessageBag& bag, ImportRealsenseSummary& S) {
  if (st.color_topic.empty() && (st.camera_info_topic.empty() || !d.cam_info)) return std::nullopt;
  // Only reached with --salvage when the bag is damaged: the CameraInfo may be in the part that is lost.
  const std::string lost =
      bag.damaged() ? " in the intact part of the bag: the bag is damaged (" + bag.damage_summary() + ")" : std::string();
  if (!d.cam_info && !opt.images) {
    S.warnings.push_back("no CameraInfo for the colour stream" + lost + ": no camera section written");
    return std::nullopt;
  }
  if (!d.cam_info)
    throw InputError("no CameraInfo for the colour stream (expected on " +
                         (st.camera_info_topic.empty() ? std::string("<color>/camera_info") : st.camera_info_topic) +
                         ")" + lost + (lost.empty() ? "" : "; --no-images imports the IMU without it") + bag.damage_listing(),
                     {bag.name()});
  const ros::CameraInfo& ci = *d.cam_info;
  image::CameraModel cm;
  cm.width = static_cast<int>(ci.width);
  cm.height = static_cast<int>(ci.height);
  cm.fx = ci.K[0];
  cm.fy = ci.K[4];
  cm.cx = ci.K[2];
  cm.cy = ci.K[5];
  cm.model = image::parse_distortion(ci.distortion_model);
  for (std::size_t i = 0; i < 5 && i < ci.D.size(); ++i) cm.coeffs[i] = ci.D[i];
  for (std::size_t i = 5; i < ci.D.size(); ++i)
    if (ci.D[i] != 0.0)
      throw InputError(fmt::format("distortion with {} coefficients (rational model?) is not supported", ci.D.size()),
                       {bag.name(), 0, 0, st.camera_info_topic});
  S.source_width = cm.width;
  S.source_height = cm.height;
  S.source_fx = cm.fx;
  S.source_fy = cm.fy;
  S.source_cx = cm.cx;
  S.source_cy = cm.cy;
  S.source_distortion = ci.distortion_model;
  S.source_coeffs = ci.D;
  image::ProcessOptions po;
  po.crop_width = opt.crop_width;
  po.crop_height = opt.crop_height;
  po.out_width = opt.out_width;
  po.out_height = opt.out_height;
  po.undistort = opt.undistort;
  po.png_compression = opt.png_compression;
  try {
    return image::FrameProcessor(cm, po);
  } catch (const InputError& e) {
    throw InputError(std::string(e.what()) + " (colour stream " + st.color_topic + ")", {bag.name()});
  }
}

/// Pass 2: every colour frame (raw or compressed) processed to a PNG named by its header.stamp.
std::vector<CameraFrame> write_images(io::MessageBag& bag, const std::string& topic, image::FrameProcessor& proc,
                                      const fs::path& img_dir, const ImportRealsenseOptions& opt,
                                      const ProgressCallback& progress, ImportRealsenseSummary& S) {
  std::vector<CameraFrame> frames;
  std::size_t dup_frames = 0;
  std::set<Timestamp> seen;
  std::size_t total = bag.message_count(topic);
  if (opt.max_frames) total = std::min(total, opt.max_frames);
  const bool compressed = bag.topic_type(topic) == "sensor_msgs/CompressedImage";
  bag.for_each({topic}, [&](const io::BagMessage& m) {
    const std::string w = m.where();
    std::optional<ros::CompressedImage> ci;
    std::optional<ros::Image> im;
    if (compressed) ci = io::decode<ros::msg::CompressedImage>(m);
    else im = io::decode<ros::msg::Image>(m);
    const Timestamp stamp = compressed ? ci->header.stamp_ns : im->header.stamp_ns;
    if (!seen.insert(stamp).second) {
      ++dup_frames;
      return true;
    }
    const std::string name = std::to_string(stamp) + ".png";
    if (compressed) {
      proc.process_encoded_to_png(ci->data, img_dir / name, w);
    } else {
      image::RawImage raw{static_cast<int>(im->width), static_cast<int>(im->height), im->encoding, im->step, im->data};
      if (im->is_bigendian && (image::canonical_encoding(im->encoding) == "mono16" || im->encoding == "16UC1"))
        throw InputError(w + ": big-endian 16-bit images are not supported");
      proc.process_to_png(raw, img_dir / name, w);
    }
    frames.push_back({stamp, name});
    if (progress) progress(frames.size(), total);
    return !(opt.max_frames && frames.size() >= opt.max_frames);
  });
  std::sort(frames.begin(), frames.end(), [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });
  if (dup_frames) S.warnings.push_back(fmt::format("{} colour frames with a repeated header.stamp skipped", dup_frames));
  return frames;
}

/// The prior T_I_C: recorder tf/0 of the colour and accel streams, or realsense-ros /tf_static from
/// the IMU messages' frame to the CameraInfo's frame; identity (with a warning) when neither is there.
Pose camera_imu_extrinsics(const io::RealsenseRecording& d, const io::RealsenseStreams& st, bool have_imu,
                           ImportRealsenseSummary& S, std::string& source) {
  for (const auto& [label, tf] : d.recorder_tf) S.extrinsics[label] = Pose(tf.q.normalized(), tf.t);
  const auto color_label = io::recorder_stream(st.color_topic);
  const auto accel_label = io::recorder_stream(st.accel_topic);
  if (color_label && accel_label && S.extrinsics.count(color_label->label) && S.extrinsics.count(accel_label->label)) {
    // tf/0 of stream S is rs2_extrinsics(ref → S): x_S = R x_ref + t, i.e. T_S_ref.
    S.have_T_I_C = true;
    source = "recorder tf/0 of " + accel_label->label + " and " + color_label->label;
    return S.extrinsics[accel_label->label] * S.extrinsics[color_label->label].inverse();
  }
  const std::string color_frame = d.cam_info ? d.cam_info->header.frame_id : std::string();
  if (!d.tf_static.empty() && !d.imu_frame.empty() && !color_frame.empty()) {
    if (const auto T = io::static_transform(d.tf_static, d.imu_frame, color_frame)) {
      S.have_T_I_C = true;
      source = st.tf_static_topic + ": " + d.imu_frame + " <- " + color_frame;
      return *T;
    }
    if (have_imu)
      S.warnings.push_back(fmt::format("{} does not connect the IMU frame \"{}\" and the camera frame \"{}\"",
                                       st.tf_static_topic, d.imu_frame, color_frame));
  }
  if (have_imu)
    S.warnings.push_back(
        "no camera-IMU extrinsics in the bag (neither recorder tf/0 nor a /tf_static linking the IMU and camera "
        "frames): camera.T_I_C prior set to identity; import a Kalibr calibration (roe import kalibr) before running "
        "the filter");
  return Pose();
}

}  // namespace

nlohmann::json ImportRealsenseSummary::to_json() const {
  nlohmann::json ext = nlohmann::json::object();
  for (const auto& [k, T] : extrinsics)
    ext[k] = io::pose_to_json(T);
  return {{"command", "import realsense"},
          {"dataset", dataset.string()},
          {"layout", layout},
          {"topics", {{"color", color_topic}, {"accel", accel_topic}, {"gyro", gyro_topic}, {"imu", imu_topic}}},
          {"frames", frames},
          {"accel_samples", accel_samples},
          {"gyro_samples", gyro_samples},
          {"imu_samples", imu_samples},
          {"gyro_outside_accel", gyro_outside_accel},
          {"accel_rate_hz", accel_rate_hz},
          {"gyro_rate_hz", gyro_rate_hz},
          {"timestamp_domain", timestamp_domain},
          {"imu_timestamp_domain", imu_timestamp_domain},
          {"source_camera",
           {{"width", source_width},
            {"height", source_height},
            {"fx", source_fx},
            {"fy", source_fy},
            {"cx", source_cx},
            {"cy", source_cy},
            {"distortion_model", source_distortion},
            {"distortion", source_coeffs}}},
          {"camera",
           {{"width", camera.width},
            {"height", camera.height},
            {"fx", camera.fx},
            {"fy", camera.fy},
            {"cx", camera.cx},
            {"cy", camera.cy},
            {"distortion_model", camera.distortion_model}}},
          {"extrinsics", ext},
          {"T_I_C_from_bag", have_T_I_C},
          {"warnings", warnings}};
}

namespace {

/// roe.json: provenance of the bag and the effective import options, IMU and camera sections.
DatasetManifest build_manifest(const fs::path& bag_path, const io::MessageBag& bag, const io::RealsenseStreams& st,
                               const io::RealsenseRecording& d, const std::vector<ImuSample>& imu,
                               const std::optional<image::FrameProcessor>& proc, const Pose& T_I_C,
                               const std::string& T_I_C_source, bool united, const ImportRealsenseOptions& opt,
                               ImportRealsenseSummary& S) {
  DatasetManifest m;
  std::string stem = bag_path.lexically_normal().stem().string();
  if (stem.empty()) stem = bag_path.lexically_normal().parent_path().filename().string();  // "folder/"
  m.name = opt.name.empty() ? stem : opt.name;
  SourceRecord src;
  src.kind = S.layout == "recorder" ? "realsense-bag" : bag.ros2() ? "ros2-bag" : "ros1-bag";
  src.path = io::provenance_path(bag_path);
  src.sha256 = io::bag_sha256(bag_path);
  src.options["layout"] = S.layout;
  src.options["storage"] = bag.format();
  if (!st.color_topic.empty()) src.options["color_topic"] = st.color_topic;
  if (!st.accel_topic.empty()) src.options["accel_topic"] = st.accel_topic;
  if (!st.gyro_topic.empty()) src.options["gyro_topic"] = st.gyro_topic;
  if (!st.imu_topic.empty()) src.options["imu_topic"] = st.imu_topic;
  src.options["timestamps"] = "header.stamp";
  src.options["timestamp_domain"] = S.timestamp_domain.empty() ? "unknown" : S.timestamp_domain;
  const bool have_imu_stream = !imu.empty() || !d.accel.empty() || !d.gyro.empty();
  if (have_imu_stream)
    src.options["imu_timestamp_domain"] = S.imu_timestamp_domain.empty() ? "unknown" : S.imu_timestamp_domain;
  if (proc) {
    src.options["source_width"] = std::to_string(S.source_width);
    src.options["source_height"] = std::to_string(S.source_height);
    src.options["source_fx"] = io::format_double(S.source_fx);
    src.options["source_fy"] = io::format_double(S.source_fy);
    src.options["source_cx"] = io::format_double(S.source_cx);
    src.options["source_cy"] = io::format_double(S.source_cy);
    src.options["source_distortion_model"] = S.source_distortion;
    src.options["source_distortion"] = fmt_vec(S.source_coeffs);
    src.options["undistort"] = opt.undistort ? "true" : "false";
    src.options["crop"] = fmt::format("x0={},y0={},w={},h={}", proc->crop_x0(), proc->crop_y0(),
                                      opt.crop_width > 0 ? opt.crop_width : S.source_width,
                                      opt.crop_height > 0 ? opt.crop_height : S.source_height);
    src.options["output_size"] = fmt::format("{}x{}", proc->output().width, proc->output().height);
    if (d.color_fps) src.options["color_fps"] = std::to_string(d.color_fps);
  }
  for (const auto& [label, T] : S.extrinsics) src.options["tf0_" + label] = fmt_pose(T);
  if (!S.extrinsics.empty())
    src.options["tf0_convention"] = "T_stream_ref: x_stream = R x_ref + t (rs2_extrinsics ref->stream)";
  if (S.have_T_I_C) src.options["T_I_C_source"] = T_I_C_source;
  const auto vec = [](const auto& a) { return fmt_vec({a.begin(), a.end()}); };
  if (d.accel_intr) src.options["accel_intrinsic"] = vec(d.accel_intr->data);
  if (d.accel_intr) src.options["accel_noise_variances"] = vec(d.accel_intr->noise_variances);
  if (d.gyro_intr) src.options["gyro_intrinsic"] = vec(d.gyro_intr->data);
  if (d.gyro_intr) src.options["gyro_noise_variances"] = vec(d.gyro_intr->noise_variances);
  if (!imu.empty()) {
    src.options["imu_merge"] = united ? "united topic" : "accel linearly interpolated at gyro stamps";
    if (S.accel_rate_hz > 0) src.options["accel_rate_hz"] = io::format_double(S.accel_rate_hz);
    if (S.gyro_rate_hz > 0) src.options["gyro_rate_hz"] = io::format_double(S.gyro_rate_hz);
  }
  m.sources.push_back(src);
  if (!imu.empty()) {
    ImuInfo ii;
    ii.rate_hz = S.gyro_rate_hz > 0 ? S.gyro_rate_hz : median_rate_hz(imu, imu_stamp);
    if (!(ii.rate_hz > 0)) ii.rate_hz = 1.0;
    m.imu = ii;
    S.warnings.push_back(
        "IMU noise densities unknown (not written to roe.json): import a Kalibr imu.yaml with roe import kalibr, "
        "or set them in the run config");
  }
  if (proc) {
    CameraInfo c;
    const auto& o = proc->output();
    c.width = o.width;
    c.height = o.height;
    c.fx = o.fx;
    c.fy = o.fy;
    c.cx = o.cx;
    c.cy = o.cy;
    if (o.model == image::Distortion::kNone) {
      c.distortion_model = "none";
    } else {
      c.distortion_model = image::distortion_name(o.model);
      c.distortion.assign(o.coeffs.begin(), o.coeffs.end());
    }
    c.T_I_C = T_I_C;
    m.camera = c;
    S.camera = c;
  }
  return m;
}

}  // namespace

ImportRealsenseSummary import_realsense(const fs::path& bag_path, const fs::path& dataset,
                                        const ImportRealsenseOptions& opt, const ProgressCallback& progress) {
  ImportRealsenseSummary S;
  S.dataset = dataset;
  // Refuse an existing output before the (possibly long) read.
  io::OutputDir out(dataset, opt.force, {bag_path});
  io::BagOpenOptions bo;
  bo.allow_missing_files = opt.salvage;
  const auto bag = io::open_bag(bag_path, bo);
  const io::RealsenseStreams st =
      io::discover_realsense_bag(*bag, {opt.color_topic, opt.accel_topic, opt.gyro_topic, opt.imu_topic});
  S.layout = st.layout;
  S.color_topic = st.color_topic;
  S.accel_topic = st.accel_topic;
  S.gyro_topic = st.gyro_topic;
  S.imu_topic = st.imu_topic;
  S.warnings = st.warnings;
  fail_if_damaged(*bag, opt.salvage);

  io::RealsenseRecording d = io::read_realsense_recording(*bag, st);
  fail_if_damaged(*bag, opt.salvage);
  const bool united = !d.united.empty();
  const std::vector<ImuSample> imu = merge_imu(d, st, bag->name(), S);
  const bool have_imu_stream = !imu.empty() || !d.accel.empty() || !d.gyro.empty();
  check_clocks(d, st, have_imu_stream, S);
  std::optional<image::FrameProcessor> proc = make_frame_processor(d, st, opt, *bag, S);

  std::vector<CameraFrame> frames;
  if (proc && opt.images && !st.color_topic.empty())
    frames = write_images(*bag, st.color_topic, *proc, out.file("mav0/cam0/data/x").parent_path(), opt, progress, S);
  S.frames = frames.size();
  fail_if_damaged(*bag, opt.salvage);
  for (const auto& w : bag->warnings()) S.warnings.push_back(w.file + ": " + w.text());
  if (S.frames == 0 && imu.empty())
    throw InputError("nothing to import: no colour frame and no IMU sample could be read", {bag->name()});

  std::string T_I_C_source;
  const Pose T_I_C = camera_imu_extrinsics(d, st, !imu.empty(), S, T_I_C_source);
  const DatasetManifest m = build_manifest(bag_path, *bag, st, d, imu, proc, T_I_C, T_I_C_source, united, opt, S);
  if (!frames.empty()) store::write_cam_csv(out.file("mav0/cam0/data.csv"), frames);
  if (!imu.empty()) store::write_imu_csv(out.file("mav0/imu0/data.csv"), imu);
  if (!d.accel.empty()) write_xyz_csv(out.file("mav0/imu0_raw/accel.csv"), d.accel, "m s^-2");
  if (!d.gyro.empty()) write_xyz_csv(out.file("mav0/imu0_raw/gyro.csv"), d.gyro, "rad s^-1");
  store::write_manifest(m, out.file("roe.json"));
  out.commit();
  for (const auto& w : S.warnings) log::warn("{}", w);
  return S;
}

}  // namespace roe::app
