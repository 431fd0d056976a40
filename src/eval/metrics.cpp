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
  return compute_ape(
      est.size(), [&](std::size_t i) { return std::pair<Pose, Pose>(est[i], gt[i]); }, cov, threads);
}

ApeResult compute_ape(std::size_t n, const PosePairAt& pair, const std::vector<PoseCovariance>& cov,
                      unsigned threads) {
  if (!cov.empty() && cov.size() != n) {
    throw InputError(fmt::format("APE: {} covariances for {} pairs", cov.size(), n));
  }
  ApeResult r;
  if (!cov.empty()) r.nees.resize(n);
  std::vector<double> tn(n), an(n);
  // Each pair's errors on its own (in parallel); the sums take the pairs in order, whichever thread
  // computed them, so the result does not depend on the thread count. Only the norms stay (for the
  // medians): a pair's errors are recomputed where they are written (Report::error).
  using Parts = std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>>;  // dp, rpy_deg
  Eigen::Vector3d sum_dp = Eigen::Vector3d::Zero(), sq_dp = Eigen::Vector3d::Zero(),
                  sq_rpy = Eigen::Vector3d::Zero();
  parallel_ranges_ordered(
      n, kPairsPerTask, threads ? threads : available_cpus(),
      [&](std::size_t b, std::size_t e) {
        Parts parts(e - b);
        for (std::size_t i = b; i < e; ++i) {
          const auto [est, gt] = pair(i);
          const PoseError pe = pose_error(est, gt);
          tn[i] = pe.dp.norm();
          an[i] = pe.angle_deg;
          parts[i - b] = {pe.dp, pe.rpy_deg};
          if (!cov.empty()) r.nees[i] = pose_nees(est, gt, cov[i]);
        }
        return parts;
      },
      [&](Parts&& parts) {
        for (const auto& [dp, rpy] : parts) {
          sum_dp += dp;
          sq_dp += dp.cwiseAbs2();
          sq_rpy += rpy.cwiseAbs2();
        }
      });
  if (n > 0) {
    const double N = static_cast<double>(n);
    r.pos_mean_m = sum_dp / N;
    r.pos_rmse_m = (sq_dp / N).cwiseSqrt();
    r.rpy_rmse_deg = (sq_rpy / N).cwiseSqrt();
  }
  parallel_for(2, threads ? threads : available_cpus(), [&](std::size_t k) {  // two independent statistics
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
