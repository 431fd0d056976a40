// roe import realsense: RealSense recorder bags and realsense-ros bags → dataset folder.
#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include <fmt/format.h>

#include "roe/app/import.hpp"
#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/image/frame_processor.hpp"
#include "roe/io/csv.hpp"
#include "roe/io/dataset.hpp"
#include "roe/io/output.hpp"
#include "roe/io/ros_msgs.hpp"
#include "roe/io/rosbag.hpp"

namespace roe::app {
namespace {

namespace bag = roe::io::bag;
namespace ros = roe::io::ros;
using Vec3Stamped = std::pair<Timestamp, Eigen::Vector3d>;

std::vector<std::string> split_path(const std::string& topic) {
  std::vector<std::string> parts;
  std::size_t p = 0;
  while (p <= topic.size()) {
    const std::size_t q = topic.find('/', p);
    const std::string s = topic.substr(p, q == std::string::npos ? std::string::npos : q - p);
    if (!s.empty()) parts.push_back(s);
    if (q == std::string::npos) break;
    p = q + 1;
  }
  return parts;
}

bool starts_with(const std::string& s, const std::string& p) { return s.compare(0, p.size(), p) == 0; }
bool ends_with(const std::string& s, const std::string& p) {
  return s.size() >= p.size() && s.compare(s.size() - p.size(), p.size(), p) == 0;
}

/// A stream of the recorder layout: /device_D/sensor_S/<Name>_<i>.
struct RsStream {
  std::string prefix;   // "/device_0/sensor_1/Color_0"
  std::string sensor;   // "/device_0/sensor_1"
  std::string kind;     // "Color"
  std::string label;    // "Color_0"
};

std::optional<RsStream> recorder_stream(const std::string& topic) {
  const auto parts = split_path(topic);
  if (parts.size() < 4 || !starts_with(parts[0], "device_") || !starts_with(parts[1], "sensor_")) return {};
  const std::string& s = parts[2];
  const std::size_t us = s.rfind('_');
  if (us == std::string::npos || us == 0 || us + 1 >= s.size()) return {};
  if (!std::all_of(s.begin() + static_cast<long>(us) + 1, s.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return {};
  RsStream r;
  r.sensor = "/" + parts[0] + "/" + parts[1];
  r.prefix = r.sensor + "/" + s;
  r.kind = s.substr(0, us);
  r.label = s;
  return r;
}

std::string where_msg(const bag::Reader& r, const bag::MessageView& m) {
  return fmt::format("{}: {} (chunk at byte {})", r.name(), m.connection->topic, m.chunk_offset);
}

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
void sort_unique(std::vector<Vec3Stamped>& v, std::size_t& dropped) {
  std::stable_sort(v.begin(), v.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  const std::size_t n = v.size();
  v.erase(std::unique(v.begin(), v.end(), [](const auto& a, const auto& b) { return a.first == b.first; }), v.end());
  dropped += n - v.size();
}

double median_rate(const std::vector<Vec3Stamped>& v) {
  return median_rate_hz(v, [](const Vec3Stamped& x) { return x.first; });
}

/// "a, b, c", or "none".
std::string join_or_none(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s.empty() ? "none" : s;
}

/// realsense-ros namespace of an image topic: what precedes its last two names
/// ("/d455/color/image_raw" → "/d455", "/color/image_raw" → "").
std::string ros_namespace_of(const std::string& image_topic) {
  const std::size_t p = image_topic.rfind('/');
  if (p == std::string::npos || p == 0) return {};
  const std::size_t q = image_topic.rfind('/', p - 1);
  return q == std::string::npos ? std::string() : image_topic.substr(0, q);
}

/// "byte N: what; K problem(s)", naming the most specific damage (bag::Reader::damage).
std::string damage_text(const bag::Reader& r) {
  const auto d = r.damage();
  if (d.empty()) return {};
  return fmt::format("byte {}: {}; {} problem(s)", d.front().offset, d.front().message, d.size());
}

/// Every damage on its own line, in file order, when there are several (else "").
std::string damage_list(const bag::Reader& r) {
  const auto d = r.damage();
  if (d.size() < 2) return {};
  std::string s = "\nproblems found:";
  for (const auto& w : r.warnings())
    if (w.damage) s += fmt::format("\n  byte {}: {}", w.offset, w.message);
  return s;
}

void write_xyz_csv(const fs::path& file, const std::vector<Vec3Stamped>& v, const char* unit) {
  io::CsvWriter w;
  w.header({"timestamp [ns]", std::string("x [") + unit + "]", std::string("y [") + unit + "]",
            std::string("z [") + unit + "]"},
           "#");
  for (const auto& [t, x] : v) w.add(static_cast<std::int64_t>(t)).add(x.x()).add(x.y()).add(x.z()).end_row();
  w.write(file);
}

}  // namespace

std::vector<ImuSample> merge_accel_gyro(const std::vector<Vec3Stamped>& accel, const std::vector<Vec3Stamped>& gyro,
                                        std::size_t* dropped) {
  std::vector<ImuSample> out;
  out.reserve(gyro.size());
  std::size_t n_drop = 0, j = 0;
  for (const auto& [t, w] : gyro) {
    if (accel.empty() || t < accel.front().first || t > accel.back().first) {
      ++n_drop;
      continue;
    }
    while (j + 1 < accel.size() && accel[j + 1].first < t) ++j;
    // accel[j].first < t <= accel[j+1].first, or t == accel[j].first at the very start.
    ImuSample s;
    s.t_ns = t;
    s.gyro = w;
    if (accel[j].first == t || j + 1 >= accel.size()) {
      s.accel = accel[j].second;
    } else {
      const Timestamp t0 = accel[j].first, t1 = accel[j + 1].first;
      const double a = static_cast<double>(t - t0) / static_cast<double>(t1 - t0);
      s.accel = (1.0 - a) * accel[j].second + a * accel[j + 1].second;
    }
    out.push_back(s);
  }
  if (dropped) *dropped = n_drop;
  return out;
}

nlohmann::json ImportRealsenseSummary::to_json() const {
  nlohmann::json ext = nlohmann::json::object();
  for (const auto& [k, T] : extrinsics)
    ext[k] = {{"p", {T.p.x(), T.p.y(), T.p.z()}}, {"q", {T.q.x(), T.q.y(), T.q.z(), T.q.w()}}};
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

ImportRealsenseSummary import_realsense(const fs::path& bag_path, const fs::path& dataset,
                                        const ImportRealsenseOptions& opt, const ProgressCallback& progress) {
  ImportRealsenseSummary S;
  S.dataset = dataset;
  // Refuse an existing output before the (possibly long) read.
  io::OutputDir out(dataset, opt.force, {bag_path});
  bag::Reader reader(bag_path);
  const auto& conns = reader.connections();
  std::set<std::string> topics;
  for (const auto& c : conns) topics.insert(c.topic);
  const auto type_of = [&](const std::string& t) { return reader.topic_type(t); };
  const auto is_image = [&](const std::string& t) {
    return type_of(t) == "sensor_msgs/Image" || type_of(t) == "sensor_msgs/CompressedImage";
  };
  std::vector<std::string> image_topics, imu_typed_topics;
  for (const auto& t : topics) {
    if (is_image(t)) image_topics.push_back(t);
    if (type_of(t) == "sensor_msgs/Imu") imu_typed_topics.push_back(t);
  }
  // Without --salvage a damaged bag is refused as soon as the damage is known: right after the scan
  // (a truncated bag), after the static pass, and after the images, never after writing everything.
  const auto fail_if_damaged = [&]() {
    if (reader.damaged() && !opt.salvage)
      throw InputError("the bag is damaged (" + damage_text(reader) +
                           "); use --salvage to import the part that is intact" + damage_list(reader),
                       {reader.name()});
  };
  // An explicitly chosen IMU topic must exist and be a sensor_msgs/Imu topic.
  const auto check_imu_option = [&](const std::string& t, const char* option) {
    if (t.empty()) return;
    if (!topics.count(t))
      throw InputError(fmt::format("{} \"{}\" is not in the bag (sensor_msgs/Imu topics in the bag: {})", option, t,
                                   join_or_none(imu_typed_topics)),
                       {reader.name()});
    if (type_of(t) != "sensor_msgs/Imu")
      throw InputError(fmt::format("{} \"{}\" has type {}, expected sensor_msgs/Imu", option, t, type_of(t)),
                       {reader.name()});
  };
  check_imu_option(opt.accel_topic, "--accel-topic");
  check_imu_option(opt.gyro_topic, "--gyro-topic");
  check_imu_option(opt.imu_topic, "--imu-topic");

  // ---- Layout and topics ----------------------------------------------------------------------
  std::map<std::string, std::string> sensor_names;  // "/device_0/sensor_1" → "RGB Camera"
  bool recorder = false;
  for (const auto& t : topics)
    if (recorder_stream(t)) recorder = true;
  if (recorder) {
    reader.for_each(
        [](const bag::Connection& c) {
          const auto p = split_path(c.topic);
          return p.size() == 3 && starts_with(p[0], "device_") && starts_with(p[1], "sensor_") && p[2] == "info" &&
                 c.type == "diagnostic_msgs/KeyValue";
        },
        [&](const bag::MessageView& m) {
          const auto kv = ros::decode_key_value(m.data, where_msg(reader, m));
          if (kv.key == "Name") sensor_names[m.connection->topic.substr(0, m.connection->topic.size() - 5)] = kv.value;
          return true;
        });
  }
  std::string camera_info_topic, color_info_topic, color_tf_topic, accel_tf_topic, metadata_topic;
  std::string accel_info_topic, gyro_info_topic, accel_intr_topic, gyro_intr_topic;
  std::string accel_meta_topic, gyro_meta_topic;  // recorder: imu/metadata (timestamp_domain)
  if (recorder) {
    S.layout = "recorder";
    // Streams by kind; prefer the sensor with the expected name, else the lowest index.
    auto pick = [&](const std::string& kind, const std::string& sensor_name, const std::string& leaf) {
      std::vector<RsStream> cands;
      for (const auto& t : topics) {
        auto s = recorder_stream(t);
        if (s && s->kind == kind && t == s->prefix + leaf) cands.push_back(*s);
      }
      std::stable_sort(cands.begin(), cands.end(), [&](const RsStream& a, const RsStream& b) {
        const bool na = sensor_names[a.sensor] == sensor_name, nb = sensor_names[b.sensor] == sensor_name;
        return na != nb ? na : a.prefix < b.prefix;
      });
      return cands.empty() ? std::optional<RsStream>() : std::optional<RsStream>(cands.front());
    };
    // A chosen IMU topic of the recorder layout: its stream's info, intrinsics and tf/0 come with it.
    auto imu_stream = [&](const std::string& t) {
      const auto s = recorder_stream(t);
      return s && t == s->prefix + "/imu/data" ? s : std::optional<RsStream>();
    };
    std::optional<RsStream> color;
    if (!opt.color_topic.empty()) {
      color = recorder_stream(opt.color_topic);
      if (!color || !topics.count(color->prefix + "/image/data"))
        throw InputError("colour topic \"" + opt.color_topic + "\" is not an image stream of this bag (image topics: " +
                             join_or_none(image_topics) + ")",
                         {reader.name()});
    } else {
      color = pick("Color", "RGB Camera", "/image/data");
    }
    const auto accel = opt.accel_topic.empty() ? pick("Accel", "Motion Module", "/imu/data") : imu_stream(opt.accel_topic);
    const auto gyro = opt.gyro_topic.empty() ? pick("Gyro", "Motion Module", "/imu/data") : imu_stream(opt.gyro_topic);
    if (color) {
      S.color_topic = color->prefix + "/image/data";
      camera_info_topic = color->prefix + "/info/camera_info";
      color_info_topic = color->prefix + "/info";
      color_tf_topic = color->prefix + "/tf/0";
      metadata_topic = color->prefix + "/image/metadata";
    }
    S.accel_topic = opt.accel_topic;
    S.gyro_topic = opt.gyro_topic;
    S.imu_topic = opt.imu_topic;
    if (accel) {
      S.accel_topic = accel->prefix + "/imu/data";
      accel_tf_topic = accel->prefix + "/tf/0";
      accel_info_topic = accel->prefix + "/info";
      accel_intr_topic = accel->prefix + "/imu_intrinsic";
      accel_meta_topic = accel->prefix + "/imu/metadata";
    }
    if (gyro) {
      S.gyro_topic = gyro->prefix + "/imu/data";
      gyro_info_topic = gyro->prefix + "/info";
      gyro_intr_topic = gyro->prefix + "/imu_intrinsic";
      gyro_meta_topic = gyro->prefix + "/imu/metadata";
    }
  } else {
    S.layout = "realsense-ros";
    // Colour: an Image/CompressedImage topic <ns>/color/image_raw (or image_rect_raw, or their
    // /compressed), any namespace: /camera first, then in name order; raw before compressed.
    std::string color_ns;
    if (!opt.color_topic.empty()) {
      if (!topics.count(opt.color_topic))
        throw InputError("colour topic \"" + opt.color_topic + "\" is not in the bag (image topics: " +
                             join_or_none(image_topics) + ")",
                         {reader.name()});
      S.color_topic = opt.color_topic;
    } else {
      struct Cand {
        std::string topic, ns;
        int rank;
      };
      std::vector<Cand> cands;
      for (const auto& t : image_topics) {
        const bool compressed = ends_with(t, "/compressed");
        const std::string base = compressed ? t.substr(0, t.size() - 11) : t;
        for (const auto& [leaf, rank] : {std::pair{"/color/image_raw", 0}, std::pair{"/color/image_rect_raw", 1}})
          if (ends_with(base, leaf))
            cands.push_back({t, base.substr(0, base.size() - std::string(leaf).size()), rank + (compressed ? 2 : 0)});
      }
      std::stable_sort(cands.begin(), cands.end(), [](const Cand& a, const Cand& b) {
        if (a.ns != b.ns) return a.ns == "/camera" || (b.ns != "/camera" && a.ns < b.ns);
        return a.rank < b.rank;
      });
      if (!cands.empty()) {
        S.color_topic = cands.front().topic;
        std::set<std::string> others;
        for (const auto& c : cands)
          if (c.ns != cands.front().ns) others.insert(c.topic);
        if (!others.empty())
          S.warnings.push_back(fmt::format("colour images of several cameras: using {} (others: {}); choose with "
                                           "--color-topic",
                                           S.color_topic, join_or_none({others.begin(), others.end()})));
      }
    }
    if (!S.color_topic.empty()) {
      std::string base = S.color_topic;
      if (ends_with(base, "/compressed")) base = base.substr(0, base.size() - 11);
      camera_info_topic = base.substr(0, base.rfind('/')) + "/camera_info";
      if (!topics.count(camera_info_topic)) camera_info_topic.clear();
      color_ns = ros_namespace_of(base);
    }
    // IMU: sensor_msgs/Imu topics <ns>/accel/sample, <ns>/gyro/sample, <ns>/imu (unite_imu_method),
    // all from one namespace: the colour topic's when it has IMU topics, else /camera, else the first.
    std::map<std::string, std::map<std::string, std::string>> imu_by_ns;  // ns → {accel|gyro|imu → topic}
    for (const auto& t : imu_typed_topics)
      for (const auto& [leaf, kind] : {std::pair{"/accel/sample", "accel"}, std::pair{"/gyro/sample", "gyro"},
                                       std::pair{"/imu", "imu"}})
        if (ends_with(t, leaf)) imu_by_ns[t.substr(0, t.size() - std::string(leaf).size())][kind] = t;
    std::string imu_ns;
    if (!imu_by_ns.empty()) {
      imu_ns = imu_by_ns.count(color_ns) && !S.color_topic.empty() ? color_ns
               : imu_by_ns.count("/camera")                       ? std::string("/camera")
                                                                  : imu_by_ns.begin()->first;
      if (imu_by_ns.size() > 1 && (opt.accel_topic.empty() || opt.gyro_topic.empty()) && opt.imu_topic.empty()) {
        std::vector<std::string> nss;
        for (const auto& kv : imu_by_ns) nss.push_back(kv.first.empty() ? "/" : kv.first);
        S.warnings.push_back(fmt::format("IMU topics under several namespaces ({}): using those of {}; choose with "
                                         "--imu-topic or --accel-topic and --gyro-topic",
                                         join_or_none(nss), imu_ns.empty() ? "/" : imu_ns));
      }
      auto& found = imu_by_ns[imu_ns];
      S.accel_topic = found["accel"];
      S.gyro_topic = found["gyro"];
      S.imu_topic = found["imu"];
    }
    if (!opt.accel_topic.empty()) S.accel_topic = opt.accel_topic;
    if (!opt.gyro_topic.empty()) S.gyro_topic = opt.gyro_topic;
    if (!opt.imu_topic.empty()) S.imu_topic = opt.imu_topic;
    // realsense2_camera/IMUInfo beside the chosen topics (<ns>/accel/imu_info, <ns>/gyro/imu_info).
    auto info_beside = [&](const std::string& t, const char* sample_leaf, const char* info_leaf) {
      std::string info;
      if (ends_with(t, sample_leaf)) info = t.substr(0, t.size() - std::string(sample_leaf).size()) + info_leaf;
      else if (ends_with(t, "/imu")) info = t.substr(0, t.size() - 4) + info_leaf;
      return topics.count(info) ? info : std::string();
    };
    accel_intr_topic = info_beside(!S.accel_topic.empty() ? S.accel_topic : S.imu_topic, "/accel/sample", "/accel/imu_info");
    gyro_intr_topic = info_beside(!S.gyro_topic.empty() ? S.gyro_topic : S.imu_topic, "/gyro/sample", "/gyro/imu_info");
  }
  if (S.color_topic.empty() && S.gyro_topic.empty() && S.imu_topic.empty()) {
    if (reader.damaged())  // e.g. cut inside its first chunk: the topics are in the part that is lost
      throw InputError("the bag is damaged (" + damage_text(reader) +
                           ") and its intact part has no colour image and no IMU stream: nothing to import, "
                           "even with --salvage" + damage_list(reader),
                       {reader.name()});
    std::string list;
    for (const auto& t : topics) list += "\n  " + t + " (" + type_of(t) + ")";
    throw InputError("no colour image and no IMU stream found (RealSense recorder layout /device_0/sensor_N/Color_0/"
                     "image/data, or realsense-ros <ns>/color/image_raw, <ns>/imu, <ns>/gyro/sample); image topics: " +
                         join_or_none(image_topics) + " (choose one with --color-topic); sensor_msgs/Imu topics: " +
                         join_or_none(imu_typed_topics) + " (choose with --imu-topic or --accel-topic and "
                         "--gyro-topic); topics in the bag:" + list,
                     {reader.name()});
  }
  if (!S.color_topic.empty() && !is_image(S.color_topic))
    throw InputError("topic " + S.color_topic + " has type " + type_of(S.color_topic) +
                     ", expected sensor_msgs/Image or CompressedImage", {reader.name()});
  if (S.color_topic.empty())
    S.warnings.push_back("no colour image stream found: cam0 not written; image topics in the bag: " +
                         join_or_none(image_topics) + (image_topics.empty() ? "" : " (choose one with --color-topic)"));
  fail_if_damaged();

  // ---- Pass 1: everything but images ----------------------------------------------------------
  std::optional<ros::CameraInfo> cam_info;
  std::vector<Vec3Stamped> accel, gyro;
  std::vector<ImuSample> united;
  std::map<std::string, std::string> domain_of;  // metadata topic → its first timestamp_domain
  std::optional<ros::ImuIntrinsic> accel_intr, gyro_intr;
  std::uint32_t color_fps = 0, accel_fps = 0, gyro_fps = 0;
  std::map<std::string, ros::Transform> tfs;  // label → tf/0
  std::set<std::string> pass1 = {camera_info_topic, color_info_topic, metadata_topic,   S.accel_topic,
                                 S.gyro_topic,      S.imu_topic,      accel_info_topic, gyro_info_topic,
                                 accel_intr_topic,  gyro_intr_topic,  accel_meta_topic, gyro_meta_topic};
  pass1.erase("");
  reader.for_each(
      [&](const bag::Connection& c) {
        if (pass1.count(c.topic)) return true;
        // Every stream's tf/0 (recorder) for the extrinsics record.
        const auto s = recorder_stream(c.topic);
        return s && c.topic == s->prefix + "/tf/0" && c.type == "geometry_msgs/Transform";
      },
      [&](const bag::MessageView& m) {
        const std::string& t = m.connection->topic;
        const std::string w = where_msg(reader, m);
        if (t == camera_info_topic) {
          if (!cam_info) cam_info = ros::decode_camera_info(m.data, w);
        } else if (t == S.imu_topic) {  // before accel/gyro: a united topic given as one of them too
          const auto imu = ros::decode_imu(m.data, w);
          united.push_back({imu.header.stamp_ns, imu.angular_velocity, imu.linear_acceleration});
        } else if (t == S.accel_topic || t == S.gyro_topic) {
          const auto imu = ros::decode_imu(m.data, w);
          if (t == S.accel_topic) accel.emplace_back(imu.header.stamp_ns, imu.linear_acceleration);
          if (t == S.gyro_topic) gyro.emplace_back(imu.header.stamp_ns, imu.angular_velocity);
        } else if (t == metadata_topic || t == accel_meta_topic || t == gyro_meta_topic) {
          const auto kv = ros::decode_key_value(m.data, w);
          if (kv.key == "timestamp_domain" && !domain_of.count(t)) domain_of[t] = kv.value;
        } else if (t == color_info_topic) {
          color_fps = ros::decode_stream_info(m.data, w).fps;
        } else if (t == accel_info_topic || t == gyro_info_topic) {
          (t == accel_info_topic ? accel_fps : gyro_fps) = ros::decode_stream_info(m.data, w).fps;
        } else if (t == accel_intr_topic || t == gyro_intr_topic) {
          const auto ii = m.connection->type == "realsense_msgs/ImuIntrinsic" ? ros::decode_rs_imu_intrinsic(m.data, w)
                                                                               : ros::decode_rs2_imu_info(m.data, w);
          (t == accel_intr_topic ? accel_intr : gyro_intr) = ii;
        } else {
          const auto s = recorder_stream(t);
          if (s && !tfs.count(s->label)) tfs[s->label] = ros::decode_transform(m.data, w);
        }
        return true;
      });
  fail_if_damaged();

  // ---- IMU --------------------------------------------------------------------------------------
  std::vector<ImuSample> imu;
  const bool used_united = !united.empty();
  std::size_t dup = 0;
  sort_unique(accel, dup);
  sort_unique(gyro, dup);
  S.accel_samples = accel.size();
  S.gyro_samples = gyro.size();
  S.accel_rate_hz = accel_fps ? accel_fps : median_rate(accel);
  S.gyro_rate_hz = gyro_fps ? gyro_fps : median_rate(gyro);
  if (!united.empty()) {
    std::stable_sort(united.begin(), united.end(), [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });
    const std::size_t n = united.size();
    united.erase(std::unique(united.begin(), united.end(), [](const auto& a, const auto& b) { return a.t_ns == b.t_ns; }),
                 united.end());
    dup += n - united.size();
    // The united topic carries the gyro stamps (realsense-ros unite_imu_method): its rate is the gyro's.
    if (gyro.empty()) S.gyro_rate_hz = median_rate_hz(united, [](const ImuSample& x) { return x.t_ns; });
    imu = std::move(united);
  } else if (!accel.empty() && !gyro.empty()) {
    imu = merge_accel_gyro(accel, gyro, &S.gyro_outside_accel);
  } else if (!accel.empty() || !gyro.empty()) {
    S.warnings.push_back("only one of accel/gyro is present: imu0 not written (raw stream kept in imu0_raw)");
  } else if (!S.accel_topic.empty() || !S.gyro_topic.empty() || !S.imu_topic.empty()) {
    S.warnings.push_back(fmt::format(
        "the bag has no IMU stream with samples (no message on {}): imu0 not written, so roe run cannot use this "
        "dataset",
        join_or_none([&] {
          std::vector<std::string> v;
          for (const auto* t : {&S.imu_topic, &S.accel_topic, &S.gyro_topic})
            if (!t->empty()) v.push_back(*t);
          return v;
        }())));
  } else if (!imu_typed_topics.empty()) {
    S.warnings.push_back(
        "the bag has no IMU stream that roe recognises (realsense-ros <ns>/imu, <ns>/accel/sample and "
        "<ns>/gyro/sample; recorder Accel_N/Gyro_N of the Motion Module); sensor_msgs/Imu topics in the bag: " +
        join_or_none(imu_typed_topics) +
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
      throw InputError(fmt::format("non-finite IMU sample at stamp {} ns", s.t_ns), {reader.name()});

  // ---- Clocks: each stream's timestamp_domain -----------------------------------------------------
  const auto domain = [&](const std::string& t) { return domain_of.count(t) ? domain_of.at(t) : std::string(); };
  const std::string color_domain = domain(metadata_topic);
  const std::string accel_domain = domain(accel_meta_topic), gyro_domain = domain(gyro_meta_topic);
  S.imu_timestamp_domain = !gyro_domain.empty() ? gyro_domain : accel_domain;
  if (!accel_domain.empty() && !gyro_domain.empty() && accel_domain != gyro_domain)
    S.warnings.push_back(fmt::format("the accelerometer's header.stamp is in \"{}\" but the gyro's in \"{}\": the "
                                     "merged IMU samples mix two clocks",
                                     accel_domain, gyro_domain));
  S.timestamp_domain = !S.color_topic.empty() ? color_domain : S.imu_timestamp_domain;
  const bool have_imu_stream = !imu.empty() || !accel.empty() || !gyro.empty();
  if (!S.color_topic.empty() && have_imu_stream && !color_domain.empty() && !S.imu_timestamp_domain.empty() &&
      color_domain != S.imu_timestamp_domain)
    S.warnings.push_back(fmt::format(
        "the colour frames are stamped in \"{}\" and the IMU samples in \"{}\": the two clocks are not comparable, "
        "so camera and IMU are not synchronised in this dataset (record with the same timestamp domain, e.g. "
        "global time, or calibrate the offset)",
        color_domain, S.imu_timestamp_domain));

  // ---- Camera model and frame processor ---------------------------------------------------------
  std::optional<image::FrameProcessor> proc;
  // Only reached with --salvage when the bag is damaged: the CameraInfo may be in the part that is lost.
  const std::string lost = reader.damaged() ? " in the intact part of the bag: the bag is damaged (" +
                                                  damage_text(reader) + ")"
                                            : std::string();
  if (!S.color_topic.empty() && !cam_info && !opt.images) {
    S.warnings.push_back("no CameraInfo for the colour stream" + lost + ": no camera section written");
  } else if (!S.color_topic.empty()) {
    if (!cam_info)
      throw InputError("no CameraInfo for the colour stream (expected on " +
                           (camera_info_topic.empty() ? std::string("<color>/camera_info") : camera_info_topic) + ")" +
                           lost + (lost.empty() ? "" : "; --no-images imports the IMU without it") +
                           damage_list(reader),
                       {reader.name()});
    image::CameraModel cm;
    cm.width = static_cast<int>(cam_info->width);
    cm.height = static_cast<int>(cam_info->height);
    cm.fx = cam_info->K[0];
    cm.fy = cam_info->K[4];
    cm.cx = cam_info->K[2];
    cm.cy = cam_info->K[5];
    cm.model = image::parse_distortion(cam_info->distortion_model);
    for (std::size_t i = 0; i < 5 && i < cam_info->D.size(); ++i) cm.coeffs[i] = cam_info->D[i];
    if (cam_info->D.size() > 5)
      for (std::size_t i = 5; i < cam_info->D.size(); ++i)
        if (cam_info->D[i] != 0.0)
          throw InputError(fmt::format("distortion with {} coefficients (rational model?) is not supported",
                                       cam_info->D.size()),
                           {reader.name(), 0, 0, camera_info_topic});
    S.source_width = cm.width;
    S.source_height = cm.height;
    S.source_fx = cm.fx;
    S.source_fy = cm.fy;
    S.source_cx = cm.cx;
    S.source_cy = cm.cy;
    S.source_distortion = cam_info->distortion_model;
    S.source_coeffs = cam_info->D;
    image::ProcessOptions po;
    po.crop_width = opt.crop_width;
    po.crop_height = opt.crop_height;
    po.out_width = opt.out_width;
    po.out_height = opt.out_height;
    po.undistort = opt.undistort;
    po.png_compression = opt.png_compression;
    try {
      proc.emplace(cm, po);
    } catch (const InputError& e) {
      throw InputError(std::string(e.what()) + " (colour stream " + S.color_topic + ")", {reader.name()});
    }
  }

  // ---- Pass 2: images ------------------------------------------------------------------------------
  std::vector<CameraFrame> frames;
  std::size_t dup_frames = 0;
  if (proc && opt.images) {
    const fs::path img_dir = out.file("mav0/cam0/data/x").parent_path();
    std::set<Timestamp> seen;
    std::size_t total = reader.message_count(S.color_topic);
    if (opt.max_frames) total = std::min(total, opt.max_frames);
    const bool compressed = reader.topic_type(S.color_topic) == "sensor_msgs/CompressedImage";
    reader.for_each_topic(
        {S.color_topic},
        [&](const bag::MessageView& m) {
          const std::string w = where_msg(reader, m);
          Timestamp stamp = 0;
          if (compressed) {
            const auto ci = ros::decode_compressed_image(m.data, w);
            stamp = ci.header.stamp_ns;
            if (!seen.insert(stamp).second) {
              ++dup_frames;
              return true;
            }
            const std::string name = std::to_string(stamp) + ".png";
            proc->process_encoded_to_png(ci.data, img_dir / name, w);
            frames.push_back({stamp, name});
          } else {
            const auto im = ros::decode_image(m.data, w);
            stamp = im.header.stamp_ns;
            if (!seen.insert(stamp).second) {
              ++dup_frames;
              return true;
            }
            const std::string name = std::to_string(stamp) + ".png";
            image::RawImage raw{static_cast<int>(im.width), static_cast<int>(im.height), im.encoding, im.step, im.data};
            if (im.is_bigendian && (image::canonical_encoding(im.encoding) == "mono16" || im.encoding == "16UC1"))
              throw InputError(w + ": big-endian 16-bit images are not supported");
            proc->process_to_png(raw, img_dir / name, w);
            frames.push_back({stamp, name});
          }
          if (progress) progress(frames.size(), total);
          return !(opt.max_frames && frames.size() >= opt.max_frames);
        });
    std::sort(frames.begin(), frames.end(), [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });
    if (dup_frames) S.warnings.push_back(fmt::format("{} colour frames with a repeated header.stamp skipped", dup_frames));
  }
  S.frames = frames.size();
  fail_if_damaged();
  for (const auto& w : reader.warnings())
    S.warnings.push_back(fmt::format("{}: byte {}: {}", reader.name(), w.offset, w.message));
  if (S.frames == 0 && imu.empty())
    throw InputError("nothing to import: no colour frame and no IMU sample could be read", {reader.name()});

  // ---- Extrinsics -----------------------------------------------------------------------------------
  for (const auto& [label, tf] : tfs) S.extrinsics[label] = Pose(tf.q.normalized(), tf.t);
  const auto color_label = recorder_stream(S.color_topic);
  const auto accel_label = recorder_stream(S.accel_topic);
  Pose T_I_C;
  if (color_label && accel_label && S.extrinsics.count(color_label->label) && S.extrinsics.count(accel_label->label)) {
    // tf/0 of stream S is rs2_extrinsics(ref → S): x_S = R x_ref + t, i.e. T_S_ref.
    T_I_C = S.extrinsics[accel_label->label] * S.extrinsics[color_label->label].inverse();
    S.have_T_I_C = true;
  } else if (!imu.empty()) {
    S.warnings.push_back(
        "no camera-IMU extrinsics in the bag (realsense-ros /tf_static is not read): camera.T_I_C prior set "
        "to identity; import a Kalibr calibration (roe import kalibr) before running the filter");
  }

  // ---- Write the dataset -------------------------------------------------------------------------
  DatasetManifest m;
  m.name = opt.name.empty() ? bag_path.stem().string() : opt.name;
  SourceRecord src;
  src.kind = recorder ? "realsense-bag" : "ros1-bag";
  src.path = io::provenance_path(bag_path);
  src.sha256 = io::sha256_file(bag_path);
  src.options["layout"] = S.layout;
  if (!S.color_topic.empty()) src.options["color_topic"] = S.color_topic;
  if (!S.accel_topic.empty()) src.options["accel_topic"] = S.accel_topic;
  if (!S.gyro_topic.empty()) src.options["gyro_topic"] = S.gyro_topic;
  if (!S.imu_topic.empty()) src.options["imu_topic"] = S.imu_topic;
  src.options["timestamps"] = "header.stamp";
  src.options["timestamp_domain"] = S.timestamp_domain.empty() ? "unknown" : S.timestamp_domain;
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
    if (color_fps) src.options["color_fps"] = std::to_string(color_fps);
  }
  for (const auto& [label, T] : S.extrinsics) src.options["tf0_" + label] = fmt_pose(T);
  if (!S.extrinsics.empty()) src.options["tf0_convention"] = "T_stream_ref: x_stream = R x_ref + t (rs2_extrinsics ref->stream)";
  if (accel_intr) src.options["accel_intrinsic"] = fmt_vec({accel_intr->data.begin(), accel_intr->data.end()});
  if (accel_intr) src.options["accel_noise_variances"] = fmt_vec({accel_intr->noise_variances.begin(), accel_intr->noise_variances.end()});
  if (gyro_intr) src.options["gyro_intrinsic"] = fmt_vec({gyro_intr->data.begin(), gyro_intr->data.end()});
  if (gyro_intr) src.options["gyro_noise_variances"] = fmt_vec({gyro_intr->noise_variances.begin(), gyro_intr->noise_variances.end()});
  if (!imu.empty()) {
    src.options["imu_merge"] = used_united ? "united topic" : "accel linearly interpolated at gyro stamps";
    if (S.accel_rate_hz > 0) src.options["accel_rate_hz"] = io::format_double(S.accel_rate_hz);
    if (S.gyro_rate_hz > 0) src.options["gyro_rate_hz"] = io::format_double(S.gyro_rate_hz);
  }
  m.sources.push_back(src);
  if (!imu.empty()) {
    ImuInfo ii;
    std::vector<Vec3Stamped> g;
    for (const auto& s : imu) g.emplace_back(s.t_ns, s.gyro);
    ii.rate_hz = S.gyro_rate_hz > 0 ? S.gyro_rate_hz : median_rate(g);
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
  if (!frames.empty()) io::write_cam_csv(out.file("mav0/cam0/data.csv"), frames);
  if (!imu.empty()) io::write_imu_csv(out.file("mav0/imu0/data.csv"), imu);
  if (!accel.empty()) write_xyz_csv(out.file("mav0/imu0_raw/accel.csv"), accel, "m s^-2");
  if (!gyro.empty()) write_xyz_csv(out.file("mav0/imu0_raw/gyro.csv"), gyro, "rad s^-1");
  io::write_manifest(m, out.file("roe.json"));
  out.commit();
  for (const auto& w : S.warnings) log::warn("{}", w);
  return S;
}

}  // namespace roe::app
