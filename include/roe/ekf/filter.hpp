#pragma once
/// @file
/// The self-calibrating multi-object error-state EKF of the paper (§III), DESIGN §6.
///
/// The nominal state is one StateEstimate (state.hpp), corrected in place with its ⊞.
/// Error state (this order, one dense covariance P behind one door, the FilterCovariance member (covariance.hpp):
/// the only code that changes P — propagation with the lazy cross terms, augmentation, the anchor's change of
/// variables, the stacked update, symmetrisation, the checks, the recording's covariance; this class holds the
/// policy and the maths that decide what to apply, and reads P through const accessors):
///   [δp_W_I, δv_W_I, δθ_W_I, δb_g, δb_a | δp_I_C, δθ_I_C | per object: δp_O_W, δθ_O_W]
/// - the extrinsics block is present only with FilterOptions::estimate_extrinsics;
/// - objects are appended on first sight (augmentation with J_x P J_xᵀ + J_z R J_zᵀ and cross terms
///   J_x P, measurement.hpp);
/// - the anchor (main object) has no position error state (the paper zeroes H_{p,p_OmW}, which is
///   equivalent); of its rotation it keeps δθ_O_W (kPosition, the paper), only the tilt δθ_x, δθ_y
///   (kPositionYaw, roe's default) or nothing (kPose). On its first sight the gauge of W is fixed by an exact
///   linear change of variables (docs/filter.md §4): the world is re-defined so that the fixed components of
///   the anchor are exactly their initial estimate, and the uncertainty that was in the anchor moves into the
///   IMU pose, velocity and the other object-worlds (δx' = δx + G Γ δa, P' = M P_aug Mᵀ).
///
/// Propagation is block-sparse: only the 15 core rows/columns change. P_cc is propagated every IMU
/// sample with every product on contiguous columns: C = P_cc Fᵀ (only C's columns p, v, θ change), then
/// only the 9x9 block B[0:9, 0:9] of B = F C = Cᵀ Fᵀ needs a second product (B's bias rows/columns are C's),
/// and of it only the lower block triangle (mirrored; diagonal blocks symmetrised), + Q. The core/rest cross-covariance is updated lazily with the accumulated transition
/// Φ = F_k⋯F_1 (kept transposed, only its non-trivial columns θ, b_g, b_a multiplied) the next time it is
/// needed (update, augmentation, covariance()). Between images P_cc lives in a fixed-size 15x15 member and
/// goes back into P with that sync (a copy); FilterCovariance, covariance.hpp. No heap allocation per IMU
/// sample; one per image (the FrameResult's detection list).
///
/// Update per image: residual and H per detection of an initialised object (the paper's T_O_C
/// residual, or the same model with the residual formed on T_C_O, FilterOptions::residual_frame), a χ² test
/// per object on its own 6x6 S_k = H_k P H_kᵀ + R_k, all inliers stacked into one update. What is computed:
/// P H_kᵀ from H_k's ≤ 18 non-zero columns (runs of contiguous state columns); the stacked S's diagonal
/// blocks are the gate's S_k, its off-diagonal blocks H_a (P H_cᵀ) are evaluated once and mirrored; S = L Lᵀ
/// (Cholesky in place; not positive definite → guard rail), W = P Hᵀ L⁻ᵀ by one triangular solve (no
/// explicit inverse; K = W L⁻¹), δx = W L⁻¹ r, and the posterior P − W Wᵀ (the Joseph form
/// (I−KH)P(I−KH)ᵀ + KRKᵀ for this optimal K) as a rank-m product on the lower triangle only (n²m/2
/// multiply-adds), then mirrored (symmetrisation); stacked_update.hpp.
/// Guard rails throw roe::NumericError naming the time and what broke: state bounds after every update
/// and object initialisation (the core state after every IMU sample), the covariance diagonal every time,
/// a full Cholesky test of P every FilterOptions::pd_check_every updates and after every augmentation.

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/ekf/covariance.hpp"
#include "roe/ekf/imu.hpp"
#include "roe/ekf/measurement.hpp"
#include "roe/ekf/options.hpp"
#include "roe/ekf/relock.hpp"
#include "roe/ekf/smoother.hpp"
#include "roe/ekf/state.hpp"
#include "roe/ekf/symmetry.hpp"

namespace roe::ekf {

/// What happened to one detection (reprojection.csv `status`).
enum class DetectionStatus {
  kAccepted,        ///< used in the update (passed the χ² gate)
  kInitialized,     ///< first sight: its object-world was initialised from it (anchor: gauge fixed)
  kRejectedChi2,    ///< failed the χ² gate
  kRejectedNoMain,  ///< frame without the anchor (require_anchor)
  kRejectedScore,   ///< score below min_score
  kRejectedNoImu,   ///< frame outside the IMU stream (before the first / after the last sample)
  kPendingInit,     ///< first sight not yet confirmed (FilterOptions::init_min_detections)
};
std::string to_string(DetectionStatus s);

struct DetectionOutcome {
  int object_id = 0;
  DetectionStatus status = DetectionStatus::kAccepted;
  double nis = std::numeric_limits<double>::quiet_NaN();  ///< rᵀ S⁻¹ r before the update (6 dof)
  /// The part(s) of the residual the update used: kBoth for an accepted detection with the joint gate
  /// and for a first sight (initialised from the whole detection); with the split gate the part(s) that
  /// passed; kNone for every other status.
  ResidualPart used = ResidualPart::kNone;
  /// Angle of the detection's rotation residual before the update (deg; 180 for a flip whose 2 q_v/q_w is
  /// infinite), for every gated detection with a 6-row residual; NaN otherwise (run health, health.hpp).
  double rot_residual_deg = std::numeric_limits<double>::quiet_NaN();
  bool has_T_W_I = false;                                 ///< false while the object has no object-world yet
  /// IMU pose implied by the raw detection and the current object-world estimate:
  /// T_W_I = T_O_W⁻¹ · T_O_C · T_I_C⁻¹ (paper Fig. 3, "obj").
  Pose T_W_I;
};

struct FrameResult {
  Timestamp t_ns = 0;
  std::vector<DetectionOutcome> detections;  ///< in the order given to update()
  int n_inliers = 0;                         ///< detections used in the stacked update
  /// The update used the position part of at least one detection: the estimate's position is supported
  /// by this image (run health; an update with rotations only does not bound the position's drift).
  bool position_used = false;
  /// Set when, before this image's gate, the position estimate was declared lost and its covariance
  /// inflated (FilterOptions::relock_after_s, relock.hpp).
  std::optional<Relock> relock;
};

class Filter {
 public:
  /// `time_offset_prior_s`: the declared camera–IMU offset (roe.json camera.time_offset_s) the images' stamps
  /// were already shifted by (images.hpp); the prior of t_d with FilterOptions::estimate_time_offset.
  Filter(const FilterOptions& options, const ImuNoiseParams& noise, const Pose& T_I_C_prior,
         double time_offset_prior_s = 0.0);

  /// Starts the filter at t0 with the IMU at the origin of W, v = 0, yaw 0 and roll/pitch from
  /// `mean_accel` (the accelerometer mean over the init window, minus the configured bias); gyro0 and
  /// accel0 are the IMU measurement at t0 (start of the first integration interval). The gyro bias
  /// starts at `gyro_bias` when given (run_filter: the init window's mean at rest), else at
  /// FilterOptions::init_gyro_bias.
  void initialize(Timestamp t0, const Vec3& gyro0, const Vec3& accel0, const Vec3& mean_accel,
                  const Vec3* gyro_bias = nullptr);
  bool initialized() const { return initialized_; }

  /// Propagates to t (> time()) with the IMU measurement at t (midpoint integrator, imu.hpp).
  void propagate(Timestamp t, const Vec3& gyro, const Vec3& accel);
  /// One image at time() + dt_image_s: gate, stacked update, first-sight initialisations. The image is normally
  /// processed at its own time (dt_image_s = 0: run_filter propagates to t_cam + t̂_d); an image whose time
  /// lies a little before time() (t̂_d moved back by more than the gap to the last IMU sample) is predicted
  /// with the state shifted by dt_image_s (shift_in_time, measurement.hpp).
  FrameResult update(const std::vector<Detection>& detections, double dt_image_s = 0.0);

  Timestamp time() const { return s_.t_ns; }
  const CoreState& core() const { return s_.x; }
  /// The IMU's angular rate at time(), ω = ω_m − b̂_g (body axes): with v_W_I, what moves a prediction in time.
  Vec3 body_rate() const { return gyro_ - s_.x.b_g; }
  const Pose& T_I_C() const { return s_.T_I_C; }
  const std::vector<ObjectEntry>& objects() const { return s_.objects; }
  /// nullptr when the object has no object-world yet.
  const ObjectEntry* object(int id) const;
  int anchor_id() const { return anchor_id_; }
  int dim() const { return s_.dim; }
  int extrinsics_offset() const { return s_.extr_offset; }
  /// The camera–IMU time offset t̂_d (s; the declared prior when it is not estimated) and its error-state
  /// column (−1: not estimated).
  double time_offset_s() const { return s_.t_d; }
  int time_offset_offset() const { return s_.td_offset; }
  /// t̂_d − the declared prior, in ns: what run_filter adds to the images' (prior-shifted) stamps.
  Timestamp time_offset_shift_ns() const;
  /// Diagonal entry of the reported covariance (always current, also between updates): P, or the consider
  /// covariance P_a with consider_correlated_errors (docs/filter.md §18). Every σ the filter reports reads it
  /// (variance, core_covariance, object_covariance*); the gain and the gate read P.
  double variance(int i) const { return cov_.reported_variance(i); }
  /// Entry (i, j) of the core 15x15 block of the reported covariance (always current).
  double core_covariance(int i, int j) const { return cov_.reported_core(i, j); }
  /// Covariance of an object's error state [δp_O_W; δθ_O_W] (6x6; rows/columns of components the
  /// anchor does not estimate are 0). Always current: propagation changes only the core rows/columns.
  Mat6 object_covariance(const ObjectEntry& o) const;
  /// Covariance of the object's pose in W, T_W_O = T_O_W⁻¹, as [δp_W_O; δθ_W_O] with the same right
  /// perturbation (R_W_O = R̂_W_O Exp(δθ_W_O)): J P_O Jᵀ with J = inverse_pose_jacobian (measurement.hpp).
  /// Unlike δp_O_W (the origin of W seen from the object, whose σ grows with the object's orientation σ
  /// times its distance to the origin of W), δp_W_O is the uncertainty of where the object is.
  Mat6 object_covariance_in_world(const ObjectEntry& o) const;
  /// Covariance of the object's pose relative to the anchor A, T_A_O = T_A_W T_O_W⁻¹, as [δp_A_O; δθ_A_O]
  /// (relative_pose_jacobian, measurement.hpp, with the anchor/object cross-covariance). Gauge-free:
  /// it does not contain the uncertainty of how W is pinned to the anchor. Zero for the anchor itself or
  /// before the anchor is initialised. Always current, like object_covariance.
  Mat6 object_covariance_relative_to_anchor(const ObjectEntry& o) const;
  /// Symmetries of the objects (by id; objects not listed have none): from then on their residuals use
  /// the symmetry-equivalent measurement nearest the prediction, and a continuous symmetry removes the
  /// rotation about its axis from residual and gate (5 dof; ekf/symmetry.hpp).
  void set_symmetries(std::map<int, ObjectSymmetry> symmetries) { symmetries_ = std::move(symmetries); }
  const ObjectSymmetry* symmetry(int object_id) const;
  /// The full covariance, brought up to date (applies the pending cross-covariance transition).
  const Eigen::MatrixXd& covariance();
  /// The reported covariance brought up to date: the consider covariance P_a, or P when it is off.
  const Eigen::MatrixXd& reported_covariance() { return cov_.reported_full(); }
  const FilterOptions& options() const { return opt_; }
  std::size_t n_updates() const { return n_updates_; }
  /// The factor the per-detection σ are multiplied with (1 unless adapt_detection_sigma_scale).
  double detection_sigma_scale() const { return std::sqrt(sigma_var_scale_); }

  /// From now on, records into `rec` what the RTS smoother needs (smoother.hpp): call before
  /// initialize(), and finish_recording() after the last propagate(). nullptr stops recording.
  void set_recording(FilterRecording* rec) { rec_ = rec; }
  /// Closes the recording's last propagation segment.
  void finish_recording();
  /// The nominal state with its error-state layout.
  StateEstimate snapshot() const;

  // --- Lower-level access (tests, diagnostics) ---
  /// x ← x ⊞ δx with the error-state definition above (the correction step of update()).
  void boxplus(const Eigen::VectorXd& dx);
  /// Predicted T_O_C of an initialised object.
  Pose predict(int object_id) const;
  /// Residual and the full 6 x dim() Jacobian H of one detection of an initialised object, in the
  /// configured residual frame (z is T_O_C; a discrete symmetry's nearest equivalent is used; an object
  /// with a continuous symmetry has 5 rows: measurement_rows).
  void measurement_jacobian(int object_id, const Pose& T_O_C_meas, Vec6& r, Eigen::MatrixXd& H) const;
  /// The rows of that residual and H that an update with `part` uses (residual_rows, measurement.hpp):
  /// the selection Filter::update applies after the split gate. r is m, H is m x dim().
  void measurement_rows(int object_id, const Pose& T_O_C_meas, ResidualPart part, Eigen::VectorXd& r,
                        Eigen::MatrixXd& H) const;
  /// The generator of an infinitesimal change of W (γ = [t; φ]: x_W = Exp(φ) x_W' + t) acting on the
  /// current error state: δx' = δx + G γ (dim() x 6).
  Eigen::MatrixXd gauge_generator() const;
  /// Measurement noise R of a detection in the update's residual frame, or (object_frame) in the
  /// T_O_C frame used by the first-sight initialisation (options: meas_sigma_*, use_detection_sigmas).
  Mat6 measurement_covariance(const Detection& d, bool object_frame) const;
  /// Test-only reference arithmetic (tests/ekf/test_filter_bound.cpp), set before initialize(): the
  /// covariance propagated densely, P ← F P Fᵀ + Q on the whole n x n matrix at every IMU sample (F the dense
  /// transition; no fixed-size core block, no lazy cross terms), every P H_kᵀ from the full 6 x n H_k, and the
  /// stacked update in the textbook Joseph form (I − KH) P (I − KH)ᵀ + K R Kᵀ, K = P Hᵀ S⁻¹ with
  /// S = H P Hᵀ + R formed densely (the constant-gain update of correlated detection errors is the same in
  /// both). The policy (gates, first sight, relock, σ scale) is the same code. Roughly 10x slower.
  void set_reference_arithmetic(bool on) { reference_ = on; }

 private:
  // A detection's H acts on at most 25 error-state columns: the IMU's p and θ, the extrinsics, t_d, its object's
  // Gauss–Markov detection-error state and its object-world.
  static constexpr int kMaxCols = 25;
  struct MeasBlock {
    int det = 0;  // index into the detection vector
    int obj = 0;  // index into s_.objects (objects())
    // The first m rows of r, H, R and S are used (m < 6 after the split gate kept one part: the selected
    // rows moved up, the rest zero, S's identity-padded).
    int m = 6;
    Mat6 A;                 // the first m rows: r = A r_full (identity, or the continuous-symmetry reduction)
    bool separable = true;  // position and rotation rows separate (the split gate applies)
    Vec6 r;
    Mat6 R;
    Mat6 S;                          // H P Hᵀ + R of this block (the χ² gate; the stacked S's diagonal)
    double k = 1.0;                  // variance inflation of R for the constant states (correlated errors)
    Eigen::Matrix<double, 6, kMaxCols> H;  // compact columns
    int idx[kMaxCols];
    int nc = 0;
    // H's compact columns as runs of contiguous error-state columns: run k covers the state columns
    // run_off[k] … run_off[k]+run_len[k]−1 and the compact columns run_col[k] …
    int run_off[6], run_col[6], run_len[6];
    int nruns = 0;
  };

  /// propagate()'s guard rails: core state and core variances.
  void check_propagated();
  /// The reference arithmetic's stacked update (set_reference_arithmetic): the inliers' dense H and R, applied
  /// by FilterCovariance::update_dense.
  bool reference_update(const std::vector<int>& inliers, const std::vector<int>& row0, Eigen::VectorXd& dx);
  /// The inliers' stacked m x n Jacobian H and block-diagonal R (the dense forms of their blocks).
  void stacked_jacobian(const std::vector<int>& inliers, const std::vector<int>& row0, Eigen::MatrixXd& H,
                        Eigen::MatrixXd& R) const;
  /// √k per stacked row (error_inflation's k of each block).
  Eigen::VectorXd stacked_inflation(const std::vector<int>& inliers, const std::vector<int>& row0) const;
  /// ws_PHt_'s first 6·nb columns ← P H_kᵀ of blocks_[0 … nb−1]: the columns every H_k shares (core p, θ,
  /// extrinsics; gathered once) in one product, each object's own columns in place.
  void stacked_pht(int nb);
  /// Recording: ends the propagation segment since the last node (a kPropagate node) if it has steps.
  void close_segment();
  /// Recording: a node of the given kind with the current state and (synchronised) covariance.
  RecordedNode& push_node(RecordedNode::Kind kind);
  /// r, H (symmetry-aware: nearest equivalent measurement, continuous reduction) of one detection (`det`: its
  /// σ for the Gauss–Markov error state's columns; nullptr: the configured σ at z).
  void build_block(const ObjectEntry& o, const Pose& z, MeasBlock& b, const Detection* det = nullptr) const;
  /// The Gauss–Markov error state's Jacobian G (detection_error_states) of a detection, at its detected T_C_O
  /// (the symmetry-equivalent one nearest the prediction), in the update's residual frame or (object_frame)
  /// the T_O_C frame of the first sight: G_C (gauss_markov_error_jacobian) or J G_C. It depends on the
  /// detection only, so the residual r = z ⊟ ẑ(x) − G ê is linear in the error state.
  Mat6 error_state_jacobian(const Detection& d, bool object_frame) const;
  /// Decays the error states of the objects detected in this image to the image's time (a kDecay link).
  void decay_error_states(const std::vector<Detection>& dets);
  /// b.R ← A R Aᵀ on the first b.m rows, identity-padded (a no-op for a 6-row block).
  static void reduce_covariance(MeasBlock& b);
  /// Keeps the rows of `part` in b (r, H, R, S moved up to its first m rows) and in its P Hᵀ columns.
  /// PHt's columns col0 … col0+5 are the block's P Hᵀ (PHt may have no rows: measurement_rows).
  static void select_rows(ResidualPart part, MeasBlock& b, Eigen::MatrixXd& PHt, Eigen::Index col0);
  /// The χ² test of one block (options: chi2_gate, gate_mode): the part(s) to use; the joint NIS to `nis`.
  ResidualPart gate(const MeasBlock& b, const Eigen::LDLT<Mat6>& ldlt, double& nis) const;
  // The steps of update(), in order (ws_z_, ws_usable_, blocks_, ws_new_objects_, ws_inliers_ carry the image):
  /// Marks duplicates (an error) and unusable detections, chooses the anchor if not yet chosen, inverts
  /// every detection to T_O_C (ws_z_); returns the usable anchor detection's index or −1.
  int screen_detections(const std::vector<Detection>& dets, FrameResult& res);
  /// r, H, R of every usable detection of an initialised object (blocks_); the others to ws_new_objects_.
  void build_blocks(const std::vector<Detection>& dets);
  /// P H_kᵀ, S_k and the χ² gate of every block; outcomes to res, the inliers to ws_inliers_.
  void gate_blocks(const std::vector<Detection>& dets, FrameResult& res);
  /// The stacked update with the inliers (stacked S, apply_stacked_update, ⊞, guard rails, recording).
  void update_with_inliers(FrameResult& res);
  /// Each detection's implied T_W_I (DetectionOutcome::T_W_I) for the objects with an object-world.
  void set_implied_poses(const std::vector<Detection>& dets, FrameResult& res) const;
  void initialize_object(const Detection& d, const Pose& z, bool anchor);
  /// Records a first-sight candidate; true when init_min_detections consecutive candidates agree.
  bool confirm_first_sight(int id, const Pose& z);
  /// Lock-out: inflates the position and velocity covariance when the monitor declares the position lost
  /// (before the gate), and feeds it this image's outcomes (after the update).
  void relock_lost_position(FrameResult& res);
  void observe_lockout(const std::vector<Detection>& dets, FrameResult& res);
  void check_state(const char* where, bool core_only = false) const;
  void check_covariance(bool full, const char* where);
  std::string when() const;

  FilterOptions opt_;
  ImuNoiseParams noise_;
  bool initialized_ = false;
  // The nominal state with its error-state layout (time, core, extrinsics, object-worlds, offsets, dim): the
  // one state struct with ⊞/⊟ (state.hpp), held here and changed in place.
  StateEstimate s_;
  double td_prior_s_ = 0.0;  // the declared time offset (the images' stamps hold it already)
  // update()'s dt_image_s while it runs (0 otherwise): image_core() is the core state at the image, s_.x shifted
  // by it (after the update's ⊞ too: the first sights use the posterior).
  double dt_img_s_ = 0.0;
  CoreState image_core() const;
  FrameResult update_image(const std::vector<Detection>& detections);
  Vec3 gyro_ = Vec3::Zero(), accel_ = Vec3::Zero();
  int anchor_id_ = -1;
  FilterCovariance cov_;  // P behind its door (covariance.hpp): every change to P goes through it
  std::vector<MeasBlock> blocks_;
  // Update workspaces, kept between images and only grown (no heap allocation per image once the state
  // dimension and the number of detections per image have been seen).
  Eigen::MatrixXd ws_PHt_;  // n x 6·blocks: P H_kᵀ per block, inliers compacted to the left
  Eigen::MatrixXd ws_Hs_;   // 6·blocks x 12: the blocks' H on the shared columns (p, θ, extrinsics)
  Eigen::MatrixXd ws_S_;    // stacked S (m x m, top-left)
  Eigen::MatrixXd ws_L_;    // its Cholesky factor (m x m, top-left)
  Eigen::MatrixXd ws_W_;    // n x m: P Hᵀ L⁻ᵀ (S = L Lᵀ); first the gather buffer of P's columns
  Eigen::VectorXd ws_r_, ws_dx_, ws_u_;
  std::vector<Pose> ws_z_;
  std::vector<char> ws_usable_;
  std::vector<int> ws_new_objects_, ws_inliers_, ws_row0_;
  struct Pending {
    Pose T_O_W;
    int count = 0;
  };
  std::vector<std::pair<int, Pending>> pending_;
  LockoutMonitor lost_position_;
  // Online scale of the per-detection σ (adapt_detection_sigma_scale): variance scale and the last
  // detections' NIS · k / χ²_m median, a ring of kSigmaScaleWindow.
  static constexpr int kSigmaScaleWindow = 150;
  static constexpr std::size_t kSigmaScaleMin = 15;  // before this many, the median is too noisy
  double sigma_var_scale_ = 1.0;
  std::vector<double> sigma_scale_samples_;
  std::size_t sigma_scale_next_ = 0;
  void learn_sigma_scale(const std::vector<double>& frame_samples);
  double gate_ = 0.0;   // χ²₆ quantile of chi2_confidence
  double gate3_ = 0.0;  // χ²₃ quantile (split gate, per part)
  double gate5_ = 0.0;  // χ²₅ (joint gate of a continuous-symmetry object)
  double gate2_ = 0.0;  // χ²₂ (its 2-row rotation part, split gate)
  double chi2_median6_ = 0.0, chi2_median5_ = 0.0;  // χ² medians (the σ scale's reference)
  std::vector<double> ws_scale_, ws_scale_sorted_;  // this image's σ-scale samples; a sorting copy
  std::map<int, ObjectSymmetry> symmetries_;
  // detection_error_correlation_s: each object's previous detection time, and the variance inflation k of
  // its detection now (1 for a first detection or white errors).
  std::map<int, Timestamp> last_detection_ns_;
  double error_inflation(int object_id);
  std::vector<Eigen::Index> ws_const_rows_;
  Eigen::VectorXd ws_decay_;  // decay_error_states' diag(B)
  // The stacked update, applied by the covariance owner: FilterCovariance::update, or update_constant_gain when a
  // block's k > 1.
  bool apply_stacked_update(const Eigen::Ref<const Eigen::MatrixXd>& Y, const Eigen::Ref<const Eigen::MatrixXd>& S,
                            const std::vector<int>& inliers, const std::vector<int>& row0, Eigen::VectorXd& dx);
  std::size_t n_updates_ = 0;
  FilterRecording* rec_ = nullptr;
  bool reference_ = false;  // set_reference_arithmetic
};

}  // namespace roe::ekf
