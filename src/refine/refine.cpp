// The batch refinement: problem assembly, solve and marginal covariances with Ceres (docs/refine.md).
#include "roe/refine/refine.hpp"

#include <ceres/autodiff_cost_function.h>
#include <ceres/autodiff_manifold.h>
#include <ceres/loss_function.h>
#include <ceres/ordered_groups.h>
#include <ceres/problem.h>
#include <ceres/solver.h>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <memory>

#include "roe/core/error.hpp"
#include "roe/ekf/filter.hpp"
#include "roe/ekf/measurement.hpp"
#include "roe/ekf/symmetry.hpp"
#include "roe/math/se3.hpp"
#include "roe/refine/factors.hpp"
#include "roe/refine/marginals.hpp"
#include "roe/refine/preintegration.hpp"

namespace roe::refine {

Eigen::MatrixXd sqrt_information(const Eigen::MatrixXd& cov) {
  const Eigen::LLT<Eigen::MatrixXd> llt(cov);
  if (llt.info() != Eigen::Success) throw NumericError("refine: a residual's covariance is not positive definite");
  return llt.matrixL().solve(Eigen::MatrixXd::Identity(cov.rows(), cov.cols()));
}

std::string to_string(Loss l) {
  switch (l) {
    case Loss::kNone: return "none";
    case Loss::kHuber: return "huber";
    case Loss::kCauchy: return "cauchy";
  }
  return "?";
}

Loss parse_loss(const std::string& name) {
  for (const Loss l : {Loss::kNone, Loss::kHuber, Loss::kCauchy})
    if (to_string(l) == name) return l;
  throw ConfigError(fmt::format("unknown loss '{}' (none, huber, cauchy)", name), {"", 0, 0, "loss"});
}

namespace {

using Clock = std::chrono::steady_clock;
using Block7 = std::array<double, 7>;
using Block3 = std::array<double, 3>;
using Block6 = std::array<double, 6>;
constexpr double kDeg = M_PI / 180.0;
/// Variance floor of the IMU residuals (a noise-free IMU would make them singular): σ = 1e-7.
constexpr double kVarFloor = 1e-14;
/// The detection-error scales are at least this (a detector 100 times better than its σ model is taken as
/// that): on exact detections (a noise-free simulation) the fitted scales would go to the residuals'
/// rounding level and the solve weight them by 10¹⁰.
constexpr double kMinScale = 0.01;

Block7 to_block(const Pose& T) { return {T.p.x(), T.p.y(), T.p.z(), T.q.x(), T.q.y(), T.q.z(), T.q.w()}; }
Pose to_pose(const Block7& b) { return Pose(Eigen::Quaterniond(b[6], b[3], b[4], b[5]), Eigen::Vector3d(b[0], b[1], b[2])); }

/// The state at t from a time-sorted sequence: linear in p, v and the biases, slerp in q.
ekf::CoreState interpolate_state(const std::vector<StateSample>& s, Timestamp t, std::size_t& k) {
  while (k + 1 < s.size() && s[k + 1].t_ns <= t) ++k;
  if (k + 1 == s.size() || s[k].t_ns == t) return s[k].x;
  const StateSample& a = s[k];
  const StateSample& b = s[k + 1];
  const double u = static_cast<double>(t - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  ekf::CoreState x;
  const Pose T = math::interpolate(Pose(a.x.q_W_I, a.x.p_W_I), Pose(b.x.q_W_I, b.x.p_W_I), u);
  x.p_W_I = T.p;
  x.q_W_I = T.q;
  x.v_W_I = a.x.v_W_I + u * (b.x.v_W_I - a.x.v_W_I);
  x.b_g = a.x.b_g + u * (b.x.b_g - a.x.b_g);
  x.b_a = a.x.b_a + u * (b.x.b_a - a.x.b_a);
  return x;
}

/// The unknowns and everything Ceres holds pointers into (addresses stable once built).
struct Problem {
  std::vector<Timestamp> t;
  std::vector<Block7> pose;
  std::vector<Block3> vel;
  std::vector<Block6> bias;
  Block7 extr{};
  std::map<int, Block7> obj;
  /// δ = t_d − the declared offset (docs/refine.md §2b), a parameter block when the offset is estimated.
  std::array<double, 1> td{};
  bool estimate_td = false;
  std::vector<Eigen::Vector3d> gyro;  ///< per node: the gyro measured at its time (the time shift's ω + b_g)
  std::unique_ptr<ceres::Manifold> pose_manifold = std::make_unique<ceres::AutoDiffManifold<PosePlus, 7, 6>>();
  std::unique_ptr<ceres::Manifold> tilt_manifold = std::make_unique<ceres::AutoDiffManifold<AnchorTiltPlus, 7, 2>>();
  std::unique_ptr<ceres::LossFunction> loss;
  std::unique_ptr<ceres::Problem> cp;
  /// One used detection of an object with an object-world (in image order, so in time order per object).
  struct Det {
    ceres::ResidualBlockId id = nullptr;
    Timestamp t_ns = 0;
    int object_id = 0;
    std::size_t node = 0;
    Detection det;               ///< as detected (the σ model reads its per-detection σ)
    Pose T_C_O;                  ///< as detected
    Pose meas;                   ///< T_C_O, or a symmetric object's equivalent nearest the prediction
    double s_lat = 1.0, s_ray = 1.0, s_rot = 1.0;  ///< the σ model's σ at the prediction (unit scales)
    const ObjectSymmetry* sym = nullptr;
    Mat6 S = Mat6::Identity();   ///< standardising matrix at unit scales (ray frame, σ, symmetry)
    Vector6d y = Vector6d::Zero();  ///< S e at the current estimate
    bool gross = false;          ///< dropped (its chain bridged over it)
  };
  std::vector<Det> dets;
  std::map<int, std::vector<std::size_t>> chains;  ///< per object, its detections' indices in time order
  int anchor_id = -1;
  std::unique_ptr<ekf::Filter> sigma_model;  ///< the filter's detection σ model (one definition)
  double sigma_var_scale = 1.0;              ///< the run's learned scale² of per-detection σ, where used
  std::size_t imu_factors = 0;
};

using RowMat6 = Eigen::Matrix<double, 6, 6, Eigen::RowMajor>;

/// A detection factor (FirstDetectionResidual, or WhitenedDetectionResidual with a previous detection)
/// with the analytic Jacobians of factors.cpp: r = A e_k − B e_{k−1}; blocks T_W_I of k, T_I_C, T_O_W
/// [, T_W_I of k−1].
class DetectionCost : public ceres::CostFunction {
 public:
  DetectionCost(const Pose& meas, const Mat6& A) : q_(meas.q), t_(meas.p), A_(A) {
    set_num_residuals(6);
    *mutable_parameter_block_sizes() = {7, 7, 7};
  }
  DetectionCost(const Pose& meas, const Pose& prev, const Mat6& A, const Mat6& B)
      : q_(meas.q), t_(meas.p), q0_(prev.q), t0_(prev.p), A_(A), B_(B), chained_(true) {
    set_num_residuals(6);
    *mutable_parameter_block_sizes() = {7, 7, 7, 7};
  }
  bool Evaluate(double const* const* x, double* residuals, double** jac) const override {
    Mat6 J[3], J0[3];
    const bool want = jac != nullptr;
    Eigen::Map<Vector6d> r(residuals);
    r = A_ * detection_error_jacobians(q_, t_, x[0], x[1], x[2], want ? &J[0] : nullptr, want ? &J[1] : nullptr,
                                       want ? &J[2] : nullptr);
    if (chained_)
      r -= B_ * detection_error_jacobians(q0_, t0_, x[3], x[1], x[2], want ? &J0[0] : nullptr, want ? &J0[1] : nullptr,
                                          want ? &J0[2] : nullptr);
    if (!want) return true;
    for (int k = 0; k < (chained_ ? 4 : 3); ++k) {
      if (!jac[k]) continue;
      RowMat6 T;
      if (k == 3) T = -B_ * J0[0];
      else T = chained_ && k > 0 ? Mat6(A_ * J[k] - B_ * J0[k]) : Mat6(A_ * J[k]);
      pose_ambient_jacobian(x[k], T.data(), 6, jac[k]);
    }
    return true;
  }

 private:
  Eigen::Quaterniond q_;
  Eigen::Vector3d t_;
  Eigen::Quaterniond q0_ = Eigen::Quaterniond::Identity();
  Eigen::Vector3d t0_ = Eigen::Vector3d::Zero();
  Mat6 A_, B_ = Mat6::Zero();
  bool chained_ = false;
};

/// A detection factor with the camera–IMU time offset estimated (docs/refine.md §2b): r = A e_k − B e_{k−1}, each
/// error at its node's pose carried by δ (shifted_detection_error_jacobians). Blocks: T_W_I, v, bias of k, T_I_C,
/// T_O_W [, T_W_I, v, bias of k−1], δ.
class TimeShiftedDetectionCost : public ceres::CostFunction {
 public:
  struct Side {
    Pose meas;
    Eigen::Vector3d gyro;
  };
  TimeShiftedDetectionCost(const Side& k, const Mat6& A) : k_(k), A_(A) {
    set_num_residuals(6);
    *mutable_parameter_block_sizes() = {7, 3, 6, 7, 7, 1};
  }
  TimeShiftedDetectionCost(const Side& k, const Side& prev, const Mat6& A, const Mat6& B)
      : k_(k), prev_(prev), A_(A), B_(B), chained_(true) {
    set_num_residuals(6);
    *mutable_parameter_block_sizes() = {7, 3, 6, 7, 7, 7, 3, 6, 1};
  }
  bool Evaluate(double const* const* x, double* residuals, double** jac) const override {
    using RM63 = Eigen::Matrix<double, 6, 3, Eigen::RowMajor>;
    const double delta = x[chained_ ? 8 : 5][0];
    TimeShiftJacobians J, J0;
    const bool want = jac != nullptr;
    Eigen::Map<Vector6d> r(residuals);
    r = A_ * shifted_detection_error_jacobians(k_.meas.q, k_.meas.p, x[0], x[1], x[2], k_.gyro, delta, x[3], x[4],
                                               want ? &J : nullptr);
    if (chained_)
      r -= B_ * shifted_detection_error_jacobians(prev_.meas.q, prev_.meas.p, x[5], x[6], x[7], prev_.gyro, delta,
                                                  x[3], x[4], want ? &J0 : nullptr);
    if (!want) return true;
    const auto pose = [&](int b, const Mat6& T_) {
      if (!jac[b]) return;
      const RowMat6 T = T_;
      pose_ambient_jacobian(x[b], T.data(), 6, jac[b]);
    };
    pose(0, A_ * J.pose);
    if (jac[1]) Eigen::Map<RM63>{jac[1]} = A_ * J.vel;
    if (jac[2]) Eigen::Map<RowMat6>{jac[2]} = A_ * J.bias;
    pose(3, chained_ ? Mat6(A_ * J.extr - B_ * J0.extr) : Mat6(A_ * J.extr));
    pose(4, chained_ ? Mat6(A_ * J.obj - B_ * J0.obj) : Mat6(A_ * J.obj));
    if (chained_) {
      pose(5, -B_ * J0.pose);
      if (jac[6]) Eigen::Map<RM63>{jac[6]} = -B_ * J0.vel;
      if (jac[7]) Eigen::Map<RowMat6>{jac[7]} = -B_ * J0.bias;
    }
    if (double* jd = jac[chained_ ? 8 : 5]) Eigen::Map<Vector6d>{jd} = chained_ ? Vector6d(A_ * J.delta - B_ * J0.delta)
                                                                                 : Vector6d(A_ * J.delta);
    return true;
  }

 private:
  Side k_, prev_{};
  Mat6 A_, B_ = Mat6::Zero();
  bool chained_ = false;
};

/// The IMU factor (ImuResidual) with the analytic Jacobians of factors.cpp.
class ImuCost : public ceres::SizedCostFunction<9, 7, 3, 6, 7, 3> {
 public:
  explicit ImuCost(const ImuResidual& f) : f_(f) {}
  bool Evaluate(double const* const* x, double* residuals, double** jac) const override {
    using RM96 = Eigen::Matrix<double, 9, 6, Eigen::RowMajor>;
    using RM93 = Eigen::Matrix<double, 9, 3, Eigen::RowMajor>;
    Eigen::Matrix<double, 9, 6> Jpi, Jb, Jpj;
    Eigen::Matrix<double, 9, 3> Jvi, Jvj;
    const bool want = jac != nullptr;
    const Eigen::Matrix<double, 9, 1> e = imu_error_jacobians(f_, x[0], x[1], x[2], x[3], x[4], want ? &Jpi : nullptr,
                                                              want ? &Jvi : nullptr, want ? &Jb : nullptr,
                                                              want ? &Jpj : nullptr, want ? &Jvj : nullptr);
    const auto W = f_.W.triangularView<Eigen::Lower>();
    Eigen::Map<Eigen::Matrix<double, 9, 1>> r(residuals);
    r = W * e;
    if (!want) return true;
    if (jac[0]) {
      const RM96 T = W * Jpi;
      pose_ambient_jacobian(x[0], T.data(), 9, jac[0]);
    }
    if (jac[1]) Eigen::Map<RM93>{jac[1]} = W * Jvi;
    if (jac[2]) Eigen::Map<RM96>{jac[2]} = W * Jb;
    if (jac[3]) {
      const RM96 T = W * Jpj;
      pose_ambient_jacobian(x[3], T.data(), 9, jac[3]);
    }
    if (jac[4]) Eigen::Map<RM93>{jac[4]} = W * Jvj;
    return true;
  }

 private:
  ImuResidual f_;
};

/// Node times: the first and last sample of the initial estimate and every image in between with a
/// detection of an object that has an initial object-world.
std::vector<Timestamp> node_times(const RefineInput& in) {
  const Timestamp t0 = in.initial.front().t_ns, t1 = in.initial.back().t_ns;
  std::vector<Timestamp> t = {t0};
  for (const auto& im : in.images) {
    if (im.t_ns < t0 || im.t_ns > t1) continue;
    const bool any = std::any_of(im.detections.begin(), im.detections.end(),
                                 [&](const Detection& d) { return in.initial_T_O_W.count(d.object_id) > 0; });
    if (any && im.t_ns > t.back()) t.push_back(im.t_ns);
  }
  if (t1 > t.back()) t.push_back(t1);
  return t;
}

/// The IMU noise of the batch: the run's, its filter.imu_noise_scale undone, × RefineOptions::imu_noise_scale.
ekf::ImuNoiseParams batch_imu_noise(const RefineInput& in, const RefineOptions& opt) {
  const double k = opt.imu_noise_scale / (in.filter.imu_noise_scale > 0.0 ? in.filter.imu_noise_scale : 1.0);
  ekf::ImuNoiseParams n = in.noise;
  n.gyro_noise_density *= k;
  n.gyro_random_walk *= k;
  n.accel_noise_density *= k;
  n.accel_random_walk *= k;
  return n;
}

void add_imu_factors(const RefineInput& in, const RefineOptions& opt, Problem& P) {
  std::size_t hint = 0;
  const ekf::ImuNoiseParams noise = batch_imu_noise(in, opt);
  const double rg = noise.gyro_random_walk, ra = noise.accel_random_walk;
  for (std::size_t i = 0; i + 1 < P.t.size(); ++i) {
    const Eigen::Map<const Eigen::Vector3d> bg(P.bias[i].data()), ba(P.bias[i].data() + 3);
    const Preintegration pre = preintegrate(in.imu, P.t[i], P.t[i + 1], bg, ba, noise, hint);
    Mat9 cov = pre.cov;
    cov.diagonal().array() += kVarFloor;
    const ImuResidual f{pre.dR, pre.dv, pre.dp, pre.bg_lin, pre.ba_lin, ekf::kGravity_W, pre.dt, pre.J_bias,
                        sqrt_information(cov)};
    P.cp->AddResidualBlock(new ImuCost(f), nullptr, P.pose[i].data(), P.vel[i].data(), P.bias[i].data(),
                           P.pose[i + 1].data(), P.vel[i + 1].data());
    Vector6d inv_sigma;
    inv_sigma << Eigen::Vector3d::Constant(1.0 / std::sqrt(rg * rg * pre.dt + kVarFloor)),
        Eigen::Vector3d::Constant(1.0 / std::sqrt(ra * ra * pre.dt + kVarFloor));
    P.cp->AddResidualBlock(new ceres::AutoDiffCostFunction<BiasWalkResidual, 6, 6, 6>(new BiasWalkResidual{inv_sigma}),
                           nullptr, P.bias[i].data(), P.bias[i + 1].data());
    ++P.imu_factors;
  }
}

/// The axes of a translation error for a translation t (the viewing ray r and two lateral axes u1, u2:
/// u1 ∥ ŷ × r, which stays near the image x axis for rays near the optical axis) — the frame roe simulate
/// draws its errors in (docs/simulator.md §6).
void ray_frame(const Eigen::Vector3d& t, Eigen::Vector3d& u1, Eigen::Vector3d& u2, Eigen::Vector3d& r) {
  r = t.norm() > 1e-9 ? Eigen::Vector3d(t.normalized()) : Eigen::Vector3d::UnitZ();
  u1 = Eigen::Vector3d::UnitY().cross(r);
  if (u1.norm() < 1e-9) u1 = Eigen::Vector3d::UnitX();
  u1.normalize();
  u2 = r.cross(u1);
}

/// The σ model's lateral, along-ray and rotation σ of a detection at a pose T_C_O (the prediction: the
/// simulator, and a detector, err about the true pose): the filter's covariance
/// (ekf::Filter::measurement_covariance, one definition; the per-detection σ times the run's learned scale
/// where the run used them) projected on that viewing ray and across it.
void sigma_model_of(const Problem& P, const Pose& T_C_O, Problem::Det& out) {
  Detection d = out.det;
  d.T_C_O = T_C_O;
  Mat6 R = P.sigma_model->measurement_covariance(d, false);
  if (d.sigma) R *= P.sigma_var_scale;
  const Eigen::Vector3d t = d.T_C_O.p;
  const Eigen::Vector3d r = t.norm() > 1e-9 ? Eigen::Vector3d(t.normalized()) : Eigen::Vector3d::UnitZ();
  const Eigen::Matrix3d Rt = R.topLeftCorner<3, 3>();
  out.s_ray = std::sqrt(r.dot(Rt * r));
  out.s_lat = std::sqrt(std::max(0.5 * (Rt.trace() - r.dot(Rt * r)), 1e-300));
  out.s_rot = std::sqrt(R.bottomRightCorner<3, 3>().trace() / 3.0);
}

/// The detections of the objects with an object-world, with their σ model and each object's chain.
void collect_detections(const RefineInput& in, Problem& P) {
  P.sigma_model = std::make_unique<ekf::Filter>(in.filter, in.noise, in.prior_T_I_C);
  P.sigma_var_scale = in.filter.use_detection_sigmas ? in.detection_sigma_scale * in.detection_sigma_scale : 1.0;
  for (const auto& im : in.images) {
    const auto it = std::lower_bound(P.t.begin(), P.t.end(), im.t_ns);
    if (it == P.t.end() || *it != im.t_ns) continue;
    for (const Detection& d : im.detections) {
      if (!P.obj.count(d.object_id)) continue;
      std::vector<std::size_t>& chain = P.chains[d.object_id];
      if (!chain.empty() && P.dets[chain.back()].t_ns == im.t_ns) continue;  // one per object and image
      Problem::Det det;
      det.t_ns = im.t_ns;
      det.object_id = d.object_id;
      det.node = static_cast<std::size_t>(it - P.t.begin());
      det.det = d;
      det.T_C_O = det.meas = d.T_C_O;
      if (const auto s = in.symmetries.find(d.object_id); s != in.symmetries.end() && !s->second.empty())
        det.sym = &s->second;
      chain.push_back(P.dets.size());
      P.dets.push_back(det);
    }
  }
  if (P.dets.empty()) throw DataError("refine: no detection of an object with an object-world: nothing to refine");
  // An object-world without a used detection is not in the problem (nothing observes it).
  for (auto it = P.obj.begin(); it != P.obj.end();) it = P.chains.count(it->first) ? std::next(it) : P.obj.erase(it);
  if (!P.obj.count(in.anchor_id))
    throw DataError(fmt::format("refine: no used detection of the anchor object {}", in.anchor_id));
}

/// The pose of node n when its images saw the rig: carried by δ = t_d − the declared offset when the offset is
/// estimated (docs/refine.md §2b, shifted_detection_error_jacobians), the node's own otherwise.
Block7 viewing_pose(const Problem& P, std::size_t n) {
  if (!P.estimate_td) return P.pose[n];
  const double delta = P.td[0];
  const Eigen::Vector3d w = P.gyro[n] - Eigen::Vector3d(P.bias[n][0], P.bias[n][1], P.bias[n][2]);
  const Pose T = to_pose(P.pose[n]);
  return to_block(Pose((T.q * Eigen::Quaterniond(math::exp_so3(w * delta))).normalized(),
                       T.p + Eigen::Vector3d(P.vel[n][0], P.vel[n][1], P.vel[n][2]) * delta));
}

/// At the current estimate: each detection's prediction, its measurement (a symmetric object's nearest
/// equivalent), its standardising matrix S (the ray frame of the prediction, as roe simulate draws the
/// error; a continuous symmetry's direction projected out) and y = S e.
void update_standardisation(Problem& P) {
  const Pose T_I_C = to_pose(P.extr);
  for (Problem::Det& d : P.dets) {
    const Pose T_O_W = to_pose(P.obj.at(d.object_id));
    const Block7 pose = viewing_pose(P, d.node);
    const Pose T_C_O_hat = (T_O_W * to_pose(pose) * T_I_C).inverse();
    if (d.sym) d.meas = ekf::nearest_equivalent(T_C_O_hat.inverse(), d.T_C_O.inverse(), *d.sym).inverse();
    sigma_model_of(P, T_C_O_hat, d);
    Eigen::Vector3d u1, u2, r;
    ray_frame(T_C_O_hat.p, u1, u2, r);
    Mat6 S = Mat6::Zero();
    S.row(0).head<3>() = u1.transpose() / d.s_lat;
    S.row(1).head<3>() = u2.transpose() / d.s_lat;
    S.row(2).head<3>() = r.transpose() / d.s_ray;
    S.bottomRightCorner<3, 3>() = Eigen::Matrix3d::Identity() / d.s_rot;
    if (d.sym && d.sym->continuous) {
      // T_C_O S(ψ) moves e by ψ [R (o × a); a] (translation in C, rotation in O): project it out in y.
      const ContinuousSymmetry& c = *d.sym->continuous;
      Vector6d dir;
      dir << T_C_O_hat.q * c.offset.cross(c.axis), c.axis;
      const Vector6d dy = (S * dir).normalized();
      S = (Mat6::Identity() - dy * dy.transpose()) * S;
    }
    d.S = S;
    d.y = S * detection_error<double>(d.meas.q, d.meas.p, pose.data(), P.extr.data(), P.obj.at(d.object_id).data());
  }
}

/// The standardised squared error of a detection under the model's scales.
double standardised_chi2(const Problem::Det& d, const DetectionErrorModel& m) {
  return d.y.head<3>().squaredNorm() / (m.scale_translation * m.scale_translation) +
         d.y.tail<3>().squaredNorm() / (m.scale_rotation * m.scale_rotation);
}

/// Robust scales from the medians of the blocks' squared norms (χ²₃ median 2.366, χ²₂ 1.386): the start
/// of a fit, before the gross detections are known.
DetectionErrorModel median_scales(const Problem& P) {
  std::vector<double> t, r;
  for (const auto& d : P.dets) {
    t.push_back(d.y.head<3>().squaredNorm() / 2.366);
    r.push_back(d.y.tail<3>().squaredNorm() / (d.sym && d.sym->continuous ? 1.386 : 2.366));
  }
  const auto median = [](std::vector<double>& v) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  DetectionErrorModel m;
  m.scale_translation = std::sqrt(std::max(median(t), kMinScale * kMinScale));
  m.scale_rotation = std::sqrt(std::max(median(r), kMinScale * kMinScale));
  return m;
}

/// The non-gross detections' standardised errors per object (and which detection each entry is).
std::vector<ErrorSeries> inlier_series(const Problem& P, std::vector<std::vector<std::size_t>>& index) {
  std::vector<ErrorSeries> series;
  index.clear();
  for (const auto& [id, chain] : P.chains) {
    ErrorSeries s;
    std::vector<std::size_t> idx;
    for (const std::size_t i : chain) {
      const Problem::Det& d = P.dets[i];
      if (d.gross) continue;
      s.t_s.push_back(to_seconds(d.t_ns));
      s.y.push_back(d.y);
      idx.push_back(i);
      if (d.sym && d.sym->continuous) s.rotation_dof = 2;
    }
    series.push_back(std::move(s));
    index.push_back(std::move(idx));
  }
  return series;
}

/// One fit round (docs/refine.md §2a): robust scales from the medians, the gross detections under them
/// (‖y‖²), then maximum likelihood fit and leave-one-out outliers (isolated_outliers) in turn until no
/// detection is added (at most 4 fits).
DetectionErrorModel fit_round(const RefineOptions& opt, Problem& P) {
  update_standardisation(P);
  DetectionErrorModel m = median_scales(P);
  for (auto& d : P.dets) d.gross = standardised_chi2(d, m) > opt.gross_chi2;
  std::vector<std::vector<std::size_t>> index;
  for (int pass = 0;; ++pass) {
    const std::vector<ErrorSeries> series = inlier_series(P, index);
    m = fit_error_model(series, opt.tau_s);
    if (pass == 3) break;
    std::size_t added = 0;
    for (std::size_t o = 0; o < series.size(); ++o) {
      const std::vector<bool> out = isolated_outliers(series[o], m, opt.gross_chi2);
      for (std::size_t k = 0; k < out.size(); ++k)
        if (out[k]) P.dets[index[o][k]].gross = true, ++added;
    }
    if (added == 0) break;
  }
  m.gross = 0;
  for (const auto& d : P.dets) m.gross += d.gross ? 1 : 0;
  return m;
}

/// A detection factor with the time offset estimated (TimeShiftedDetectionCost): first or whitened against `prev`.
void add_time_shifted_factor(Problem::Det& d, const Problem::Det* prev, double rho, const Mat6& D, double* obj,
                             Problem& P) {
  using Side = TimeShiftedDetectionCost::Side;
  const std::size_t n = d.node;
  if (rho < 1e-12) {
    d.id = P.cp->AddResidualBlock(new TimeShiftedDetectionCost(Side{d.meas, P.gyro[n]}, D * d.S), P.loss.get(),
                                  std::vector<double*>{P.pose[n].data(), P.vel[n].data(), P.bias[n].data(),
                                                       P.extr.data(), obj, P.td.data()});
    return;
  }
  const double c = 1.0 / std::sqrt(1.0 - rho * rho);
  const std::size_t m = prev->node;
  d.id = P.cp->AddResidualBlock(
      new TimeShiftedDetectionCost(Side{d.meas, P.gyro[n]}, Side{prev->meas, P.gyro[m]}, c * D * d.S,
                                   c * rho * D * prev->S),
      P.loss.get(),
      std::vector<double*>{P.pose[n].data(), P.vel[n].data(), P.bias[n].data(), P.extr.data(), obj,
                           P.pose[m].data(), P.vel[m].data(), P.bias[m].data(), P.td.data()});
}

/// The detection factors of the model (docs/refine.md §2), replacing the previous ones: per object, its
/// first non-gross detection standardised, each next one whitened against the previous non-gross one.
void install_detection_factors(const DetectionErrorModel& m, Problem& P) {
  for (auto& d : P.dets)
    if (d.id) P.cp->RemoveResidualBlock(d.id), d.id = nullptr;
  Mat6 D = Mat6::Zero();
  D.diagonal() << Eigen::Vector3d::Constant(1.0 / m.scale_translation), Eigen::Vector3d::Constant(1.0 / m.scale_rotation);
  for (auto& [id, chain] : P.chains) {
    double* obj = P.obj.at(id).data();
    if (id != P.anchor_id && P.cp->IsParameterBlockConstant(obj)) P.cp->SetParameterBlockVariable(obj);
    const Problem::Det* prev = nullptr;
    for (const std::size_t i : chain) {
      Problem::Det& d = P.dets[i];
      if (d.gross) continue;
      const double rho = prev ? m.rho(to_seconds(d.t_ns - prev->t_ns)) : 0.0;
      if (P.estimate_td) {
        add_time_shifted_factor(d, prev, rho, D, obj, P);
      } else if (rho < 1e-12) {
        d.id = P.cp->AddResidualBlock(new DetectionCost(d.meas, D * d.S), P.loss.get(), P.pose[d.node].data(),
                                      P.extr.data(), obj);
      } else {
        const double c = 1.0 / std::sqrt(1.0 - rho * rho);
        d.id = P.cp->AddResidualBlock(new DetectionCost(d.meas, prev->meas, c * D * d.S, c * rho * D * prev->S),
                                      P.loss.get(), P.pose[d.node].data(), P.extr.data(), obj,
                                      P.pose[prev->node].data());
      }
      prev = &d;
    }
    // An object whose every detection is gross keeps its start (nothing observes it).
    if (!prev && id != P.anchor_id) P.cp->SetParameterBlockConstant(obj);
    if (!prev && id == P.anchor_id) throw DataError(fmt::format("refine: every detection of the anchor {} is gross", id));
  }
}

void add_priors_and_gauge(const RefineInput& in, Problem& P) {
  for (auto& b : P.pose) P.cp->SetManifold(b.data(), P.pose_manifold.get());
  P.cp->AddParameterBlock(P.extr.data(), 7, P.pose_manifold.get());
  if (in.filter.estimate_extrinsics) {
    Vector6d s;
    s << Eigen::Vector3d::Constant(in.filter.extrinsics_sigma_p_m),
        Eigen::Vector3d::Constant(in.filter.extrinsics_sigma_rot_deg * kDeg);
    auto* f = new PosePriorResidual{in.prior_T_I_C.q, in.prior_T_I_C.p, Mat6(s.cwiseInverse().asDiagonal())};
    P.cp->AddResidualBlock(new ceres::AutoDiffCostFunction<PosePriorResidual, 6, 7>(f), nullptr, P.extr.data());
  } else {
    P.cp->SetParameterBlockConstant(P.extr.data());
  }
  for (auto& [id, b] : P.obj) {
    if (id != in.anchor_id) {
      P.cp->AddParameterBlock(b.data(), 7, P.pose_manifold.get());
    } else if (in.filter.anchor_gauge == ekf::AnchorGauge::kPose) {
      P.cp->AddParameterBlock(b.data(), 7);
      P.cp->SetParameterBlockConstant(b.data());
    } else {
      P.cp->AddParameterBlock(b.data(), 7, P.tilt_manifold.get());
    }
  }
  if (P.estimate_td) {  // δ's prior: the declared offset (δ = 0) with the filter's σ
    P.cp->AddParameterBlock(P.td.data(), 1);
    auto* prior = new ceres::AutoDiffCostFunction<ScalarPriorResidual, 1, 1>(
        new ScalarPriorResidual{0.0, 1.0 / in.filter.time_offset_sigma_s});
    P.cp->AddResidualBlock(prior, nullptr, P.td.data());
  }
  Vector6d s;
  s << Eigen::Vector3d::Constant(in.filter.init_sigma_gyro_bias), Eigen::Vector3d::Constant(in.filter.init_sigma_accel_bias);
  Vector6d b0;
  b0 << in.prior_b_g, in.prior_b_a;
  auto* f = new BiasPriorResidual{b0, Mat6(s.cwiseInverse().asDiagonal())};
  P.cp->AddResidualBlock(new ceres::AutoDiffCostFunction<BiasPriorResidual, 6, 6>(f), nullptr, P.bias[0].data());
}

/// The gyro measured at each time (sorted, within the stream): linear between the samples around it.
std::vector<Eigen::Vector3d> gyro_at(const std::vector<ImuSample>& imu, const std::vector<Timestamp>& t) {
  std::vector<Eigen::Vector3d> out;
  std::size_t k = 0;
  for (const Timestamp ti : t) {
    while (k + 2 < imu.size() && imu[k + 1].t_ns <= ti) ++k;
    const ImuSample &a = imu[k], &b = imu[k + 1];
    const double u = std::clamp(static_cast<double>(ti - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns), 0.0, 1.0);
    out.push_back(a.gyro + u * (b.gyro - a.gyro));
  }
  return out;
}

void validate(const RefineInput& in) {
  if (in.imu.size() < 2) throw InputError("refine: fewer than 2 IMU samples");
  if (in.initial.size() < 2) throw InputError("refine: the initial estimate has fewer than 2 states");
  if (in.initial.front().t_ns < in.imu.front().t_ns || in.initial.back().t_ns > in.imu.back().t_ns)
    throw InputError("refine: the initial estimate reaches outside the IMU stream");
  if (in.initial_T_O_W.empty()) throw InputError("refine: no object-world to start from (the run initialised none)");
  if (!in.initial_T_O_W.count(in.anchor_id))
    throw InputError(fmt::format("refine: the anchor object {} has no object-world in the run", in.anchor_id));
  if (in.estimate_time_offset && !(in.filter.time_offset_sigma_s > 0.0))
    throw InputError("refine: the time offset's prior σ (filter.time_offset_sigma_s) must be positive");
}

/// The problem built at the initial estimate.
Problem build(const RefineInput& in, const RefineOptions& opt) {
  Problem P;
  P.t = node_times(in);
  std::size_t k = 0;
  for (const Timestamp t : P.t) {
    const ekf::CoreState x = interpolate_state(in.initial, t, k);
    P.pose.push_back(to_block(Pose(x.q_W_I, x.p_W_I)));
    P.vel.push_back({x.v_W_I.x(), x.v_W_I.y(), x.v_W_I.z()});
    P.bias.push_back({x.b_g.x(), x.b_g.y(), x.b_g.z(), x.b_a.x(), x.b_a.y(), x.b_a.z()});
  }
  P.extr = to_block(in.initial_T_I_C);
  for (const auto& [id, T] : in.initial_T_O_W) P.obj[id] = to_block(T);
  P.estimate_td = in.estimate_time_offset;
  if (P.estimate_td) {
    P.td[0] = in.initial_time_offset_s - in.declared_time_offset_s;
    P.gyro = gyro_at(in.imu, P.t);
  }
  ceres::Problem::Options po;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.enable_fast_removal = true;  // each fit round replaces the detection factors
  P.cp = std::make_unique<ceres::Problem>(po);
  P.anchor_id = in.anchor_id;
  if (opt.loss == Loss::kHuber) P.loss = std::make_unique<ceres::HuberLoss>(opt.loss_scale);
  if (opt.loss == Loss::kCauchy) P.loss = std::make_unique<ceres::CauchyLoss>(opt.loss_scale);
  add_imu_factors(in, opt, P);
  collect_detections(in, P);
  add_priors_and_gauge(in, P);
  return P;
}

/// One Ceres solve; the report accumulates over the solves of the fit rounds (costs: the first's initial,
/// the last's final).
void solve(const RefineOptions& opt, Problem& P, SolveReport& r) {
  ceres::Solver::Options so;
  if (opt.linear_solver == "sparse_normal_cholesky") so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  else if (opt.linear_solver == "sparse_schur") so.linear_solver_type = ceres::SPARSE_SCHUR;
  else throw ConfigError(fmt::format("unknown linear solver '{}' (sparse_normal_cholesky, sparse_schur)", opt.linear_solver),
                         {"", 0, 0, "linear_solver"});
  // Eigen's simplicial Cholesky rather than CHOLMOD's supernodal one: on these banded node chains with a few
  // dense calibration columns the supernodes are tiny, and CHOLMOD's OpenMP and BLAS threads spent more
  // CPU waking each other than factorising (a third of the batch's CPU, much of it system time, on
  // paper-seq4; docs/refine.md §7). Single-threaded, and available in every Ceres build.
  so.sparse_linear_algebra_library_type = ceres::EIGEN_SPARSE;
  if (so.linear_solver_type == ceres::SPARSE_NORMAL_CHOLESKY) {
    // The many node blocks first, the calibration last: the fill-reducing ordering (constrained AMD) then
    // keeps the dense calibration columns out of the chain's elimination (docs/refine.md §7).
    auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
    for (std::size_t i = 0; i < P.t.size(); ++i)
      for (double* b : {P.pose[i].data(), P.vel[i].data(), P.bias[i].data()}) ordering->AddElementToGroup(b, 0);
    ordering->AddElementToGroup(P.extr.data(), 1);
    if (P.estimate_td) ordering->AddElementToGroup(P.td.data(), 1);
    for (auto& [id, b] : P.obj) ordering->AddElementToGroup(b.data(), 1);
    so.linear_solver_ordering = ordering;
  }
  so.max_num_iterations = opt.max_iterations;
  so.num_threads = opt.threads;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  const auto t0 = Clock::now();
  ceres::Solver::Summary sum;
  ceres::Solve(so, P.cp.get(), &sum);
  r.solve_s += std::chrono::duration<double>(Clock::now() - t0).count();
  r.iterations += static_cast<int>(sum.iterations.size()) - 1;
  r.residual_s += sum.residual_evaluation_time_in_seconds;
  r.jacobian_s += sum.jacobian_evaluation_time_in_seconds;
  r.linear_solver_s += sum.linear_solver_time_in_seconds;
  if (r.solves++ == 0) r.initial_cost = sum.initial_cost;
  r.final_cost = sum.final_cost;
  r.termination = ceres::TerminationTypeToString(sum.termination_type) + std::string(": ") + sum.message;
  r.usable = sum.IsSolutionUsable();
  r.nodes = P.t.size();
  r.imu_factors = P.imu_factors;
  r.detection_factors = 0;
  for (const auto& d : P.dets) r.detection_factors += d.id ? 1 : 0;
  r.parameters = static_cast<std::size_t>(sum.num_effective_parameters);
  r.residuals = static_cast<std::size_t>(sum.num_residuals);
  if (!r.usable) throw NumericError("refine: Ceres found no usable solution (" + r.termination + ")");
}

/// A series' whitened residuals w_k = (y_k − μ − ρ_k (y_{k−1} − μ))/√(1 − ρ_k²) (w_1 = y_1 − μ) with the
/// series' constant μ (per component) profiled out: its generalised least-squares estimate, the exact
/// maximum likelihood one under the model. μ is the calibration's error at the estimate the series comes
/// from (an object-world off by a constant): without it a fit at a poor estimate reads that constant as a
/// very slow error (τ and the scales far too large). Returns Σ_k ln(1 − ρ_k²).
double whiten_series(const ErrorSeries& s, const DetectionErrorModel& m, std::vector<Vector6d>& w) {
  const std::size_t n = s.y.size();
  w.resize(n);
  std::vector<double> a(n);  // the whitened regressor of the constant
  double logdet = 0.0, aa = 0.0;
  Vector6d ay = Vector6d::Zero();
  for (std::size_t k = 0; k < n; ++k) {
    const double rho = k == 0 ? 0.0 : m.rho(s.t_s[k] - s.t_s[k - 1]);
    const double c = 1.0 - rho * rho, r = 1.0 / std::sqrt(c);
    w[k] = k == 0 ? s.y[k] : Vector6d((s.y[k] - rho * s.y[k - 1]) * r);
    a[k] = (1.0 - rho) * r;
    logdet += std::log(c);
    aa += a[k] * a[k];
    ay += a[k] * w[k];
  }
  if (aa > 0.0)
    for (std::size_t k = 0; k < n; ++k) w[k] -= a[k] * ay / aa;
  return logdet;
}

/// The profile negative log-likelihood of the series at τ (fit_error_model), with the scales it implies.
double profile_nll(const std::vector<ErrorSeries>& series, double tau, DetectionErrorModel& m) {
  m.tau_s = tau;
  double st = 0.0, sr = 0.0, logdet = 0.0;
  double nt = 0.0, nr = 0.0;  // degrees of freedom: the components less the profiled constants
  std::vector<Vector6d> w;
  for (const auto& s : series) {
    if (s.y.size() < 2) continue;
    logdet += (3 + s.rotation_dof) * whiten_series(s, m, w);
    for (const auto& v : w) {
      st += v.head<3>().squaredNorm();
      sr += v.tail<3>().squaredNorm();
    }
    nt += 3.0 * static_cast<double>(w.size() - 1);
    nr += s.rotation_dof * static_cast<double>(w.size() - 1);
  }
  if (!(nt > 0.0)) return 0.0;
  m.scale_translation = std::sqrt(std::max(st / nt, 1e-300));
  m.scale_rotation = std::sqrt(std::max(sr / nr, 1e-300));
  return 0.5 * (nt * std::log(m.scale_translation * m.scale_translation) +
                nr * std::log(m.scale_rotation * m.scale_rotation) + logdet);
}

/// The lag-1 correlation of the whitened residuals (each block over its scale), pooled.
double whitened_lag1(const std::vector<ErrorSeries>& series, const DetectionErrorModel& m) {
  Vector6d inv;
  inv << Eigen::Vector3d::Constant(1.0 / m.scale_translation), Eigen::Vector3d::Constant(1.0 / m.scale_rotation);
  double num = 0.0, den = 0.0;
  std::vector<Vector6d> w;
  for (const auto& s : series) {
    whiten_series(s, m, w);
    for (std::size_t k = 0; k < w.size(); ++k) {
      if (k > 0) num += w[k].cwiseProduct(inv).dot(w[k - 1].cwiseProduct(inv));
      den += w[k].cwiseProduct(inv).squaredNorm();
    }
  }
  return den > 0.0 ? num / den : 0.0;
}

void floor_scales(DetectionErrorModel& m) {
  m.scale_translation = std::max(m.scale_translation, kMinScale);
  m.scale_rotation = std::max(m.scale_rotation, kMinScale);
}

}  // namespace

std::vector<bool> isolated_outliers(const ErrorSeries& s, const DetectionErrorModel& m, double chi2) {
  const std::size_t n = s.y.size();
  Vector6d inv;
  inv << Eigen::Vector3d::Constant(1.0 / m.scale_translation), Eigen::Vector3d::Constant(1.0 / m.scale_rotation);
  std::vector<double> d2(n, 0.0);
  for (std::size_t k = 0; k < n; ++k) {
    // y_k given its neighbours under the unit-variance AR(1): precision λ, mean μ.
    double lambda = 0.0;
    Vector6d mu = Vector6d::Zero();
    if (k > 0) {
      const double r = m.rho(s.t_s[k] - s.t_s[k - 1]);
      lambda += 1.0 / (1.0 - r * r);
      mu += r / (1.0 - r * r) * s.y[k - 1];
    } else {
      lambda += 1.0;  // the stationary distribution
    }
    if (k + 1 < n) {
      const double r = m.rho(s.t_s[k + 1] - s.t_s[k]);
      lambda += r * r / (1.0 - r * r);
      mu += r / (1.0 - r * r) * s.y[k + 1];
    }
    d2[k] = lambda * (s.y[k] - mu / lambda).cwiseProduct(inv).squaredNorm();
  }
  std::vector<bool> out(n, false);
  for (std::size_t k = 0; k < n; ++k)
    out[k] = d2[k] > chi2 && (k == 0 || d2[k] >= d2[k - 1]) && (k + 1 == n || d2[k] >= d2[k + 1]);
  return out;
}

double DetectionErrorModel::rho(double dt_s) const { return tau_s > 0.0 ? std::exp(-dt_s / tau_s) : 0.0; }

DetectionErrorModel fit_error_model(const std::vector<ErrorSeries>& series, double tau_fixed) {
  DetectionErrorModel m;
  for (const auto& s : series) m.used += s.y.size();
  if (tau_fixed >= 0.0) {
    profile_nll(series, tau_fixed, m);
    floor_scales(m);
    m.whitened_lag1 = whitened_lag1(series, m);
    return m;
  }
  // τ = 0 and a log grid over [0.01, 100] s (4 points per decade), then golden section about the best.
  const auto nll = [&](double tau) {
    DetectionErrorModel t;
    return profile_nll(series, tau, t);
  };
  double best_tau = 0.0, best = nll(0.0);
  for (int i = 0; i <= 24; ++i) {
    const double tau = 0.01 * std::pow(10.0, i / 6.0);
    if (const double v = nll(tau); v < best) best = v, best_tau = tau;
  }
  if (best_tau > 0.0) {
    const double g = 0.5 * (std::sqrt(5.0) - 1.0);
    double a = std::log(best_tau) - std::log(10.0) / 6.0, b = std::log(best_tau) + std::log(10.0) / 6.0;
    for (int it = 0; it < 30; ++it) {
      const double c = b - g * (b - a), d = a + g * (b - a);
      if (nll(std::exp(c)) < nll(std::exp(d))) b = d;
      else a = c;
    }
    if (const double tau = std::min(std::exp(0.5 * (a + b)), 100.0); nll(tau) < best) best_tau = tau;
  }
  profile_nll(series, best_tau, m);
  m.fitted_tau = true;
  floor_scales(m);
  m.whitened_lag1 = whitened_lag1(series, m);
  return m;
}

namespace {

/// The anchor's tangent (2: δθ_x, δθ_y) as rows of the 6-dof error [δp_O_W; δθ_O_W].
Eigen::Matrix<double, 6, 2> anchor_embedding() {
  Eigen::Matrix<double, 6, 2> E = Eigen::Matrix<double, 6, 2>::Zero();
  E(3, 0) = E(4, 1) = 1.0;
  return E;
}

/// Marginal covariances of the extrinsics and the object-worlds at the solution: the Schur complement onto
/// the calibration blocks, the nodes eliminated (marginals.hpp; the robust loss applied as in the solve).
/// False when the information is singular.
bool marginals(const RefineInput& in, const RefineOptions& opt, Problem& P, RefineResult& out) {
  std::vector<double*> nodes, calib;
  for (std::size_t i = 0; i < P.t.size(); ++i)
    for (double* b : {P.pose[i].data(), P.vel[i].data(), P.bias[i].data()}) nodes.push_back(b);
  const double* extr = P.extr.data();
  const bool extr_free = !P.cp->IsParameterBlockConstant(const_cast<double*>(extr));
  const auto a_it = P.obj.find(in.anchor_id);
  const double* anchor = a_it->second.data();
  const bool anchor_free = !P.cp->IsParameterBlockConstant(const_cast<double*>(anchor));
  calib.push_back(P.extr.data());
  for (auto& [id, b] : P.obj) calib.push_back(b.data());
  if (P.estimate_td) calib.push_back(P.td.data());
  const auto cov = marginal_covariance(*P.cp, nodes, calib, opt.threads);
  if (!cov) return false;
  if (P.estimate_td) out.sigma_time_offset_s = std::sqrt(std::max(cov->block(P.td.data(), P.td.data())(0, 0), 0.0));
  if (extr_free) out.cov_T_I_C = cov->block(extr, extr);
  const Eigen::Matrix<double, 6, 2> E = anchor_embedding();
  const Mat6 C_AA = anchor_free ? Mat6(E * cov->block(anchor, anchor) * E.transpose()) : Mat6::Zero();
  out.objects[in.anchor_id].cov = C_AA;
  for (const auto& [id, b] : P.obj) {
    if (id == in.anchor_id) continue;
    const Mat6 C_OO = cov->block(b.data(), b.data());
    const Mat6 C_AO = anchor_free ? Mat6(E * cov->block(anchor, b.data())) : Mat6::Zero();
    Eigen::Matrix<double, 12, 12> C;
    C << C_AA, C_AO, C_AO.transpose(), C_OO;
    RefinedObject& o = out.objects[id];
    o.cov = C_OO;
    const Eigen::Matrix<double, 6, 12> J = ekf::relative_pose_jacobian(out.objects[in.anchor_id].T_O_W, o.T_O_W);
    o.cov_relative = J * C * J.transpose();
  }
  return true;
}

/// The solution read back from the parameter blocks, and each detection's fit.
void collect(const RefineInput& in, Problem& P, RefineResult& out) {
  const DetectionErrorModel& m = out.report.error_model;
  for (std::size_t i = 0; i < P.t.size(); ++i) {
    StateSample s;
    s.t_ns = P.t[i];
    const Pose T = to_pose(P.pose[i]);
    s.x.p_W_I = T.p;
    s.x.q_W_I = T.q;
    s.x.v_W_I = Eigen::Vector3d(P.vel[i][0], P.vel[i][1], P.vel[i][2]);
    s.x.b_g = Eigen::Vector3d(P.bias[i][0], P.bias[i][1], P.bias[i][2]);
    s.x.b_a = Eigen::Vector3d(P.bias[i][3], P.bias[i][4], P.bias[i][5]);
    out.nodes.push_back(s);
  }
  out.T_I_C = to_pose(P.extr);
  out.extrinsics_estimated = in.filter.estimate_extrinsics;
  out.time_offset_estimated = P.estimate_td;
  out.time_offset_s = in.declared_time_offset_s + (P.estimate_td ? P.td[0] : 0.0);
  for (const auto& [id, b] : P.obj) {
    RefinedObject& o = out.objects[id];
    o.T_O_W = to_pose(b);
    o.anchor = id == in.anchor_id;
  }
  for (const auto& d : P.dets) {
    DetectionFit f;
    f.t_ns = d.t_ns;
    f.object_id = d.object_id;
    if (!d.id) {  // dropped as gross: its standardised error under the fitted scales
      f.chi2 = standardised_chi2(d, m);
      f.weight = 0.0;
      out.detections.push_back(f);
      continue;
    }
    double cost = 0.0;
    std::array<double, 6> r{};
    P.cp->EvaluateResidualBlock(d.id, false, &cost, r.data(), nullptr);
    f.chi2 = 2.0 * cost;
    if (P.loss) {
      double rho[3];
      P.loss->Evaluate(f.chi2, rho);
      f.weight = rho[1];
    }
    out.detections.push_back(f);
  }
}

}  // namespace

RefineResult refine(const RefineInput& in, const RefineOptions& opt) {
  validate(in);
  if (opt.fit_rounds < 1) throw ConfigError("refine: fit_rounds must be at least 1", {"", 0, 0, "fit_rounds"});
  Problem P = build(in, opt);
  RefineResult out;
  for (int round = 0; round < opt.fit_rounds; ++round) {
    out.report.error_model = fit_round(opt, P);
    install_detection_factors(out.report.error_model, P);
    solve(opt, P, out.report);
  }
  // The gross flags and standardised errors at the solution (for the report), the factors unchanged.
  update_standardisation(P);
  collect(in, P, out);
  if (opt.covariance) {
    const auto t0 = Clock::now();
    out.report.covariance_ok = marginals(in, opt, P, out);
    out.report.covariance_s = std::chrono::duration<double>(Clock::now() - t0).count();
  }
  return out;
}

std::vector<StateSample> states_at(const RefineResult& r, const std::vector<ImuSample>& imu,
                                   const std::vector<Timestamp>& times) {
  std::vector<StateSample> out;
  out.reserve(times.size());
  if (r.nodes.empty()) return out;
  std::size_t n = 0, hint = 0;
  StateSample cur = r.nodes.front();
  for (const Timestamp t : times) {
    if (t < r.nodes.front().t_ns || t > r.nodes.back().t_ns)
      throw InputError(fmt::format("refine: time {} ns outside the refined span", t));
    while (n + 1 < r.nodes.size() && r.nodes[n + 1].t_ns <= t) ++n;
    if (cur.t_ns < r.nodes[n].t_ns || cur.t_ns > t) cur = r.nodes[n];
    cur.x = propagate(imu, cur.x, cur.t_ns, t, hint);
    cur.t_ns = t;
    out.push_back(cur);
  }
  return out;
}

}  // namespace roe::refine
