#pragma once
// Shared pieces of the symmetric-object filter tests (test_symmetry.cpp, test_symmetry_nees.cpp): a
// continuous symmetry about a tilted axis, its transforms S(ψ) and the end-for-end flip of such a body;
// a started filter with two objects.
#include "roe/core/symmetry.hpp"
#include "roe/ekf/filter.hpp"
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

/// A filter with `opt` (plus: every detection used, ungated, first sight initialises; anchor 1) started at
/// rest, objects 1 and 2 initialised from detections at depths about depth_1 and depth_2, 20 ms of IMU later.
inline ekf::Filter two_objects_started(ekf::FilterOptions opt, double depth_1, double depth_2) {
  using ekf::Vec3;
  opt.init_min_detections = 1;
  opt.anchor_id = 1;
  opt.require_anchor = false;
  opt.chi2_gate = false;
  ekf::Filter f(opt, ekf::ImuNoiseParams{1e-3, 1e-4, 1e-2, 1e-3},
                Pose(math::exp_quat(Vec3(0.1, -0.2, 0.05)), Vec3(0.02, 0.01, -0.03)));
  f.initialize(0, Vec3::Zero(), Vec3(0, 0, 9.81), Vec3(0.3, -0.2, 9.8));
  Detection d1, d2;
  d1.object_id = 1;
  d1.T_C_O = Pose(math::exp_quat(Vec3(0.3, 0.2, -0.1)), Vec3(0.2, -0.1, depth_1));
  d2.object_id = 2;
  d2.T_C_O = Pose(math::exp_quat(Vec3(-0.6, 0.4, 0.3)), Vec3(-0.3, 0.2, depth_2));
  f.update({d1, d2});
  f.propagate(20'000'000, Vec3(0.05, -0.02, 0.01), Vec3(0.1, 0.0, 9.8));
  return f;
}

}  // namespace roe::test
