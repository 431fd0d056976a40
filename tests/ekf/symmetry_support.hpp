#pragma once
// Shared pieces of the symmetric-object filter tests (test_symmetry.cpp, test_symmetry_nees.cpp): a
// continuous symmetry about a tilted axis, its transforms S(ψ) and the end-for-end flip of such a body.
#include "roe/core/symmetry.hpp"
#include "roe/math/so3.hpp"

namespace roe::test {

inline ContinuousSymmetry about_z(const Eigen::Vector3d& offset = Eigen::Vector3d::Zero()) {
  ContinuousSymmetry c;
  c.axis = Eigen::Vector3d(0.2, -0.1, 1.0).normalized();
  c.offset = offset;
  return c;
}

/// S(ψ) = (Exp(ψa), o − Exp(ψa) o).
inline Pose continuous(const ContinuousSymmetry& c, double psi) {
  const Eigen::Quaterniond q = math::exp_quat(psi * c.axis);
  return Pose(q, c.offset - q * c.offset);
}

/// The flip of a body of revolution: 180° about an axis ⟂ its symmetry axis, through a point of it (so
/// that the group {S(ψ), flip · S(ψ)} is closed, as for a BOP cylinder).
inline Pose flip_of(const ContinuousSymmetry& c) {
  const Eigen::Quaterniond q = math::exp_quat(M_PI * c.axis.cross(Eigen::Vector3d::UnitX()).normalized());
  return Pose(q, c.offset - q * c.offset);
}

}  // namespace roe::test
