#pragma once
/// @file
/// The filter's nominal state with its error-state layout, and ⊞/⊟ on it (docs/filter.md §1): additive
/// positions, velocities and biases, right rotation errors; an anchor keeps only its leading δθ_O_W
/// components. One definition: the filter's object list (Filter::objects()) is this state's objects, and
/// the smoother's recorded nodes are snapshots of it. I/O-free.

#include <Eigen/Core>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/ekf/imu.hpp"
#include "roe/ekf/measurement.hpp"  // Vec6

namespace roe::ekf {

struct StateEstimate {
  Timestamp t_ns = 0;
  CoreState x;
  Pose T_I_C;
  int extr_offset = -1;  ///< first column of the extrinsics (−1: held fixed)
  /// Camera–IMU time offset t_d (s; t_imu = t_cam + t_d) and its error-state column (−1: held at the
  /// declared value, not in the state). Additive: t_d ← t_d + δt_d.
  double t_d = 0.0;
  int td_offset = -1;
  int dim = kCore;       ///< error-state dimension
  /// One object-world.
  struct Object {
    int id = 0;
    Pose T_O_W;  ///< the paper's (p_O_W, q_O_W)
    bool anchor = false;
    int offset = -1;  ///< first error-state column (−1 when dim == 0)
    int dim = 0;      ///< 6; anchor: 0 (kPose), 3 (kPosition: δθ) or 2 (kPositionYaw: δθ_x, δθ_y)
    Timestamp t_init_ns = 0;  ///< when it entered the state
    /// Gauss–Markov detection-error state (FilterOptions::detection_error_states; docs/filter.md §17): its
    /// first error-state column (6 columns [x_t; x_θ], right before `offset`'s; −1: none), its mean (additive
    /// ⊞) and the time it was last decayed to (x ← ρ x between the object's detections).
    int err_offset = -1;
    Vec6 err = Vec6::Zero();
    Timestamp t_err_ns = 0;
  };
  std::vector<Object> objects;
};

/// The filter's entry of an object (Filter::objects()).
using ObjectEntry = StateEstimate::Object;

/// The core block of ⊞: x ← x ⊞ δx for the 15 IMU error states [δp, δv, δθ, δb_g, δb_a].
void boxplus_core(CoreState& x, const Eigen::Matrix<double, 15, 1>& dx);
/// x ← x ⊞ δx (the anchor's components are its leading δθ_O_W components).
void boxplus(StateEstimate& x, const Eigen::VectorXd& dx);
/// δ = a ⊟ b with a = b ⊞ δ; a and b must have the same layout.
Eigen::VectorXd boxminus(const StateEstimate& a, const StateEstimate& b);

}  // namespace roe::ekf
