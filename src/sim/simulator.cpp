#include "roe/sim/simulator.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <set>

#include "roe/core/error.hpp"
#include "roe/math/euler.hpp"
#include "roe/math/so3.hpp"

namespace roe::sim {
namespace {

/// One object in one frame: the visibility rules, then (when seen) the PoET-like error model. Appends
/// the detection and its label and counts it in run.stats; returns whether it was detected.
bool observe_object(Timestamp t, int id, const Pose& T_C_O, const PinholeCamera& cam,
                    const VisibilityConfig& vis, const FrameCondition& frame, PoetErrorModel& model, Rng& rng_vis,
                    Rng& rng_det, std::vector<Detection>& dets, SimRun& run) {
  SimStats& st = run.stats;
  if (!object_in_view(T_C_O, cam, vis)) return false;
  if (!object_visible(T_C_O, cam, vis, rng_vis)) {
    ++st.missed;
    return false;
  }
  DetectionLabel label;
  dets.push_back(model.measure(t, id, T_C_O, frame, rng_det, &label));
  run.labels.push_back(label);
  ++st.detections;
  ++st.detections_per_object[id];
  if (label.outlier) ++st.outliers;
  if (label.flipped) ++st.flips;
  if (label.blurred) ++st.blurred_detections;
  if (label.bad_frame) ++st.bad_frame_detections;
  return true;
}
using math::kPi;
using math::kRadPerDeg;
const Eigen::Vector3d kGravity_W(0.0, 0.0, 9.81);

[[noreturn]] void bad(const std::string& key, const std::string& what) {
  throw ConfigError(what, ErrorContext{"", 0, 0, key});
}
void require_positive(double v, const std::string& key) { check_range(v, Range::kPositive, key); }
void require_nonneg(double v, const std::string& key) { check_range(v, Range::kNonneg, key); }
void require_prob(double v, const std::string& key) { check_range(v, Range::kProb, key); }
void require_finite_signal(const SmoothSignal& s, const std::string& key) {
  if (!std::isfinite(s.offset) || !std::isfinite(s.rate)) bad(key, "must be finite");
  for (std::size_t i = 0; i < s.terms.size(); ++i) {
    const auto& t = s.terms[i];
    const std::string term = key + ".terms[" + std::to_string(i) + "]";
    if (!std::isfinite(t.amplitude) || !std::isfinite(t.phase_rad)) bad(term, "must be finite");
    if (!(std::isfinite(t.frequency_hz) && t.frequency_hz >= 0.0)) bad(term, "frequency must be a finite number >= 0");
  }
}

// Stamps t0 + round(k · 1e9 / rate) for k = 0.. while <= t_end.
std::vector<Timestamp> stamps(Timestamp t0, Timestamp t_end, double rate_hz) {
  std::vector<Timestamp> out;
  for (std::int64_t k = 0;; ++k) {
    const Timestamp t = t0 + static_cast<Timestamp>(std::llround(static_cast<double>(k) * 1e9 / rate_hz));
    if (t > t_end) break;
    out.push_back(t);
  }
  return out;
}

void vary(SmoothSignal& s, const VariationConfig& v, Rng& rng) {
  for (auto& term : s.terms) {
    term.amplitude *= rng.uniform(1.0 - v.amplitude_rel, 1.0 + v.amplitude_rel);
    term.frequency_hz *= rng.uniform(1.0 - v.frequency_rel, 1.0 + v.frequency_rel);
    term.phase_rad += rng.uniform(-v.phase_rad, v.phase_rad);
  }
}

std::map<int, ObjectSymmetry> symmetry_map(const std::vector<int>& ids, const std::vector<int>& symmetric_ids) {
  std::map<int, ObjectSymmetry> m;
  for (int id : ids) {
    if (std::find(symmetric_ids.begin(), symmetric_ids.end(), id) == symmetric_ids.end()) continue;
    m[id] = simulated_symmetry(id);
  }
  return m;
}

// truth.detection_noise: every number key of the detection and visibility configs (the latter
// prefixed "visibility_"), and translation_frame as translation_frame_is_ray.
std::map<std::string, double> noise_map(const DetectionNoiseConfig& d, const VisibilityConfig& v) {
  std::map<std::string, double> m;
  for (const auto& f : detection_fields()) m[f.key] = d.*f.member;
  for (const auto& f : visibility_fields()) m[std::string("visibility_") + f.key] = v.*f.member;
  m["translation_frame_is_ray"] = d.translation_frame == "ray" ? 1.0 : 0.0;
  return m;
}

CameraInfo camera_info(const PinholeCamera& k, const Pose& T_I_C_prior, double declared_time_offset_s) {
  CameraInfo c;
  c.width = k.width;
  c.height = k.height;
  c.fx = k.fx;
  c.fy = k.fy;
  c.cx = k.cx;
  c.cy = k.cy;
  c.distortion_model = "none";
  c.T_I_C = T_I_C_prior;
  c.time_offset_s = declared_time_offset_s;
  return c;
}

void validate_detection(const DetectionNoiseConfig& d, const VisibilityConfig& v, const PinholeCamera& k,
                        const std::string& det, const std::string& vis, const std::string& cam) {
  validate(d, det);
  validate(v, vis);
  if (k.width <= 0) bad(cam + ".width", "must be a positive integer");
  if (k.height <= 0) bad(cam + ".height", "must be a positive integer");
  require_positive(k.fx, cam + ".fx");
  require_positive(k.fy, cam + ".fy");
  if (!std::isfinite(k.cx)) bad(cam + ".cx", "must be finite");
  if (!std::isfinite(k.cy)) bad(cam + ".cy", "must be finite");
  if (2.0 * v.margin_px >= std::min(k.width, k.height)) bad(vis + ".margin_px", "leaves no image area");
}

std::vector<int> ids_of(const std::vector<TruthObject>& objects) {
  std::vector<int> ids;
  for (const auto& o : objects) ids.push_back(o.id);
  return ids;
}

// `key_of(i)` names the i-th id in the config (e.g. objects.list[2].id).
void validate_ids(const std::vector<int>& ids, const std::function<std::string(std::size_t)>& key_of) {
  std::set<int> seen;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    if (ids[i] <= 0) bad(key_of(i), "object ids must be positive integers (YCB-V uses 1..21)");
    if (!seen.insert(ids[i]).second) bad(key_of(i), "object id " + std::to_string(ids[i]) + " appears twice");
  }
}
}  // namespace

void validate(const SimConfig& c) {
  require_positive(c.duration_s, "duration_s");
  if (c.duration_s > 24 * 3600.0) bad("duration_s", "must be at most one day");
  if (c.start_time_ns < 0) bad("start_time_ns", "must be >= 0");
  const auto& t = c.trajectory;
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(t.center(i))) bad("trajectory.center", "must be finite");
  require_finite_signal(t.azimuth_rad, "trajectory.azimuth_rad");
  require_finite_signal(t.radius_m, "trajectory.radius_m");
  require_finite_signal(t.height_m, "trajectory.height_m");
  require_finite_signal(t.target_x_m, "trajectory.target_x_m");
  require_finite_signal(t.target_y_m, "trajectory.target_y_m");
  require_finite_signal(t.target_z_m, "trajectory.target_z_m");
  require_finite_signal(t.roll_rad, "trajectory.roll_rad");
  require_finite_signal(t.shake_x_m, "trajectory.shake_x_m");
  require_finite_signal(t.shake_y_m, "trajectory.shake_y_m");
  require_finite_signal(t.shake_z_m, "trajectory.shake_z_m");
  require_positive(t.radius_m.offset, "trajectory.radius_m.offset");
  const auto& v = c.variation;
  require_prob(v.amplitude_rel, "variation.amplitude_rel");
  require_prob(v.frequency_rel, "variation.frequency_rel");
  require_nonneg(v.phase_rad, "variation.phase_rad");
  require_prob(v.offset_rel, "variation.offset_rel");
  require_nonneg(v.azimuth_start_rad, "variation.azimuth_start_rad");
  const auto& o = c.objects;
  if (o.objects.empty()) bad("objects.list", "at least one object is needed");
  std::vector<int> ids;
  for (const auto& s : o.objects) ids.push_back(s.id);
  validate_ids(ids, [](std::size_t i) { return "objects.list[" + std::to_string(i) + "].id"; });
  require_positive(o.area_size_m, "objects.area_size_m");
  require_nonneg(o.min_separation_m, "objects.min_separation_m");
  require_nonneg(o.height_jitter_m, "objects.height_jitter_m");
  require_prob(o.lying_prob, "objects.lying_prob");
  const auto& imu = c.imu;
  require_positive(imu.rate_hz, "imu.rate_hz");
  if (imu.rate_hz > 10000.0) bad("imu.rate_hz", "must be at most 10000");
  require_nonneg(imu.gyro_noise_density, "imu.gyro_noise_density");
  require_nonneg(imu.gyro_random_walk, "imu.gyro_random_walk");
  require_nonneg(imu.accel_noise_density, "imu.accel_noise_density");
  require_nonneg(imu.accel_random_walk, "imu.accel_random_walk");
  require_nonneg(imu.gyro_bias_sigma, "imu.gyro_bias_sigma");
  require_nonneg(imu.accel_bias_sigma, "imu.accel_bias_sigma");
  require_positive(c.camera.rate_hz, "camera.rate_hz");
  if (c.camera.rate_hz > imu.rate_hz) bad("camera.rate_hz", "must not exceed imu.rate_hz");
  if (!(std::abs(c.camera.time_offset_s) <= 1.0)) bad("camera.time_offset_s", "must be within [-1, 1] s");
  if (!(std::abs(c.camera.declared_time_offset_s) <= 1.0))
    bad("camera.declared_time_offset_s", "must be within [-1, 1] s");
  validate_detection(c.detection, c.visibility, c.camera.intrinsics, "detection", "visibility", "camera.intrinsics");
  require_positive(c.mocap.rate_hz, "mocap.rate_hz");
  if (c.mocap.rate_hz > 10000.0) bad("mocap.rate_hz", "must be at most 10000");
  // At least one IMU interval (two samples; the first image comes at the start), and not so many
  // samples that memory runs out (each stream is held in memory): at most 1e8 per stream.
  if (c.duration_s * imu.rate_hz < 1.0)
    bad("duration_s", fmt::format("{} s is shorter than one IMU period (1/{} s): nothing to run a filter on",
                                  c.duration_s, imu.rate_hz));
  constexpr double kMaxSamples = 1e8;
  for (const auto& [rate, key] : {std::pair<double, const char*>{imu.rate_hz, "imu.rate_hz"},
                                  {c.camera.rate_hz, "camera.rate_hz"},
                                  {c.mocap.rate_hz, "mocap.rate_hz"}})
    if (c.duration_s * rate > kMaxSamples)
      bad(key, fmt::format("{} Hz over duration_s {} s is {:.3g} samples; at most {:g} per stream (lower the "
                           "rate or shorten the run)",
                           rate, c.duration_s, c.duration_s * rate, kMaxSamples));
  // The last stamp must fit in int64 nanoseconds.
  if (c.start_time_ns > std::numeric_limits<std::int64_t>::max() - from_seconds(c.duration_s) - 1'000'000'000)
    bad("start_time_ns", "too large: start_time_ns + duration_s does not fit in 64-bit nanoseconds");
  require_nonneg(c.mocap.position_sigma_m, "mocap.position_sigma_m");
  require_nonneg(c.mocap.rotation_sigma_deg, "mocap.rotation_sigma_deg");
}

TrajectoryConfig vary_trajectory(const TrajectoryConfig& nominal, const VariationConfig& v,
                                 std::uint64_t seed) {
  TrajectoryConfig t = nominal;
  Rng rng = Rng::stream(seed, "trajectory");
  t.azimuth_rad.offset += rng.uniform(-v.azimuth_start_rad, v.azimuth_start_rad);
  t.radius_m.offset *= rng.uniform(1.0 - v.offset_rel, 1.0 + v.offset_rel);
  t.height_m.offset *= rng.uniform(1.0 - v.offset_rel, 1.0 + v.offset_rel);
  for (SmoothSignal* s : {&t.azimuth_rad, &t.radius_m, &t.height_m, &t.target_x_m, &t.target_y_m,
                          &t.target_z_m, &t.roll_rad, &t.shake_x_m, &t.shake_y_m, &t.shake_z_m})
    vary(*s, v, rng);
  return t;
}

std::vector<TruthObject> place_objects(const ObjectsConfig& o) {
  Rng rng = Rng::stream(o.layout_seed, "objects");
  std::vector<TruthObject> out;
  // Explicit poses first, so drawn objects keep their distance from them.
  for (const auto& s : o.objects)
    if (s.has_pose) out.push_back({s.id, s.T_M_O});
  for (const auto& s : o.objects) {
    if (s.has_pose) continue;
    bool placed = false;
    for (int attempt = 0; attempt < 10000 && !placed; ++attempt) {
      const double x = o.area_center.x() + rng.uniform(-0.5, 0.5) * o.area_size_m;
      const double y = o.area_center.y() + rng.uniform(-0.5, 0.5) * o.area_size_m;
      const double z = o.area_center.z() + rng.uniform(0.0, 1.0) * o.height_jitter_m;
      const double yaw = rng.uniform(-kPi, kPi);
      const bool lying = rng.uniform() < o.lying_prob;
      const Eigen::Vector3d p(x, y, z);
      bool ok = true;
      for (const auto& other : out)
        if ((other.T_W_O.p.head<2>() - p.head<2>()).norm() < o.min_separation_m) ok = false;
      if (!ok) continue;
      Eigen::Matrix3d R = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
      if (lying) R = R * Eigen::AngleAxisd(0.5 * kPi, Eigen::Vector3d::UnitX()).toRotationMatrix();
      out.push_back({s.id, Pose(R, p)});
      placed = true;
    }
    if (!placed)
      bad("objects.min_separation_m", "cannot place object " + std::to_string(s.id) +
                                          ": the area is too small for the minimum separation");
  }
  // Keep the configured order (by position in the objects list).
  std::vector<TruthObject> ordered;
  for (const auto& s : o.objects)
    for (const auto& p : out)
      if (p.id == s.id) ordered.push_back(p);
  return ordered;
}

Dataset simulate(const SimConfig& config, std::uint64_t seed) { return simulate_run(config, seed).dataset; }

namespace {

// roe.json of a preset run: the declared camera (prior T_I_C, declared time offset) and the truth.
void set_manifest(const SimConfig& config, const std::vector<TruthObject>& objects_M, const Pose& T_W_M,
                  DatasetManifest& m) {
  m.name = config.name;
  m.imu = ImuInfo{config.imu.rate_hz, ImuNoise{config.imu.gyro_noise_density, config.imu.gyro_random_walk,
                                               config.imu.accel_noise_density, config.imu.accel_random_walk}};
  m.camera = camera_info(config.camera.intrinsics, config.camera.T_I_C * config.camera.prior_error,
                         config.camera.declared_time_offset_s);
  if (config.mocap.enabled) m.mocap = MocapInfo{config.mocap.body, config.mocap.T_B_I, 0.0};
  const auto syms = symmetry_map(ids_of(objects_M), config.objects.symmetric_ids);
  Truth truth;
  truth.T_I_C = config.camera.T_I_C;
  truth.camera_time_offset_s = config.camera.time_offset_s;
  for (const auto& o : objects_M) {
    m.objects.push_back({o.id, ycbv_name(o.id), syms.count(o.id) > 0, "", -1, {}});
    truth.objects.push_back({o.id, T_W_M * o.T_W_O});
  }
  truth.imu_noise = m.imu->noise;
  truth.detection_noise = noise_map(config.detection, config.visibility);
  m.truth = truth;
}

}  // namespace

SimRun simulate_run(const SimConfig& config, std::uint64_t seed) {
  validate(config);
  const InspectionTrajectory traj(vary_trajectory(config.trajectory, config.variation, seed));
  const std::vector<TruthObject> objects_M = place_objects(config.objects);
  const Pose T_C_I = config.camera.T_I_C.inverse();
  const Timestamp t0 = config.start_time_ns;
  const Timestamp t_end = t0 + from_seconds(config.duration_s);
  auto rel = [t0](Timestamp t) { return dt_seconds(t0, t); };

  SimRun run;
  Dataset& ds = run.dataset;
  SimStats& st = run.stats;

  // W: gravity-aligned, parallel to M, origin at the IMU's initial position.
  const Kinematics k0 = traj.attached(0.0, T_C_I);
  const Pose T_M_W(Eigen::Quaterniond::Identity(), k0.T_M_X.p);
  const Pose T_W_M = T_M_W.inverse();

  // IMU and ground truth.
  {
    Rng rng = Rng::stream(seed, config.name + "/imu");
    const auto& ic = config.imu;
    Eigen::Vector3d b_g = ic.gyro_bias_sigma * rng.normal3();
    Eigen::Vector3d b_a = ic.accel_bias_sigma * rng.normal3();
    const double sd_g = ic.gyro_noise_density * std::sqrt(ic.rate_hz);
    const double sd_a = ic.accel_noise_density * std::sqrt(ic.rate_hz);
    const std::vector<Timestamp> ts = stamps(t0, t_end, ic.rate_hz);
    ds.imu.reserve(ts.size());
    ds.groundtruth.reserve(ts.size());
    for (std::size_t k = 0; k < ts.size(); ++k) {
      const Kinematics ki = traj.attached(rel(ts[k]), T_C_I);
      const Eigen::Matrix3d R_W_I = ki.T_M_X.R();  // W is parallel to M
      ImuSample s;
      s.t_ns = ts[k];
      const Eigen::Vector3d n_g = sd_g * rng.normal3();
      const Eigen::Vector3d n_a = sd_a * rng.normal3();
      s.gyro = ki.omega_X + b_g + n_g;
      s.accel = R_W_I.transpose() * (ki.a_M + kGravity_W) + b_a + n_a;
      ds.imu.push_back(s);
      ImuState g;
      g.t_ns = ts[k];
      g.T_W_I = T_W_M * ki.T_M_X;
      g.v_W_I = ki.v_M;
      g.b_g = b_g;
      g.b_a = b_a;
      ds.groundtruth.push_back(g);
      st.max_speed_m_s = std::max(st.max_speed_m_s, ki.v_M.norm());
      st.max_rate_deg_s = std::max(st.max_rate_deg_s, ki.omega_X.norm() / kRadPerDeg);
      if (k + 1 < ts.size()) {
        const double dt = dt_seconds(ts[k], ts[k + 1]);
        b_g += ic.gyro_random_walk * std::sqrt(dt) * rng.normal3();
        b_a += ic.accel_random_walk * std::sqrt(dt) * rng.normal3();
      }
    }
    st.imu_samples = ds.imu.size();
  }

  // Camera frames and detections.
  {
    PoetErrorModel model(config.detection, symmetry_map(ids_of(objects_M), config.objects.symmetric_ids),
                         config.camera.intrinsics);
    Rng rng_vis = Rng::stream(seed, config.name + "/visibility");
    Rng rng_blur = Rng::stream(seed, config.name + "/blur");
    Rng rng_burst = Rng::stream(seed, config.name + "/bursts");
    Rng rng_det = Rng::stream(seed, config.name + "/detections");
    auto& dets = ds.detections["sim"];
    st.min_distance_m = std::numeric_limits<double>::infinity();
    // A frame that sees the rig at IMU time t is stamped t − offset (t_imu = t_cam + offset).
    const Timestamp offset_ns = from_seconds(config.camera.time_offset_s);
    for (Timestamp t : stamps(t0, t_end, config.camera.rate_hz)) {
      const Timestamp t_cam = t - offset_ns;
      ds.frames.push_back({t_cam, std::to_string(t_cam) + ".png"});
      const Kinematics kc = traj.camera(rel(t));
      const double dist = (kc.T_M_X.p - config.trajectory.center).norm();
      st.min_distance_m = std::min(st.min_distance_m, dist);
      st.max_distance_m = std::max(st.max_distance_m, dist);
      const FrameCondition frame = model.frame_condition(kc.omega_X.norm(), rng_blur, rng_burst);
      if (frame.blurred) ++st.blurred_frames;
      if (frame.bad) ++st.bad_frames;
      const Pose T_C_M = kc.T_M_X.inverse();
      bool any = false;
      for (const auto& o : objects_M) {
        const Pose T_C_O = T_C_M * o.T_W_O;  // T_W_O holds T_M_O here
        any |= observe_object(t_cam, o.id, T_C_O, config.camera.intrinsics, config.visibility, frame, model,
                              rng_vis, rng_det, dets, run);
      }
      if (any) ++st.frames_with_detections;
    }
    st.frames = ds.frames.size();
    if (ds.frames.empty()) st.min_distance_m = 0.0;
  }

  // Motion capture of the body B.
  if (config.mocap.enabled) {
    Rng rng = Rng::stream(seed, config.name + "/mocap");
    const Pose T_I_B = config.mocap.T_B_I.inverse();
    for (Timestamp t : stamps(t0, t_end, config.mocap.rate_hz)) {
      const Pose T_M_B = traj.attached(rel(t), T_C_I).T_M_X * T_I_B;
      const Eigen::Vector3d dp = config.mocap.position_sigma_m * rng.normal3();
      const Eigen::Vector3d dth = config.mocap.rotation_sigma_deg * kRadPerDeg * rng.normal3();
      ds.mocap.push_back({t, Pose(math::canonical(T_M_B.q * math::exp_quat(dth)), T_M_B.p + dp)});
    }
  }

  set_manifest(config, objects_M, T_W_M, ds.manifest);
  return run;
}

// ---------------------------------------------------------------------------------------------
// --from-groundtruth
// ---------------------------------------------------------------------------------------------

Pose FromGroundtruthConfig::euroc_T_I_C() {
  // EuRoC MAV mav0/cam0/sensor.yaml, T_BS (body = IMU, sensor = cam0), row-major.
  Eigen::Matrix3d R;
  R << 0.0148655429818, -0.999880929698, 0.00414029679422,  //
      0.999557249008, 0.0149672133247, 0.025715529948,      //
      -0.0257744366974, 0.00375618835797, 0.999660727178;
  return Pose(math::orthonormalize(R), Eigen::Vector3d(-0.0216401454975, -0.064676986768, 0.00981073058949));
}

namespace {
// T_W_I at time t by interpolation of the (sorted) ground truth; t must lie within it.
Pose gt_pose_at(const std::vector<ImuState>& gt, Timestamp t) {
  auto it =
      std::lower_bound(gt.begin(), gt.end(), t, [](const ImuState& s, Timestamp x) { return s.t_ns < x; });
  if (it == gt.end()) return gt.back().T_W_I;
  if (it->t_ns == t || it == gt.begin()) return it->T_W_I;
  const auto& a = *(it - 1);
  const auto& b = *it;
  return math::interpolate(a.T_W_I, b.T_W_I, dt_seconds(a.t_ns, t) / dt_seconds(a.t_ns, b.t_ns));
}

// The time between the two ground-truth poses around t (0 at a pose's own stamp).
Timestamp groundtruth_gap_at(const std::vector<ImuState>& gt, Timestamp t) {
  auto it =
      std::lower_bound(gt.begin(), gt.end(), t, [](const ImuState& s, Timestamp x) { return s.t_ns < x; });
  if (it == gt.end() || it->t_ns == t || it == gt.begin()) return 0;
  return it->t_ns - (it - 1)->t_ns;
}

// |ω| of the IMU sample nearest to t.
double rate_at(const std::vector<ImuSample>& imu, Timestamp t) {
  auto it =
      std::lower_bound(imu.begin(), imu.end(), t, [](const ImuSample& s, Timestamp x) { return s.t_ns < x; });
  if (it == imu.end()) return imu.back().gyro.norm();
  if (it != imu.begin() && (t - (it - 1)->t_ns) < (it->t_ns - t)) --it;
  return it->gyro.norm();
}

// Frames (indices into T_C_W) in which a point is in view (object_in_view: depth range, margin).
std::vector<std::uint32_t> frames_seeing(const std::vector<Pose>& T_C_W, const Eigen::Vector3d& p_W,
                                         const PinholeCamera& cam, const VisibilityConfig& vis) {
  std::vector<std::uint32_t> seen;
  for (std::size_t k = 0; k < T_C_W.size(); ++k)
    if (object_in_view(Pose(Eigen::Quaterniond::Identity(), T_C_W[k].act(p_W)), cam, vis))
      seen.push_back(static_cast<std::uint32_t>(k));
  return seen;
}

std::vector<Pose> inverses(const std::vector<Pose>& T) {
  std::vector<Pose> out;
  out.reserve(T.size());
  for (const auto& x : T) out.push_back(x.inverse());
  return out;
}
}  // namespace

PlacementCoverage placement_coverage(const std::vector<Timestamp>& t, const std::vector<Pose>& T_W_C,
                                     const std::vector<Eigen::Vector3d>& p_W, const PinholeCamera& cam,
                                     const VisibilityConfig& vis) {
  if (t.size() != T_W_C.size()) throw DataError("placement_coverage: stamps and poses differ in size");
  PlacementCoverage c;
  c.frames = t.size();
  const std::vector<Pose> T_C_W = inverses(T_W_C);
  std::vector<char> covered(t.size(), 0);
  for (const auto& p : p_W) {
    const auto seen = frames_seeing(T_C_W, p, cam, vis);
    c.frames_per_object.push_back(seen.size());
    for (auto k : seen) covered[k] = 1;
  }
  if (t.empty()) return c;
  // Gaps: between consecutive covered frames, and the uncovered stretches at both ends.
  Timestamp last = t.front();
  for (std::size_t k = 0; k < t.size(); ++k) {
    if (!covered[k]) continue;
    ++c.frames_covered;
    c.longest_gap_s = std::max(c.longest_gap_s, dt_seconds(last, t[k]));
    last = t[k];
  }
  c.longest_gap_s = std::max(c.longest_gap_s, dt_seconds(last, t.back()));
  return c;
}

std::vector<Eigen::Vector3d> place_along_trajectory(const std::vector<Timestamp>& t,
                                                    const std::vector<Pose>& T_W_C,
                                                    const FromGroundtruthConfig& config, std::uint64_t seed) {
  const std::string cfg = "from_groundtruth";
  require_positive(config.place_min_depth_m, cfg + ".place_min_depth_m");
  if (!(config.place_max_depth_m > config.place_min_depth_m))
    bad(cfg + ".place_max_depth_m", "must be greater than place_min_depth_m");
  if (!(config.place_inner_fraction > 0.0 && config.place_inner_fraction <= 1.0))
    bad(cfg + ".place_inner_fraction", "must be in (0, 1]");
  require_positive(config.place_candidate_every_s, cfg + ".place_candidate_every_s");
  if (config.place_candidates_per_frame < 1) bad(cfg + ".place_candidates_per_frame", "must be at least 1");
  require_nonneg(config.anchor_window_s, cfg + ".anchor_window_s");
  require_nonneg(config.anchor_lead_s, cfg + ".anchor_lead_s");
  require_nonneg(config.min_separation_m, cfg + ".min_separation_m");
  if (config.num_objects < 1) bad("objects", "--objects must be at least 1");
  if (t.size() != T_W_C.size()) throw DataError("place_along_trajectory: stamps and poses differ in size");
  if (t.empty()) throw DataError("no camera frames to place objects for");

  // Candidates: points in front of the camera at frames spread over the whole recording, so that
  // every part of the trajectory proposes positions it sees.
  Rng rng = Rng::stream(seed, "placement");
  const auto& K = config.intrinsics;
  const std::vector<Pose> T_C_W = inverses(T_W_C);
  struct Candidate {
    Eigen::Vector3d p_W;
    std::vector<std::uint32_t> seen;  // sorted frame indices
  };
  std::vector<Candidate> cands;
  Timestamp next = t.front();
  for (std::size_t k = 0; k < t.size(); ++k) {
    if (t[k] < next) continue;
    next = t[k] + static_cast<Timestamp>(std::llround(config.place_candidate_every_s * 1e9));
    for (int j = 0; j < config.place_candidates_per_frame; ++j) {
      const double f = config.place_inner_fraction;
      const double u = K.cx + rng.uniform(-0.5, 0.5) * f * K.width;
      const double v = K.cy + rng.uniform(-0.5, 0.5) * f * K.height;
      const double z = rng.uniform(config.place_min_depth_m, config.place_max_depth_m);
      const Eigen::Vector3d p_W =
          T_W_C[k].act(Eigen::Vector3d((u - K.cx) / K.fx * z, (v - K.cy) / K.fy * z, z));
      auto seen = frames_seeing(T_C_W, p_W, K, config.visibility);
      if (seen.size() >= config.min_frames_visible) cands.push_back({p_W, std::move(seen)});
    }
  }

  auto far_enough = [&](const Eigen::Vector3d& p, const std::vector<Eigen::Vector3d>& chosen) {
    for (const auto& q : chosen)
      if ((q - p).norm() < config.min_separation_m) return false;
    return true;
  };
  // Anchor: seen first (within the window) and in as many frames as possible, so that the filter's
  // main object is the first one detected and stays in view repeatedly.
  const Timestamp window_end = t.front() + static_cast<Timestamp>(std::llround(config.anchor_window_s * 1e9));
  const Candidate* anchor = nullptr;
  for (const auto& c : cands)
    if (t[c.seen.front()] <= window_end && (!anchor || c.seen.size() > anchor->seen.size())) anchor = &c;
  if (!anchor)
    throw DataError("no position in front of the camera within " + std::to_string(config.anchor_window_s) +
                    " s of the start is seen in " + std::to_string(config.min_frames_visible) +
                    " frames; cannot place the anchor object");
  std::vector<Eigen::Vector3d> chosen{anchor->p_W};
  std::vector<char> covered(t.size(), 0);
  for (auto k : anchor->seen) covered[k] = 1;
  const Timestamp others_from =
      t[anchor->seen.front()] + static_cast<Timestamp>(std::llround(config.anchor_lead_s * 1e9));

  // Greedy maximum coverage for the others (the classic (1 − 1/e) approximation of max coverage).
  while (chosen.size() < static_cast<std::size_t>(config.num_objects)) {
    const Candidate* best = nullptr;
    std::size_t best_gain = 0;
    for (const auto& c : cands) {
      if (t[c.seen.front()] < others_from || !far_enough(c.p_W, chosen)) continue;
      std::size_t gain = 0;
      for (auto k : c.seen) gain += covered[k] ? 0 : 1;
      if (!best || gain > best_gain || (gain == best_gain && c.seen.size() > best->seen.size())) {
        best = &c;
        best_gain = gain;
      }
    }
    if (!best)
      throw DataError("only " + std::to_string(chosen.size()) + " of " + std::to_string(config.num_objects) +
                      " objects can be placed where the camera sees them in " +
                      std::to_string(config.min_frames_visible) + " frames, " +
                      std::to_string(config.min_separation_m) + " m apart");
    chosen.push_back(best->p_W);
    for (auto k : best->seen) covered[k] = 1;
  }

  return chosen;
}

SimRun simulate_from_groundtruth(const std::vector<ImuSample>& imu, const std::vector<ImuState>& gt,
                                 const FromGroundtruthConfig& config, std::uint64_t seed) {
  const std::string cfg = "from_groundtruth";
  if (config.num_objects < 1) bad("objects", "--objects must be at least 1");
  if (static_cast<std::size_t>(config.num_objects) > config.object_ids.size())
    bad("objects", "at most " + std::to_string(config.object_ids.size()) + " objects are available");
  require_positive(config.camera_rate_hz, cfg + ".camera_rate_hz");
  if (!(std::abs(config.time_offset_s) <= 1.0)) bad(cfg + ".time_offset_s", "must be within [-1, 1] s");
  validate_detection(config.detection, config.visibility, config.intrinsics, cfg + ".detection",
                     cfg + ".visibility", cfg + ".intrinsics");
  const std::vector<int> ids(config.object_ids.begin(), config.object_ids.begin() + config.num_objects);
  validate_ids(ids, [](std::size_t) { return std::string("objects"); });
  if (imu.size() < 2) throw DataError("the IMU stream has fewer than 2 samples");
  if (gt.size() < 2) throw DataError("the ground truth has fewer than 2 poses");

  const Timestamp t_begin = std::max(imu.front().t_ns, gt.front().t_ns);
  const Timestamp t_end = std::min(imu.back().t_ns, gt.back().t_ns);
  if (t_end - t_begin < kNsPerSecond)
    throw DataError("the IMU and the ground truth overlap for less than one second");

  SimRun run;
  Dataset& ds = run.dataset;
  SimStats& st = run.stats;
  ds.imu = imu;
  ds.groundtruth = gt;
  st.imu_samples = imu.size();

  // Camera poses at the frame stamps inside the overlap.
  std::vector<Timestamp> ts = stamps(t_begin, t_end, config.camera_rate_hz);
  require_positive(config.max_groundtruth_gap_s, cfg + ".max_groundtruth_gap_s");
  ts.erase(std::remove_if(ts.begin(), ts.end(),
                          [&](Timestamp t) { return groundtruth_gap_at(gt, t) > from_seconds(config.max_groundtruth_gap_s); }),
           ts.end());
  std::vector<Pose> T_W_C, T_C_W;
  for (Timestamp t : ts) {
    ds.frames.push_back({t, std::to_string(t) + ".png"});
    T_W_C.push_back(gt_pose_at(gt, t) * config.T_I_C);
    T_C_W.push_back(T_W_C.back().inverse());
  }
  st.frames = ts.size();

  // Placement (place_along_trajectory): centres covering the trajectory; orientations uniform.
  Rng rng_rot = Rng::stream(seed, "from-groundtruth/orientations");
  std::vector<TruthObject> objects_W;
  const std::vector<Eigen::Vector3d> centres = place_along_trajectory(ts, T_W_C, config, seed);
  for (std::size_t i = 0; i < centres.size(); ++i)
    objects_W.push_back({ids[i], Pose(rng_rot.rotation(), centres[i])});
  const auto& K = config.intrinsics;

  // Detections.
  const auto syms = symmetry_map(ids, config.symmetric_ids);
  PoetErrorModel model(config.detection, syms, K);
  Rng rng_vis = Rng::stream(seed, "from-groundtruth/visibility");
  Rng rng_blur = Rng::stream(seed, "from-groundtruth/blur");
  Rng rng_burst = Rng::stream(seed, "from-groundtruth/bursts");
  Rng rng_det = Rng::stream(seed, "from-groundtruth/detections");
  auto& dets = ds.detections["sim"];
  const Timestamp offset_ns = from_seconds(config.time_offset_s);  // stamped t − offset (t_imu = t_cam + offset)
  for (auto& f : ds.frames) {
    f.t_ns -= offset_ns;
    f.filename = std::to_string(f.t_ns) + ".png";
  }
  for (std::size_t k = 0; k < ts.size(); ++k) {
    const FrameCondition frame = model.frame_condition(rate_at(imu, ts[k]), rng_blur, rng_burst);
    if (frame.blurred) ++st.blurred_frames;
    if (frame.bad) ++st.bad_frames;
    bool any = false;
    for (const auto& o : objects_W) {
      const Pose T_C_O = T_C_W[k] * o.T_W_O;
      any |= observe_object(ts[k] - offset_ns, o.id, T_C_O, K, config.visibility, frame, model, rng_vis, rng_det, dets,
                            run);
    }
    if (any) ++st.frames_with_detections;
  }
  for (std::size_t k = 0; k < gt.size(); ++k) {
    st.max_speed_m_s = std::max(st.max_speed_m_s, gt[k].v_W_I.norm());
  }
  for (const auto& s : imu) st.max_rate_deg_s = std::max(st.max_rate_deg_s, s.gyro.norm() / kRadPerDeg);
  st.min_distance_m = st.max_distance_m = 0.0;

  // The ground-truth poses double as the mocap stream (body = IMU, M = W), unchanged.
  for (const auto& g : gt) ds.mocap.push_back({g.t_ns, g.T_W_I});

  DatasetManifest& m = ds.manifest;
  m.name = "from-groundtruth";
  // Rate from the median sample interval of the real IMU.
  const double rate = median_rate_hz(imu, [](const ImuSample& s) { return s.t_ns; });
  m.imu = ImuInfo{rate, config.imu_noise};
  m.camera = camera_info(K, config.T_I_C, config.declared_time_offset_s);
  m.mocap = MocapInfo{"groundtruth", Pose(), 0.0};
  Truth truth;
  truth.T_I_C = config.T_I_C;
  truth.camera_time_offset_s = config.time_offset_s;
  for (const auto& o : objects_W) {
    m.objects.push_back({o.id, ycbv_name(o.id), syms.count(o.id) > 0, "", -1, {}});
    truth.objects.push_back(o);
  }
  truth.imu_noise = config.imu_noise;
  truth.detection_noise = noise_map(config.detection, config.visibility);
  m.truth = truth;
  return run;
}

}  // namespace roe::sim
