#pragma once
/// @file
/// IMU propagation of the core state [p_W_I, v_W_I, q_W_I, b_g, b_a] (paper eqs. 2–4) and its
/// error-state transition.
///
/// Integrator (one interval t_k → t_{k+1}, dt): the measurements at both ends are averaged
/// (ω̄ = (ω_k + ω_{k+1})/2 − b_g, ā = (a_k + a_{k+1})/2 − b_a) and held constant; the rotation is
/// integrated exactly and the specific force is rotated with the mid-interval attitude (midpoint
/// rule, second order):
///   R⁺ = R Exp(ω̄ dt),  R_m = R Exp(ω̄ dt/2),
///   v⁺ = v + (R_m ā − g) dt,   p⁺ = p + v dt + ½ (R_m ā − g) dt².
/// F below is the exact Jacobian of this map in the error state (δp, δv, δθ, δb_g, δb_a) with
/// R = R̂ Exp(δθ) (DESIGN §2):
///   δθ⁺ = Exp(−ω̄dt) δθ − Jr(ω̄dt) dt δb_g
///   δv⁺ = δv − R_m[ā]× dt (Exp(−ω̄dt/2) δθ − Jr(ω̄dt/2) dt/2 δb_g) − R_m dt δb_a
///   δp⁺ = δp + dt δv + (dt/2)(δv⁺ − δv)            (the same terms scaled by dt/2)
/// Q from the continuous white-noise model (noise densities σ_g, σ_a and random walks σ_bg, σ_ba):
///   Q_pp = σ_a² dt³/3, Q_pv = σ_a² dt²/2, Q_vv = σ_a² dt, Q_θθ = σ_g² dt, Q_bg = σ_bg² dt,
///   Q_ba = σ_ba² dt (isotropic noise, so the rotation R_m drops out; terms of order σ_b² dt² and
///   the bias–attitude coupling inside one interval are neglected).

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace roe::ekf {

using Mat3 = Eigen::Matrix3d;
using Vec3 = Eigen::Vector3d;
using Mat15 = Eigen::Matrix<double, 15, 15>;

/// Error-state indices of the core (DESIGN §6 order).
inline constexpr int kP = 0, kV = 3, kTheta = 6, kBg = 9, kBa = 12, kCore = 15;

/// Gravity in W (DESIGN §2): v̇ = R (a_m − b_a) − g.
inline const Vec3 kGravity_W(0.0, 0.0, 9.81);

struct CoreState {
  Vec3 p_W_I = Vec3::Zero();
  Vec3 v_W_I = Vec3::Zero();
  Eigen::Quaterniond q_W_I = Eigen::Quaterniond::Identity();
  Vec3 b_g = Vec3::Zero();
  Vec3 b_a = Vec3::Zero();
};

/// Continuous-time IMU noise used for Q.
struct ImuNoiseParams {
  double gyro_noise_density = 0.0;
  double gyro_random_walk = 0.0;
  double accel_noise_density = 0.0;
  double accel_random_walk = 0.0;
};

/// The non-trivial 3x3 blocks of the discrete transition F (all other blocks are 0 or I, dt I).
struct CoreTransition {
  double dt = 0.0;
  Mat3 F_vtheta, F_vbg, F_vba;  ///< rows δv
  Mat3 F_tt, F_tbg;             ///< rows δθ
  /// The dense 15x15 F (tests, diagnostics).
  Mat15 dense() const;
  /// X ← F X for a 15 x m block (block-sparse: 8 small products instead of a dense 15x15 product).
  template <typename Derived>
  void apply_left(Eigen::MatrixBase<Derived>& X) const;
  /// X ← X Fᵀ for a fixed-size r x 15 block: the same 8 small products on columns (contiguous in
  /// column-major storage, so they vectorise over the rows; used by the per-sample F P Fᵀ and Φ).
  template <typename Derived>
  void apply_right_transposed(Eigen::MatrixBase<Derived>& X) const;
  /// X ← X F for a fixed-size r x 15 block (the smoother's backward product Φ(b, t) = Φ(b, t') F).
  template <typename Derived>
  void apply_right(Eigen::MatrixBase<Derived>& X) const;
};

/// Integrates the nominal state over dt with the measurements (w0, a0) at the start and (w1, a1) at
/// the end of the interval; fills F when not null.
CoreState integrate(const CoreState& x, const Vec3& w0, const Vec3& a0, const Vec3& w1, const Vec3& a1,
                    double dt, CoreTransition* F = nullptr);

/// Adds the discrete process noise of one interval to the core block of a covariance.
template <typename Derived>
void add_process_noise(const ImuNoiseParams& n, double dt, Eigen::MatrixBase<Derived>& P_cc) {
  const double qa = n.accel_noise_density * n.accel_noise_density;
  const double qg = n.gyro_noise_density * n.gyro_noise_density;
  const double qbg = n.gyro_random_walk * n.gyro_random_walk;
  const double qba = n.accel_random_walk * n.accel_random_walk;
  const double dt2 = dt * dt;
  for (int i = 0; i < 3; ++i) {
    P_cc(kP + i, kP + i) += qa * dt2 * dt / 3.0;
    P_cc(kP + i, kV + i) += 0.5 * qa * dt2;
    P_cc(kV + i, kP + i) += 0.5 * qa * dt2;
    P_cc(kV + i, kV + i) += qa * dt;
    P_cc(kTheta + i, kTheta + i) += qg * dt;
    P_cc(kBg + i, kBg + i) += qbg * dt;
    P_cc(kBa + i, kBa + i) += qba * dt;
  }
}

template <typename Derived>
void CoreTransition::apply_left(Eigen::MatrixBase<Derived>& X) const {
  // Old rows are read before they are overwritten: p uses old v and θ, v uses old θ, θ last.
  if constexpr (Derived::ColsAtCompileTime != Eigen::Dynamic) {
    // Fixed-size path for the core block, its first 9 columns and Φ's last 9 columns (the
    // per-IMU-sample hot path: fully unrolled 3x3 products, no loop over column chunks).
    constexpr int kCols = Derived::ColsAtCompileTime;
    Eigen::Matrix<double, 3, kCols> dv, dth;
    dv.noalias() = F_vtheta * X.template middleRows<3>(kTheta);
    dv.noalias() += F_vbg * X.template middleRows<3>(kBg);
    dv.noalias() += F_vba * X.template middleRows<3>(kBa);
    dth.noalias() = F_tt * X.template middleRows<3>(kTheta);
    dth.noalias() += F_tbg * X.template middleRows<3>(kBg);
    X.template middleRows<3>(kP) += dt * X.template middleRows<3>(kV) + (0.5 * dt) * dv;
    X.template middleRows<3>(kV) += dv;
    X.template middleRows<3>(kTheta) = dth;
    return;
  }
  const int m = static_cast<int>(X.cols());
  for (int c0 = 0; c0 < m; c0 += 15) {
    const int w = std::min(15, m - c0);
    Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, 15> dv(3, w), dth(3, w);
    dv.noalias() = F_vtheta * X.block(kTheta, c0, 3, w);
    dv.noalias() += F_vbg * X.block(kBg, c0, 3, w);
    dv.noalias() += F_vba * X.block(kBa, c0, 3, w);
    dth.noalias() = F_tt * X.block(kTheta, c0, 3, w);
    dth.noalias() += F_tbg * X.block(kBg, c0, 3, w);
    X.block(kP, c0, 3, w) += dt * X.block(kV, c0, 3, w) + (0.5 * dt) * dv;
    X.block(kV, c0, 3, w) += dv;
    X.block(kTheta, c0, 3, w) = dth;
  }
}

template <typename Derived>
void CoreTransition::apply_right_transposed(Eigen::MatrixBase<Derived>& X) const {
  static_assert(Derived::RowsAtCompileTime != Eigen::Dynamic && Derived::ColsAtCompileTime == 15,
                "apply_right_transposed: fixed-size r x 15 block");
  constexpr int kRows = Derived::RowsAtCompileTime;
  // (X Fᵀ)[:, v] = X_v + X_θ F_vθᵀ + X_bg F_vbgᵀ + X_ba F_vbaᵀ, (X Fᵀ)[:, p] = X_p + dt X_v + (dt/2)(…),
  // (X Fᵀ)[:, θ] = X_θ F_θθᵀ + X_bg F_θbgᵀ; old columns are read before they are overwritten.
  Eigen::Matrix<double, kRows, 3> dv, dth;
  dv.noalias() = X.template middleCols<3>(kTheta) * F_vtheta.transpose();
  dv.noalias() += X.template middleCols<3>(kBg) * F_vbg.transpose();
  dv.noalias() += X.template middleCols<3>(kBa) * F_vba.transpose();
  dth.noalias() = X.template middleCols<3>(kTheta) * F_tt.transpose();
  dth.noalias() += X.template middleCols<3>(kBg) * F_tbg.transpose();
  X.template middleCols<3>(kP) += dt * X.template middleCols<3>(kV) + (0.5 * dt) * dv;
  X.template middleCols<3>(kV) += dv;
  X.template middleCols<3>(kTheta) = dth;
}

template <typename Derived>
void CoreTransition::apply_right(Eigen::MatrixBase<Derived>& X) const {
  static_assert(Derived::RowsAtCompileTime != Eigen::Dynamic && Derived::ColsAtCompileTime == 15,
                "apply_right: fixed-size r x 15 block");
  constexpr int kRows = Derived::RowsAtCompileTime;
  // F = I except rows δp (+ dt δv + dt/2 · the δv rows' terms), δv (F_vθ, F_vbg, F_vba) and δθ (F_θθ, F_θbg),
  // so with u = X_v + (dt/2) X_p: (X F)[:, v] = X_v + dt X_p, [:, θ] = u F_vθ + X_θ F_θθ,
  // [:, bg] = X_bg + u F_vbg + X_θ F_θbg, [:, ba] = X_ba + u F_vba; old columns are read first.
  const Eigen::Matrix<double, kRows, 3> u = X.template middleCols<3>(kV) + (0.5 * dt) * X.template middleCols<3>(kP);
  Eigen::Matrix<double, kRows, 3> th;
  th.noalias() = u * F_vtheta;
  th.noalias() += X.template middleCols<3>(kTheta) * F_tt;
  X.template middleCols<3>(kBg).noalias() += u * F_vbg;
  X.template middleCols<3>(kBg).noalias() += X.template middleCols<3>(kTheta) * F_tbg;
  X.template middleCols<3>(kBa).noalias() += u * F_vba;
  X.template middleCols<3>(kV) += dt * X.template middleCols<3>(kP);
  X.template middleCols<3>(kTheta) = th;
}

}  // namespace roe::ekf
