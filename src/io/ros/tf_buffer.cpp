#include "roe/io/ros/tf_buffer.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
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
    throw InputError(fmt::format("{}: a transform with an empty frame name (parent \"{}\", child \"{}\")", where,
                                 parent, child),
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
  auto it = std::find_if(edges_.begin(), edges_.end(), [&](const Edge& e) {
    return e.child == child && e.parent == parent && e.is_static == is_static;
  });
  if (it == edges_.end()) {
    edges_.push_back({parent, child, is_static, {}, where});
    it = edges_.end() - 1;
  }
  const StampedPose s{tf.header.stamp_ns, Pose(tf.transform.q.normalized(), tf.transform.t)};
  if (is_static) {  // a static edge holds at any time: the last one published wins, as in tf2
    it->samples = {s};
    return;
  }
  auto& v = it->samples;
  const auto pos = std::lower_bound(v.begin(), v.end(), s.t_ns,
                                    [](const StampedPose& a, Timestamp t) { return a.t_ns < t; });
  if (pos != v.end() && pos->t_ns == s.t_ns) return;  // a repeated stamp keeps the first transform
  v.insert(pos, s);
}

std::vector<std::string> TfBuffer::frames() const {
  std::set<std::string> f;
  for (const Edge& e : edges_) {
    f.insert(e.parent);
    f.insert(e.child);
  }
  return {f.begin(), f.end()};
}

std::string TfBuffer::edge_listing() const {
  std::vector<const Edge*> sorted;
  for (const Edge& e : edges_) sorted.push_back(&e);
  std::sort(sorted.begin(), sorted.end(), [](const Edge* a, const Edge* b) {
    return std::tie(a->parent, a->child, a->is_static) < std::tie(b->parent, b->child, b->is_static);
  });
  std::string out;
  for (const Edge* e : sorted) {
    out += "\n  " + e->parent + " -> " + e->child;
    out += e->is_static ? std::string(" (static)")
                        : fmt::format(" ({} stamps, {} .. {} s)", e->samples.size(), seconds(e->samples.front().t_ns),
                                      seconds(e->samples.back().t_ns));
  }
  return out;
}

std::string TfBuffer::found_listing() const {
  std::string frames_list;
  for (const std::string& f : frames()) frames_list += (frames_list.empty() ? "" : ", ") + f;
  return "\nframes: " + (frames_list.empty() ? std::string("none") : frames_list) +
         "\nedges (parent -> child):" + (edges_.empty() ? std::string(" none") : edge_listing());
}

std::vector<const TfBuffer::Edge*> TfBuffer::edges_to(const std::string& child) const {
  std::vector<const Edge*> out;
  for (const Edge& e : edges_)
    if (e.child == child) out.push_back(&e);
  return out;
}

std::vector<std::pair<const TfBuffer::Edge*, bool>> TfBuffer::chain(const std::string& parent,
                                                                    const std::string& child) const {
  const auto known = frames();
  for (const std::string& f : {parent, child})
    if (!std::binary_search(known.begin(), known.end(), f))
      throw InputError(fmt::format("no frame \"{}\" in the transforms{}", f, found_listing()), {source_});
  if (parent == child)
    throw InputError(fmt::format("the parent and the child are the same frame \"{}\"", parent), {source_});
  // The edges from a frame up to its root (at most one visit per frame: a cycle ends the walk).
  const auto up = [&](const std::string& frame) {
    std::vector<const Edge*> path;
    std::set<std::string> seen{frame};
    for (std::string f = frame;;) {
      const auto in = edges_to(f);
      if (in.empty()) break;
      if (in.size() > 1)
        throw InputError(fmt::format("frame \"{}\" has more than one parent ({} and {}, first seen in {} and {}); "
                                     "the chain {} -> {} is ambiguous{}",
                                     f, in[0]->parent + (in[0]->is_static ? " static" : ""),
                                     in[1]->parent + (in[1]->is_static ? " static" : ""), in[0]->where, in[1]->where,
                                     parent, child, found_listing()),
                         {source_});
      path.push_back(in[0]);
      f = in[0]->parent;
      if (!seen.insert(f).second) break;
    }
    return path;
  };
  const auto from_parent = up(parent), from_child = up(child);
  // Frames above `parent` (itself included) with the number of edges walked to reach them.
  std::vector<std::string> above_parent{parent};
  for (const Edge* e : from_parent) above_parent.push_back(e->parent);
  std::vector<std::pair<const Edge*, bool>> out;
  std::size_t down = 0;
  for (std::string f = child;; f = from_child[down++]->parent) {
    const auto hit = std::find(above_parent.begin(), above_parent.end(), f);
    if (hit != above_parent.end()) {
      // parent → ancestor (inverted edges), then ancestor → child (edges as stored).
      std::vector<std::pair<const Edge*, bool>> steps;
      for (std::size_t k = 0; k < static_cast<std::size_t>(hit - above_parent.begin()); ++k)
        steps.push_back({from_parent[k], false});
      for (std::size_t k = down; k-- > 0;) steps.push_back({from_child[k], true});
      return steps;
    }
    if (down == from_child.size()) break;
  }
  throw InputError(fmt::format("frames \"{}\" and \"{}\" are not connected (their roots are \"{}\" and \"{}\"){}",
                               parent, child, above_parent.back(),
                               from_child.empty() ? child : from_child.back()->parent, found_listing()),
                   {source_});
}

std::optional<Pose> TfBuffer::compose(const std::vector<std::pair<const Edge*, bool>>& steps, Timestamp t_ns) {
  Pose T;  // T_parent_frame, walking the chain
  for (const auto& [edge, forward] : steps) {
    const auto T_e = edge->is_static ? std::optional<Pose>(edge->samples.front().T)
                                     : eval::interpolate_pose_at(edge->samples, t_ns);
    if (!T_e) return std::nullopt;
    T = T * (forward ? *T_e : T_e->inverse());
  }
  return T;
}

std::optional<Pose> TfBuffer::lookup(const std::string& parent, const std::string& child, Timestamp t_ns) const {
  return compose(chain(parent, child), t_ns);
}

std::vector<StampedPose> TfBuffer::trajectory(const std::string& parent, const std::string& child) const {
  const auto steps = chain(parent, child);
  Timestamp begin = std::numeric_limits<Timestamp>::min(), end = std::numeric_limits<Timestamp>::max();
  const Edge* densest = nullptr;
  Timestamp latest_static = 0;
  std::string ranges;
  for (const auto& [e, forward] : steps) {
    if (e->is_static) {
      latest_static = std::max(latest_static, e->samples.front().t_ns);
      continue;
    }
    begin = std::max(begin, e->samples.front().t_ns);
    end = std::min(end, e->samples.back().t_ns);
    if (!densest || e->samples.size() > densest->samples.size()) densest = e;
    ranges += fmt::format("\n  {} -> {}: {} .. {} s", e->parent, e->child, seconds(e->samples.front().t_ns),
                          seconds(e->samples.back().t_ns));
  }
  if (!densest) return {{latest_static, *compose(steps, latest_static)}};
  if (begin > end)
    throw InputError(fmt::format("the chain {} -> {} is never known at one time: its dynamic edges do not overlap "
                                 "(tf does not extrapolate):{}",
                                 parent, child, ranges),
                     {source_});
  std::vector<StampedPose> out;
  for (const StampedPose& s : densest->samples)
    if (s.t_ns >= begin && s.t_ns <= end) out.push_back({s.t_ns, *compose(steps, s.t_ns)});
  return out;
}

}  // namespace roe::io
