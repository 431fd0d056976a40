#include "roe/sim/detection_model.hpp"

#include <algorithm>
#include <cmath>

#include "roe/core/error.hpp"
#include "roe/math/euler.hpp"
#include "roe/math/so3.hpp"

namespace roe::sim {
namespace {
using math::kPi;
using math::kRadPerDeg;

// Axes (u1, u2 lateral, r along) of the translation error for a true translation t.
void error_axes(const Eigen::Vector3d& t, const std::string& frame, Eigen::Vector3d& u1, Eigen::Vector3d& u2,
                Eigen::Vector3d& r) {
  if (frame == "camera" || t.norm() < 1e-9) {
    u1 = Eigen::Vector3d::UnitX();
    u2 = Eigen::Vector3d::UnitY();
    r = Eigen::Vector3d::UnitZ();
    return;
  }
  r = t.normalized();
  // ŷ × r̂ is ≈ x̂ for rays near the optical axis, so u1, u2 stay close to the image axes.
  u1 = Eigen::Vector3d::UnitY().cross(r);
  if (u1.norm() < 1e-9) u1 = Eigen::Vector3d::UnitX();
  u1.normalize();
  u2 = r.cross(u1);
}
}  // namespace

const std::vector<NumberField<VisibilityConfig>>& visibility_fields() {
  using V = VisibilityConfig;
  static const std::vector<NumberField<V>> f{
      {"margin_px", &V::margin_px, Range::kNonneg, "the centre projects at least this far inside the image (px)"},
      {"min_depth_m", &V::min_depth_m, Range::kPositive, "nearest detectable depth z_C (m)"},
      {"max_depth_m", &V::max_depth_m, Range::kPositive, "farthest detectable depth z_C (m)"},
      {"miss_prob", &V::miss_prob, Range::kProb, "miss probability well inside the image"},
      {"border_miss_prob", &V::border_miss_prob, Range::kProb, "extra miss probability at the margin"},
      {"border_band_px", &V::border_band_px, Range::kNonneg, "band in which the extra miss probability ramps up (px)"},
  };
  return f;
}

const std::vector<NumberField<DetectionNoiseConfig>>& detection_fields() {
  using D = DetectionNoiseConfig;
  static const std::vector<NumberField<D>> f{
      {"lateral_sigma_m", &D::lateral_sigma_m, Range::kNonneg, "σ_lat at depth 0 (m)"},
      {"lateral_sigma_per_depth", &D::lateral_sigma_per_depth, Range::kNonneg, "σ_lat growth per m of depth"},
      {"along_ray_sigma_m", &D::along_ray_sigma_m, Range::kNonneg, "σ_ray at depth 0 (m)"},
      {"along_ray_sigma_per_depth", &D::along_ray_sigma_per_depth, Range::kNonneg, "σ_ray growth per m of depth"},
      {"rotation_sigma_deg", &D::rotation_sigma_deg, Range::kNonneg, "σ_rot per axis at depth 0 (deg)"},
      {"correlation_time_s", &D::correlation_time_s, Range::kNonneg, "τ of the Gauss-Markov errors; 0 = white"},
      {"outlier_prob", &D::outlier_prob, Range::kProb, "probability of a gross error"},
      {"outlier_translation_max_m", &D::outlier_translation_max_m, Range::kNonneg, "radius of the outlier ball (m)"},
      {"symmetric_flip_prob", &D::symmetric_flip_prob, Range::kProb, "flip probability of a symmetric object"},
      {"blur_rate_threshold_deg_s", &D::blur_rate_threshold_deg_s, Range::kFinite,
       "frames rotating faster are blurred (deg/s); <= 0 disables"},
      {"blur_frame_prob", &D::blur_frame_prob, Range::kProb, "fraction of frames blurred at random"},
      {"rotation_sigma_per_depth_deg", &D::rotation_sigma_per_depth_deg, Range::kNonneg,
       "σ_rot growth per m of depth (deg/m)"},
      {"object_radius_m", &D::object_radius_m, Range::kNonneg, "radius of the projected extent for the border cut (m)"},
      {"border_sigma_gain", &D::border_sigma_gain, Range::kNonneg, "σ × (1 + gain · border cut)"},
      {"border_outlier_prob", &D::border_outlier_prob, Range::kProb, "outlier probability + this · border cut"},
      {"view_sigma_gain", &D::view_sigma_gain, Range::kNonneg, "σ × (1 + gain · |cos θ|), θ sight to model z"},
      {"flip_view_gain", &D::flip_view_gain, Range::kProb, "flip probability + this · |cos θ|"},
      {"burst_start_prob", &D::burst_start_prob, Range::kProb, "per-frame probability that a bad run starts"},
      {"burst_mean_frames", &D::burst_mean_frames, Range::kAtLeastOne, "mean length of a bad run (frames)"},
      {"burst_sigma_scale", &D::burst_sigma_scale, Range::kNonneg, "σ scale in a bad frame"},
      {"burst_outlier_prob", &D::burst_outlier_prob, Range::kProb, "outlier probability in a bad frame"},
      {"reported_sigma_scale", &D::reported_sigma_scale, Range::kPositive, "reported σ = this × true σ"},
      {"failure_sigma_m", &D::failure_sigma_m, Range::kPositive, "reported translation σ of a gross error (m)"},
      {"failure_sigma_deg", &D::failure_sigma_deg, Range::kPositive, "reported rotation σ of a gross error (deg)"},
  };
  return f;
}

void check_range(double v, Range range, const std::string& key) {
  auto bad = [&](const char* what) { throw ConfigError(what, ErrorContext{"", 0, 0, key}); };
  switch (range) {
    case Range::kFinite:
      if (!std::isfinite(v)) bad("must be finite");
      break;
    case Range::kNonneg:
      if (!(std::isfinite(v) && v >= 0.0)) bad("must be a finite number >= 0");
      break;
    case Range::kPositive:
      if (!(std::isfinite(v) && v > 0.0)) bad("must be a positive number");
      break;
    case Range::kProb:
      if (!(std::isfinite(v) && v >= 0.0 && v <= 1.0)) bad("must be a probability in [0, 1]");
      break;
    case Range::kAtLeastOne:
      if (!(std::isfinite(v) && v >= 1.0)) bad("must be a finite number >= 1");
      break;
  }
}

void validate(const DetectionNoiseConfig& d, const std::string& prefix) {
  for (const auto& f : detection_fields()) check_range(d.*f.member, f.range, prefix + "." + f.key);
  auto bad = [&](const char* key, const char* what) {
    throw ConfigError(what, ErrorContext{"", 0, 0, prefix + "." + key});
  };
  if (d.translation_frame != "ray" && d.translation_frame != "camera")
    bad("translation_frame", "must be \"ray\" or \"camera\"");
  if (d.reported_failure_sigma != "nominal" && d.reported_failure_sigma != "inflated")
    bad("reported_failure_sigma", "must be \"nominal\" or \"inflated\"");
}

void validate(const VisibilityConfig& v, const std::string& prefix) {
  for (const auto& f : visibility_fields()) check_range(v.*f.member, f.range, prefix + "." + f.key);
  if (v.max_depth_m <= v.min_depth_m)
    throw ConfigError("must be greater than min_depth_m", ErrorContext{"", 0, 0, prefix + ".max_depth_m"});
}

bool object_in_view(const Pose& T_C_O, const PinholeCamera& cam, const VisibilityConfig& vis) {
  const Eigen::Vector3d& p = T_C_O.p;
  if (!(p.z() >= vis.min_depth_m && p.z() <= vis.max_depth_m)) return false;
  const Eigen::Vector2d uv = cam.project(p);
  return uv.x() >= vis.margin_px && uv.x() <= cam.width - vis.margin_px && uv.y() >= vis.margin_px &&
         uv.y() <= cam.height - vis.margin_px;
}

double miss_probability(const Pose& T_C_O, const PinholeCamera& cam, const VisibilityConfig& vis) {
  if (!object_in_view(T_C_O, cam, vis)) return 0.0;
  const Eigen::Vector2d uv = cam.project(T_C_O.p);
  const double d_edge = std::min({uv.x() - vis.margin_px, cam.width - vis.margin_px - uv.x(),
                                  uv.y() - vis.margin_px, cam.height - vis.margin_px - uv.y()});
  const double b = vis.border_band_px > 0.0 ? std::clamp(1.0 - d_edge / vis.border_band_px, 0.0, 1.0) : 0.0;
  return std::clamp(vis.miss_prob + vis.border_miss_prob * b, 0.0, 1.0);
}

bool object_visible(const Pose& T_C_O, const PinholeCamera& cam, const VisibilityConfig& vis, Rng& rng) {
  if (!object_in_view(T_C_O, cam, vis)) return false;
  return rng.uniform() >= miss_probability(T_C_O, cam, vis);
}

PoetErrorModel::PoetErrorModel(DetectionNoiseConfig config, std::map<int, ObjectSymmetry> symmetries,
                               PinholeCamera camera)
    : config_(std::move(config)), symmetries_(std::move(symmetries)), camera_(camera) {}

bool PoetErrorModel::frame_blurred(double camera_rate_rad_s, Rng& rng) const {
  // Always draw, so the stream stays aligned whatever the rate.
  const bool random_blur = rng.uniform() < config_.blur_frame_prob;
  const bool fast = config_.blur_rate_threshold_deg_s > 0.0 &&
                    camera_rate_rad_s > config_.blur_rate_threshold_deg_s * kRadPerDeg;
  return fast || random_blur;
}

FrameCondition PoetErrorModel::frame_condition(double camera_rate_rad_s, Rng& rng_blur, Rng& rng_burst) {
  FrameCondition f;
  f.blurred = frame_blurred(camera_rate_rad_s, rng_blur);
  // Two-state chain: a run ends after each frame with probability 1 / mean length (geometric).
  const double u = rng_burst.uniform();
  in_burst_ = in_burst_ ? u >= 1.0 / config_.burst_mean_frames : u < config_.burst_start_prob;
  f.bad = in_burst_;
  return f;
}

double PoetErrorModel::border_cut(const Pose& T_C_O_true) const {
  const Eigen::Vector3d& p = T_C_O_true.p;
  if (!(camera_.fx > 0.0 && camera_.fy > 0.0 && p.z() > 0.0 && config_.object_radius_m > 0.0)) return 0.0;
  const Eigen::Vector2d uv = camera_.project(p);
  const double r_px = std::min(camera_.fx, camera_.fy) * config_.object_radius_m / p.z();
  const double d_edge = std::min({uv.x(), camera_.width - uv.x(), uv.y(), camera_.height - uv.y()});
  return std::clamp((r_px - d_edge) / (2.0 * r_px), 0.0, 1.0);
}

double PoetErrorModel::end_on(const Pose& T_C_O_true) {
  const Eigen::Vector3d sight_O = -(T_C_O_true.q.conjugate() * T_C_O_true.p);  // object → camera, in O
  const double n = sight_O.norm();
  return n > 1e-12 ? std::abs(sight_O.z()) / n : 0.0;
}

Eigen::Vector3d PoetErrorModel::scaled_sigmas(const Pose& T_C_O_true, bool bad_frame) const {
  const DetectionNoiseConfig& c = config_;
  const double z = std::max(0.0, T_C_O_true.p.z());
  // Each factor is exactly 1 when its mode is off, so the default σ are bit-identical to (1).
  double k = 1.0;
  if (c.border_sigma_gain != 0.0) k *= 1.0 + c.border_sigma_gain * border_cut(T_C_O_true);
  if (c.view_sigma_gain != 0.0) k *= 1.0 + c.view_sigma_gain * end_on(T_C_O_true);
  if (bad_frame) k *= c.burst_sigma_scale;
  return {(c.lateral_sigma_m + c.lateral_sigma_per_depth * z) * k,
          (c.along_ray_sigma_m + c.along_ray_sigma_per_depth * z) * k,
          (c.rotation_sigma_deg + c.rotation_sigma_per_depth_deg * z) * kRadPerDeg * k};
}

Vector6d PoetErrorModel::sigmas(const Pose& T_C_O_true, bool bad_frame) const {
  const Eigen::Vector3d& t = T_C_O_true.p;
  const Eigen::Vector3d s3 = scaled_sigmas(T_C_O_true, bad_frame);
  const double s_lat = s3(0), s_ray = s3(1);
  Eigen::Vector3d u1, u2, r;
  error_axes(t, config_.translation_frame, u1, u2, r);
  // Covariance in C = Σ σ_i² a_i a_iᵀ; report the square roots of its diagonal.
  const Eigen::Matrix3d cov =
      s_lat * s_lat * (u1 * u1.transpose() + u2 * u2.transpose()) + s_ray * s_ray * r * r.transpose();
  Vector6d s;
  s << std::sqrt(cov(0, 0)), std::sqrt(cov(1, 1)), std::sqrt(cov(2, 2)), s3(2), s3(2), s3(2);
  return s;
}

Detection PoetErrorModel::measure(Timestamp t_ns, int object_id, const Pose& T_C_O_true,
                                  const FrameCondition& frame, Rng& rng, DetectionLabel* label) {
  const DetectionNoiseConfig& c = config_;
  // 1–2. Correlated standard-normal factors (first-order Gauss-Markov, unit stationary variance).
  Vector6d w;
  for (int i = 0; i < 6; ++i) w(i) = rng.normal();
  auto it = state_.find(object_id);
  if (it == state_.end() || c.correlation_time_s <= 0.0) {
    state_[object_id] = State{t_ns, w};
  } else {
    const double dt = std::max(0.0, static_cast<double>(t_ns - it->second.t_ns) * 1e-9);
    const double rho = std::exp(-dt / c.correlation_time_s);
    it->second.x = rho * it->second.x + std::sqrt(std::max(0.0, 1.0 - rho * rho)) * w;
    it->second.t_ns = t_ns;
  }
  const Vector6d x = state_[object_id].x;

  // Every remaining draw is made whether it is used or not, so the streams stay aligned; the
  // failure modes (6–8) only move the thresholds the draws are compared with.
  const double p_outlier = (frame.bad ? c.burst_outlier_prob : c.outlier_prob) +
                           (c.border_outlier_prob != 0.0 ? c.border_outlier_prob * border_cut(T_C_O_true) : 0.0);
  const bool outlier = rng.uniform() < p_outlier;
  const Eigen::Vector3d outlier_offset = rng.in_ball(c.outlier_translation_max_m);
  const Eigen::Quaterniond outlier_rotation = rng.rotation();
  const double flip_draw = rng.uniform();
  const double flip_angle = rng.uniform(0.0, 2.0 * kPi);
  const double p_flip =
      c.symmetric_flip_prob + (c.flip_view_gain != 0.0 ? c.flip_view_gain * end_on(T_C_O_true) : 0.0);

  const Eigen::Vector3d& t = T_C_O_true.p;
  const Eigen::Vector3d s3 = scaled_sigmas(T_C_O_true, frame.bad);
  const double s_lat = s3(0), s_ray = s3(1), s_rot = s3(2);
  Eigen::Vector3d u1, u2, r;
  error_axes(t, c.translation_frame, u1, u2, r);

  // The pose detected before the errors: T_C_O, or an equivalent T_C_O · S of a symmetric object.
  Eigen::Quaterniond q = T_C_O_true.q;
  Eigen::Vector3d t_seen = t;
  bool flipped = false;
  const auto sym = symmetries_.find(object_id);
  if (sym != symmetries_.end() && !sym->second.empty() && flip_draw < p_flip) {
    const Pose S = flip_transform(sym->second, flip_draw / p_flip, flip_angle);
    q = q * S.q;
    t_seen = t + T_C_O_true.q * S.p;
    flipped = true;
  }
  Eigen::Vector3d t_meas = t_seen + s_lat * x(0) * u1 + s_lat * x(1) * u2 + s_ray * x(2) * r;
  q = q * math::exp_quat(s_rot * x.segment<3>(3));
  const bool gross = outlier || frame.blurred;
  if (gross) {
    t_meas = t + outlier_offset;
    q = outlier_rotation;
  }

  Detection d;
  d.t_ns = t_ns;
  d.object_id = object_id;
  d.T_C_O = Pose(math::canonical(q.normalized()), t_meas);
  d.score = 1.0;
  if (c.write_sigmas) d.sigma = reported_sigmas(T_C_O_true, frame.bad, gross, flipped);
  if (label) {
    label->outlier = outlier;
    label->flipped = flipped;
    label->blurred = frame.blurred;
    label->bad_frame = frame.bad;
    label->T_C_O_true = T_C_O_true;
  }
  return d;
}

Vector6d PoetErrorModel::reported_sigmas(const Pose& T_C_O_true, bool bad_frame, bool gross, bool flipped) const {
  Vector6d s = config_.reported_sigma_scale * sigmas(T_C_O_true, bad_frame);
  if (config_.reported_failure_sigma == "inflated") {
    if (gross) s.head<3>().setConstant(config_.failure_sigma_m);
    if (gross || flipped) s.tail<3>().setConstant(config_.failure_sigma_deg * kRadPerDeg);
  }
  return s;
}

std::string ycbv_name(int id) {
  static const char* kNames[] = {"002_master_chef_can",
                                 "003_cracker_box",
                                 "004_sugar_box",
                                 "005_tomato_soup_can",
                                 "006_mustard_bottle",
                                 "007_tuna_fish_can",
                                 "008_pudding_box",
                                 "009_gelatin_box",
                                 "010_potted_meat_can",
                                 "011_banana",
                                 "019_pitcher_base",
                                 "021_bleach_cleanser",
                                 "024_bowl",
                                 "025_mug",
                                 "035_power_drill",
                                 "036_wood_block",
                                 "037_scissors",
                                 "040_large_marker",
                                 "051_large_clamp",
                                 "052_extra_large_clamp",
                                 "061_foam_brick"};
  if (id >= 1 && id <= 21) return kNames[id - 1];
  return "obj_" + std::to_string(id);
}

ObjectSymmetry ycbv_symmetry(int id) {
  ObjectSymmetry s;
  if (id == 13) {
    s.continuous = ContinuousSymmetry{};  // the model z axis through the origin
  } else if (id == 16 || id == 19 || id == 20 || id == 21) {
    s.discrete.push_back(Pose(Eigen::Quaterniond(Eigen::AngleAxisd(kPi, Eigen::Vector3d::UnitZ())),
                              Eigen::Vector3d::Zero()));
  }
  return s;
}

ObjectSymmetry simulated_symmetry(int id) {
  const ObjectSymmetry s = ycbv_symmetry(id);
  return s.empty() ? ycbv_symmetry(16) : s;  // as the wood block
}

Pose flip_transform(const ObjectSymmetry& s, double u, double angle) {
  // Members: the discrete transforms, and with a continuous axis the identity first.
  const bool cont = s.continuous.has_value();
  const std::size_t n = s.discrete.size() + (cont ? 1 : 0);
  const std::size_t j = std::min(n - 1, static_cast<std::size_t>(std::max(0.0, u) * static_cast<double>(n)));
  Pose D;
  if (!cont) return s.discrete.at(j);
  if (j > 0) D = s.discrete[j - 1];
  // S(ψ) = (Exp(ψa), o − Exp(ψa) o), set member-wise: the angle-axis quaternion is unit to rounding, and
  // keeping its bits keeps the presets' detections as they were before the shared definitions.
  const ContinuousSymmetry& c = *s.continuous;
  Pose C;
  C.q = Eigen::Quaterniond(Eigen::AngleAxisd(angle, c.axis));
  C.p = c.offset - C.q * c.offset;
  return j > 0 ? D * C : C;
}

}  // namespace roe::sim
