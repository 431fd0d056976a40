#pragma once
/// @file
/// Options of the multi-object error-state EKF (DESIGN §6). A plain struct with inline defaults; the
/// app layer loads it strictly from JSON (`"filter": {...}` in configs/*.json, unknown keys are errors)
/// and echoes it into run.json. Defaults are roe's recommended settings; configs/paper.json sets the
/// paper's choices (docs/filter.md lists where they differ and why).

#include <Eigen/Core>
#include <string>

namespace roe::ekf {

/// How the main (anchor) object fixes the gauge of the world frame W.
enum class AnchorGauge {
  /// The anchor's object-world pose T_O_W held fixed in all 6 dof (kept out of the state). Roll and
  /// pitch of W then come from a single noisy detection and disagree with gravity: not recommended.
  kPose,
  /// The paper (§III-C): "the position of the main object's frame with respect to the navigation world
  /// is not changed", i.e. H_{p,p_OmW} = H_{R,p_OmW} = 0; its orientation R_O_W stays estimated
  /// (δθ_x, δθ_y, δθ_z in the state). Yaw is then a free direction held only by its prior.
  kPosition,
  /// roe's default: only the unobservable directions are fixed — the anchor's position and its
  /// rotation about W's z axis (gravity). Its roll/pitch (δθ_x, δθ_y of R_O_W) stay in the state, so
  /// gravity and the detections are fused consistently (4-dof gauge of visual-inertial estimation).
  kPositionYaw,
};

/// "pose" / "position" / "position_yaw".
std::string to_string(AnchorGauge g);
/// Parses to_string's names; returns false for anything else.
bool parse_anchor_gauge(const std::string& s, AnchorGauge& out);

/// Where the 6-dof residual of a detection is formed.
enum class ResidualFrame {
  /// The paper: z = T_O_C (camera in the object frame), r = [p − p̂ ; 2 δq_v/δq_w of q̂⁻¹⊗q].
  /// Detector noise lives in the camera frame, so a rotation error of the detection moves p_O_C by
  /// |t| θ along a sphere: the linear noise model is then poor in exactly the directions where the
  /// measurement is most precise, and the NIS is inflated (measured on `matched`: 9.6 % above a 95 % gate).
  kObject,
  /// roe's default: r = [t − t̂ ; 2 δq_v/δq_w of q⊗q̂⁻¹] on the detected T_C_O itself (left rotation
  /// error, camera axes), H = J_inv H_paper with J_inv the Jacobian of the inversion T_O_C → T_C_O.
  /// The detector's noise enters linearly: consistent NIS (docs/filter.md §3).
  kCamera,
};

std::string to_string(ResidualFrame f);
bool parse_residual_frame(const std::string& s, ResidualFrame& out);

/// How the χ² gate treats a detection's 6-dof residual.
enum class GateMode {
  /// The paper: one test of the whole residual (χ²₆); a detection is used whole or not at all.
  kJoint,
  /// Position and rotation tested separately (χ²₃ each, at the same confidence) and the update made with
  /// the part(s) that pass (ResidualPart, measurement.hpp): a detection whose rotation is wrong (a
  /// symmetric object's flip, an ambiguous view) still gives its position.
  kSplit,
};

/// "joint" / "split".
std::string to_string(GateMode m);
bool parse_gate_mode(const std::string& s, GateMode& out);

struct FilterOptions {
  // --- Measurement model ---
  ResidualFrame residual_frame = ResidualFrame::kCamera;
  /// Fixed measurement σ per axis (position, orientation). The paper's 10 cm / 20° are PoET's own
  /// errors ("the standard deviation of PoET across a video sequence"), i.e. σ of the detected T_C_O
  /// in camera axes; with meas_sigma_in_camera they are mapped through the inversion into the T_O_C
  /// residual frame (notes/filter.md §1.7), otherwise they are put on the residual's axes directly.
  double meas_sigma_p_m = 0.10;      ///< position σ per axis (paper: 10 cm)
  double meas_sigma_rot_deg = 20.0;  ///< orientation σ per axis (paper: 20°)
  bool meas_sigma_in_camera = true;
  /// Depth-dependent, ray-aligned position σ of the detected T_C_O (needs meas_sigma_in_camera or the
  /// camera residual frame). With d = |t_C_O| and u = t_C_O / d the camera-frame position covariance is
  ///   σ_lat² (I − u uᵀ) + σ_ray² u uᵀ,  σ_lat = meas_sigma_p_m + meas_sigma_p_per_depth · d,
  ///   σ_ray = meas_sigma_ray_m + meas_sigma_ray_per_depth · d   (σ_ray = σ_lat when meas_sigma_ray_m < 0).
  /// Monocular detectors are worse along the viewing ray (scale/depth) than across it; the defaults
  /// (0, −1, 0) give the paper's isotropic σ.
  double meas_sigma_p_per_depth = 0.0;
  double meas_sigma_ray_m = -1.0;
  double meas_sigma_ray_per_depth = 0.0;
  /// Use the per-detection sigma columns of detections.csv (camera-frame σ of T_C_O, mapped into the
  /// T_O_C residual frame) where present; the fixed σ above otherwise.
  bool use_detection_sigmas = false;
  /// Scale the per-detection σ by one factor learned online (docs/filter.md §14): the median over the last
  /// detections that carried σ of NIS · k / χ²_m median (k the variance scale they were gated with) is
  /// the variance scale that makes them consistent. Networks' predicted σ are often right in shape and
  /// off in scale; an overconfident σ makes the filter overconfident, and its gate then refuses the
  /// correct detections. The median ignores the gross failures (up to half of them). Ignored (the scale stays
  /// 1) with detection_error_states: their NIS is not the χ² the scale assumes (docs/filter.md §17).
  bool adapt_detection_sigma_scale = false;
  /// Correlation time τ (s) of the detection errors, modelled per object as first-order Gauss-Markov
  /// (docs/filter.md §15). 0 (the paper): white errors. Otherwise the constant states (extrinsics,
  /// object-worlds) are updated as if each detection's noise were k R, k = (1+ρ)/(1−ρ), ρ = exp(−Δt/τ) with
  /// Δt the time since the object's previous detection: the variance inflation of a mean of such errors, so
  /// that what a constant state learns from a run is the number of independent detections in it, not the
  /// number of images. The core (pose, velocity, biases) keeps the gain of R (stacked_update_constant_gain).
  /// With consider_correlated_errors the gain stays the white one and τ enters the consider covariance only.
  double detection_error_correlation_s = 0.0;
  /// Gauss–Markov detection-error states (docs/filter.md §17; issue 49): instead of the inflated gain above,
  /// every object carries a 6-dof error state x (normalised, unit stationary variance) that its detections
  /// share: a detection's camera-frame error is n = √s L (x_t; R_C_O x_θ) + the white rest, L L = Σ_C the
  /// detection covariance (meas_sigma_*, or the detection's σ, unscaled), s =
  /// detection_error_correlated_share; x decays between that object's detections as x ← ρ x + √(1−ρ²) w,
  /// ρ = exp(−Δt/τ), τ = detection_error_correlation_s (> 0 required). The RTS smoother takes each decay as a
  /// linear link (smoother.hpp), so it is consistent with the augmented model.
  bool detection_error_states = false;
  /// Share s of the detection-error variance that is correlated (in (0, 1)); the white rest (1 − s) Σ.
  double detection_error_correlated_share = 0.9;
  /// The consider covariance for detection errors correlated in time (docs/filter.md §18; issue 49): the
  /// filter's mean, gain, gate and smoother stay those of white errors (as with detection_error_correlation_s
  /// 0), and beside its covariance P it keeps an actual covariance P_a, updated in Joseph form with that gain
  /// and the white-equivalent noise of §15 for τ = detection_error_correlation_s (> 0 required; not with
  /// detection_error_states). Every σ the filter reports (states.csv, objects.csv, run.json final) is P_a's;
  /// the smoothed trajectory's is the smoother's (nominal).
  bool consider_correlated_errors = false;
  /// Detections with a finite score below this are ignored (status rejected_score). 0 keeps all.
  double min_score = 0.0;

  // --- Outlier gate: χ² test per object on its 6-dof residual with its own S ---
  bool chi2_gate = true;
  double chi2_confidence = 0.95;  ///< gate = χ²₆ quantile at this probability (split: χ²₃ per part)
  GateMode gate_mode = GateMode::kJoint;

  // --- Re-lock after a lock-out (relock.hpp, docs/filter.md §13) ---
  /// When every detection's position has been refused by the gate for at least this long while the refused
  /// detections agree on where the camera is, the position estimate is declared lost and the covariance of
  /// the position and velocity inflated by the observed offset and drift, so that the next detections pull
  /// it back. 0: never (the paper: a gate that, once the estimate has drifted, refuses every later detection).
  double relock_after_s = 0.0;
  /// Refused detections needed for that decision (at least 3).
  int relock_min_detections = 6;

  // --- Anchor (main object) ---
  /// Object id of the anchor; −1 = chosen by the rule of choose_anchor (images.hpp): among the objects
  /// of the first usable image, the one detected in the most images, then the lowest id. run_filter
  /// applies it over the whole run; Filter::update alone knows one image (every count 1: lowest id).
  int anchor_id = -1;
  AnchorGauge anchor_gauge = AnchorGauge::kPositionYaw;
  /// true (paper): frames in which the anchor is not detected are rejected (status rejected_no_main);
  /// false: updates (and first-sight initialisations) from other objects are used as well.
  bool require_anchor = true;

  // --- First sight: an object-world (and the anchor) is initialised only after this many consecutive
  // detections of the object whose implied T_O_W agree within the gates below (1 = the paper: the
  // first detection). Guards against initialising from an outlier, which no later update can repair.
  int init_min_detections = 3;
  double init_gate_p_m = 0.3;
  double init_gate_rot_deg = 30.0;

  // --- Camera-IMU extrinsics T_I_C (self-calibration) ---
  bool estimate_extrinsics = true;        ///< false: held fixed at the dataset prior (not in the state)
  double extrinsics_sigma_p_m = 0.02;     ///< prior σ of p_I_C per axis
  double extrinsics_sigma_rot_deg = 2.0;  ///< prior σ of δθ_I_C per axis

  // --- Camera–IMU time offset t_d (t_imu = t_cam + t_d; Li & Mourikis 2014, docs/filter.md §16) ---
  /// true: t_d is an error state (prior = the dataset's camera.time_offset_s, σ time_offset_sigma_s); each
  /// image is processed at t_cam + t̂_d and its detections predicted with the Jacobian ∂ẑ/∂t_d = H_p v + H_θ ω.
  /// false (the paper): the declared offset is taken as exact.
  bool estimate_time_offset = false;
  double time_offset_sigma_s = 0.02;  ///< prior σ of t_d (s): tens of ms (a D435i colour stream, a network's stamps)

  // --- IMU noise (continuous time). Negative = take the dataset's roe.json imu values ---
  double gyro_noise_density = -1.0;   ///< rad/s/√Hz
  double gyro_random_walk = -1.0;     ///< rad/s²/√Hz
  double accel_noise_density = -1.0;  ///< m/s²/√Hz
  double accel_random_walk = -1.0;    ///< m/s³/√Hz
  double imu_noise_scale = 1.0;       ///< multiplies all four densities (inflation for real IMUs)

  // --- Initialisation: IMU at the origin of W, v = 0, yaw 0, roll/pitch from the mean accelerometer ---
  double init_window_s = 0.2;  ///< accelerometer averaging window from the first IMU sample
  Eigen::Vector3d init_gyro_bias = Eigen::Vector3d::Zero();   ///< rad/s
  /// Take the initial gyro bias from the gyro mean over the init window when that window is at rest
  /// (every axis's sample σ within init_rest_max_gyro_std and init_rest_max_accel_std); otherwise
  /// init_gyro_bias is kept and FilterRunSummary says why. For recordings that start standing still
  /// (EuRoC, TUM-VI, most handheld recordings): a MEMS gyro bias of several σ of
  /// init_sigma_gyro_bias turns into a yaw drift the detections correct only slowly.
  bool init_gyro_bias_from_rest = false;
  double init_rest_max_gyro_std = 0.01;  ///< rad/s, per-axis sample σ over the window
  double init_rest_max_accel_std = 0.1;  ///< m/s², per-axis sample σ over the window
  Eigen::Vector3d init_accel_bias = Eigen::Vector3d::Zero();  ///< m/s²
  double init_sigma_p_m = 0.01;
  double init_sigma_v_mps = 0.5;
  double init_sigma_roll_pitch_deg = 3.0;
  double init_sigma_yaw_deg = 5.0;
  double init_sigma_gyro_bias = 0.01;  ///< rad/s
  double init_sigma_accel_bias = 0.1;  ///< m/s²

  // --- Guard rails (NumericError beyond these) ---
  double max_position_m = 1.0e3;
  double max_velocity_mps = 50.0;
  double max_gyro_bias = 1.0;   ///< rad/s
  double max_accel_bias = 5.0;  ///< m/s²
  double max_time_offset_s = 0.5;  ///< |t̂_d − declared| (s)
  int pd_check_every = 30;      ///< full Cholesky test of P every N updates (and after init/augment)
};

}  // namespace roe::ekf
