#pragma once
/// @file
/// A tf buffer for recorded transforms (`/tf`, `/tf_static` of a ROS bag): the pose of one frame in
/// another through any chain of edges, at any time the chain covers, as tf2's buffer answers
/// lookupTransform. docs/import.md, "tf chains".
///
/// Each edge is parent → child with `T_parent_child` (tf2_msgs: header.frame_id = parent,
/// child_frame_id = child). A dynamic edge (from `/tf`) is known at its header stamps and between them:
/// rotation slerped, translation linear, between the two nearest stamps (eval::interpolate_pose_at),
/// never extrapolated. A static edge (from `/tf_static`) holds at any time. A lookup of PARENT → CHILD
/// walks both frames up to their common ancestor A and returns T_A_PARENT⁻¹ · T_A_CHILD.
///
/// Decisions (tf2 keeps the last parent a frame was given; a recording that re-parents a frame is
/// ambiguous): a frame with two parents, or with a static and a dynamic edge, is refused when a chain
/// needs it, naming both edges; so is a cycle (a -> b -> c -> a), naming its frames in order. Repeated
/// stamps of one edge keep the first transform (as every roe reader keeps the first pose of a repeated
/// stamp).
///
/// Cost (issue 51): adding is O(log n) per transform and a lookup walks each frame of the chain once
/// (hash maps from frame to its edges), so any number of frames and edges costs n log n; the listings
/// in errors name the first kListed frames and edges, then a count. A run of static edges is composed once;
/// a trajectory interpolates every dynamic edge of the chain at every output stamp: more than
/// kMaxCompositions of those is refused, naming both numbers.

#include <cstddef>
#include <optional>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <string>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/io/ros/msgs.hpp"

namespace roe::io {

class TfBuffer {
 public:
  /// `source` names where the transforms come from in errors (a bag's path).
  explicit TfBuffer(std::string source = {});

  /// Adds one transform. Throws InputError (naming `where`) for an empty frame name, a frame that is
  /// its own parent, a non-finite translation or a quaternion whose norm is not 1 within 1e-3.
  void add(const ros::StampedTransform& tf, bool is_static, const std::string& where);

  /// Every frame seen (as a parent or a child), sorted.
  std::vector<std::string> frames() const;
  /// One line per edge, "  parent -> child (static)" or "  parent -> child (N stamps, t0 .. t1 s)".
  std::string edge_listing() const;

  /// T_parent_child at `t_ns`, nullopt when a dynamic edge of the chain does not cover `t_ns`.
  /// Throws InputError when the frames are unknown, not connected, or the chain is ambiguous.
  std::optional<Pose> lookup(const std::string& parent, const std::string& child, Timestamp t_ns) const;

  /// The chain PARENT → CHILD as a trajectory: T_parent_child at every stamp of the chain's dynamic edge
  /// with the most stamps that lies where every dynamic edge of the chain is known (no extrapolation).
  /// A chain of static edges only gives one pose, at the latest static stamp. Throws InputError (frames
  /// unknown or not connected, listing the frames and edges found; dynamic edges that never overlap in
  /// time, with their time ranges).
  std::vector<StampedPose> trajectory(const std::string& parent, const std::string& child) const;

 public:
  /// Frames and edges listed by name in an error message; the rest are counted.
  static constexpr std::size_t kListed = 20;
  /// Output stamps × dynamic edges of the chain a trajectory may compose.
  static constexpr std::size_t kMaxCompositions = 50'000'000;

 private:
  struct Edge {
    std::string parent, child;
    bool is_static = false;
    std::vector<StampedPose> samples;  ///< T_parent_child (one for a static edge); sorted by settle()
    bool sorted = true;                ///< samples are sorted by stamp with no repeated stamp
    std::string where;                 ///< where the edge was first seen (a message)
  };
  using Step = std::pair<const Edge*, bool>;
  /// Sorts the samples of every edge added to out of order (a repeated stamp keeps the first transform).
  void settle() const;
  /// The edges that end at `child` (one, unless the recording re-parents it).
  const std::vector<std::size_t>& edges_to(const std::string& child) const;
  /// The edges from `frame` up to its root; InputError on a second parent or a cycle on the way.
  std::vector<const Edge*> up(const std::string& frame, const std::string& parent, const std::string& child) const;
  /// The chain PARENT → CHILD: the edges walked down from the common ancestor (true) or up (false).
  std::vector<Step> chain(const std::string& parent, const std::string& child) const;
  std::string found_listing() const;
  /// A step of a chain to compose: a dynamic edge (inverted unless `forward`), or, with `dynamic` null, a run
  /// of static edges composed once into `fixed`.
  struct Link {
    const Edge* dynamic = nullptr;
    bool forward = true;
    Pose fixed;
  };
  static std::vector<Link> fold(const std::vector<Step>& steps);
  /// T_parent_child along `links` at `t_ns`; nullopt where a dynamic edge does not cover it.
  static std::optional<Pose> compose(const std::vector<Link>& links, Timestamp t_ns);

  std::string source_;
  mutable std::vector<Edge> edges_;  ///< in the order first seen (mutable: settle() sorts samples)
  std::unordered_map<std::string, std::size_t> index_;             ///< "parent\0child\0static" → edge
  std::unordered_map<std::string, std::vector<std::size_t>> to_;   ///< child → its edges
  std::unordered_set<std::string> frames_;                         ///< every frame seen
};

}  // namespace roe::io
