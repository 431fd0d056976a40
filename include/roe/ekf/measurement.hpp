#pragma once
/// @file
/// The object pose sensor of the paper (§III-C): measurement model, residual, H blocks, object-world
/// initialisation with its Jacobians, and the mapping of per-detection sigmas. Pure functions of the
/// nominal state; the filter (filter.hpp) places the blocks into its error-state columns.
///
/// Measurement: the detected T_C_O is inverted to z = T_O_C (paper). Prediction
///   ẑ_p = p_O_W + R_O_W (p_W_I + R_W_I p_I_C),   ẑ_q = q_O_W ⊗ q_W_I ⊗ q_I_C.
/// Residual (paper eq. res_object): r = [z_p − ẑ_p ; 2 δq_v/δq_w],  δq = ẑ_q⁻¹ ⊗ z_q.
/// H = ∂ẑ/∂δx with the error state of DESIGN §2 (additive positions, R = R̂ Exp(δθ)); with
/// p_W_C = p_W_I + R_W_I p_I_C:
///   position rows:    δp_W_I → R_O_W            δθ_W_I → −R_O_W R_W_I [p_I_C]×
///                     δp_I_C → R_O_W R_W_I      δθ_I_C → 0
///                     δp_O_W → I                δθ_O_W → −R_O_W [p_W_C]×
///   orientation rows: δθ_W_I → R_I_Cᵀ          δθ_I_C → I        δθ_O_W → R_I_Cᵀ R_W_Iᵀ
/// (paper eqs. for H_p and H_R; −R_O_W[p_W_I]× − R_O_W[R_W_I p_I_C]× = −R_O_W[p_W_C]×). All other
/// blocks (v, biases, other objects) are zero.
///
/// First sight (paper): R_O_W = R_O_C R_I_Cᵀ R_W_Iᵀ,  p_O_W = p_O_C − R_O_W (R_W_I p_I_C + p_W_I),
/// i.e. T_O_W = z · (T_W_I T_I_C)⁻¹. Its Jacobians (right error of R_O_W, R_O_C):
///   δθ_O_W = R_W_C δz_θ − R_W_C δθ_I_C − R_W_I δθ_W_I
///   δp_O_W = δz_p + R_O_W [p_W_C]× δθ_O_W − R_O_W (δp_W_I + R_W_I δp_I_C − R_W_I [p_I_C]× δθ_W_I)

#include <Eigen/Core>
#include <string>

#include "roe/core/types.hpp"
#include "roe/ekf/imu.hpp"

namespace roe::ekf {

using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat63 = Eigen::Matrix<double, 6, 3>;

/// Predicted measurement and its Jacobian blocks (6x3 each, rows [position; orientation]).
struct ObjectPrediction {
  Pose T_O_C_hat;
  Mat63 H_p_WI, H_theta_WI, H_p_IC, H_theta_IC, H_p_OW, H_theta_OW;
};

/// ẑ = T_O_W T_W_I T_I_C and the H blocks above.
ObjectPrediction predict_object(const CoreState& x, const Pose& T_I_C, const Pose& T_O_W);

/// The camera–IMU time offset t_d (t_imu = t_cam + t_d; Li & Mourikis 2014, OpenVINS): a detection stamped
/// t_cam sees the rig at t_cam + t_d. Shifted in time by τ, the IMU pose moves to first order as
///   p_W_I(t + τ) = p_W_I + v_W_I τ,   R_W_I(t + τ) = R_W_I Exp(ω τ)   (ω = ω_m − b_g, the body rate),
/// (shift_in_time; v, the biases unchanged). So the prediction's derivative with respect to t_d at the time the
/// filter evaluates it is
///   ∂ẑ/∂t_d = H_p_WI v_W_I + H_θ_WI ω   (6x1, rows [position; orientation], the object residual frame),
/// and that of the first-sight object-world J_td = J_p_WI v_W_I + J_θ_WI ω (time_offset_column on the
/// ObjectInit blocks).
CoreState shift_in_time(const CoreState& x, const Vec3& omega_I, double tau_s);
Vec6 time_offset_column(const Mat63& d_p_WI, const Mat63& d_theta_WI, const Vec3& v_W_I, const Vec3& omega_I);

/// Paper residual r = [z_p − ẑ_p ; 2 δq_v/δq_w] of a measurement z = T_O_C.
Vec6 object_residual(const Pose& T_O_C_hat, const Pose& T_O_C_meas);

/// The two parts of the 6-dof residual r = [position (rows 0–2); rotation (rows 3–5)] in either residual
/// frame (object: p_O_C and the right error of R_O_C; camera: t_C_O and the left error of R_C_O), and
/// which of them a detection's update used (reprojection.csv `used`).
enum class ResidualPart { kNone = 0, kPosition = 1, kRotation = 2, kBoth = 3 };
/// "none" / "position" / "rotation" / "both".
std::string to_string(ResidualPart p);
/// The residual rows a part keeps, in increasing order: writes them to `rows` and returns their count.
/// Rows 0–2 are the position, rows 3 … dim−1 the rotation (dim 6; 5 for an object with a continuous
/// symmetry, whose rotation residual has 2 rows, ekf/symmetry.hpp). Selecting rows of r, H and (rows and
/// columns) of R gives the part's own measurement model: r_s = E r, H_s = E H, R_s = E R Eᵀ (the marginal
/// block of R), S_s = E S Eᵀ (the marginal block of S).
int residual_rows(ResidualPart p, int rows[6], int dim = 6);

/// Split χ² gate (3 + 3 dof). Each part is tested alone with its marginal innovation covariance, the
/// diagonal 3x3 block of S = H P Hᵀ + R:
///   NIS_p = r_pᵀ S_pp⁻¹ r_p ≤ gate_position,   NIS_r = r_rᵀ S_rr⁻¹ r_r ≤ gate_rotation
/// (the χ²₃ quantile of the configured confidence; χ²₂ for a 2-row rotation part, whose r and S are
/// padded with a zero row and an identity row/column: the padded NIS is the 2-row NIS). `used` is the part(s) that pass. A non-finite part
/// (the rotation residual 2 q_v/q_w of a detection 180° from the prediction) fails with NIS ∞; the other
/// part is tested as usual. Each test alone has the configured false-rejection rate, so an inlier keeps
/// both parts with probability ≈ confidence² when the parts are independent.
struct SplitGate {
  ResidualPart used = ResidualPart::kNone;
  double nis_position = 0.0, nis_rotation = 0.0;
};
SplitGate split_gate(const Vec6& r, const Mat6& S, double gate_position, double gate_rotation);

/// First-sight object-world T_O_W from z = T_O_C, and its Jacobians (6x3 blocks, rows [δp_O_W; δθ_O_W])
/// with respect to δp_W_I, δθ_W_I, δp_I_C, δθ_I_C and the measurement z (6x6, [δz_p; δz_θ]).
struct ObjectInit {
  Pose T_O_W;
  Mat63 J_p_WI, J_theta_WI, J_p_IC, J_theta_IC;
  Mat6 J_z;
};
ObjectInit init_object(const CoreState& x, const Pose& T_I_C, const Pose& T_O_C_meas);

/// Covariance of the residual-frame measurement error of z = T_O_C given the camera-frame σ of the
/// detected T_C_O = (R, t): σ = (tx, ty, tz, rx, ry, rz), with the convention
///   t_meas = t + n_t,  R_meas = Exp(n_r) R   (rotation noise about the camera axes).
/// Inversion: p_O_C = −Rᵀt, R_O_C = Rᵀ, so δp_O_C = −R_O_C n_t − R_O_C [t]× n_r and
/// δθ_O_C = −n_r:  Σ = J diag(σ²) Jᵀ with J = [[−R_O_C, −R_O_C [t]×], [0, −I]].
Mat6 detection_covariance_in_residual_frame(const Pose& T_C_O, const Vec6& sigma_C);
/// The same for a full camera-frame covariance Σ_C of (n_t, n_r): J Σ_C Jᵀ.
Mat6 detection_covariance_in_residual_frame(const Pose& T_C_O, const Mat6& cov_C);
/// That J: the T_O_C residual-frame error of a detection whose camera-frame error is (n_t, n_r).
Mat6 detection_error_to_residual_frame(const Pose& T_C_O);

/// The Gauss–Markov detection-error state of an object (FilterOptions::detection_error_states; docs/filter.md
/// §17): x = [x_t; x_θ], normalised (stationary covariance I), the translation factors on the camera axes and
/// the rotation factors on the object's axes (a network's rotation error follows the object's appearance;
/// the simulator's R_C_O Exp(δθ)). A detection of T_C_O with camera-frame covariance Σ_C = L Lᵀ (L the
/// symmetric square root) has the camera-frame error
///   (n_t, n_r) = √s L diag(I, R_C_O) x + white,  white ~ N(0, (1 − s) Σ_C),
/// whose stationary covariance is Σ_C whatever R_C_O. Returns G_C = √s L diag(I, R_C_O) (6x6, columns x).
Mat6 gauss_markov_error_jacobian(const Mat6& cov_C, const Mat3& R_C_O, double share);
/// Symmetric square root of a symmetric positive semi-definite 6x6 matrix (negative eigenvalues clipped to 0).
Mat6 symmetric_sqrt(const Mat6& A);

/// Jacobian of the inversion T_W_O = T_O_W⁻¹ in the error-state convention (additive position, right
/// rotation error): [δp_W_O; δθ_W_O] = J [δp_O_W; δθ_O_W] to first order, with
///   J = [[−R_O_Wᵀ, [p_W_O]×], [0, −R_O_W]].
/// (p_W_O = −R_O_Wᵀ p_O_W; R_W_O = Exp(−δθ) R̂_O_Wᵀ = R̂_O_Wᵀ Exp(−R̂_O_W δθ).)
Mat6 inverse_pose_jacobian(const Pose& T_O_W);

/// Jacobian of an object's pose relative to another object A (the anchor), T_A_O = T_A_W · T_O_W⁻¹, in the
/// same convention: [δp_A_O; δθ_A_O] = J [δp_A_W; δθ_A_W; δp_O_W; δθ_O_W] (6x12) to first order, with
/// X = T_A_W, Y = T_O_W, v = R_Yᵀ p_Y:
///   δθ_A_O = R_Y (δθ_X − δθ_Y),
///   δp_A_O = δp_X − R_X R_Yᵀ δp_Y + R_X [v]× (δθ_X − δθ_Y).
/// (R_X Exp(a) Exp(−b) R_Yᵀ = R_X R_Yᵀ Exp(R_Y (a − b)).) Unlike T_W_O, this does not depend on the gauge
/// chosen for W: it is where the object is as seen from the anchor.
Eigen::Matrix<double, 6, 12> relative_pose_jacobian(const Pose& T_A_W, const Pose& T_O_W);

}  // namespace roe::ekf
