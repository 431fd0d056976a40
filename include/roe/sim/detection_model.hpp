#pragma once
/// @file
/// Visibility and the PoET-like error model of simulated object detections (T_C_O).
///
/// Visibility (per frame and object): the object's origin must lie min_depth..max_depth in front of
/// the camera (z_C) and project into the image at least margin_px from every border; then a miss draw
/// drops it with probability  miss_prob + border_miss_prob · b,  where b ∈ [0, 1] grows linearly from
/// 0 (border_band_px or more inside the margin) to 1 (at the margin): detectors miss objects that are
/// cut by the image border more often.
///
/// Errors (per detection, parameters in DetectionNoiseConfig):
///  1. Gaussian: translation error with σ_lat = lateral_sigma_m + lateral_sigma_per_depth · z (two
///     axes perpendicular to the viewing ray) and σ_ray = along_ray_sigma_m + along_ray_sigma_per_depth
///     · z (along the ray), z = depth t_z; with translation_frame = "camera" the axes are the camera's
///     x, y (lateral) and z (along). Rotation error δθ ~ N(0, σ_rot² I₃), applied on the right:
///     R_meas = R · Exp(δθ) (isotropic, so the side does not change the distribution).
///  2. Correlation: the six standard-normal factors of (1) follow, per object, a first-order
///     Gauss-Markov process x_k = ρ x_{k−1} + √(1−ρ²) w_k, ρ = exp(−Δt/τ), Δt the time since that
///     object's previous detection. The marginal is still N(0, 1), so the σ above hold per sample.
///  3. Outliers (outlier_prob): t_meas = t + u, u uniform in the ball of radius outlier_translation_max_m;
///     R_meas uniform on SO(3).
///  4. Symmetric objects (symmetric_flip_prob): the detection is of a symmetry-equivalent pose T_C_O · S
///     instead of T_C_O, S a symmetry transform of the object in the definitions the filter uses
///     (core/symmetry.hpp, BOP's models_info convention; flip_transform): one of its discrete transforms
///     (uniform), a turn by a uniform angle about its continuous axis, or (both) one of {I, discrete}
///     followed by such a turn. The errors (1) are then applied to T_C_O · S, so the detection is an
///     equivalent pose of the truth plus the ordinary error. ycbv_symmetry gives the defaults: π about
///     the model z axis (2-fold), any angle about it for the YCB-V bowl (id 13).
///  5. Blur: in a frame whose camera angular rate exceeds blur_rate_threshold_deg_s, and in a random
///     fraction blur_frame_prob of all frames, every detection is corrupted like an outlier (3).
///
/// Failure modes of real PoET named by the paper (Sec. IV, Table I discussion), all off by default:
///  6. Objects partly out of the image: c ∈ [0, 1] is the share of the object's projected diameter
///     (a disc of object_radius_m at depth z, radius f·r/z px) that lies beyond the nearest image
///     border; σ (1) × (1 + border_sigma_gain · c), outlier probability + border_outlier_prob · c.
///  7. Viewpoint: a = |cos θ|, θ between the line of sight and the object's model z axis (a = 1 seen
///     end-on, where the outline pins neither tilt nor in-plane rotation); σ × (1 + view_sigma_gain ·
///     a), flip probability (4) + flip_view_gain · a. σ_rot also grows with depth
///     (rotation_sigma_per_depth_deg).
///  8. Runs of bad frames: a two-state Markov chain per frame (frame_condition): a run starts with
///     burst_start_prob and lasts burst_mean_frames on average (geometric); in a bad frame every σ is
///     × burst_sigma_scale and the outlier probability is burst_outlier_prob.
///  9. Reported σ (write_sigmas): reported_sigma_scale × the σ the error was drawn from (1 =
///     informative, < 1 overconfident, > 1 underconfident); gross errors (3–5) report the ordinary σ
///     ("nominal": overconfident failures) or failure_sigma_m/deg ("inflated").
/// The probabilities of (3, 4, 6, 7, 8) reuse the per-detection uniform draws of (3, 4), so turning a
/// mode on changes no other random stream.

#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "roe/core/symmetry.hpp"
#include "roe/core/types.hpp"
#include "roe/sim/random.hpp"

namespace roe::sim {

/// The pinhole camera of the processed images (no distortion).
struct PinholeCamera {
  int width = 640;
  int height = 480;
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;
  /// Pixel of a point in C (z > 0 assumed).
  Eigen::Vector2d project(const Eigen::Vector3d& p_C) const {
    return {fx * p_C.x() / p_C.z() + cx, fy * p_C.y() / p_C.z() + cy};
  }
};

struct VisibilityConfig {
  double margin_px = 10.0;   ///< the centre must project at least this far inside the image
  double min_depth_m = 0.3;  ///< depth range (z_C of the object origin)
  double max_depth_m = 2.5;
  double miss_prob = 0.02;        ///< miss probability well inside the image
  double border_miss_prob = 0.3;  ///< extra miss probability at the margin
  double border_band_px = 60.0;   ///< width of the band in which the extra probability ramps up
};

struct DetectionNoiseConfig {
  double lateral_sigma_m = 0.01;  ///< σ_lat = lateral_sigma_m + lateral_sigma_per_depth · z
  double lateral_sigma_per_depth = 0.01;
  double along_ray_sigma_m = 0.03;  ///< σ_ray = along_ray_sigma_m + along_ray_sigma_per_depth · z
  double along_ray_sigma_per_depth = 0.05;
  double rotation_sigma_deg = 6.0;        ///< per axis, tangent space
  std::string translation_frame = "ray";  ///< "ray" (lateral ⟂ viewing ray) or "camera" (x, y | z)
  double correlation_time_s = 0.3;        ///< τ of the Gauss-Markov process; 0 = white
  double outlier_prob = 0.05;
  double outlier_translation_max_m = 0.3;
  double symmetric_flip_prob = 0.25;
  double blur_rate_threshold_deg_s = 120.0;  ///< frames rotating faster are blurred; <= 0 disables
  double blur_frame_prob = 0.02;             ///< fraction of frames blurred at random
  bool write_sigmas = false;  ///< write the Gaussian σ of each detection (camera-frame axes) to the CSV

  // Failure modes of real PoET (paper Sec. IV); every default switches its mode off (factor 1, prob 0).
  double rotation_sigma_per_depth_deg = 0.0;  ///< σ_rot = rotation_sigma_deg + this · z (deg per m)
  double object_radius_m = 0.1;      ///< radius of the object's projected extent (border cut c, 6)
  double border_sigma_gain = 0.0;    ///< all σ × (1 + gain · c), c ∈ [0, 1] the share of the extent cut
  double border_outlier_prob = 0.0;  ///< outlier probability + this · c
  double view_sigma_gain = 0.0;      ///< all σ × (1 + gain · a), a = |cos θ| (end-on view, 7)
  double flip_view_gain = 0.0;       ///< flip probability + this · a (symmetric objects)
  double burst_start_prob = 0.0;     ///< per frame: probability that a run of bad frames starts (8)
  double burst_mean_frames = 1.0;    ///< mean length of a bad run in frames (geometric, >= 1)
  double burst_sigma_scale = 1.0;    ///< σ × this in a bad frame
  double burst_outlier_prob = 0.0;   ///< outlier probability in a bad frame (replaces outlier_prob)

  // What the simulated detector reports as its σ (the CSV's sigma columns, with write_sigmas; 9).
  double reported_sigma_scale = 1.0;  ///< reported σ = this × the σ the error was drawn from
  /// "nominal": gross errors (outliers, blur, flips) report the σ of an ordinary detection, i.e. the
  /// detector is overconfident exactly when it fails; "inflated": they report failure_sigma_m/deg.
  std::string reported_failure_sigma = "nominal";
  double failure_sigma_m = 0.3;      ///< reported translation σ of a gross error ("inflated")
  double failure_sigma_deg = 90.0;   ///< reported rotation σ of a gross error ("inflated")
};

/// Conditions of one camera frame that act on every detection in it.
struct FrameCondition {
  bool blurred = false;  ///< (5) every detection corrupted like an outlier
  bool bad = false;      ///< (8) inside a run of bad frames
};

/// The number keys of VisibilityConfig and DetectionNoiseConfig, listed once: the config reader and
/// writer (app/simulate.cpp), the manifest's truth.detection_noise and validate() iterate these
/// tables. (translation_frame, reported_failure_sigma and write_sigmas are not numbers and are
/// handled by name.)
enum class Range { kFinite, kNonneg, kPositive, kProb, kAtLeastOne };
template <typename S>
struct NumberField {
  const char* key;
  double S::*member;
  Range range;
  const char* doc;
};
const std::vector<NumberField<VisibilityConfig>>& visibility_fields();
const std::vector<NumberField<DetectionNoiseConfig>>& detection_fields();
/// Throws roe::ConfigError naming `key` when v is outside the range.
void check_range(double v, Range range, const std::string& key);
/// Range checks of every field (keys prefixed "prefix."), plus the string choices and the
/// cross-field rules. Throws roe::ConfigError naming the key.
void validate(const DetectionNoiseConfig& d, const std::string& prefix);
void validate(const VisibilityConfig& v, const std::string& prefix);

/// What happened to one simulated detection (for tests and statistics; not written to the dataset).
struct DetectionLabel {
  bool outlier = false;  ///< replaced by an outlier (3)
  bool flipped = false;  ///< symmetry-equivalent rotation returned (4)
  bool blurred = false;  ///< its frame was blurred (5); the detection is corrupted like an outlier
  bool bad_frame = false;  ///< its frame lies in a run of bad frames (8)
  Pose T_C_O_true;       ///< the error-free value
};

/// Visibility test of one object; returns false when not visible. Draws the miss from `rng` only when
/// the geometric test passes.
bool object_visible(const Pose& T_C_O, const PinholeCamera& cam, const VisibilityConfig& vis, Rng& rng);
/// The geometric part only (depth range and margin), no random miss.
bool object_in_view(const Pose& T_C_O, const PinholeCamera& cam, const VisibilityConfig& vis);
/// The miss probability of a visible object (0 when not in view).
double miss_probability(const Pose& T_C_O, const PinholeCamera& cam, const VisibilityConfig& vis);


/// Stateful PoET-like error model (the Gauss-Markov state is kept per object id).
class PoetErrorModel {
 public:
  /// `symmetries`: object id → its symmetry (objects absent or empty are not symmetric). `camera`: the image
  /// the border cut (6) is measured in; without one (fx = 0) c = 0.
  PoetErrorModel(DetectionNoiseConfig config, std::map<int, ObjectSymmetry> symmetries, PinholeCamera camera = {});

  /// Whether a frame is blurred: camera angular rate above the threshold, or the random draw.
  bool frame_blurred(double camera_rate_rad_s, Rng& rng) const;
  /// Blur (from `rng_blur`, as frame_blurred) and the bad-run chain (8; one draw from `rng_burst`
  /// per frame, kept as state).
  FrameCondition frame_condition(double camera_rate_rad_s, Rng& rng_blur, Rng& rng_burst);
  /// Corrupts one true T_C_O at time t_ns under the frame's condition.
  Detection measure(Timestamp t_ns, int object_id, const Pose& T_C_O_true, const FrameCondition& frame, Rng& rng,
                    DetectionLabel* label = nullptr);
  /// The same for a frame that is only (not) blurred.
  Detection measure(Timestamp t_ns, int object_id, const Pose& T_C_O_true, bool blurred, Rng& rng,
                    DetectionLabel* label = nullptr) {
    return measure(t_ns, object_id, T_C_O_true, FrameCondition{blurred, false}, rng, label);
  }
  /// The Gaussian σ (camera axes x, y, z in m; rx, ry, rz in rad) of a detection at this T_C_O, with
  /// the factors of (6, 7) and, in a bad frame, (8). For translation_frame "ray" the translation σ are
  /// the diagonal of the ray-frame covariance rotated into C.
  Vector6d sigmas(const Pose& T_C_O_true, bool bad_frame = false) const;
  /// The σ written with write_sigmas (9) for a detection drawn with sigmas(T_C_O_true, bad_frame);
  /// `gross`: replaced by an outlier (3, 5), `flipped`: symmetry flip (4).
  Vector6d reported_sigmas(const Pose& T_C_O_true, bool bad_frame, bool gross, bool flipped) const;
  /// Share c ∈ [0, 1] of the object's projected extent beyond the image border (6).
  double border_cut(const Pose& T_C_O_true) const;
  /// a = |cos θ| of (7).
  static double end_on(const Pose& T_C_O_true);

  const DetectionNoiseConfig& config() const { return config_; }

 private:
  struct State {
    Timestamp t_ns = 0;
    Vector6d x = Vector6d::Zero();
  };
  // σ_lat, σ_ray (m) and σ_rot (rad) of a detection at this T_C_O, with (6–8).
  Eigen::Vector3d scaled_sigmas(const Pose& T_C_O_true, bool bad_frame) const;

  DetectionNoiseConfig config_;
  std::map<int, ObjectSymmetry> symmetries_;
  PinholeCamera camera_;
  std::map<int, State> state_;
  bool in_burst_ = false;
};

/// The YCB-V class name of an id (1..21), "obj_<id>" otherwise.
std::string ycbv_name(int id);
/// The simulator's default symmetry of a YCB-V class (PoET's ycbv_symmetries.json list): 13 (bowl)
/// continuous about the model z axis through the origin; 16, 19, 20, 21 two-fold (π about the model z
/// axis); all others none (empty).
ObjectSymmetry ycbv_symmetry(int id);

/// The symmetry the simulator flips an object listed as symmetric by: ycbv_symmetry(id), or for an id
/// without one (not a symmetric YCB-V class) the two-fold turn about the model z axis.
ObjectSymmetry simulated_symmetry(int id);

/// The symmetry transform S of a flip (4) of an object with symmetry `s` (not empty): `u` uniform in
/// [0, 1) picks the discrete member (with a continuous axis too, the identity counts as a member),
/// `angle` is the turn about the continuous axis. T_C_O · S is the equivalent pose the detector reports.
Pose flip_transform(const ObjectSymmetry& s, double u, double angle);

}  // namespace roe::sim
