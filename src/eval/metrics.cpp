#include "roe/eval/metrics.hpp"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>

#include "roe/core/error.hpp"
#include "roe/core/parallel.hpp"
#include "roe/math/euler.hpp"

namespace roe::eval {

namespace {
/// Pairs per parallel task: large enough that handing out a task costs nothing, small enough to balance.
constexpr std::size_t kPairsPerTask = 16384;
}  // namespace

Stats compute_stats(std::vector<double> v) {
  Stats s;
  s.n = v.size();
  if (v.empty()) return s;
  const double n = static_cast<double>(v.size());
  double sum = 0.0, sse = 0.0;
  s.min = v.front();
  s.max = v.front();
  for (double x : v) {
    sum += x;
    sse += x * x;
    s.min = std::min(s.min, x);
    s.max = std::max(s.max, x);
  }
  s.mean = sum / n;
  s.sse = sse;
  s.rmse = std::sqrt(sse / n);
  double var = 0.0;
  for (double x : v) var += (x - s.mean) * (x - s.mean);
  s.std = std::sqrt(var / n);  // population std (numpy ddof = 0), as evo
  // Median: the middle element, or the mean of the two middle elements (numpy.median).
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  const double upper = v[mid];
  if (v.size() % 2 == 1) {
    s.median = upper;
  } else {
    const double lower = *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid));
    s.median = 0.5 * (lower + upper);
  }
  return s;
}

Eigen::Vector3d rmse_per_axis(const std::vector<PoseError>& errors, Eigen::Vector3d PoseError::*part) {
  if (errors.empty()) return Eigen::Vector3d::Zero();
  Eigen::Vector3d acc = Eigen::Vector3d::Zero();
  for (const PoseError& e : errors) acc += (e.*part).cwiseAbs2();
  return (acc / static_cast<double>(errors.size())).cwiseSqrt();
}

PoseError pose_error(const Pose& est, const Pose& gt) {
  PoseError e;
  e.dp = est.p - gt.p;
  e.q_err = math::canonical((est.q.conjugate() * gt.q).normalized());
  e.angle_deg = math::log_quat(e.q_err).norm() * math::kDegPerRad;
  const Eigen::Vector3d rpy = math::euler_zyx(e.q_err.toRotationMatrix());
  for (int k = 0; k < 3; ++k) e.rpy_deg(k) = math::wrap_180(rpy(k) * math::kDegPerRad);
  return e;
}

namespace {
double mahalanobis(const Eigen::Vector3d& e, const Eigen::Matrix3d& P) {
  Eigen::LLT<Eigen::Matrix3d> llt(0.5 * (P + P.transpose()));
  if (llt.info() != Eigen::Success || !P.allFinite()) return std::numeric_limits<double>::quiet_NaN();
  return e.dot(llt.solve(e));
}
}  // namespace

Nees pose_nees(const Pose& est, const Pose& gt, const PoseCovariance& cov) {
  Nees n;
  n.pos = mahalanobis(gt.p - est.p, cov.P_p);
  // Local error: R_gt = R_est · Exp(δθ)  ⇒  δθ = Log(R_estᵀ R_gt).
  n.rot = mahalanobis(math::log_quat(est.q.conjugate() * gt.q), cov.P_theta);
  return n;
}

PoseCovariance align_covariance(const PoseCovariance& c, const Eigen::Matrix3d& R, double s) {
  PoseCovariance out;
  out.P_p = s * s * R * c.P_p * R.transpose();
  out.P_theta = c.P_theta;
  return out;
}

ApeResult compute_ape(const std::vector<Pose>& est, const std::vector<Pose>& gt,
                      const std::vector<PoseCovariance>& cov, unsigned threads) {
  if (est.size() != gt.size()) {
    throw InputError(
        fmt::format("APE needs matched pairs: {} estimate vs {} ground-truth poses", est.size(), gt.size()));
  }
  if (!cov.empty() && cov.size() != est.size()) {
    throw InputError(fmt::format("APE: {} covariances for {} pairs", cov.size(), est.size()));
  }
  if (threads == 0) threads = available_cpus();
  ApeResult r;
  const std::size_t n = est.size();
  r.errors.resize(n);
  if (!cov.empty()) r.nees.resize(n);
  std::vector<double> tn(n), an(n);
  // Each pair's errors on its own (in parallel, into its own slot); every sum below runs in pair order
  // on this thread, so the result does not depend on the thread count.
  parallel_ranges(n, kPairsPerTask, threads, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      r.errors[i] = pose_error(est[i], gt[i]);
      tn[i] = r.errors[i].dp.norm();
      an[i] = r.errors[i].angle_deg;
      if (!cov.empty()) r.nees[i] = pose_nees(est[i], gt[i], cov[i]);
    }
  });
  for (const PoseError& e : r.errors) r.pos_mean_m += e.dp;
  if (n > 0) r.pos_mean_m /= static_cast<double>(n);
  r.pos_rmse_m = rmse_per_axis(r.errors, &PoseError::dp);
  r.rpy_rmse_deg = rmse_per_axis(r.errors, &PoseError::rpy_deg);
  parallel_for(2, threads, [&](std::size_t k) {  // the two statistics are independent
    if (k == 0) r.trans_m = compute_stats(std::move(tn));
    else r.rot_deg = compute_stats(std::move(an));
  });
  r.armse_p_m = r.trans_m.mean;
  r.armse_r_deg = r.rot_deg.mean;
  if (!cov.empty()) {
    double sp = 0.0, sr = 0.0;
    std::size_t np = 0, nr = 0;
    for (const Nees& e : r.nees) {
      if (std::isfinite(e.pos)) sp += e.pos, ++np;
      if (std::isfinite(e.rot)) sr += e.rot, ++nr;
    }
    if (np > 0) r.anees_p = sp / static_cast<double>(np);
    if (nr > 0) r.anees_r = sr / static_cast<double>(nr);
  }
  return r;
}

}  // namespace roe::eval
