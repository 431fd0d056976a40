#include "roe/infer/model.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <opencv2/dnn.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/infer/pose_head.hpp"
#include "roe/infer/rotation.hpp"
#include "roe/io/output.hpp"

namespace roe::infer {
namespace {

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

HostTensor mat_to_tensor(const cv::Mat& m) {
  HostTensor t;
  cv::Mat c = m.isContinuous() ? m : m.clone();
  if (c.depth() != CV_32F) c.convertTo(c, CV_32F);
  if (c.dims > 2) {
    for (int d = 0; d < c.dims; ++d) t.shape.push_back(c.size[d]);
  } else {
    t.shape = {c.rows, static_cast<std::int64_t>(c.cols) * c.channels()};
  }
  const float* p = c.ptr<float>();
  t.f.assign(p, p + t.numel());
  return t;
}

// Pixel-box transform through the (affine, since both K have zero skew) warp homography.
BoxDetection transform_box(const BoxDetection& b, const cv::Matx33d& H) {
  auto map = [&](double x, double y) {
    const cv::Vec3d v = H * cv::Vec3d(x, y, 1.0);
    return cv::Point2d(v[0] / v[2], v[1] / v[2]);
  };
  const cv::Point2d p[4] = {map(b.x1, b.y1), map(b.x2, b.y1), map(b.x1, b.y2), map(b.x2, b.y2)};
  BoxDetection o = b;
  o.x1 = std::min({p[0].x, p[1].x, p[2].x, p[3].x});
  o.x2 = std::max({p[0].x, p[1].x, p[2].x, p[3].x});
  o.y1 = std::min({p[0].y, p[1].y, p[2].y, p[3].y});
  o.y2 = std::max({p[0].y, p[1].y, p[2].y, p[3].y});
  return o;
}

// OpenCV's getParam: the value read with operator>> (so "0.5" reads as 0 for an int), else the default.
template <typename T>
T cfg_param(const std::map<std::string, std::string>& p, const std::string& key, T def) {
  const auto it = p.find(key);
  if (it != p.end()) {
    std::stringstream ss(it->second);
    ss >> def;
  }
  return def;
}

// a * b + c without overflow past 2^62 (nullopt beyond: no real network is that big).
std::optional<std::uint64_t> mul_add(std::uint64_t a, std::uint64_t b, std::uint64_t c) {
  constexpr std::uint64_t kMax = std::uint64_t{1} << 62;
  if (a != 0 && b > kMax / a) return std::nullopt;
  if (a * b > kMax - c) return std::nullopt;
  return a * b + c;
}

using Params = std::map<std::string, std::string>;

// Sections as OpenCV's ReadDarknetFromCfgStream reads them: characters outside '!'..'z' are
// dropped, '#'/';' lines are comments, only "[net]" is the network section. False on a malformed cfg.
bool parse_cfg_sections(const std::string& cfg_text, Params& net, std::vector<Params>& layers) {
  bool in_net = false;
  std::istringstream in(cfg_text);
  for (std::string raw; std::getline(in, raw);) {
    std::string line;
    for (char c : raw)
      if (c > ' ' && c <= 'z') line += c;
    if (line.empty() || line[0] == '#' || line[0] == ';') continue;
    if (line[0] == '[') {
      const auto close = line.find(']');
      if (close == std::string::npos || close < 2) return false;
      in_net = line == "[net]";
      if (!in_net) layers.push_back({{"layer_type", line.substr(1, close - 1)}});
      continue;
    }
    const auto eq = line.find('=');
    if (eq == std::string::npos) return false;
    const std::string key = line.substr(0, eq), value = line.substr(eq + 1);
    if (key.empty() || value.empty()) continue;
    if (in_net) net[key] = value;
    else if (layers.empty()) return false;
    else layers.back()[key] = value;
  }
  return !layers.empty();
}

// "1,2, 3" → numbers (nullopt when one is not a number).
template <typename T>
std::optional<std::vector<T>> cfg_list(const Params& p, const std::string& key) {
  std::vector<T> out;
  const auto it = p.find(key);
  if (it == p.end()) return out;
  std::stringstream ss(it->second);
  for (std::string item; std::getline(ss, item, ',');) {
    std::stringstream one(item);
    T v{};
    if (!(one >> v)) return std::nullopt;
    out.push_back(v);
  }
  return out;
}

}  // namespace

std::vector<YoloHead> darknet_yolo_heads(const std::string& cfg_text, const std::string& source) {
  Params net;
  std::vector<Params> layers;
  if (!parse_cfg_sections(cfg_text, net, layers)) throw InputError("malformed Darknet cfg", {source});
  std::vector<YoloHead> heads;
  for (const Params& p : layers) {
    if (p.at("layer_type") != "yolo") continue;
    const std::string which = "[yolo] #" + std::to_string(heads.size() + 1);
    const auto anchors = cfg_list<float>(p, "anchors");
    const auto mask = cfg_list<int>(p, "mask");
    if (!anchors || !mask || anchors->empty() || anchors->size() % 2 != 0)
      throw InputError(which + ": anchors must be a list of w,h pairs, mask a list of indices", {source});
    YoloHead h;
    h.classes = cfg_param<int>(p, "classes", 0);
    if (h.classes <= 0) throw InputError(which + ": classes must be a positive number", {source});
    std::vector<int> m = *mask;
    if (m.empty())  // Darknet: no mask = every anchor
      for (std::size_t k = 0; k < anchors->size() / 2; ++k) m.push_back(static_cast<int>(k));
    for (int k : m) {
      if (k < 0 || static_cast<std::size_t>(k) >= anchors->size() / 2)
        throw InputError(which + ": mask index " + std::to_string(k) + " has no anchor", {source});
      h.anchors.push_back({(*anchors)[2 * static_cast<std::size_t>(k)], (*anchors)[2 * static_cast<std::size_t>(k) + 1]});
    }
    heads.push_back(std::move(h));
  }
  return heads;
}

std::optional<std::uint64_t> darknet_parameter_count(const std::string& cfg_text) {
  Params net;
  std::vector<Params> layers;
  if (!parse_cfg_sections(cfg_text, net, layers)) return std::nullopt;
  const std::int64_t net_c = cfg_param<std::int64_t>(net, "channels", 3), net_w = cfg_param<std::int64_t>(net, "width", 416),
                     net_h = cfg_param<std::int64_t>(net, "height", 416);
  if (net_c <= 0 || net_w <= 0 || net_h <= 0) return std::nullopt;

  // Output channels per layer (OpenCV's out_channels_vec), following its shape rules.
  std::vector<std::int64_t> out_c(layers.size(), 0);
  std::int64_t c = net_c, w = net_w, h = net_h;
  for (std::size_t i = 0; i < layers.size(); ++i) {
    const Params& p = layers[i];
    const std::string type = p.at("layer_type");
    if (type == "convolutional") {
      const std::int64_t k = cfg_param<std::int64_t>(p, "size", -1), stride = cfg_param<std::int64_t>(p, "stride", 1),
                         filters = cfg_param<std::int64_t>(p, "filters", -1), groups = cfg_param<std::int64_t>(p, "groups", 1);
      std::int64_t padding = cfg_param<std::int64_t>(p, "padding", 0);
      if (cfg_param<int>(p, "pad", 0)) padding = k / 2;
      if (cfg_param<int>(p, "flipped", 0) == 1 || k <= 0 || filters <= 0 || stride <= 0 || groups <= 0 || c <= 0 || c % groups != 0)
        return std::nullopt;
      c = filters;
      w = (w - k + 2 * padding) / stride + 1;
      h = (h - k + 2 * padding) / stride + 1;
    } else if (type == "connected") {
      const std::int64_t output = cfg_param<std::int64_t>(p, "output", 1);
      if (output <= 0) return std::nullopt;
      if (i > 0 && w > 1) out_c[i - 1] = c * w * h;
      c = output;
      w = h = 1;
    } else if (type == "maxpool") {
      const std::int64_t k = cfg_param<std::int64_t>(p, "size", 2), stride = cfg_param<std::int64_t>(p, "stride", 2),
                         padding = cfg_param<std::int64_t>(p, "padding", k - 1);
      if (stride <= 0) return std::nullopt;
      w = (w - k + padding) / stride + 1;
      h = (h - k + padding) / stride + 1;
    } else if (type == "avgpool") {
      w = h = 1;
    } else if (type == "route") {
      const auto it = p.find("layers");
      if (it == p.end()) return std::nullopt;
      std::stringstream ss(it->second);
      c = 0;
      for (std::string item; std::getline(ss, item, ',');) {
        std::stringstream one(item);
        std::int64_t idx = 0;
        if (!(one >> idx)) return std::nullopt;
        if (idx < 0) idx += static_cast<std::int64_t>(i);
        if (idx < 0 || idx >= static_cast<std::int64_t>(i)) return std::nullopt;
        c += out_c[static_cast<std::size_t>(idx)];
      }
      // `groups=G group_id=k` (YOLOv4-tiny) passes on one of G channel groups, as OpenCV's importer does.
      const std::int64_t route_groups = cfg_param<std::int64_t>(p, "groups", 1);
      if (route_groups <= 0 || c % route_groups != 0) return std::nullopt;
      c /= route_groups;
    } else if (type == "reorg") {
      const std::int64_t stride = cfg_param<std::int64_t>(p, "stride", 2);
      if (stride <= 0) return std::nullopt;
      c *= stride * stride;
      w /= stride;
      h /= stride;
    } else if (type == "upsample") {
      const std::int64_t stride = cfg_param<std::int64_t>(p, "stride", 1);
      w *= stride;
      h *= stride;
    } else if (type == "softmax" || type == "dropout" || type == "cost" || type == "region" || type == "shortcut" ||
               type == "scale_channels" || type == "yolo") {
      // shape unchanged
    } else {
      return std::nullopt;  // OpenCV: "Unknown layer type"
    }
    if (c <= 0 || c > (std::int64_t{1} << 40)) return std::nullopt;
    out_c[i] = c;
  }

  // Parameters in the order OpenCV's ReadDarknetFromWeightsStream reads them.
  std::uint64_t total = 0;
  for (std::size_t i = 0; i < layers.size(); ++i) {
    const Params& p = layers[i];
    const std::string type = p.at("layer_type");
    if (type != "convolutional" && type != "connected") continue;
    const bool bn = cfg_param<int>(p, "batch_normalize", 0) == 1;
    const std::uint64_t in_c = static_cast<std::uint64_t>(i == 0 ? net_c : out_c[i - 1]);
    std::uint64_t filters = 0, per_filter = 0;
    if (type == "convolutional") {
      const auto k = static_cast<std::uint64_t>(cfg_param<std::int64_t>(p, "size", -1));
      filters = static_cast<std::uint64_t>(cfg_param<std::int64_t>(p, "filters", -1));
      const auto groups = static_cast<std::uint64_t>(cfg_param<std::int64_t>(p, "groups", 1));
      const auto kk = mul_add(k, k, 0);
      if (!kk) return std::nullopt;
      const auto pf = mul_add(in_c / groups, *kk, bn ? 4 : 1);  // weights + bias (+ scale, mean, variance)
      if (!pf) return std::nullopt;
      per_filter = *pf;
    } else {
      filters = static_cast<std::uint64_t>(cfg_param<std::int64_t>(p, "output", 1));
      const std::uint64_t inputs = i == 0 ? static_cast<std::uint64_t>(net_c * net_w * net_h) : in_c;
      per_filter = inputs + (bn ? 4 : 1);
    }
    const auto t = mul_add(filters, per_filter, total);
    if (!t) return std::nullopt;
    total = *t;
  }
  return total;
}

void check_darknet_weights(const fs::path& cfg, const fs::path& weights) {
  const auto params = darknet_parameter_count(io::read_file(cfg));
  if (!params) return;  // OpenCV refuses the cfg with its own message
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(weights, ec);
  if (ec) throw InputError("cannot read the Darknet weights file: " + ec.message(), {weights.string()});
  std::int32_t head[3] = {0, 0, 0};
  if (size >= sizeof head) {
    std::ifstream f(weights, std::ios::binary);
    f.read(reinterpret_cast<char*>(head), sizeof head);
    if (!f) throw InputError("cannot read the Darknet weights file", {weights.string()});
  }
  const std::int64_t major = head[0], minor = head[1];
  if (major > 1000 || minor > 1000) return;  // transposed weights: OpenCV refuses them itself
  // Header: major, minor, revision (int32), then "seen" as int64 from version 0.2 on, else int32.
  const std::uint64_t header = major * 10 + minor >= 2 ? 20 : 16;
  const std::uint64_t expected = header + 4 * *params;
  if (size == expected) return;
  const std::string sizes = "the Darknet weights file has " + std::to_string(size) + " bytes, but the layers of " +
                            cfg.filename().string() + " need " + std::to_string(expected) + " (a " + std::to_string(header) +
                            "-byte header + " + std::to_string(*params) + " float32 parameters)";
  if (size < expected) throw InputError(sizes + ": the file is truncated", {weights.string()});
  throw InputError(sizes + ": " + std::to_string(size - expected) + " byte(s) too many (weights of another cfg?)", {weights.string()});
}

nlohmann::json SelfTestReport::to_json() const {
  nlohmann::json d = nlohmann::json::object(), p = nlohmann::json::object();
  for (const auto& [k, v] : detector) d[k] = v;
  for (const auto& [k, v] : pose) p[k] = v;
  return {{"detector_max_scaled_diff", d}, {"detector_atol", detector_atol}, {"pose_max_abs_diff", p}, {"pose_atol", pose_atol}};
}

struct PoetModel::Impl {
  PoetBundle b;
  ModelOptions opt;
  cv::dnn::Net net;
  std::vector<std::string> yolo_outputs;  ///< OpenCV names of the convolutions feeding the [yolo] layers
  std::vector<YoloHead> yolo_heads;       ///< their anchors and classes, same order
  std::unique_ptr<PoseHead> head;
  SelfTestReport report;
  // camera
  bool camera_set = false;
  int cam_w = 0, cam_h = 0;
  std::optional<Intrinsics> cam_K;
  bool warp = false;
  cv::Matx33d H = cv::Matx33d::eye();  // dataset pixels → network pixels

  cv::Mat decode(const std::string& bytes, const std::string& source) const {
    cv::Mat buf(1, static_cast<int>(bytes.size()), CV_8U, const_cast<char*>(bytes.data()));
    cv::Mat img = cv::imdecode(buf, cv::IMREAD_COLOR);
    if (img.empty()) throw InputError("cannot decode the image (PNG/JPEG expected)", {source});
    return img;
  }

  // 8-bit BGR image at the network size → normalised NCHW float blob.
  HostTensor to_blob(const cv::Mat& bgr) const {
    cv::Mat img;
    if (b.image.rgb) cv::cvtColor(bgr, img, cv::COLOR_BGR2RGB);
    else img = bgr;
    img.convertTo(img, CV_32FC3, b.image.scale);
    std::vector<cv::Mat> ch;
    cv::split(img, ch);
    HostTensor t;
    t.shape = {1, 3, img.rows, img.cols};
    t.f.resize(t.numel());
    const std::size_t plane = static_cast<std::size_t>(img.rows) * img.cols;
    for (int c = 0; c < 3; ++c) {
      cv::Mat dst(img.rows, img.cols, CV_32F, t.f.data() + c * plane);
      ch[c].convertTo(dst, CV_32F, 1.0 / b.image.std[c], -b.image.mean[c] / b.image.std[c]);
    }
    return t;
  }

  std::vector<cv::Mat> forward_net(const HostTensor& blob, const std::vector<std::string>& names) {
    const int sizes[4] = {static_cast<int>(blob.shape[0]), static_cast<int>(blob.shape[1]), static_cast<int>(blob.shape[2]),
                          static_cast<int>(blob.shape[3])};
    cv::Mat in(4, sizes, CV_32F, const_cast<float*>(blob.f.data()));
    net.setInput(in);
    std::vector<cv::Mat> outs;
    std::vector<cv::String> n(names.begin(), names.end());
    net.forward(outs, n);
    return outs;
  }
};

PoetModel::PoetModel(PoetBundle bundle, ModelOptions options) : impl_(std::make_unique<Impl>()) {
  auto& m = *impl_;
  m.b = std::move(bundle);
  m.opt = std::move(options);
  if (m.opt.warp != "auto" && m.opt.warp != "on" && m.opt.warp != "off")
    throw InputError("--warp must be auto, on or off, got \"" + m.opt.warp + "\"");
  if (m.b.detector == DetectorKind::kDarknet) {
    check_darknet_weights(m.b.darknet.cfg, m.b.darknet.weights);
    try {
      m.net = cv::dnn::readNetFromDarknet(m.b.darknet.cfg.string(), m.b.darknet.weights.string());
    } catch (const cv::Exception& e) {
      throw InputError(std::string("OpenCV cannot load the Darknet detector: ") + e.what(), {m.b.darknet.cfg.string()});
    }
    if (m.net.empty()) throw InputError("OpenCV loaded an empty Darknet network", {m.b.darknet.cfg.string()});
    m.net.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
    m.net.setPreferableTarget(cv::dnn::DNN_TARGET_CPU);
    // The boxes are decoded from the raw convolution before each [yolo] layer with PoET's rule
    // (decode_yolo_head), not taken from OpenCV's Region layer, which decodes them differently.
    for (const auto& name : m.net.getLayerNames()) {
      const int id = m.net.getLayerId(name);
      if (m.net.getLayer(id)->type != "Region") continue;
      // OpenCV's importer feeds the Region layer a Permute (to NHWC) of the convolution, and the
      // network input (for the image size): take the convolution itself, in NCHW.
      auto inputs = m.net.getLayerInputs(id);
      if (!inputs.empty() && inputs[0] && inputs[0]->type == "Permute")
        inputs = m.net.getLayerInputs(m.net.getLayerId(inputs[0]->name));
      // A linear convolution (PoET's heads), or its batch norm: the raw values PoET's decoding takes.
      if (inputs.empty() || !inputs[0] || (inputs[0]->type != "Convolution" && inputs[0]->type != "BatchNorm"))
        throw InputError("the [yolo] layer " + name + " does not follow a convolution with activation=linear" +
                             (inputs.empty() || !inputs[0] ? std::string() : " (it follows " + inputs[0]->type + ")"),
                         {m.b.darknet.cfg.string()});
      m.yolo_outputs.push_back(inputs[0]->name);
    }
    m.yolo_heads = darknet_yolo_heads(io::read_file(m.b.darknet.cfg), m.b.darknet.cfg.string());
    if (m.yolo_outputs.empty())
      throw InputError("the Darknet cfg has no [yolo] layer", {m.b.darknet.cfg.string()});
    if (m.yolo_heads.size() != m.yolo_outputs.size())
      throw InputError("OpenCV made " + std::to_string(m.yolo_outputs.size()) + " [yolo] layer(s) of the cfg's " +
                           std::to_string(m.yolo_heads.size()),
                       {m.b.darknet.cfg.string()});
    for (const auto& f : m.b.darknet.feature_layers)
      if (m.net.getLayerId(f) < 0)
        throw ConfigError("OpenCV's network has no layer \"" + f + "\" (names look like conv_12, mish_143, pool_2, shortcut_20)",
                          {(m.b.dir / kBundleManifest).string(), 0, 0, "detector.feature_layers"});
  }
  m.head = std::make_unique<PoseHead>(m.b.pose.file, m.opt.device, m.opt.tuning);
  if (!m.b.pose.torch_version.empty() && m.b.pose.torch_version.substr(0, 4) != PoseHead::runtime_version().substr(0, 4))
    log::warn("the pose head was exported with torch {} and runs on LibTorch {}; TorchScript is only guaranteed to load "
              "with the same version",
              m.b.pose.torch_version, PoseHead::runtime_version());
  if (m.opt.selftest) {
    m.report = run_selftest();
    const std::string src = (m.b.dir / kBundleManifest).string();
    for (const auto& [k, v] : m.report.detector)
      if (!(v <= m.report.detector_atol))
        throw InputError("bundle self-test failed: detector " +
                             (k == "detections after NMS" ? "detections after NMS differ from PoET's (count, class or value)"
                                                          : "layer " + k + " differs from its reference") +
                             " by " + std::to_string(v) + " (atol " + std::to_string(m.report.detector_atol) + ")",
                         {src, 0, 0, "detector.selftest"});
    for (const auto& [k, v] : m.report.pose)
      if (!(v <= m.report.pose_atol))
        throw InputError("bundle self-test failed: pose-head output " + k + " differs from its reference by " + std::to_string(v) +
                             " (atol " + std::to_string(m.report.pose_atol) + ")",
                         {src, 0, 0, "selftest"});
  }
}

PoetModel::~PoetModel() = default;

const PoetBundle& PoetModel::bundle() const { return impl_->b; }
const SelfTestReport& PoetModel::selftest_report() const { return impl_->report; }

SelfTestReport PoetModel::run_selftest() {
  auto& m = *impl_;
  SelfTestReport r;
  r.pose_atol = m.b.selftest.atol;
  r.detector_atol = m.b.darknet.selftest_atol;
  if (m.b.detector == DetectorKind::kDarknet && !m.b.darknet.selftest_image.empty()) {
    const HostTensor blob = preprocess(io::read_file(m.b.darknet.selftest_image), m.b.darknet.selftest_image.string());
    std::vector<std::string> names;
    for (const auto& [n, f] : m.b.darknet.selftest_outputs) names.push_back(n);
    for (const auto& n : names)
      if (m.net.getLayerId(n) < 0)
        throw ConfigError("no layer \"" + n + "\" in the network", {(m.b.dir / kBundleManifest).string(), 0, 0, "detector.selftest.outputs"});
    const auto outs = m.forward_net(blob, names);
    for (std::size_t k = 0; k < names.size(); ++k) {
      // Scaled by the reference's magnitude: deep random or real feature maps reach 1e3-1e4, where
      // float32 summation order alone gives absolute differences of 1e-3.
      const HostTensor ref = read_npy(m.b.darknet.selftest_outputs[k].second);
      double scale = 1.0;
      for (float v : ref.f) scale = std::max(scale, static_cast<double>(std::abs(v)));
      r.detector.emplace_back(names[k], max_abs_diff(mat_to_tensor(outs[k]), ref) / scale);
    }
    if (!m.b.darknet.selftest_detections.empty()) {
      // The boxes after NMS against PoET's own: same count and classes, coordinates and scores within
      // the tolerance (scaled by the largest coordinate, as above); infinite when they do not pair up.
      const HostTensor ref = read_npy(m.b.darknet.selftest_detections);
      const auto boxes = run_detector(blob).first;
      double d = std::numeric_limits<double>::infinity();
      if (!ref.is_int && ref.shape.size() == 2 && ref.shape[1] == 6 &&
          static_cast<std::size_t>(ref.shape[0]) == boxes.size()) {
        double scale = 1.0, diff = 0.0;
        for (float v : ref.f) scale = std::max(scale, static_cast<double>(std::abs(v)));
        for (std::size_t k = 0; k < boxes.size(); ++k) {
          const float* e = ref.f.data() + 6 * k;
          const BoxDetection& b = boxes[k];
          if (static_cast<double>(e[5]) != b.class_id) diff = std::numeric_limits<double>::infinity();
          for (const auto& [x, y] : {std::pair<double, float>{b.x1, e[0]}, {b.y1, e[1]}, {b.x2, e[2]}, {b.y2, e[3]}})
            diff = std::max(diff, std::abs(x - y) / scale);
          diff = std::max(diff, std::abs(b.score - e[4]));
        }
        d = diff;
      }
      r.detector.emplace_back("detections after NMS", d);
    }
  }
  std::vector<HostTensor> in;
  for (const auto& f : m.b.selftest.inputs) in.push_back(read_npy(f));
  const auto out = m.head->forward(in);
  static const char* kNames[] = {"t", "rotation", "logvar_t", "logvar_r"};
  for (std::size_t k = 0; k < m.b.selftest.outputs.size(); ++k) {
    const HostTensor expected = read_npy(m.b.selftest.outputs[k]);
    double d = std::numeric_limits<double>::infinity();
    if (k < out.size() && out[k].numel() == expected.numel() && !expected.is_int) {
      HostTensor a = out[k];
      a.shape = expected.shape;  // [Q,3,3] vs [Q,9] is the same data
      d = max_abs_diff(a, expected);
    }
    r.pose.emplace_back(k < 4 ? kNames[k] : std::to_string(k), d);
  }
  return r;
}

void PoetModel::set_camera(int width, int height, const std::optional<Intrinsics>& K) {
  auto& m = *impl_;
  m.camera_set = true;
  m.cam_w = width;
  m.cam_h = height;
  m.cam_K = K;
  const auto& T = m.b.train_intrinsics;
  const bool same_size = width == m.b.image.width && height == m.b.image.height;
  bool same_K = true;
  if (K) {
    same_K = std::abs(K->fx - T.fx) <= 1e-6 * T.fx && std::abs(K->fy - T.fy) <= 1e-6 * T.fy &&
             std::abs(K->cx - T.cx) <= 1e-3 && std::abs(K->cy - T.cy) <= 1e-3;
  }
  if (m.opt.warp == "off") {
    m.warp = false;
    if (!same_size)
      throw InputError("the dataset's images are " + std::to_string(width) + "x" + std::to_string(height) + " but model " +
                       m.b.model_id + " needs " + std::to_string(m.b.image.width) + "x" + std::to_string(m.b.image.height) +
                       "; use --warp auto to resample them to the training camera");
    if (!same_K) log::warn("the dataset camera differs from the model's training intrinsics and --warp off: PoET's depth will be biased");
  } else {
    m.warp = m.opt.warp == "on" || !same_size || !same_K;
    if (m.warp && !K)
      throw InputError("a virtual-camera warp to the training intrinsics needs the dataset camera's intrinsics (roe.json "
                       "camera), which are missing");
  }
  m.H = cv::Matx33d::eye();
  if (m.warp) {
    const cv::Matx33d Kt(T.fx, 0, T.cx, 0, T.fy, T.cy, 0, 0, 1);
    const cv::Matx33d Kc(K->fx, 0, K->cx, 0, K->fy, K->cy, 0, 0, 1);
    m.H = Kt * Kc.inv();
  }
}

bool PoetModel::warping() const { return impl_->warp; }
std::string PoetModel::device() const { return impl_->head->device(); }
bool PoetModel::pose_head_optimized() const { return impl_->head->optimized(); }

nlohmann::json PoetModel::camera_json() const {
  const auto& m = *impl_;
  nlohmann::json j = {{"warp_mode", m.opt.warp}, {"warp", m.warp}, {"width", m.cam_w}, {"height", m.cam_h}};
  if (m.cam_K) j["intrinsics"] = {{"fx", m.cam_K->fx}, {"fy", m.cam_K->fy}, {"cx", m.cam_K->cx}, {"cy", m.cam_K->cy}};
  if (m.warp) {
    std::vector<double> h;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) h.push_back(m.H(r, c));
    j["H_train_from_camera"] = h;
  }
  return j;
}

HostTensor PoetModel::preprocess(const std::string& encoded_image, const std::string& source) {
  const cv::Mat img = impl_->decode(encoded_image, source);
  if (img.cols != impl_->b.image.width || img.rows != impl_->b.image.height)
    throw InputError("image is " + std::to_string(img.cols) + "x" + std::to_string(img.rows) + ", the model needs " +
                         std::to_string(impl_->b.image.width) + "x" + std::to_string(impl_->b.image.height),
                     {source});
  return impl_->to_blob(img);
}

std::pair<std::vector<BoxDetection>, std::vector<HostTensor>> PoetModel::run_detector(const HostTensor& blob) {
  auto& m = *impl_;
  if (m.b.detector != DetectorKind::kDarknet) throw InternalError("run_detector without a Darknet detector");
  std::vector<std::string> names = m.yolo_outputs;
  names.insert(names.end(), m.b.darknet.feature_layers.begin(), m.b.darknet.feature_layers.end());
  const auto outs = m.forward_net(blob, names);
  std::vector<BoxDetection> cand;
  for (std::size_t k = 0; k < m.yolo_outputs.size(); ++k) {
    const cv::Mat y = outs[k].isContinuous() ? outs[k] : outs[k].clone();
    const YoloHead& head = m.yolo_heads[k];
    const int no = 5 + head.classes;
    if (y.dims != 4 || y.type() != CV_32F || y.size[0] != 1 ||
        y.size[1] != static_cast<int>(head.anchors.size()) * no)
      throw InputError("the convolution before [yolo] #" + std::to_string(k + 1) + " (" + m.yolo_outputs[k] +
                           ") does not give anchors × (5 + classes) = " +
                           std::to_string(head.anchors.size() * static_cast<std::size_t>(no)) + " channels",
                       {m.b.darknet.cfg.string()});
    const int ny = y.size[2], nx = y.size[3];
    // The stride of the grid: the power of two nearest input / grid (PoET's backbone fixes 8, 16, 32
    // for its three heads; input sides that are not multiples of 32 round the grid up).
    const float stride = std::exp2(std::round(std::log2(static_cast<double>(m.b.image.width) / nx)));
    const auto rows = decode_yolo_head(y.ptr<float>(), head, ny, nx, stride);
    auto c = yolo_candidates(rows.data(), rows.size() / static_cast<std::size_t>(no), static_cast<std::size_t>(no), 1, 1,
                             m.b.darknet.nms);
    cand.insert(cand.end(), c.begin(), c.end());
  }
  std::vector<HostTensor> feats;
  for (std::size_t k = m.yolo_outputs.size(); k < outs.size(); ++k) feats.push_back(mat_to_tensor(outs[k]));
  return {nms(std::move(cand), m.b.darknet.nms), std::move(feats)};
}

std::vector<HostTensor> PoetModel::run_pose_head(const std::vector<HostTensor>& inputs) { return impl_->head->forward(inputs); }

std::vector<PoseDetection> PoetModel::decode_outputs(const std::vector<HostTensor>& out, const std::vector<BoxDetection>& boxes,
                                                     std::size_t* dropped) const {
  const auto& b = impl_->b;
  const std::size_t Q = static_cast<std::size_t>(b.num_queries);
  const std::size_t need = b.pose.aleatoric ? 4 : 2;
  if (out.size() < need)
    throw DataError("the pose head returned " + std::to_string(out.size()) + " output(s), expected " + std::to_string(need));
  const std::size_t K = static_cast<std::size_t>(rotation_size(b.rotation));
  if (out[0].numel() != Q * 3) throw DataError("pose head output t has shape " + out[0].describe() + ", expected [" + std::to_string(Q) + ", 3]");
  if (out[1].numel() != Q * K)
    throw DataError("pose head rotation output has shape " + out[1].describe() + ", expected " + std::to_string(Q) + " x " +
                    std::to_string(K) + " (" + rotation_format_name(b.rotation) + ")");
  if (b.pose.aleatoric && (out[2].numel() != Q * 3 || out[3].numel() != Q * 3))
    throw DataError("aleatoric pose head outputs must be [Q, 3] log-variances");
  std::vector<PoseDetection> dets;
  const std::size_t n = std::min(Q, boxes.size());
  for (std::size_t q = 0; q < n; ++q) {
    Eigen::Vector3d t(out[0].f[3 * q], out[0].f[3 * q + 1], out[0].f[3 * q + 2]);
    t *= b.translation_scale;
    double r[9];
    for (std::size_t k = 0; k < K; ++k) r[k] = out[1].f[K * q + k];
    const auto R = rotation_from_output(b.rotation, r);
    if (!R || !t.allFinite()) {
      if (dropped) ++*dropped;
      continue;
    }
    PoseDetection d;
    d.class_id = boxes[q].class_id;
    d.T_C_O = Pose(*R, t);
    d.score = boxes[q].score;
    d.box = {boxes[q].x1, boxes[q].y1, boxes[q].x2, boxes[q].y2};
    if (b.pose.aleatoric) {
      Vector6d s;
      for (int k = 0; k < 3; ++k) {
        s[k] = std::sqrt(std::exp(static_cast<double>(out[2].f[3 * q + k]))) * b.translation_scale;
        s[3 + k] = std::sqrt(std::exp(static_cast<double>(out[3].f[3 * q + k])));
      }
      if (s.allFinite()) d.sigma = s;
    }
    dets.push_back(d);
  }
  return dets;
}

std::vector<HostTensor> pose_queries(const std::vector<BoxDetection>& boxes, std::size_t num_queries, int width,
                                     int height) {
  // Normalised cx, cy, w, h per query; padding rows −1 and class −1 (PoET's placeholders).
  const std::size_t Q = num_queries;
  HostTensor tb = HostTensor::floats({static_cast<std::int64_t>(Q), 4}, std::vector<float>(Q * 4, -1.0f));
  HostTensor tc = HostTensor::ints({static_cast<std::int64_t>(Q)}, std::vector<std::int64_t>(Q, -1));
  const double W = width, H = height;
  for (std::size_t q = 0; q < std::min(Q, boxes.size()); ++q) {
    const auto& bx = boxes[q];
    tb.f[4 * q + 0] = static_cast<float>((bx.x1 + bx.x2) / 2 / W);
    tb.f[4 * q + 1] = static_cast<float>((bx.y1 + bx.y2) / 2 / H);
    tb.f[4 * q + 2] = static_cast<float>((bx.x2 - bx.x1) / W);
    tb.f[4 * q + 3] = static_cast<float>((bx.y2 - bx.y1) / H);
    tc.i[q] = bx.class_id;
  }
  return {std::move(tb), std::move(tc)};
}

FrameResult PoetModel::infer(const std::string& encoded_image, const std::vector<BoxDetection>* external_boxes,
                             const std::string& source) {
  auto& m = *impl_;
  using clock = std::chrono::steady_clock;
  FrameResult res;
  const auto t_start = clock::now();
  auto t0 = t_start;
  cv::Mat img = m.decode(encoded_image, source);
  res.timings.decode_ms = ms_since(t0);
  if (m.camera_set && (img.cols != m.cam_w || img.rows != m.cam_h))
    throw InputError("image is " + std::to_string(img.cols) + "x" + std::to_string(img.rows) + " but the dataset camera is " +
                         std::to_string(m.cam_w) + "x" + std::to_string(m.cam_h),
                     {source});
  if (!m.camera_set) set_camera(img.cols, img.rows, std::nullopt);
  t0 = clock::now();
  if (m.warp) {
    cv::Mat w;
    cv::warpPerspective(img, w, cv::Mat(m.H), cv::Size(m.b.image.width, m.b.image.height), cv::INTER_LINEAR, cv::BORDER_CONSTANT,
                        cv::Scalar(0, 0, 0));
    img = w;
  }
  res.timings.warp_ms = ms_since(t0);
  const HostTensor blob = m.to_blob(img);

  t0 = clock::now();
  std::vector<BoxDetection> boxes;
  std::vector<HostTensor> feats;
  if (external_boxes) {
    for (const auto& eb : *external_boxes) {
      // The pose head indexes class-specific outputs with the class: an unknown one must not reach it.
      if (m.b.class_name(eb.class_id).empty())
        throw InputError("box class " + std::to_string(eb.class_id) + " is not a class of model " + m.b.model_id, {source});
      boxes.push_back(m.warp ? transform_box(eb, m.H) : eb);
    }
    // Best first; a box without a score (NaN) ranks below every scored one, in file order (NaN in
    // the comparison itself would break the sort's ordering and mix up the scored boxes).
    const auto rank = [](double s) { return std::isnan(s) ? -std::numeric_limits<double>::infinity() : s; };
    std::stable_sort(boxes.begin(), boxes.end(),
                     [&](const BoxDetection& a, const BoxDetection& b) { return rank(a.score) > rank(b.score); });
    // A pose head on detector features still needs the detector's feature maps.
    if (m.b.pose.inputs == PoseInputs::kFeatures) feats = run_detector(blob).second;
  } else if (m.b.detector == DetectorKind::kDarknet) {
    auto r = run_detector(blob);
    boxes = std::move(r.first);
    feats = std::move(r.second);
  } else {
    throw InputError("model " + m.b.model_id + " has an external detector: give the boxes with --boxes FILE");
  }
  res.timings.detector_ms = ms_since(t0);
  res.boxes_after_nms = boxes.size();
  const std::size_t Q = static_cast<std::size_t>(m.b.num_queries);
  if (boxes.size() > Q) boxes.resize(Q);

  t0 = clock::now();
  if (!boxes.empty()) {
    std::vector<HostTensor> in = pose_queries(boxes, Q, m.b.image.width, m.b.image.height);
    if (m.b.pose.inputs == PoseInputs::kImage) in.push_back(blob);
    else for (auto& f : feats) in.push_back(std::move(f));
    const auto out = m.head->forward(in);
    res.detections = decode_outputs(out, boxes, &res.dropped_invalid);
    if (m.warp) {  // report boxes in the dataset image
      const cv::Matx33d Hi = m.H.inv();
      for (auto& d : res.detections) {
        BoxDetection bb;
        bb.x1 = d.box[0], bb.y1 = d.box[1], bb.x2 = d.box[2], bb.y2 = d.box[3];
        bb = transform_box(bb, Hi);
        d.box = {bb.x1, bb.y1, bb.x2, bb.y2};
      }
    }
  }
  res.timings.pose_ms = ms_since(t0);
  res.timings.total_ms = ms_since(t_start);
  return res;
}

}  // namespace roe::infer
