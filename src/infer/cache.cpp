#include "roe/infer/cache.hpp"

#include <cmath>

#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"

namespace roe::infer {

nlohmann::json frame_to_json(const CachedFrame& f) {
  nlohmann::json dets = nlohmann::json::array();
  for (const auto& d : f.detections) {
    const auto& q = d.T_C_O.q;
    nlohmann::json j = {{"class", d.class_id},
                        {"t", {d.T_C_O.p.x(), d.T_C_O.p.y(), d.T_C_O.p.z()}},
                        {"q", {q.x(), q.y(), q.z(), q.w()}},
                        {"score", std::isfinite(d.score) ? nlohmann::json(d.score) : nlohmann::json()},
                        {"box", d.box}};
    if (d.sigma) j["sigma"] = std::vector<double>(d.sigma->data(), d.sigma->data() + 6);
    dets.push_back(j);
  }
  nlohmann::json j = {{"key", f.key}, {"t_ns", f.t_ns}, {"ms", f.ms}, {"detections", dets}};
  if (f.dropped_invalid) j["dropped_invalid"] = f.dropped_invalid;
  return j;
}

CachedFrame frame_from_json(const nlohmann::json& j) {
  CachedFrame f;
  f.key = j.at("key").get<std::string>();
  f.t_ns = j.at("t_ns").get<Timestamp>();
  f.ms = j.at("ms").get<double>();
  f.dropped_invalid = j.value("dropped_invalid", std::size_t{0});
  for (const auto& d : j.at("detections")) {
    PoseDetection p;
    p.class_id = d.at("class").get<int>();
    const auto t = d.at("t").get<std::vector<double>>();
    const auto q = d.at("q").get<std::vector<double>>();
    if (t.size() != 3 || q.size() != 4) throw std::runtime_error("bad pose");
    const Eigen::Quaterniond qq(q[3], q[0], q[1], q[2]);
    if (std::abs(qq.norm() - 1.0) > 1e-6) throw std::runtime_error("non-unit quaternion");
    p.T_C_O = Pose(qq, Eigen::Vector3d(t[0], t[1], t[2]));
    p.score = d.at("score").is_null() ? std::numeric_limits<double>::quiet_NaN() : d.at("score").get<double>();
    const auto box = d.at("box").get<std::vector<double>>();
    if (box.size() != 4) throw std::runtime_error("bad box");
    std::copy(box.begin(), box.end(), p.box.begin());
    if (d.contains("sigma")) {
      const auto s = d.at("sigma").get<std::vector<double>>();
      if (s.size() != 6) throw std::runtime_error("bad sigma");
      p.sigma = Vector6d(Eigen::Map<const Vector6d>(s.data()));
    }
    f.detections.push_back(p);
  }
  return f;
}

DetectionCache::DetectionCache(std::filesystem::path file, std::string model_id, std::string config_hash)
    : file_(std::move(file)),
      header_({{"schema", kCacheSchema}, {"model_id", std::move(model_id)}, {"config_hash", std::move(config_hash)}}) {
  std::error_code ec;
  if (!std::filesystem::exists(file_, ec)) return;  // created by the first append
  const std::string text = io::read_file(file_);
  std::size_t pos = 0, line_no = 0;
  bool header_ok = false;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    const bool complete = end != std::string::npos;
    const std::string line = text.substr(pos, complete ? end - pos : std::string::npos);
    pos = complete ? end + 1 : text.size();
    ++line_no;
    if (line.empty()) continue;
    try {
      const auto j = nlohmann::json::parse(line);
      if (line_no == 1) {
        header_ok = j == header_;
        if (!header_ok) break;
        continue;
      }
      if (!complete) throw std::runtime_error("torn line");
      CachedFrame f = frame_from_json(j);
      const std::string key = f.key;
      if (!frames_.count(key)) order_.push_back(key);
      else ++stale_;  // an older entry of the same frame: the later line wins
      frames_[key] = std::move(f);
    } catch (const std::exception&) {
      if (line_no == 1) break;
      ++ignored_;
    }
  }
  if (!header_ok) {
    log::warn("cache {} belongs to another model or configuration (or is damaged): starting it over", file_.string());
    frames_.clear();
    order_.clear();
    ignored_ = stale_ = 0;
    restart_ = true;
  } else {
    torn_ = !text.empty() && text.back() != '\n';
    if (ignored_) log::warn("cache {}: {} unreadable line(s) ignored (an interrupted run?)", file_.string(), ignored_);
  }
  exists_ = true;
}

const CachedFrame* DetectionCache::find(const std::string& key) const {
  auto it = frames_.find(key);
  return it == frames_.end() ? nullptr : &it->second;
}

void DetectionCache::open_for_append() {
  if (out_.is_open()) return;
  std::error_code ec;
  std::filesystem::create_directories(file_.parent_path(), ec);
  if (ec) throw InputError("cannot create the cache folder: " + ec.message(), {file_.parent_path().string()});
  const bool fresh = !exists_ || restart_;
  out_.open(file_, fresh ? std::ios::trunc : std::ios::app);
  if (!out_) throw InputError("cannot write the cache file", {file_.string()});
  if (fresh) out_ << io::dump_json(header_) << '\n';
  else if (torn_) out_ << '\n';  // appended lines start on a line of their own
  out_.flush();
  exists_ = true;
  restart_ = torn_ = false;
}

void DetectionCache::append(const CachedFrame& frame) {
  open_for_append();
  out_ << io::dump_json(frame_to_json(frame)) << '\n';
  out_.flush();
  if (!out_) throw InputError("cannot append to the cache file", {file_.string()});
  if (frames_.count(frame.key)) ++stale_;
  else order_.push_back(frame.key);
  frames_[frame.key] = frame;
}

void DetectionCache::compact() {
  if (stale_ == 0 && ignored_ == 0) return;
  if (!exists_ || restart_) return;  // nothing of ours on disk
  if (out_.is_open()) out_.close();
  std::string text = io::dump_json(header_) + "\n";
  for (const auto& key : order_) text += io::dump_json(frame_to_json(frames_.at(key))) + "\n";
  io::write_file_atomic(file_, text);
  stale_ = ignored_ = 0;
  torn_ = false;
}

}  // namespace roe::infer
