// The batch refinement: problem assembly, solve and marginal covariances with Ceres (docs/refine.md).
#include "roe/refine/refine.hpp"

#include <ceres/autodiff_cost_function.h>
#include <ceres/autodiff_manifold.h>
#include <ceres/covariance.h>
#include <ceres/loss_function.h>
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
  std::unique_ptr<ceres::Manifold> pose_manifold = std::make_unique<ceres::AutoDiffManifold<PosePlus, 7, 6>>();
  std::unique_ptr<ceres::Manifold> tilt_manifold = std::make_unique<ceres::AutoDiffManifold<AnchorTiltPlus, 7, 2>>();
  std::unique_ptr<ceres::LossFunction> loss;
  std::unique_ptr<ceres::Problem> cp;
  struct Det {
    ceres::ResidualBlockId id = nullptr;
    Timestamp t_ns = 0;
    int object_id = 0;
    std::size_t node = 0;
    DetectionResidual f;
  };
  std::vector<Det> dets;
  std::vector<std::unique_ptr<ceres::LossFunction>> scaled_losses;  ///< scale_detection_information
  std::size_t imu_factors = 0;
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

void add_imu_factors(const RefineInput& in, Problem& P) {
  std::size_t hint = 0;
  const double rg = in.noise.gyro_random_walk, ra = in.noise.accel_random_walk;
  for (std::size_t i = 0; i + 1 < P.t.size(); ++i) {
    const Eigen::Map<const Eigen::Vector3d> bg(P.bias[i].data()), ba(P.bias[i].data() + 3);
    const Preintegration pre = preintegrate(in.imu, P.t[i], P.t[i + 1], bg, ba, in.noise, hint);
    Mat9 cov = pre.cov;
    cov.diagonal().array() += kVarFloor;
    auto* f = new ImuResidual{pre.dR, pre.dv, pre.dp, pre.bg_lin, pre.ba_lin, ekf::kGravity_W, pre.dt, pre.J_bias,
                              sqrt_information(cov)};
    P.cp->AddResidualBlock(new ceres::AutoDiffCostFunction<ImuResidual, 9, 7, 3, 6, 7, 3>(f), nullptr, P.pose[i].data(),
                           P.vel[i].data(), P.bias[i].data(), P.pose[i + 1].data(), P.vel[i + 1].data());
    Vector6d inv_sigma;
    inv_sigma << Eigen::Vector3d::Constant(1.0 / std::sqrt(rg * rg * pre.dt + kVarFloor)),
        Eigen::Vector3d::Constant(1.0 / std::sqrt(ra * ra * pre.dt + kVarFloor));
    P.cp->AddResidualBlock(new ceres::AutoDiffCostFunction<BiasWalkResidual, 6, 6, 6>(new BiasWalkResidual{inv_sigma}),
                           nullptr, P.bias[i].data(), P.bias[i + 1].data());
    ++P.imu_factors;
  }
}

/// The residual of one detection: the measurement in the residual frame (a symmetric object's nearest
/// equivalent of the initial prediction) and its square root information (a continuous symmetry's
/// reduction folded in, the last row zero).
DetectionResidual detection_residual(const RefineInput& in, const ekf::Filter& sigma_model, const Detection& d,
                                     const ekf::CoreState& x, const Pose& T_I_C, const Pose& T_O_W) {
  const bool camera = in.filter.residual_frame == ekf::ResidualFrame::kCamera;
  Mat6 R = sigma_model.measurement_covariance(d, false);
  if (in.filter.use_detection_sigmas && d.sigma) R *= in.detection_sigma_scale * in.detection_sigma_scale;
  Pose z = d.T_C_O.inverse();
  DetectionResidual res;
  res.camera_frame = camera;
  res.W = sqrt_information(R);
  if (const auto s = in.symmetries.find(d.object_id); s != in.symmetries.end() && !s->second.empty()) {
    const Pose z_hat = ekf::predict_object(x, T_I_C, T_O_W).T_O_C_hat;
    z = ekf::nearest_equivalent(z_hat, z, s->second);
    if (s->second.continuous) {
      bool separable = true;
      const ekf::Mat56 A = ekf::symmetry_reduction(
          ekf::symmetry_direction(in.filter.residual_frame, z_hat, *s->second.continuous), separable);
      const Eigen::MatrixXd W5 = sqrt_information(A * R * A.transpose()) * A;
      res.W.setZero();
      res.W.topRows<5>() = W5;
    }
  }
  const Pose m = camera ? z.inverse() : z;
  res.q_meas = m.q;
  res.p_meas = m.p;
  return res;
}

void add_detection_factors(const RefineInput& in, const RefineOptions& opt, Problem& P) {
  const ekf::Filter sigma_model(in.filter, in.noise, in.prior_T_I_C);  // the filter's σ model, one definition
  if (opt.loss == Loss::kHuber) P.loss = std::make_unique<ceres::HuberLoss>(opt.loss_scale);
  if (opt.loss == Loss::kCauchy) P.loss = std::make_unique<ceres::CauchyLoss>(opt.loss_scale);
  std::size_t n = 0;
  for (const auto& im : in.images) {
    const auto it = std::lower_bound(P.t.begin(), P.t.end(), im.t_ns);
    if (it == P.t.end() || *it != im.t_ns) continue;
    const std::size_t k = static_cast<std::size_t>(it - P.t.begin());
    ekf::CoreState x;
    x.p_W_I = Eigen::Vector3d(P.pose[k][0], P.pose[k][1], P.pose[k][2]);
    x.q_W_I = to_pose(P.pose[k]).q;
    for (const Detection& d : im.detections) {
      const auto o = P.obj.find(d.object_id);
      if (o == P.obj.end()) continue;
      auto* f = new DetectionResidual(detection_residual(in, sigma_model, d, x, to_pose(P.extr), to_pose(o->second)));
      const auto id = P.cp->AddResidualBlock(new ceres::AutoDiffCostFunction<DetectionResidual, 6, 7, 7, 7>(f),
                                                P.loss.get(), P.pose[k].data(), P.extr.data(), o->second.data());
      P.dets.push_back({id, im.t_ns, d.object_id, k, *f});
      ++n;
    }
  }
  if (n == 0) throw DataError("refine: no detection of an object with an object-world: nothing to refine");
  // An object-world without a used detection is not in the problem (nothing observes it).
  for (auto it = P.obj.begin(); it != P.obj.end();)
    it = P.cp->HasParameterBlock(it->second.data()) ? std::next(it) : P.obj.erase(it);
  if (!P.obj.count(in.anchor_id))
    throw DataError(fmt::format("refine: no used detection of the anchor object {}", in.anchor_id));
}

void add_priors_and_gauge(const RefineInput& in, Problem& P) {
  for (auto& b : P.pose) P.cp->SetManifold(b.data(), P.pose_manifold.get());
  P.cp->SetManifold(P.extr.data(), P.pose_manifold.get());
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
      P.cp->SetManifold(b.data(), P.pose_manifold.get());
    } else if (in.filter.anchor_gauge == ekf::AnchorGauge::kPose) {
      P.cp->SetParameterBlockConstant(b.data());
    } else {
      P.cp->SetManifold(b.data(), P.tilt_manifold.get());
    }
  }
  Vector6d s;
  s << Eigen::Vector3d::Constant(in.filter.init_sigma_gyro_bias), Eigen::Vector3d::Constant(in.filter.init_sigma_accel_bias);
  Vector6d b0;
  b0 << in.prior_b_g, in.prior_b_a;
  auto* f = new BiasPriorResidual{b0, Mat6(s.cwiseInverse().asDiagonal())};
  P.cp->AddResidualBlock(new ceres::AutoDiffCostFunction<BiasPriorResidual, 6, 6>(f), nullptr, P.bias[0].data());
}

void validate(const RefineInput& in) {
  if (in.imu.size() < 2) throw InputError("refine: fewer than 2 IMU samples");
  if (in.initial.size() < 2) throw InputError("refine: the initial estimate has fewer than 2 states");
  if (in.initial.front().t_ns < in.imu.front().t_ns || in.initial.back().t_ns > in.imu.back().t_ns)
    throw InputError("refine: the initial estimate reaches outside the IMU stream");
  if (in.initial_T_O_W.empty()) throw InputError("refine: no object-world to start from (the run initialised none)");
  if (!in.initial_T_O_W.count(in.anchor_id))
    throw InputError(fmt::format("refine: the anchor object {} has no object-world in the run", in.anchor_id));
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
  ceres::Problem::Options po;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.enable_fast_removal = true;  // scale_detection_information replaces the detection factors
  P.cp = std::make_unique<ceres::Problem>(po);
  add_imu_factors(in, P);
  add_detection_factors(in, opt, P);
  add_priors_and_gauge(in, P);
  return P;
}

SolveReport solve(const RefineOptions& opt, Problem& P) {
  ceres::Solver::Options so;
  if (opt.linear_solver == "sparse_normal_cholesky") so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  else if (opt.linear_solver == "sparse_schur") so.linear_solver_type = ceres::SPARSE_SCHUR;
  else throw ConfigError(fmt::format("unknown linear solver '{}' (sparse_normal_cholesky, sparse_schur)", opt.linear_solver),
                         {"", 0, 0, "linear_solver"});
  so.max_num_iterations = opt.max_iterations;
  so.num_threads = opt.threads;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  const auto t0 = Clock::now();
  ceres::Solver::Summary sum;
  ceres::Solve(so, P.cp.get(), &sum);
  SolveReport r;
  r.solve_s = std::chrono::duration<double>(Clock::now() - t0).count();
  r.iterations = static_cast<int>(sum.iterations.size()) - 1;
  r.residual_s = sum.residual_evaluation_time_in_seconds;
  r.jacobian_s = sum.jacobian_evaluation_time_in_seconds;
  r.linear_solver_s = sum.linear_solver_time_in_seconds;
  r.initial_cost = sum.initial_cost;
  r.final_cost = sum.final_cost;
  r.termination = ceres::TerminationTypeToString(sum.termination_type) + std::string(": ") + sum.message;
  r.usable = sum.IsSolutionUsable();
  r.nodes = P.t.size();
  r.imu_factors = P.imu_factors;
  r.detection_factors = P.dets.size();
  r.parameters = static_cast<std::size_t>(sum.num_effective_parameters);
  r.residuals = static_cast<std::size_t>(sum.num_residuals);
  if (!r.usable) throw NumericError("refine: Ceres found no usable solution (" + r.termination + ")");
  return r;
}

/// The inliers' whitened residuals u = W e per object at the current estimate (the white factors): the
/// data of fit_error_model. A detection whose ‖u‖² exceeds the loss scale² (weight below ½ under Cauchy)
/// is left out: outliers and flips are not the slowly varying error.
std::vector<ResidualSeries> residual_series(const RefineOptions& opt, Problem& P) {
  std::map<int, ResidualSeries> by_object;
  for (const auto& d : P.dets) {
    Vector6d u;
    P.cp->EvaluateResidualBlock(d.id, false, nullptr, u.data(), nullptr);
    if (u.squaredNorm() > opt.loss_scale * opt.loss_scale) continue;
    ResidualSeries& s = by_object[d.object_id];
    s.t_s.push_back(to_seconds(d.t_ns));
    s.u.push_back(u);
  }
  std::vector<ResidualSeries> out;
  for (auto& [id, s] : by_object) out.push_back(std::move(s));
  return out;
}

/// Divides each detection's information by the error model's variance factor for the marginals: the
/// factor is re-added with its loss scaled by 1/k (ceres::ScaledLoss), k = variance_factor(Δt since the
/// object's previous detection). The solution is not changed (called after collect()).
void scale_detection_information(const DetectionErrorModel& m, Problem& P) {
  std::map<int, Timestamp> previous;
  for (auto& d : P.dets) {
    const auto prev = previous.find(d.object_id);
    const double k = m.variance_factor(prev == previous.end() ? -1.0 : to_seconds(d.t_ns - prev->second));
    previous[d.object_id] = d.t_ns;
    P.cp->RemoveResidualBlock(d.id);
    P.scaled_losses.push_back(std::make_unique<ceres::ScaledLoss>(P.loss.get(), 1.0 / k, ceres::DO_NOT_TAKE_OWNERSHIP));
    d.id = P.cp->AddResidualBlock(new ceres::AutoDiffCostFunction<DetectionResidual, 6, 7, 7, 7>(new DetectionResidual(d.f)),
                                  P.scaled_losses.back().get(), P.pose[d.node].data(), P.extr.data(),
                                  P.obj.at(d.object_id).data());
  }
}

}  // namespace

DetectionErrorModel fit_error_model(const std::vector<ResidualSeries>& series) {
  // Lag bins (s): [0, 0.1) holds the neighbouring images; C(0) separately.
  static constexpr std::array<double, 7> kEdges = {0.0, 0.1, 0.3, 0.6, 1.2, 2.4, 4.8};
  constexpr std::size_t kBins = kEdges.size() - 1;
  std::array<double, kBins> sum{}, lag{};
  std::array<std::size_t, kBins> pairs{};
  double sum0 = 0.0;
  std::size_t n0 = 0;
  for (const auto& s : series) {
    for (std::size_t i = 0; i < s.u.size(); ++i) {
      sum0 += s.u[i].squaredNorm();
      ++n0;
      for (std::size_t j = i + 1; j < s.u.size(); ++j) {
        const double l = s.t_s[j] - s.t_s[i];
        if (l >= kEdges.back()) break;
        const auto b = static_cast<std::size_t>(std::upper_bound(kEdges.begin(), kEdges.end(), l) - kEdges.begin()) - 1;
        sum[b] += s.u[i].dot(s.u[j]);
        lag[b] += l;
        ++pairs[b];
      }
    }
  }
  DetectionErrorModel m;
  if (n0 == 0) return m;
  const double c0 = sum0 / (6.0 * static_cast<double>(n0));
  m.autocovariance.push_back({0.0, c0, n0});
  for (std::size_t b = 0; b < kBins; ++b)
    if (pairs[b] > 0)
      m.autocovariance.push_back({lag[b] / static_cast<double>(pairs[b]), sum[b] / (6.0 * static_cast<double>(pairs[b])), pairs[b]});
  m.sigma_white = std::sqrt(c0);
  const double c_mid = pairs[2] > 0 ? sum[2] / (6.0 * static_cast<double>(pairs[2])) : 0.0;  // C(0.3–0.6 s)
  if (!(c0 > 0.0) || c_mid <= 0.1 * c0) return m;  // white
  // Weighted least squares of ln C = a − lag/τ over the bins from 0.1 s with C > 0.02 C(0).
  double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (const auto& b : m.autocovariance) {
    if (b.lag_s < kEdges[1] || b.cov <= 0.02 * c0) continue;
    const double w = static_cast<double>(b.pairs), y = std::log(b.cov);
    sw += w, sx += w * b.lag_s, sy += w * y, sxx += w * b.lag_s * b.lag_s, sxy += w * b.lag_s * y;
  }
  const double det = sw * sxx - sx * sx;
  const double slope = det > 0.0 ? (sw * sxy - sx * sy) / det : 0.0;
  m.tau_s = slope < 0.0 ? std::clamp(-1.0 / slope, 0.1, 60.0) : 60.0;
  const double a = det > 0.0 ? (sy - slope * sx) / sw : std::log(c_mid);
  const double sb2 = std::min(std::exp(a), 0.98 * c0);
  m.correlated = true;
  m.sigma_bias = std::sqrt(sb2);
  m.sigma_white = std::sqrt(std::max(c0 - sb2, 0.02 * c0));
  return m;
}

double DetectionErrorModel::variance_factor(double dt_s) const {
  const double w = sigma_white * sigma_white, b = sigma_bias * sigma_bias;
  if (!correlated || dt_s < 0.0) return w + b;
  const double phi = std::exp(-dt_s / tau_s);
  return w + b * (1.0 + phi) / std::max(1.0 - phi, 1e-9);
}

namespace {

using RowMat6 = Eigen::Matrix<double, 6, 6, Eigen::RowMajor>;

/// The anchor's tangent (2: δθ_x, δθ_y) as rows of the 6-dof error [δp_O_W; δθ_O_W].
Eigen::Matrix<double, 6, 2> anchor_embedding() {
  Eigen::Matrix<double, 6, 2> E = Eigen::Matrix<double, 6, 2>::Zero();
  E(3, 0) = E(4, 1) = 1.0;
  return E;
}

/// Marginal covariances of the extrinsics and the object-worlds at the solution (ceres::Covariance, with
/// the robust loss applied as in the solve). False when Ceres cannot compute them (rank deficiency).
bool marginals(const RefineInput& in, const RefineOptions& opt, Problem& P, RefineResult& out) {
  ceres::Covariance::Options co;
  co.num_threads = opt.threads;
  ceres::Covariance cov(co);
  const double* extr = P.extr.data();
  const bool extr_free = !P.cp->IsParameterBlockConstant(const_cast<double*>(extr));
  const auto a_it = P.obj.find(in.anchor_id);
  const double* anchor = a_it->second.data();
  const bool anchor_free = !P.cp->IsParameterBlockConstant(const_cast<double*>(anchor));
  std::vector<std::pair<const double*, const double*>> blocks;
  if (extr_free) blocks.emplace_back(extr, extr);
  if (anchor_free) blocks.emplace_back(anchor, anchor);
  for (const auto& [id, b] : P.obj) {
    if (id == in.anchor_id) continue;
    blocks.emplace_back(b.data(), b.data());
    if (anchor_free) blocks.emplace_back(anchor, b.data());
  }
  if (!cov.Compute(blocks, P.cp.get())) return false;
  if (extr_free) {
    RowMat6 C;
    cov.GetCovarianceBlockInTangentSpace(extr, extr, C.data());
    out.cov_T_I_C = C;
  }
  const Eigen::Matrix<double, 6, 2> E = anchor_embedding();
  Mat6 C_AA = Mat6::Zero();
  if (anchor_free) {
    Eigen::Matrix<double, 2, 2, Eigen::RowMajor> c;
    cov.GetCovarianceBlockInTangentSpace(anchor, anchor, c.data());
    C_AA = E * c * E.transpose();
  }
  out.objects[in.anchor_id].cov = C_AA;
  for (const auto& [id, b] : P.obj) {
    if (id == in.anchor_id) continue;
    RowMat6 C_OO;
    cov.GetCovarianceBlockInTangentSpace(b.data(), b.data(), C_OO.data());
    Mat6 C_AO = Mat6::Zero();
    if (anchor_free) {
      Eigen::Matrix<double, 2, 6, Eigen::RowMajor> c;
      cov.GetCovarianceBlockInTangentSpace(anchor, b.data(), c.data());
      C_AO = E * c;
    }
    Eigen::Matrix<double, 12, 12> C;
    C << C_AA, C_AO, C_AO.transpose(), Mat6(C_OO);
    RefinedObject& o = out.objects[id];
    o.cov = C_OO;
    const Eigen::Matrix<double, 6, 12> J = ekf::relative_pose_jacobian(out.objects[in.anchor_id].T_O_W, o.T_O_W);
    o.cov_relative = J * C * J.transpose();
  }
  return true;
}

/// The solution read back from the parameter blocks, and each detection's fit.
void collect(const RefineInput& in, Problem& P, RefineResult& out) {
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
  for (const auto& [id, b] : P.obj) {
    RefinedObject& o = out.objects[id];
    o.T_O_W = to_pose(b);
    o.anchor = id == in.anchor_id;
  }
  for (const auto& d : P.dets) {
    double cost = 0.0;
    std::array<double, 6> r{};
    P.cp->EvaluateResidualBlock(d.id, false, &cost, r.data(), nullptr);
    DetectionFit f;
    f.t_ns = d.t_ns;
    f.object_id = d.object_id;
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
  Problem P = build(in, opt);
  RefineResult out;
  out.report = solve(opt, P);
  collect(in, P, out);
  if (opt.correlated_errors) out.report.error_model = fit_error_model(residual_series(opt, P));
  if (opt.covariance) {
    const auto t0 = Clock::now();
    if (out.report.error_model.correlated) scale_detection_information(out.report.error_model, P);
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
