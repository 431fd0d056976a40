#include "roe/io/ros/tf_buffer.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <tuple>

#include "roe/core/error.hpp"
#include "roe/eval/interpolate.hpp"

namespace roe::io {

namespace {
constexpr double kUnitQuatTolerance = 1e-3;  // as the other bag pose readers (mocap_formats)

std::string seconds(Timestamp t) { return fmt::format("{:.3f}", to_seconds(t)); }
}  // namespace

TfBuffer::TfBuffer(std::string source) : source_(std::move(source)) {}

void TfBuffer::add(const ros::StampedTransform& tf, bool is_static, const std::string& where) {
  const std::string& parent = tf.header.frame_id;
  const std::string& child = tf.child_frame_id;
  if (parent.empty() || child.empty())
    throw InputError(fmt::format("{}: the transform \"{}\" -> \"{}\" has an empty frame id ({}); tf frames need a "
                                 "name",
                                 where, parent, child, parent.empty() ? "header.frame_id" : "child_frame_id"),
                     {source_});
  if (parent == child)
    throw InputError(fmt::format("{}: the transform {} -> {} makes a frame its own parent", where, parent, child),
                     {source_});
  if (tf.header.stamp_ns < 0)  // ROS time counts from the epoch, as the CSV importers require too
    throw InputError(fmt::format("{}: transform {} -> {}: negative header stamp ({} ns); ROS stamps count from 1970",
                                 where, parent, child, tf.header.stamp_ns),
                     {source_});
  const double n = tf.transform.q.norm();
  if (!(std::abs(n - 1.0) <= kUnitQuatTolerance) || !tf.transform.t.allFinite())
    throw InputError(fmt::format("{}: transform {} -> {} (stamp {} ns): {}", where, parent, child,
                                 tf.header.stamp_ns,
                                 tf.transform.t.allFinite() ? fmt::format("quaternion is not unit norm (|q| = {:.6g})", n)
                                                            : std::string("non-finite translation")),
                     {source_});
  std::string key = parent;
  key += '\0';
  key += child;
  key += '\0';
  key += is_static ? 's' : 'd';  // a static and a dynamic edge of one pair are two edges (a char, not "\0s": that is "")
  const auto [at, inserted] = index_.try_emplace(std::move(key), edges_.size());
  if (inserted) {
    edges_.push_back({parent, child, is_static, {}, true, where});
    to_[child].push_back(at->second);
    frames_.insert(parent);
    frames_.insert(child);
  }
  Edge& e = edges_[at->second];
  const StampedPose s{tf.header.stamp_ns, Pose(tf.transform.q.normalized(), tf.transform.t)};
  if (is_static) {  // a static edge holds at any time: the last one published wins, as in tf2
    e.samples = {s};
    return;
  }
  // In stamp order (a recording's usual case) the samples stay sorted; otherwise settle() sorts them once.
  if (!e.samples.empty() && e.samples.back().t_ns >= s.t_ns) e.sorted = false;
  e.samples.push_back(s);
}

void TfBuffer::settle() const {
  for (Edge& e : edges_) {
    if (e.sorted) continue;
    auto& v = e.samples;
    std::stable_sort(v.begin(), v.end(), [](const StampedPose& a, const StampedPose& b) { return a.t_ns < b.t_ns; });
    v.erase(std::unique(v.begin(), v.end(), [](const StampedPose& a, const StampedPose& b) { return a.t_ns == b.t_ns; }),
            v.end());  // a repeated stamp keeps the first transform
    e.sorted = true;
  }
}

std::vector<std::string> TfBuffer::frames() const {
  std::vector<std::string> f(frames_.begin(), frames_.end());
  std::sort(f.begin(), f.end());
  return f;
}

std::string TfBuffer::edge_listing() const {
  settle();
  std::vector<const Edge*> sorted;
  for (const Edge& e : edges_) sorted.push_back(&e);
  const auto first = sorted.begin() + static_cast<std::ptrdiff_t>(std::min(kListed, sorted.size()));
  std::partial_sort(sorted.begin(), first, sorted.end(), [](const Edge* a, const Edge* b) {
    return std::tie(a->parent, a->child, a->is_static) < std::tie(b->parent, b->child, b->is_static);
  });
  std::string out;
  for (auto it = sorted.begin(); it != first; ++it) {
    const Edge* e = *it;
    out += "\n  " + e->parent + " -> " + e->child;
    out += e->is_static ? std::string(" (static)")
                        : fmt::format(" ({} stamps, {} .. {} s)", e->samples.size(), seconds(e->samples.front().t_ns),
                                      seconds(e->samples.back().t_ns));
  }
  if (sorted.size() > kListed) out += fmt::format("\n  ... and {} more edges", sorted.size() - kListed);
  return out;
}

std::string TfBuffer::found_listing() const {
  std::vector<std::string> f(frames_.begin(), frames_.end());
  const auto first = f.begin() + static_cast<std::ptrdiff_t>(std::min(kListed, f.size()));
  std::partial_sort(f.begin(), first, f.end());
  std::string frames_list;
  for (auto it = f.begin(); it != first; ++it) frames_list += (frames_list.empty() ? "" : ", ") + *it;
  if (f.size() > kListed) frames_list += fmt::format(", ... ({} frames in all)", f.size());
  return "\nframes: " + (frames_list.empty() ? std::string("none") : frames_list) +
         "\nedges (parent -> child):" + (edges_.empty() ? std::string(" none") : edge_listing());
}

const std::vector<std::size_t>& TfBuffer::edges_to(const std::string& child) const {
  static const std::vector<std::size_t> kNone;
  const auto it = to_.find(child);
  return it == to_.end() ? kNone : it->second;
}

std::vector<const TfBuffer::Edge*> TfBuffer::up(const std::string& frame, const std::string& parent,
                                                 const std::string& child) const {
  std::vector<const Edge*> path;
  std::unordered_map<std::string, std::size_t> seen{{frame, 0}};  // frame → its place on the walk
  for (std::string f = frame;;) {
    const auto& in = edges_to(f);
    if (in.empty()) break;
    if (in.size() > 1) {
      const Edge &a = edges_[in[0]], &b = edges_[in[1]];
      throw InputError(fmt::format("frame \"{}\" has more than one parent ({} and {}, first seen in {} and {}); "
                                   "the chain {} -> {} is ambiguous{}",
                                   f, a.parent + (a.is_static ? " static" : ""), b.parent + (b.is_static ? " static" : ""),
                                   a.where, b.where, parent, child, found_listing()),
                       {source_});
    }
    const Edge& e = edges_[in[0]];
    path.push_back(&e);
    f = e.parent;
    const auto [it, fresh] = seen.try_emplace(f, path.size());
    if (fresh) continue;
    // A cycle: the frames from the first visit of `f` round to it again, each the parent of the one before.
    std::vector<std::string> ring;
    for (std::size_t k = it->second; k < path.size(); ++k) ring.push_back(path[k]->child);
    std::reverse(ring.begin(), ring.end());
    std::string named;
    for (std::size_t k = 0; k < ring.size() && k < kListed; ++k) named += ring[k] + " -> ";
    named += ring.size() > kListed ? fmt::format("... ({} frames in all) -> {}", ring.size(), ring.front())
                                   : ring.front();
    throw InputError(fmt::format("the transforms form a cycle: {} (each the parent of the next; first seen in {}); "
                                 "a tf tree has none, so the chain {} -> {} has no root",
                                 named, e.where, parent, child),
                     {source_});
  }
  return path;
}

std::vector<TfBuffer::Step> TfBuffer::chain(const std::string& parent, const std::string& child) const {
  settle();
  for (const std::string& f : {parent, child})
    if (!frames_.count(f))
      throw InputError(fmt::format("no frame \"{}\" in the transforms{}", f, found_listing()), {source_});
  if (parent == child)
    throw InputError(fmt::format("the parent and the child are the same frame \"{}\"", parent), {source_});
  const auto from_parent = up(parent, parent, child), from_child = up(child, parent, child);
  // Frames above `parent` (itself included) with the number of edges walked to reach them.
  std::unordered_map<std::string, std::size_t> above_parent{{parent, 0}};
  for (std::size_t k = 0; k < from_parent.size(); ++k) above_parent.emplace(from_parent[k]->parent, k + 1);
  std::size_t down = 0;
  for (std::string f = child;; f = from_child[down++]->parent) {
    const auto hit = above_parent.find(f);
    if (hit != above_parent.end()) {
      // parent → ancestor (inverted edges), then ancestor → child (edges as stored).
      std::vector<Step> steps;
      for (std::size_t k = 0; k < hit->second; ++k) steps.push_back({from_parent[k], false});
      for (std::size_t k = down; k-- > 0;) steps.push_back({from_child[k], true});
      return steps;
    }
    if (down == from_child.size()) break;
  }
  const std::string& root_parent = from_parent.empty() ? parent : from_parent.back()->parent;
  throw InputError(fmt::format("frames \"{}\" and \"{}\" are not connected (their roots are \"{}\" and \"{}\"){}",
                               parent, child, root_parent, from_child.empty() ? child : from_child.back()->parent,
                               found_listing()),
                   {source_});
}

std::vector<TfBuffer::Link> TfBuffer::fold(const std::vector<Step>& steps) {
  std::vector<Link> links;
  for (const auto& [edge, forward] : steps) {
    if (!edge->is_static) {
      links.push_back({edge, forward, Pose()});
      continue;
    }
    const Pose T_e = forward ? edge->samples.front().T : edge->samples.front().T.inverse();
    if (links.empty() || links.back().dynamic) links.push_back({nullptr, true, Pose()});
    links.back().fixed = links.back().fixed * T_e;  // a run of static edges: one pose, composed once
  }
  return links;
}

std::optional<Pose> TfBuffer::compose(const std::vector<Link>& links, Timestamp t_ns) {
  Pose T;  // T_parent_frame, walking the chain
  for (const Link& l : links) {
    if (!l.dynamic) {
      T = T * l.fixed;
      continue;
    }
    const auto T_e = eval::interpolate_pose_at(l.dynamic->samples, t_ns);
    if (!T_e) return std::nullopt;
    T = T * (l.forward ? *T_e : T_e->inverse());
  }
  return T;
}

std::optional<Pose> TfBuffer::lookup(const std::string& parent, const std::string& child, Timestamp t_ns) const {
  return compose(fold(chain(parent, child)), t_ns);
}

std::vector<StampedPose> TfBuffer::trajectory(const std::string& parent, const std::string& child) const {
  const auto steps = chain(parent, child);
  Timestamp begin = std::numeric_limits<Timestamp>::min(), end = std::numeric_limits<Timestamp>::max();
  const Edge* densest = nullptr;
  Timestamp latest_static = 0;
  std::string ranges;
  std::size_t n_ranges = 0;
  for (const auto& [e, forward] : steps) {
    if (e->is_static) {
      latest_static = std::max(latest_static, e->samples.front().t_ns);
      continue;
    }
    begin = std::max(begin, e->samples.front().t_ns);
    end = std::min(end, e->samples.back().t_ns);
    if (!densest || e->samples.size() > densest->samples.size()) densest = e;
    if (++n_ranges <= kListed)
      ranges += fmt::format("\n  {} -> {}: {} .. {} s", e->parent, e->child, seconds(e->samples.front().t_ns),
                            seconds(e->samples.back().t_ns));
    else if (n_ranges == kListed + 1)
      ranges += "\n  ... (the first " + std::to_string(kListed) + " dynamic edges of the chain)";
  }
  const std::vector<Link> links = fold(steps);
  if (!densest) return {{latest_static, *compose(links, latest_static)}};
  const std::size_t n_dynamic = n_ranges;
  if (densest->samples.size() * n_dynamic > kMaxCompositions)
    throw InputError(fmt::format("the chain {} -> {} has {} dynamic edges and {} stamps: composing them at every stamp "
                                 "({} interpolations) exceeds roe's limit of {}; choose a shorter chain",
                                 parent, child, n_dynamic, densest->samples.size(),
                                 densest->samples.size() * n_dynamic, kMaxCompositions),
                     {source_});
  if (begin > end)
    throw InputError(fmt::format("the chain {} -> {} is never known at one time: its dynamic edges do not overlap "
                                 "(tf does not extrapolate):{}",
                                 parent, child, ranges),
                     {source_});
  std::vector<StampedPose> out;
  for (const StampedPose& s : densest->samples)
    if (s.t_ns >= begin && s.t_ns <= end) out.push_back({s.t_ns, *compose(links, s.t_ns)});
  return out;
}

}  // namespace roe::io
