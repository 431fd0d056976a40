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
/// needs it, naming both edges. Repeated stamps of one edge keep the first transform (as every roe
/// reader keeps the first pose of a repeated stamp).

#include <optional>
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

 private:
  struct Edge {
    std::string parent, child;
    bool is_static = false;
    std::vector<StampedPose> samples;  ///< T_parent_child, sorted by stamp (one for a static edge)
    std::string where;                 ///< where the edge was first seen (a message)
  };
  /// The edges that end at `child` (one, unless the recording re-parents it).
  std::vector<const Edge*> edges_to(const std::string& child) const;
  /// The chain PARENT → CHILD: the edges walked down from the common ancestor (true) or up (false).
  std::vector<std::pair<const Edge*, bool>> chain(const std::string& parent, const std::string& child) const;
  std::string found_listing() const;
  /// T_parent_child along `steps` at `t_ns`; nullopt where a dynamic edge does not cover it.
  static std::optional<Pose> compose(const std::vector<std::pair<const Edge*, bool>>& steps, Timestamp t_ns);

  std::string source_;
  std::vector<Edge> edges_;  ///< in the order first seen
};

}  // namespace roe::io
