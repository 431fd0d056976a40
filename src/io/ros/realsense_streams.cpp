// Stream discovery for RealSense bags of every generation (include/roe/io/ros/realsense_streams.hpp).
#include "roe/io/ros/realsense_streams.hpp"

#include <algorithm>
#include <set>

#include <fmt/format.h>

#include "roe/core/error.hpp"

namespace roe::io {
namespace {

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

struct Context {
  std::map<std::string, std::string> type;  // topic → type
  const RealsenseTopicChoice& opt;
  std::map<std::string, std::string> names;  // recorder sensor names
  bool has(const std::string& t) const { return type.count(t) != 0; }
};

void discover_recorder(const Context& c, RealsenseStreams& S) {
  S.layout = "recorder";
  // Streams by kind; prefer the sensor with the expected name, else the lowest index.
  auto pick = [&](const std::string& kind, const std::string& sensor_name, const std::string& leaf) {
    std::vector<RecorderStream> cands;
    for (const auto& [t, ty] : c.type) {
      auto s = recorder_stream(t);
      if (s && s->kind == kind && t == s->prefix + leaf) cands.push_back(*s);
    }
    auto name_of = [&](const RecorderStream& s) {
      const auto it = c.names.find(s.sensor);
      return it == c.names.end() ? std::string() : it->second;
    };
    std::stable_sort(cands.begin(), cands.end(), [&](const RecorderStream& a, const RecorderStream& b) {
      const bool na = name_of(a) == sensor_name, nb = name_of(b) == sensor_name;
      return na != nb ? na : a.prefix < b.prefix;
    });
    return cands.empty() ? std::optional<RecorderStream>() : std::optional<RecorderStream>(cands.front());
  };
  // A chosen IMU topic of the recorder layout: its stream's info, intrinsics and tf/0 come with it.
  auto imu_stream = [&](const std::string& t) {
    const auto s = recorder_stream(t);
    return s && t == s->prefix + "/imu/data" ? s : std::optional<RecorderStream>();
  };
  std::optional<RecorderStream> color;
  if (!c.opt.color_topic.empty()) {
    color = recorder_stream(c.opt.color_topic);
    if (!color || !c.has(color->prefix + "/image/data"))
      throw InputError("colour topic \"" + c.opt.color_topic + "\" is not an image stream of this bag (image topics: " +
                       join_or_none(S.image_topics) + ")");
  } else {
    color = pick("Color", "RGB Camera", "/image/data");
  }
  const auto accel = c.opt.accel_topic.empty() ? pick("Accel", "Motion Module", "/imu/data") : imu_stream(c.opt.accel_topic);
  const auto gyro = c.opt.gyro_topic.empty() ? pick("Gyro", "Motion Module", "/imu/data") : imu_stream(c.opt.gyro_topic);
  if (color) {
    S.color_topic = color->prefix + "/image/data";
    S.camera_info_topic = color->prefix + "/info/camera_info";
    S.color_info_topic = color->prefix + "/info";
    S.metadata_topic = color->prefix + "/image/metadata";
  }
  S.accel_topic = c.opt.accel_topic;
  S.gyro_topic = c.opt.gyro_topic;
  S.imu_topic = c.opt.imu_topic;
  if (accel) {
    S.accel_topic = accel->prefix + "/imu/data";
    S.accel_info_topic = accel->prefix + "/info";
    S.accel_intr_topic = accel->prefix + "/imu_intrinsic";
    S.accel_meta_topic = accel->prefix + "/imu/metadata";
  }
  if (gyro) {
    S.gyro_topic = gyro->prefix + "/imu/data";
    S.gyro_info_topic = gyro->prefix + "/info";
    S.gyro_intr_topic = gyro->prefix + "/imu_intrinsic";
    S.gyro_meta_topic = gyro->prefix + "/imu/metadata";
  }
}

void discover_ros(const Context& c, RealsenseStreams& S) {
  S.layout = "realsense-ros";
  // Colour: an Image/CompressedImage topic <ns>/color/image_raw (or image_rect_raw, or their
  // /compressed), any namespace: /camera first, then in name order; raw before compressed.
  std::string color_ns;
  if (!c.opt.color_topic.empty()) {
    if (!c.has(c.opt.color_topic))
      throw InputError("colour topic \"" + c.opt.color_topic + "\" is not in the bag (image topics: " +
                       join_or_none(S.image_topics) + ")");
    S.color_topic = c.opt.color_topic;
  } else {
    struct Cand {
      std::string topic, ns;
      int rank;
    };
    std::vector<Cand> cands;
    for (const auto& t : S.image_topics) {
      const bool compressed = ends_with(t, "/compressed");
      const std::string base = compressed ? t.substr(0, t.size() - 11) : t;
      for (const auto& [leaf, rank] : {std::pair{"/color/image_raw", 0}, std::pair{"/color/image_rect_raw", 1}})
        if (ends_with(base, leaf))
          cands.push_back({t, base.substr(0, base.size() - std::string(leaf).size()), rank + (compressed ? 2 : 0)});
    }
    // /camera (realsense-ros 2.x default) and /camera/camera (4.x default) before other namespaces.
    const auto default_ns = [](const std::string& ns) { return ns == "/camera" || ns == "/camera/camera"; };
    std::stable_sort(cands.begin(), cands.end(), [&](const Cand& a, const Cand& b) {
      if (a.ns != b.ns) return default_ns(a.ns) != default_ns(b.ns) ? default_ns(a.ns) : a.ns < b.ns;
      return a.rank < b.rank;
    });
    if (!cands.empty()) {
      S.color_topic = cands.front().topic;
      std::set<std::string> others;
      for (const auto& x : cands)
        if (x.ns != cands.front().ns) others.insert(x.topic);
      if (!others.empty())
        S.warnings.push_back(fmt::format("colour images of several cameras: using {} (others: {}); choose with "
                                         "--color-topic",
                                         S.color_topic, join_or_none({others.begin(), others.end()})));
    }
  }
  if (!S.color_topic.empty()) {
    std::string base = S.color_topic;
    if (ends_with(base, "/compressed")) base = base.substr(0, base.size() - 11);
    S.camera_info_topic = base.substr(0, base.rfind('/')) + "/camera_info";
    if (!c.has(S.camera_info_topic)) S.camera_info_topic.clear();
    color_ns = ros_namespace_of(base);
  }
  // IMU: sensor_msgs/Imu topics <ns>/accel/sample, <ns>/gyro/sample, <ns>/imu (unite_imu_method),
  // all from one namespace: the colour topic's when it has IMU topics, else a default one, else the first.
  std::map<std::string, std::map<std::string, std::string>> imu_by_ns;  // ns → {accel|gyro|imu → topic}
  for (const auto& t : S.imu_typed_topics)
    for (const auto& [leaf, kind] :
         {std::pair{"/accel/sample", "accel"}, std::pair{"/gyro/sample", "gyro"}, std::pair{"/imu", "imu"}})
      if (ends_with(t, leaf)) imu_by_ns[t.substr(0, t.size() - std::string(leaf).size())][kind] = t;
  if (!imu_by_ns.empty()) {
    const std::string imu_ns = imu_by_ns.count(color_ns) && !S.color_topic.empty() ? color_ns
                               : imu_by_ns.count("/camera/camera")               ? std::string("/camera/camera")
                               : imu_by_ns.count("/camera")                      ? std::string("/camera")
                                                                                 : imu_by_ns.begin()->first;
    if (imu_by_ns.size() > 1 && (c.opt.accel_topic.empty() || c.opt.gyro_topic.empty()) && c.opt.imu_topic.empty()) {
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
  if (!c.opt.accel_topic.empty()) S.accel_topic = c.opt.accel_topic;
  if (!c.opt.gyro_topic.empty()) S.gyro_topic = c.opt.gyro_topic;
  if (!c.opt.imu_topic.empty()) S.imu_topic = c.opt.imu_topic;
  // realsense2_camera/IMUInfo beside the chosen topics (<ns>/accel/imu_info, <ns>/gyro/imu_info).
  auto info_beside = [&](const std::string& t, const char* sample_leaf, const char* info_leaf) {
    std::string info;
    if (ends_with(t, sample_leaf)) info = t.substr(0, t.size() - std::string(sample_leaf).size()) + info_leaf;
    else if (ends_with(t, "/imu")) info = t.substr(0, t.size() - 4) + info_leaf;
    return c.has(info) && c.type.at(info) == "realsense2_camera/IMUInfo" ? info : std::string();
  };
  S.accel_intr_topic = info_beside(!S.accel_topic.empty() ? S.accel_topic : S.imu_topic, "/accel/sample", "/accel/imu_info");
  S.gyro_intr_topic = info_beside(!S.gyro_topic.empty() ? S.gyro_topic : S.imu_topic, "/gyro/sample", "/gyro/imu_info");
  if (c.has("/tf_static") && c.type.at("/tf_static") == "tf2_msgs/TFMessage") S.tf_static_topic = "/tf_static";
  // No colour image (recorded without images): the colour CameraInfo beside the IMU still gives the
  // camera model and, with /tf_static, T_I_C.
  const std::string& imu_any = !S.imu_topic.empty() ? S.imu_topic : S.gyro_topic;
  if (S.color_topic.empty() && !imu_any.empty()) {
    const std::size_t cut = imu_any.rfind(imu_any == S.imu_topic ? "/imu" : "/gyro/sample");
    const std::string info = imu_any.substr(0, cut) + "/color/camera_info";
    if (c.has(info) && c.type.at(info) == "sensor_msgs/CameraInfo") S.camera_info_topic = info;
  }
}

}  // namespace

std::optional<RecorderStream> recorder_stream(const std::string& topic) {
  const auto parts = split_path(topic);
  if (parts.size() < 4 || !starts_with(parts[0], "device_") || !starts_with(parts[1], "sensor_")) return {};
  const std::string& s = parts[2];
  const std::size_t us = s.rfind('_');
  if (us == std::string::npos || us == 0 || us + 1 >= s.size()) return {};
  if (!std::all_of(s.begin() + static_cast<long>(us) + 1, s.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return {};
  RecorderStream r;
  r.sensor = "/" + parts[0] + "/" + parts[1];
  r.prefix = r.sensor + "/" + s;
  r.kind = s.substr(0, us);
  r.label = s;
  return r;
}

std::optional<std::string> recorder_sensor_info(const std::string& topic) {
  const auto p = split_path(topic);
  if (p.size() == 3 && starts_with(p[0], "device_") && starts_with(p[1], "sensor_") && p[2] == "info")
    return "/" + p[0] + "/" + p[1];
  return {};
}

RealsenseStreams discover_realsense_streams(const std::vector<TopicType>& topics, const RealsenseTopicChoice& choice,
                                            const std::map<std::string, std::string>& sensor_names) {
  Context c{{}, choice, sensor_names};
  RealsenseStreams S;
  bool recorder = false;
  for (const auto& t : topics) {
    c.type[t.topic] = t.type;
    recorder = recorder || recorder_stream(t.topic).has_value();
  }
  for (const auto& [t, ty] : c.type) {
    if (ty == "sensor_msgs/Image" || ty == "sensor_msgs/CompressedImage") S.image_topics.push_back(t);
    if (ty == "sensor_msgs/Imu") S.imu_typed_topics.push_back(t);
  }
  // An explicitly chosen IMU topic must exist and be a sensor_msgs/Imu topic.
  for (const auto& [t, option] : {std::pair{choice.accel_topic, "--accel-topic"}, std::pair{choice.gyro_topic, "--gyro-topic"},
                                  std::pair{choice.imu_topic, "--imu-topic"}}) {
    if (t.empty()) continue;
    if (!c.has(t))
      throw InputError(fmt::format("{} \"{}\" is not in the bag (sensor_msgs/Imu topics in the bag: {})", option, t,
                                   join_or_none(S.imu_typed_topics)));
    if (c.type.at(t) != "sensor_msgs/Imu")
      throw InputError(fmt::format("{} \"{}\" has type {}, expected sensor_msgs/Imu", option, t, c.type.at(t)));
  }
  if (recorder) discover_recorder(c, S);
  else discover_ros(c, S);
  if (S.color_topic.empty() && S.gyro_topic.empty() && S.imu_topic.empty()) {
    std::string list;
    for (const auto& [t, ty] : c.type) list += "\n  " + t + " (" + ty + ")";
    throw InputError("no colour image and no IMU stream found (RealSense recorder layout /device_0/sensor_N/Color_0/"
                     "image/data, or realsense-ros <ns>/color/image_raw, <ns>/imu, <ns>/gyro/sample); image topics: " +
                     join_or_none(S.image_topics) + " (choose one with --color-topic); sensor_msgs/Imu topics: " +
                     join_or_none(S.imu_typed_topics) + " (choose with --imu-topic or --accel-topic and "
                     "--gyro-topic); topics in the bag:" + (list.empty() ? std::string(" none") : list));
  }
  if (!S.color_topic.empty()) {
    const std::string& ty = c.type.at(S.color_topic);
    if (ty != "sensor_msgs/Image" && ty != "sensor_msgs/CompressedImage")
      throw InputError("topic " + S.color_topic + " has type " + ty + ", expected sensor_msgs/Image or CompressedImage");
  } else {
    S.warnings.push_back("no colour image stream found: cam0 not written; image topics in the bag: " +
                         join_or_none(S.image_topics) + (S.image_topics.empty() ? "" : " (choose one with --color-topic)"));
  }
  return S;
}

std::optional<Pose> static_transform(const std::vector<ros::StampedTransform>& tfs, const std::string& target,
                                     const std::string& source) {
  std::map<std::string, std::pair<std::string, Pose>> up;  // child → (parent, T_parent_child)
  for (const auto& t : tfs)
    up[t.child_frame_id] = {t.header.frame_id, Pose(t.transform.q.normalized(), t.transform.t)};
  // T_root_frame and the root, following parents (at most one visit per frame: no cycles).
  auto to_root = [&](std::string f) {
    Pose T;
    std::set<std::string> seen;
    while (up.count(f) && seen.insert(f).second) {
      const auto& [parent, T_p_c] = up.at(f);
      T = T_p_c * T;
      f = parent;
    }
    return std::pair{f, T};
  };
  const auto [root_t, T_root_target] = to_root(target);
  const auto [root_s, T_root_source] = to_root(source);
  if (root_t != root_s) return std::nullopt;
  return T_root_target.inverse() * T_root_source;
}

}  // namespace roe::io
