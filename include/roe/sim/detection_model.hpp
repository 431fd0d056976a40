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
///  4. Symmetric objects (symmetric_flip_prob): R_meas is additionally right-multiplied by a symmetry of
///     the object: a rotation by π about its model z axis (2-fold symmetry), or by a uniform angle for
///     objects with a continuous symmetry (YCB-V bowl, id 13).
///  5. Blur: in a frame whose camera angular rate exceeds blur_rate_threshold_deg_s, and in a random
///     fraction blur_frame_prob of all frames, every detection is corrupted like an outlier (3).

#include <cstdint>
#include <map>
#include <set>
#include <string>

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
};

/// What happened to one simulated detection (for tests and statistics; not written to the dataset).
struct DetectionLabel {
  bool outlier = false;  ///< replaced by an outlier (3)
  bool flipped = false;  ///< symmetry-equivalent rotation returned (4)
  bool blurred = false;  ///< its frame was blurred (5); the detection is corrupted like an outlier
  Pose T_C_O_true;       ///< the error-free value
};

/// Visibility test of one object; returns false when not visible. Draws the miss from `rng` only when
/// the geometric test passes.
bool object_visible(const Pose& T_C_O, const PinholeCamera& cam, const VisibilityConfig& vis, Rng& rng);
/// The geometric part only (depth range and margin), no random miss.
bool object_in_view(const Pose& T_C_O, const PinholeCamera& cam, const VisibilityConfig& vis);
/// The miss probability of a visible object (0 when not in view).
double miss_probability(const Pose& T_C_O, const PinholeCamera& cam, const VisibilityConfig& vis);

/// The object's symmetry as used by the flip model.
enum class Symmetry { kNone, kDiscrete2, kContinuous };

/// Stateful PoET-like error model (the Gauss-Markov state is kept per object id).
class PoetErrorModel {
 public:
  /// `symmetries`: object id → symmetry type (objects absent are not symmetric).
  PoetErrorModel(DetectionNoiseConfig config, std::map<int, Symmetry> symmetries);

  /// Whether a frame is blurred: camera angular rate above the threshold, or the random draw.
  bool frame_blurred(double camera_rate_rad_s, Rng& rng) const;
  /// Corrupts one true T_C_O at time t_ns. `blurred` from frame_blurred for this frame.
  Detection measure(Timestamp t_ns, int object_id, const Pose& T_C_O_true, bool blurred, Rng& rng,
                    DetectionLabel* label = nullptr);
  /// The Gaussian σ (camera axes x, y, z in m; rx, ry, rz in rad) of a detection at this T_C_O.
  /// For translation_frame "ray" the translation σ are the diagonal of the ray-frame covariance
  /// rotated into C.
  Vector6d sigmas(const Pose& T_C_O_true) const;

  const DetectionNoiseConfig& config() const { return config_; }

 private:
  struct State {
    Timestamp t_ns = 0;
    Vector6d x = Vector6d::Zero();
  };
  DetectionNoiseConfig config_;
  std::map<int, Symmetry> symmetries_;
  std::map<int, State> state_;
};

/// The YCB-V class name of an id (1..21), "obj_<id>" otherwise.
std::string ycbv_name(int id);
/// Symmetry of a YCB-V class under the flip model: 13 (bowl) continuous; 16, 19, 20, 21 two-fold
/// (PoET's ycbv_symmetries.json list); all others none.
Symmetry ycbv_symmetry(int id);

}  // namespace roe::sim
