#pragma once
/// @file
/// Smooth (C-infinity) handheld/UAV-like inspection trajectories around a group of objects, with
/// analytic first and second derivatives for the IMU model.
///
/// The camera C moves on a "orbit" around a centre point c (the object group) in the mocap/room
/// frame M (z up): with azimuth a(t), horizontal radius r(t) and height h(t), all sums of sinusoids
/// plus a linear term (SmoothSignal),
///     p_M_C(t) = c + [r cos a, r sin a, h] + shake(t).
/// The camera looks at the moving point c + target(t): the optical axis z_C is the unit vector towards
/// it, the roll about the optical axis is roll(t). Orientation is R_M_C = Rz(ψ) Ry(θ) Rx(φ) · R_L_C
/// with ψ = atan2(d_y, d_x), θ = −atan2(d_z, |d_xy|) (d = target − p), φ = roll, where R_L_C maps
/// the optical frame (x right, y down, z forward) to a "look" frame (x forward, y left, z up).
/// Every scalar is evaluated as a second-order jet (value, first and second time derivative), so
/// velocity, acceleration, angular velocity and angular acceleration are exact, not differenced.

#include <Eigen/Core>
#include <vector>

#include "roe/math/se3.hpp"

namespace roe::sim {

/// a · sin(2π f t + φ).
struct Sinusoid {
  double amplitude = 0.0;
  double frequency_hz = 0.0;
  double phase_rad = 0.0;
};

/// s(t) = offset + rate · t + Σ_k a_k sin(2π f_k t + φ_k), t in seconds from the start.
struct SmoothSignal {
  double offset = 0.0;
  double rate = 0.0;
  std::vector<Sinusoid> terms;
};

/// The trajectory's shape. Angles in radians, lengths in metres, all in the room frame M (z up).
struct TrajectoryConfig {
  Eigen::Vector3d center = Eigen::Vector3d(0.0, 0.0, 0.8);  ///< c: centre of the object group in M
  SmoothSignal azimuth_rad{0.0, 0.15, {}};                  ///< a(t): angle of the camera around c (about z)
  SmoothSignal radius_m{1.0, 0.0, {}};                      ///< r(t): horizontal distance from c
  SmoothSignal height_m{0.5, 0.0, {}};                      ///< h(t): camera height above c
  SmoothSignal target_x_m, target_y_m, target_z_m;          ///< look-at point offset from c (slow wander)
  SmoothSignal roll_rad;                                    ///< roll about the optical axis
  SmoothSignal shake_x_m, shake_y_m, shake_z_m;             ///< handheld shake added to the position (M)
};

/// The kinematic state of a rigid frame X at one instant, everything in the fixed frame M unless
/// named otherwise.
struct Kinematics {
  math::Pose T_M_X;                                   ///< pose
  Eigen::Vector3d v_M = Eigen::Vector3d::Zero();      ///< velocity of the origin of X
  Eigen::Vector3d a_M = Eigen::Vector3d::Zero();      ///< acceleration of the origin of X
  Eigen::Vector3d omega_X = Eigen::Vector3d::Zero();  ///< angular velocity in X (body rates)
  Eigen::Vector3d alpha_X = Eigen::Vector3d::Zero();  ///< angular acceleration in X (d/dt omega_X)
};

/// A trajectory evaluated analytically at any time.
class InspectionTrajectory {
 public:
  explicit InspectionTrajectory(TrajectoryConfig config);
  /// Camera kinematics at t seconds from the start.
  Kinematics camera(double t) const;
  /// Kinematics of a frame rigidly attached to the camera, at pose T_C_X in C (e.g. the IMU,
  /// T_C_I): p_X = p_C + R_M_C p_C_X, v_X = v_C + ω × r, a_X = a_C + α × r + ω × (ω × r) with
  /// r = R_M_C p_C_X (world), ω, α in M; omega_X = R_X_C omega_C.
  Kinematics attached(double t, const math::Pose& T_C_X) const;
  const TrajectoryConfig& config() const { return config_; }

 private:
  TrajectoryConfig config_;
};

/// Evaluates s(t), s'(t), s''(t) of a SmoothSignal.
Eigen::Vector3d evaluate_signal(const SmoothSignal& s, double t);

}  // namespace roe::sim
