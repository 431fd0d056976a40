#pragma once
/// @file
/// Object symmetries in the BOP convention (models_info.json: `symmetries_discrete`,
/// `symmetries_continuous`; Hodaň et al., BOP, ECCV 2018): a transform S of the model frame maps the model
/// onto itself, so the poses T_C_O and T_C_O · S of the object look the same. Types only; the filter's use is
/// in ekf/symmetry.hpp, the reader in io/ (translations converted from the file's mm to metres).

#include <optional>
#include <vector>

#include "roe/core/types.hpp"

namespace roe {

/// Rotation about the line through `offset` along `axis` (model frame), by any angle ψ:
///   S(ψ) x = Exp(ψ a) (x − o) + o,  i.e. S(ψ) = (Exp(ψ a), o − Exp(ψ a) o).
struct ContinuousSymmetry {
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();     ///< unit vector
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();   ///< a point on the axis, metres
};

struct ObjectSymmetry {
  /// The non-identity transforms S (model frame, metres) of a discrete symmetry group.
  std::vector<Pose> discrete;
  /// At most one continuous symmetry (a body of revolution).
  std::optional<ContinuousSymmetry> continuous;
  bool empty() const { return discrete.empty() && !continuous.has_value(); }
};

}  // namespace roe
