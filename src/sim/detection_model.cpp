#include "roe/sim/detection_model.hpp"

#include <algorithm>
#include <cmath>

#include "roe/math/so3.hpp"

namespace roe::sim {
namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

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

PoetErrorModel::PoetErrorModel(DetectionNoiseConfig config, std::map<int, Symmetry> symmetries)
    : config_(std::move(config)), symmetries_(std::move(symmetries)) {}

bool PoetErrorModel::frame_blurred(double camera_rate_rad_s, Rng& rng) const {
  // Always draw, so the stream stays aligned whatever the rate.
  const bool random_blur = rng.uniform() < config_.blur_frame_prob;
  const bool fast =
      config_.blur_rate_threshold_deg_s > 0.0 && camera_rate_rad_s > config_.blur_rate_threshold_deg_s * kDeg;
  return fast || random_blur;
}

Vector6d PoetErrorModel::sigmas(const Pose& T_C_O_true) const {
  const Eigen::Vector3d& t = T_C_O_true.p;
  const double z = std::max(0.0, t.z());
  const double s_lat = config_.lateral_sigma_m + config_.lateral_sigma_per_depth * z;
  const double s_ray = config_.along_ray_sigma_m + config_.along_ray_sigma_per_depth * z;
  Eigen::Vector3d u1, u2, r;
  error_axes(t, config_.translation_frame, u1, u2, r);
  // Covariance in C = Σ σ_i² a_i a_iᵀ; report the square roots of its diagonal.
  const Eigen::Matrix3d cov =
      s_lat * s_lat * (u1 * u1.transpose() + u2 * u2.transpose()) + s_ray * s_ray * r * r.transpose();
  Vector6d s;
  const double s_rot = config_.rotation_sigma_deg * kDeg;
  s << std::sqrt(cov(0, 0)), std::sqrt(cov(1, 1)), std::sqrt(cov(2, 2)), s_rot, s_rot, s_rot;
  return s;
}

Detection PoetErrorModel::measure(Timestamp t_ns, int object_id, const Pose& T_C_O_true, bool blurred,
                                  Rng& rng, DetectionLabel* label) {
  // 1–2. Correlated standard-normal factors (first-order Gauss-Markov, unit stationary variance).
  Vector6d w;
  for (int i = 0; i < 6; ++i) w(i) = rng.normal();
  auto it = state_.find(object_id);
  if (it == state_.end() || config_.correlation_time_s <= 0.0) {
    state_[object_id] = State{t_ns, w};
  } else {
    const double dt = std::max(0.0, static_cast<double>(t_ns - it->second.t_ns) * 1e-9);
    const double rho = std::exp(-dt / config_.correlation_time_s);
    it->second.x = rho * it->second.x + std::sqrt(std::max(0.0, 1.0 - rho * rho)) * w;
    it->second.t_ns = t_ns;
  }
  const Vector6d x = state_[object_id].x;

  // Every remaining draw is made whether it is used or not, so the streams stay aligned.
  const bool outlier = rng.uniform() < config_.outlier_prob;
  const Eigen::Vector3d outlier_offset = rng.in_ball(config_.outlier_translation_max_m);
  const Eigen::Quaterniond outlier_rotation = rng.rotation();
  const double flip_draw = rng.uniform();
  const double flip_angle = rng.uniform(0.0, 2.0 * kPi);

  const Eigen::Vector3d& t = T_C_O_true.p;
  const double z = std::max(0.0, t.z());
  const double s_lat = config_.lateral_sigma_m + config_.lateral_sigma_per_depth * z;
  const double s_ray = config_.along_ray_sigma_m + config_.along_ray_sigma_per_depth * z;
  const double s_rot = config_.rotation_sigma_deg * kDeg;
  Eigen::Vector3d u1, u2, r;
  error_axes(t, config_.translation_frame, u1, u2, r);

  Eigen::Quaterniond q = T_C_O_true.q;
  bool flipped = false;
  const auto sym = symmetries_.find(object_id);
  if (sym != symmetries_.end() && sym->second != Symmetry::kNone && flip_draw < config_.symmetric_flip_prob) {
    // A symmetry of the object about its model z axis: π (two-fold) or any angle (continuous).
    const double angle = sym->second == Symmetry::kDiscrete2 ? kPi : flip_angle;
    q = q * Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()));
    flipped = true;
  }
  Eigen::Vector3d t_meas = t + s_lat * x(0) * u1 + s_lat * x(1) * u2 + s_ray * x(2) * r;
  q = q * math::exp_quat(s_rot * x.segment<3>(3));
  if (outlier || blurred) {
    t_meas = t + outlier_offset;
    q = outlier_rotation;
  }

  Detection d;
  d.t_ns = t_ns;
  d.object_id = object_id;
  d.T_C_O = Pose(math::canonical(q.normalized()), t_meas);
  d.score = 1.0;
  if (config_.write_sigmas) d.sigma = sigmas(T_C_O_true);
  if (label) {
    label->outlier = outlier;
    label->flipped = flipped;
    label->blurred = blurred;
    label->T_C_O_true = T_C_O_true;
  }
  return d;
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

Symmetry ycbv_symmetry(int id) {
  switch (id) {
    case 13:
      return Symmetry::kContinuous;
    case 16:
    case 19:
    case 20:
    case 21:
      return Symmetry::kDiscrete2;
    default:
      return Symmetry::kNone;
  }
}

}  // namespace roe::sim
