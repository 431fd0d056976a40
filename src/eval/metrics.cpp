#include "roe/eval/metrics.hpp"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

#include "roe/core/error.hpp"
#include "roe/core/parallel.hpp"
#include "roe/math/euler.hpp"

namespace roe::eval {

std::string to_string(EulerMetric m) {
  switch (m) {
    case EulerMetric::kAbsolute: return "absolute";
    case EulerMetric::kAbsoluteUnwrapped: return "absolute-unwrapped";
    case EulerMetric::kError: break;
  }
  return "error";
}

EulerMetric parse_euler_metric(const std::string& name) {
  for (EulerMetric m : {EulerMetric::kError, EulerMetric::kAbsolute, EulerMetric::kAbsoluteUnwrapped})
    if (name == to_string(m)) return m;
  throw InputError(
      fmt::format("unknown Euler metric '{}' (expected error, absolute or absolute-unwrapped)", name),
      {"", 0, 0, "euler"});
}

std::string euler_metric_definition(EulerMetric m) {
  switch (m) {
    case EulerMetric::kAbsolute:
      return "wrap(Euler(R_est) - Euler(R_gt)) to [-180,180): difference of the absolute ZYX angles after "
             "alignment (ov_eval); not a rotation error";
    case EulerMetric::kAbsoluteUnwrapped:
      return "Euler(R_est) - Euler(R_gt), not wrapped (-360,360): difference of the absolute ZYX angles after "
             "alignment, with 360 deg jumps where one angle crosses +-180; not a rotation error";
    case EulerMetric::kError: break;
  }
  return "Euler(R_est^T*R_gt) wrapped to [-180,180): ZYX angles of the rotation error";
}


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

Eigen::Vector3d absolute_euler_difference_deg(const Pose& est, const Pose& gt) {
  return (math::euler_zyx(est.R()) - math::euler_zyx(gt.R())) * math::kDegPerRad;
}

Eigen::Vector3d euler_figure_deg(const Pose& est, const Pose& gt, const PoseError& e, EulerMetric m) {
  if (m == EulerMetric::kError) return e.rpy_deg;
  Eigen::Vector3d d = absolute_euler_difference_deg(est, gt);
  if (m == EulerMetric::kAbsolute)
    for (int k = 0; k < 3; ++k) d(k) = math::wrap_180(d(k));
  return d;
}

Eigen::Quaterniond mean_rotation(std::size_t n, const std::function<Eigen::Quaterniond(std::size_t)>& q_at) {
  if (n == 0) return Eigen::Quaterniond::Identity();
  // Start: the principal eigenvector of Σ q qᵀ (sign-free quaternion average), then Gauss-Newton on SO(3).
  Eigen::Matrix4d M = Eigen::Matrix4d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector4d v = q_at(i).normalized().coeffs();
    M += v * v.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> es(M);
  Eigen::Quaterniond R(Eigen::Vector4d(es.eigenvectors().col(3)));
  R.normalize();
  for (int it = 0; it < 100; ++it) {
    Eigen::Vector3d step = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < n; ++i) step += math::log_quat(R.conjugate() * q_at(i).normalized());
    step /= static_cast<double>(n);
    R = (R * math::exp_quat(step)).normalized();
    if (step.norm() < 1e-12) break;
  }
  return math::canonical(R);
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
                      const std::vector<PoseCovariance>& cov, unsigned threads, EulerMetric euler) {
  if (est.size() != gt.size()) {
    throw InputError(
        fmt::format("APE needs matched pairs: {} estimate vs {} ground-truth poses", est.size(), gt.size()));
  }
  return compute_ape(
      est.size(), [&](std::size_t i) { return std::pair<Pose, Pose>(est[i], gt[i]); }, cov, threads, euler);
}

namespace {

/// One pair's contribution to the per-axis sums.
struct PairParts {
  Eigen::Vector3d dp, rpy, fig;  ///< e_p, kError's Euler, the chosen metric's Euler
  Eigen::Vector3d jump;          ///< 1 on the axes whose absolute-angle difference jumped by 360°
};

/// Running per-axis sums; the pairs are added in order (ordered reduction: any thread count, same bits).
struct AxisSums {
  Eigen::Vector3d sum_dp = Eigen::Vector3d::Zero(), sq_dp = Eigen::Vector3d::Zero();
  Eigen::Vector3d sum_rpy = Eigen::Vector3d::Zero(), sq_rpy = Eigen::Vector3d::Zero();
  Eigen::Vector3d sum_fig = Eigen::Vector3d::Zero(), sq_fig = Eigen::Vector3d::Zero();
  Eigen::Vector3d jumps = Eigen::Vector3d::Zero();
  double jumps_any = 0.0;
  void add(const PairParts& p) {
    sum_dp += p.dp;
    sq_dp += p.dp.cwiseAbs2();
    sq_rpy += p.rpy.cwiseAbs2();
    sum_rpy += p.rpy;
    sum_fig += p.fig;
    sq_fig += p.fig.cwiseAbs2();
    jumps += p.jump;
    jumps_any += p.jump.maxCoeff();
  }
};

EulerStats euler_stats(const Eigen::Vector3d& sum, const Eigen::Vector3d& sq, double N) {
  EulerStats s;
  s.rmse = (sq / N).cwiseSqrt();
  s.mean = sum / N;
  s.std = (sq / N - s.mean.cwiseAbs2()).cwiseMax(0.0).cwiseSqrt();
  return s;
}

}  // namespace

ApeResult compute_ape(std::size_t n, const PosePairAt& pair, const std::vector<PoseCovariance>& cov,
                      unsigned threads, EulerMetric euler) {
  if (!cov.empty() && cov.size() != n) {
    throw InputError(fmt::format("APE: {} covariances for {} pairs", cov.size(), n));
  }
  ApeResult r;
  r.euler_metric = euler;
  if (!cov.empty()) r.nees.resize(n);
  std::vector<double> tn(n), an(n);
  // Each pair's errors on its own (in parallel); the sums take the pairs in order, whichever thread
  // computed them, so the result does not depend on the thread count. Only the norms stay (for the
  // medians): a pair's errors are recomputed where they are written (Report::error).
  using Parts = std::vector<PairParts>;
  AxisSums sums;
  parallel_ranges_ordered(
      n, kPairsPerTask, threads ? threads : available_cpus(),
      [&](std::size_t b, std::size_t e) {
        Parts parts(e - b);
        for (std::size_t i = b; i < e; ++i) {
          const auto [est, gt] = pair(i);
          const PoseError pe = pose_error(est, gt);
          tn[i] = pe.dp.norm();
          an[i] = pe.angle_deg;
          PairParts& p = parts[i - b];
          p.dp = pe.dp;
          p.rpy = pe.rpy_deg;
          p.fig = pe.rpy_deg;
          p.jump.setZero();
          if (euler != EulerMetric::kError) {
            const Eigen::Vector3d d = absolute_euler_difference_deg(est, gt);
            for (int k = 0; k < 3; ++k) {
              p.jump(k) = std::abs(d(k)) >= 180.0 ? 1.0 : 0.0;
              p.fig(k) = euler == EulerMetric::kAbsolute ? math::wrap_180(d(k)) : d(k);
            }
          }
          if (!cov.empty()) r.nees[i] = pose_nees(est, gt, cov[i]);
        }
        return parts;
      },
      [&](Parts&& parts) {
        for (const PairParts& p : parts) sums.add(p);
      });
  if (n > 0) {
    const double N = static_cast<double>(n);
    r.pos_mean_m = sums.sum_dp / N;
    r.pos_rmse_m = (sums.sq_dp / N).cwiseSqrt();
    r.rpy_error = euler_stats(sums.sum_rpy, sums.sq_rpy, N);
    r.rpy = euler == EulerMetric::kError ? r.rpy_error : euler_stats(sums.sum_fig, sums.sq_fig, N);
    r.rpy_rmse_deg = r.rpy.rmse;
    r.jump_share = sums.jumps / N;
    r.jump_share_any = sums.jumps_any / N;
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
