#pragma once
/// @file
/// IMU preintegration between two times for the batch refinement (docs/refine.md §2). I/O-free.
///
/// The integrator is the filter's (ekf::integrate, docs/filter.md §2: averaged samples, exact attitude,
/// midpoint-rotated specific force; the IMU linearly interpolated at a stamp between samples, as
/// ekf::run_filter does). Started at R = I, v = 0, p = 0 with the biases b̄_g, b̄_a held fixed, it gives
///   ΔR = R_iᵀ R_j,   Δv = R_iᵀ (v_j − v_i + g Δt),   Δp = R_iᵀ (p_j − p_i − v_i Δt + ½ g Δt²)
/// exactly as the filter would propagate any state from t_i to t_j (the integrator is linear in the
/// start state's p, v and equivariant in its R). The chained transitions F of ekf::integrate give, in the
/// error state [δp, δv, δθ] (ΔR = ΔR̄ Exp(δθ), Δv = Δv̄ + δv, Δp = Δp̄ + δp):
///   - the bias Jacobians ∂(δp, δv, δθ)/∂(δb_g, δb_a) (first-order bias correction in the factor), and
///   - the covariance of (δp, δv, δθ) from the measurement white noise (F P Fᵀ + Q per interval with the
///     filter's Q, ekf::add_process_noise, random walks left out: the bias random walk is its own
///     residual between the two nodes, σ² = σ_bw² Δt).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <functional>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/ekf/imu.hpp"

namespace roe::refine {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Mat9 = Eigen::Matrix<double, 9, 9>;

/// The IMU measurement at t: the sample at t, or the two samples around t linearly interpolated
/// (ekf::run_filter's rule). `hint` is an index ≤ the answer's left sample (advanced; pass 0 first).
/// roe::InputError when t lies outside [imu.front().t_ns, imu.back().t_ns].
ImuSample imu_at(const std::vector<ImuSample>& imu, Timestamp t_ns, std::size_t& hint);

/// Calls fn(a, b) for every integration interval of [t_i, t_j] (t_i < t_j): the IMU samples inside,
/// with the interpolated measurements at both ends (imu_at). `hint` as for imu_at.
void for_each_interval(const std::vector<ImuSample>& imu, Timestamp t_i, Timestamp t_j, std::size_t& hint,
                       const std::function<void(const ImuSample& a, const ImuSample& b)>& fn);

struct Preintegration {
  Timestamp t_i = 0, t_j = 0;
  double dt = 0.0;                   ///< t_j − t_i, s
  Vec3 bg_lin = Vec3::Zero();        ///< the biases it was integrated with
  Vec3 ba_lin = Vec3::Zero();
  Eigen::Quaterniond dR = Eigen::Quaterniond::Identity();
  Vec3 dv = Vec3::Zero(), dp = Vec3::Zero();
  /// ∂/∂δb of [δp; δv; δθ] (9x6, columns [δb_g, δb_a]).
  Eigen::Matrix<double, 9, 6> J_bias = Eigen::Matrix<double, 9, 6>::Zero();
  /// Covariance of [δp; δv; δθ] from the measurement noise densities.
  Mat9 cov = Mat9::Zero();
};

/// Preintegrates the IMU over [t_i, t_j] with the biases (bg, ba) and the noise densities of `noise`.
Preintegration preintegrate(const std::vector<ImuSample>& imu, Timestamp t_i, Timestamp t_j, const Vec3& bg,
                            const Vec3& ba, const ekf::ImuNoiseParams& noise, std::size_t& hint);

/// The IMU state at t_j propagated from `x` at t_i with ekf::integrate (the refined trajectory between
/// two nodes, and a test of preintegrate).
ekf::CoreState propagate(const std::vector<ImuSample>& imu, const ekf::CoreState& x, Timestamp t_i, Timestamp t_j,
                         std::size_t& hint);

}  // namespace roe::refine
