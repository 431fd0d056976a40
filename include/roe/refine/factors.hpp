#pragma once
/// @file
/// The residuals of the batch refinement (docs/refine.md §2), templated for Ceres' automatic
/// differentiation (so there are no hand-written Jacobians: tests/refine check the residuals against an
/// independent computation with the filter's own functions instead). I/O-free; Ceres appears only in
/// refine.cpp, these functors use nothing but Eigen.
///
/// Parameter blocks (DESIGN §2 conventions):
///   pose        [p (3), q (x y z w)]: T_W_I of a node, T_I_C, T_O_W of an object; tangent [δp; δθ] with
///               p = p̂ + δp, R = R̂ Exp(δθ) (the filter's error state, so marginal covariances are in
///               the same coordinates as the filter's σ)
///   velocity    v_W_I of a node; bias [b_g, b_a] of a node (additive)
/// The anchor object's T_O_W keeps only its tilt δθ_x, δθ_y (AnchorTiltPlus; docs/refine.md §3).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

namespace roe::refine {

template <typename T>
using V3 = Eigen::Matrix<T, 3, 1>;
template <typename T>
using Q = Eigen::Quaternion<T>;

/// Exp of a rotation vector as a unit quaternion (Taylor series below 1e-12 rad²).
template <typename T>
Q<T> exp_q(const V3<T>& phi) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const T th2 = phi.squaredNorm();
  T w, s;
  if (th2 > T(1e-12)) {
    const T th = sqrt(th2);
    w = cos(th / T(2));
    s = sin(th / T(2)) / th;
  } else {
    w = T(1) - th2 / T(8);
    s = T(0.5) - th2 / T(48);
  }
  return Q<T>(w, s * phi(0), s * phi(1), s * phi(2));
}

/// Log of a unit quaternion (norm in [0, π]; the hemisphere of q does not matter).
template <typename T>
V3<T> log_q(const Q<T>& q_in) {
  using std::atan2;
  using std::sqrt;
  const Q<T> q = q_in.w() < T(0) ? Q<T>(-q_in.w(), -q_in.x(), -q_in.y(), -q_in.z()) : q_in;
  const V3<T> v = q.vec();
  const T n2 = v.squaredNorm();
  if (n2 > T(1e-20)) {
    const T n = sqrt(n2);
    return v * (T(2) * atan2(n, q.w()) / n);
  }
  return v * (T(2) / q.w());
}

/// Pose block ⊞/⊟: p + δp, q ⊗ Exp(δθ) (ceres::AutoDiffManifold<PosePlus, 7, 6>).
struct PosePlus {
  template <typename T>
  bool Plus(const T* x, const T* d, T* out) const {
    for (int i = 0; i < 3; ++i) out[i] = x[i] + d[i];
    Eigen::Map<Q<T>>(out + 3) = Eigen::Map<const Q<T>>(x + 3) * exp_q<T>(V3<T>(d[3], d[4], d[5]));
    return true;
  }
  template <typename T>
  bool Minus(const T* y, const T* x, T* d) const {
    for (int i = 0; i < 3; ++i) d[i] = y[i] - x[i];
    const V3<T> th = log_q<T>(Eigen::Map<const Q<T>>(x + 3).conjugate() * Eigen::Map<const Q<T>>(y + 3));
    for (int i = 0; i < 3; ++i) d[3 + i] = th(i);
    return true;
  }
};

/// The anchor's T_O_W: position fixed, rotation q ⊗ Exp([δθ_x, δθ_y, 0]) (ceres::AutoDiffManifold<…, 7, 2>).
struct AnchorTiltPlus {
  template <typename T>
  bool Plus(const T* x, const T* d, T* out) const {
    for (int i = 0; i < 3; ++i) out[i] = x[i];
    Eigen::Map<Q<T>>(out + 3) = Eigen::Map<const Q<T>>(x + 3) * exp_q<T>(V3<T>(d[0], d[1], T(0)));
    return true;
  }
  template <typename T>
  bool Minus(const T* y, const T* x, T* d) const {
    const V3<T> th = log_q<T>(Eigen::Map<const Q<T>>(x + 3).conjugate() * Eigen::Map<const Q<T>>(y + 3));
    d[0] = th(0);
    d[1] = th(1);
    return true;
  }
};

/// The error of one detection of an object (T_C_O measured) against the node's T_W_I, the extrinsics T_I_C
/// and the object-world T_O_W, in the frames where a pose detector's error arises (docs/refine.md §2):
///   e = [t − t̂ ; Log(R̂ᵀ R)]     (detected T_C_O = (R, t), predicted T̂_C_O = (T_O_W T_W_I T_I_C)⁻¹)
/// the translation in the camera frame (the σ model then projects it on the viewing ray and across it),
/// the rotation on the right, in the object frame. A detection R Exp(δθ), t + δt has e = (δt, δθ) exactly
/// at the truth, as roe simulate draws it (docs/simulator.md §6).
template <typename T>
Eigen::Matrix<T, 6, 1> detection_error(const Eigen::Quaterniond& q_meas, const Eigen::Vector3d& t_meas,
                                       const T* pose_WI, const T* pose_IC, const T* pose_OW) {
  const Eigen::Map<const V3<T>> p_WI(pose_WI), p_IC(pose_IC), p_OW(pose_OW);
  const Eigen::Map<const Q<T>> q_WI(pose_WI + 3), q_IC(pose_IC + 3), q_OW(pose_OW + 3);
  // T_O_C = T_O_W T_W_I T_I_C; T̂_C_O = T_O_C⁻¹, so R̂ᵀ R = R_O_C R.
  const Q<T> q_OC = q_OW * q_WI * q_IC;
  const V3<T> p_OC = p_OW + q_OW * (p_WI + q_WI * p_IC);
  const V3<T> t_CO = -(q_OC.conjugate() * p_OC);
  Eigen::Matrix<T, 6, 1> e;
  e.template head<3>() = t_meas.cast<T>() - t_CO;
  e.template tail<3>() = log_q<T>(q_OC * q_meas.cast<T>());
  return e;
}

/// An object's first used detection (no predecessor in its chain): r = A e, A = the standardising matrix
/// S (docs/refine.md §2: the ray frame and σ, the fitted scales, a continuous symmetry projected out).
struct FirstDetectionResidual {
  Eigen::Quaterniond q_meas;  ///< detected R_C_O (a symmetric object's nearest equivalent)
  Eigen::Vector3d t_meas;     ///< detected t_C_O
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Identity();

  template <typename T>
  bool operator()(const T* pose_WI, const T* pose_IC, const T* pose_OW, T* r) const {
    Eigen::Map<Eigen::Matrix<T, 6, 1>> out(r);
    out = A.cast<T>() * detection_error<T>(q_meas, t_meas, pose_WI, pose_IC, pose_OW);
    return true;
  }
};

/// The pre-whitened factor of an object's detection k after its previous used detection k−1 (Bryson and
/// Henrikson's differencing of a first-order Gauss-Markov error; docs/refine.md §2):
///   r = (y_k − ρ y_{k−1}) / √(1 − ρ²),  y = S e,  ρ = exp(−Δt/τ)
/// stored as A = S_k / √(1 − ρ²) and B = ρ S_{k−1} / √(1 − ρ²): r = A e_k − B e_{k−1}. Blocks: the node of
/// k, T_I_C, T_O_W, the node of k−1.
struct WhitenedDetectionResidual {
  Eigen::Quaterniond q_meas, q_prev;
  Eigen::Vector3d t_meas, t_prev;
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Identity();
  Eigen::Matrix<double, 6, 6> B = Eigen::Matrix<double, 6, 6>::Zero();

  template <typename T>
  bool operator()(const T* pose_WI, const T* pose_IC, const T* pose_OW, const T* pose_WI_prev, T* r) const {
    Eigen::Map<Eigen::Matrix<T, 6, 1>> out(r);
    out = A.cast<T>() * detection_error<T>(q_meas, t_meas, pose_WI, pose_IC, pose_OW) -
          B.cast<T>() * detection_error<T>(q_prev, t_prev, pose_WI_prev, pose_IC, pose_OW);
    return true;
  }
};

/// IMU preintegration between nodes i and j (preintegration.hpp). With δb = b_i − b̄ (the biases it was
/// integrated with) and J = ∂[δp; δv; δθ]/∂[δb_g; δb_a]:
///   e_p = R_iᵀ(p_j − p_i − v_i Δt + ½ g Δt²) − (Δp̄ + J_p δb)
///   e_v = R_iᵀ(v_j − v_i + g Δt) − (Δv̄ + J_v δb)
///   e_θ = Log((ΔR̄ Exp(J_θ δb))ᵀ R_iᵀ R_j)
/// r = W e with W the square root information of the preintegration covariance. Blocks: pose_i, v_i,
/// b_i = [b_g, b_a], pose_j, v_j.
struct ImuResidual {
  Eigen::Quaterniond dR;
  Eigen::Vector3d dv, dp, bg_lin, ba_lin, gravity;
  double dt = 0.0;
  Eigen::Matrix<double, 9, 6> J_bias;
  Eigen::Matrix<double, 9, 9> W;

  template <typename T>
  bool operator()(const T* pose_i, const T* v_i_, const T* b_i, const T* pose_j, const T* v_j_, T* r) const {
    const Eigen::Map<const V3<T>> p_i(pose_i), p_j(pose_j), v_i(v_i_), v_j(v_j_);
    const Eigen::Map<const Q<T>> q_i(pose_i + 3), q_j(pose_j + 3);
    Eigen::Matrix<T, 6, 1> db;
    for (int k = 0; k < 3; ++k) {
      db(k) = b_i[k] - T(bg_lin(k));
      db(3 + k) = b_i[3 + k] - T(ba_lin(k));
    }
    const Eigen::Matrix<T, 9, 1> corr = J_bias.cast<T>() * db;
    const T Dt(dt);
    const V3<T> g = gravity.cast<T>();
    const Q<T> qi_inv = q_i.conjugate();
    Eigen::Matrix<T, 9, 1> e;
    e.template segment<3>(0) =
        qi_inv * (p_j - p_i - v_i * Dt + T(0.5) * g * Dt * Dt) - (dp.cast<T>() + corr.template segment<3>(0));
    e.template segment<3>(3) = qi_inv * (v_j - v_i + g * Dt) - (dv.cast<T>() + corr.template segment<3>(3));
    const Q<T> dR_corr = dR.cast<T>() * exp_q<T>(V3<T>(corr.template segment<3>(6)));
    e.template segment<3>(6) = log_q<T>(dR_corr.conjugate() * qi_inv * q_j);
    Eigen::Map<Eigen::Matrix<T, 9, 1>> out(r);
    out = W.cast<T>().template triangularView<Eigen::Lower>() * e;
    return true;
  }
};

/// The bias random walk between nodes i and j: r = [(b_g,j − b_g,i)/σ_g ; (b_a,j − b_a,i)/σ_a] with
/// σ² = σ_bw² Δt per axis (inv_sigma holds the six 1/σ).
struct BiasWalkResidual {
  Eigen::Matrix<double, 6, 1> inv_sigma;

  template <typename T>
  bool operator()(const T* b_i, const T* b_j, T* r) const {
    for (int k = 0; k < 6; ++k) r[k] = (b_j[k] - b_i[k]) * T(inv_sigma(k));
    return true;
  }
};

/// A Gaussian prior on a pose block: r = W [p − p̄ ; Log(R̄ᵀ R)] (the extrinsics' prior).
struct PosePriorResidual {
  Eigen::Quaterniond q_prior;
  Eigen::Vector3d p_prior;
  Eigen::Matrix<double, 6, 6> W = Eigen::Matrix<double, 6, 6>::Identity();

  template <typename T>
  bool operator()(const T* pose, T* r) const {
    Eigen::Matrix<T, 6, 1> e;
    e.template head<3>() = Eigen::Map<const V3<T>>(pose) - p_prior.cast<T>();
    e.template tail<3>() = log_q<T>(q_prior.cast<T>().conjugate() * Eigen::Map<const Q<T>>(pose + 3));
    Eigen::Map<Eigen::Matrix<T, 6, 1>> out(r);
    out = W.cast<T>() * e;
    return true;
  }
};

/// A Gaussian prior on a scalar block (the time offset's δ): r = (x − x̄) / σ.
struct ScalarPriorResidual {
  double prior = 0.0;
  double inv_sigma = 1.0;

  template <typename T>
  bool operator()(const T* x, T* r) const {
    r[0] = (x[0] - T(prior)) * T(inv_sigma);
    return true;
  }
};

/// A Gaussian prior on a bias block: r = W [b_g − b̄_g ; b_a − b̄_a].
struct BiasPriorResidual {
  Eigen::Matrix<double, 6, 1> b_prior;
  Eigen::Matrix<double, 6, 6> W = Eigen::Matrix<double, 6, 6>::Identity();

  template <typename T>
  bool operator()(const T* b, T* r) const {
    Eigen::Matrix<T, 6, 1> e;
    for (int i = 0; i < 6; ++i) e(i) = b[i] - T(b_prior(i));
    Eigen::Map<Eigen::Matrix<T, 6, 1>> out(r);
    out = W.cast<T>() * e;
    return true;
  }
};

/// Analytic Jacobians (docs/refine.md §7; tests/refine/test_factors.cpp checks each against central
/// differences). Tangent Jacobians are in the blocks' [δp; δθ] (or the vector's) coordinates.
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

/// detection_error on doubles with its Jacobians in the tangents of T_W_I, T_I_C and T_O_W (any may be null).
Vec6 detection_error_jacobians(const Eigen::Quaterniond& q_meas, const Eigen::Vector3d& t_meas, const double* pose_WI,
                               const double* pose_IC, const double* pose_OW, Mat6* J_WI, Mat6* J_IC, Mat6* J_OW);

/// The camera–IMU time offset in the batch (docs/refine.md §2b): a detection stamped t (the IMU clock with the
/// declared offset) saw the rig at t + δ, δ = t_d − the declared offset, and the node's pose is carried there with
/// its velocity and the bias-corrected gyro ω measured at t: T_W_I(t + δ) ≈ [p + v δ ; q ⊗ Exp((ω − b_g) δ)].
/// The detection error at that pose, with its Jacobians in the tangents of the node's pose (6x6), v (6x3), its
/// bias block [b_g, b_a] (6x6), T_I_C, T_O_W (6x6 each) and δ (6x1) (any may be null).
struct TimeShiftJacobians {
  Mat6 pose, bias, extr, obj;
  Eigen::Matrix<double, 6, 3> vel;
  Vec6 delta;
};
Vec6 shifted_detection_error_jacobians(const Eigen::Quaterniond& q_meas, const Eigen::Vector3d& t_meas,
                                       const double* pose_WI, const double* v_WI, const double* bias,
                                       const Eigen::Vector3d& gyro, double delta, const double* pose_IC,
                                       const double* pose_OW, TimeShiftJacobians* J);

/// ImuResidual's unwhitened error e (9) on doubles with its Jacobians in the tangents of pose_i (9x6), v_i
/// (9x3), b_i (9x6), pose_j (9x6), v_j (9x3) (any may be null).
Eigen::Matrix<double, 9, 1> imu_error_jacobians(const ImuResidual& f, const double* pose_i, const double* v_i,
                                                const double* b_i, const double* pose_j, const double* v_j,
                                                Eigen::Matrix<double, 9, 6>* J_pose_i, Eigen::Matrix<double, 9, 3>* J_v_i,
                                                Eigen::Matrix<double, 9, 6>* J_b_i, Eigen::Matrix<double, 9, 6>* J_pose_j,
                                                Eigen::Matrix<double, 9, 3>* J_v_j);

/// The ambient (7-column) Jacobian of a pose block whose tangent Jacobian is J (k x 6), for the pose
/// manifold (PosePlus): J_amb · PlusJacobian = J. The quaternion's 4 columns are 4 J_θ Mᵀ with
/// M = ∂(q ⊗ Exp(δθ))/∂δθ at 0 = ½ [w I + [q_v]×; −q_vᵀ] (MᵀM = I/4).
void pose_ambient_jacobian(const double* pose, const double* J_tangent, int rows, double* J_ambient);

/// The square root information W (Wᵀ W = Σ⁻¹, lower triangular) of a covariance: W = L⁻¹ with Σ = L Lᵀ.
/// roe::NumericError when Σ is not positive definite.
Eigen::MatrixXd sqrt_information(const Eigen::MatrixXd& cov);

}  // namespace roe::refine
