// Clock offsets from angular rates (eval/time_offset.hpp): the one correlator, and the estimate–ground-truth
// offset refined by minimising the APE.
#include "roe/eval/time_offset.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>

#include <unsupported/Eigen/FFT>

#include "roe/core/error.hpp"
#include "roe/eval/interpolate.hpp"
#include "roe/eval/metrics.hpp"
#include "roe/math/so3.hpp"

namespace roe::eval {

namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

}  // namespace

double effective_sample_fraction(const std::vector<Eigen::Vector3d>& r) {
  const std::size_t n = r.size();
  if (n < 4) return 1.0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& x : r) mean += x;
  mean /= static_cast<double>(n);
  // Every lag's sum c_k = Σ_j (r_j − mean)·(r_{j+k} − mean) at once: the three components' autocorrelations
  // by FFT, zero-padded to at least 2n samples so that nothing wraps around. O(n log n): the direct sum is
  // O(n · lags), and residuals that drift (most trajectories' APE) correlate over half the series, which
  // made this the whole of `roe eval`'s CPU on an hour at IMU rate. c_0 is summed directly.
  std::size_t m = 1;
  while (m < 2 * n) m <<= 1;
  Eigen::FFT<double> fft;
  fft.SetFlag(Eigen::FFT<double>::HalfSpectrum);  // real input: half the spectrum, half the work
  std::vector<double> x(m, 0.0), a, c(n / 2, 0.0);
  std::vector<std::complex<double>> X;
  double c0 = 0.0;
  for (int i = 0; i < 3; ++i) {
    for (std::size_t k = 0; k < n; ++k) {
      x[k] = r[k][i] - mean[i];
      c0 += x[k] * x[k];
    }
    fft.fwd(X, x);
    for (auto& z : X) z = std::norm(z);
    fft.inv(a, X);
    for (std::size_t k = 1; k < c.size(); ++k) c[k] += a[k];
  }
  if (!(c0 > 0)) return 1.0;
  double sum = 0.0;
  for (std::size_t lag = 1; lag < n / 2; ++lag) {
    const double rho = c[lag] / c0;
    if (rho < 0.05) break;
    sum += rho;
  }
  return 1.0 / (1.0 + 2.0 * sum);
}

namespace {

/// The residuals at one offset: positions A(p_est) − p_gt(t_est + offset) with the ground truth's velocity v
/// there, and rotations Log(R_gtᵀ·R·R_est·R_offᵀ) (R_off the mean rotation between the two bodies, removed)
/// with the ground truth's body rate w: d r_p / d offset = −v, d r_θ / d offset = −w.
struct OffsetResiduals {
  std::vector<Eigen::Vector3d> r, v, rr, w;
  double sse = 0.0, sse_r = 0.0;
  std::size_t size() const { return r.size(); }
};

/// The two blocks' weights: each block's effective samples over its residual variance (f / s²), so that
/// metres and radians add up as information.
struct OffsetWeights {
  double p = 0.0, r = 0.0;
};

struct OffsetProblem {
  const std::vector<Timestamp>& est_t;
  const std::vector<Pose>& est;
  std::vector<StampedPose> gt;
  Timestamp max_gap_ns = 0;
  AlignType align = AlignType::kSe3;

  OffsetResiduals residuals(double offset_s) const {
    const Timestamp off = from_seconds(offset_s), h = std::max<Timestamp>(max_gap_ns / 6, 1'000'000);
    const double two_h = 2e-9 * static_cast<double>(h);
    std::vector<Pose> e, g;
    OffsetResiduals out;
    e.reserve(est_t.size()), g.reserve(est_t.size()), out.v.reserve(est_t.size()), out.w.reserve(est_t.size());
    for (std::size_t k = 0; k < est_t.size(); ++k) {
      const Timestamp t = est_t[k] + off;
      const auto p = interpolate_pose_at(gt, t, max_gap_ns);
      const auto a = interpolate_pose_at(gt, t - h, max_gap_ns), b = interpolate_pose_at(gt, t + h, max_gap_ns);
      if (!p || !a || !b) continue;
      e.push_back(est[k]), g.push_back(*p);
      out.v.push_back((b->p - a->p) / two_h);
      out.w.push_back(math::log_quat(a->q.conjugate() * b->q) / two_h);
    }
    if (e.size() < 10) return {};
    const Alignment al = compute_alignment(align, e, g);
    const Eigen::Quaterniond qa = al.q();
    const Eigen::Quaterniond q_off =
        mean_rotation(e.size(), [&](std::size_t k) { return (g[k].q.conjugate() * qa * e[k].q).normalized(); });
    out.r.reserve(e.size()), out.rr.reserve(e.size());
    for (std::size_t k = 0; k < e.size(); ++k) {
      out.r.push_back(al.apply(e[k].p) - g[k].p);
      out.sse += out.r.back().squaredNorm();
      out.rr.push_back(math::log_quat(g[k].q.conjugate() * qa * e[k].q * q_off.conjugate()));
      out.sse_r += out.rr.back().squaredNorm();
    }
    return out;
  }
};

OffsetWeights weights_of(const OffsetResiduals& R, bool effective) {
  const auto n = static_cast<double>(R.size());
  OffsetWeights w;
  if (n == 0) return w;
  w.p = 1.0 / std::max(R.sse / (3.0 * n), 1e-18) * (effective ? effective_sample_fraction(R.r) : 1.0);
  w.r = 1.0 / std::max(R.sse_r / (3.0 * n), 1e-18) * (effective ? effective_sample_fraction(R.rr) : 1.0);
  return w;
}

double weighted_cost(const OffsetResiduals& R, const OffsetWeights& w) { return w.p * R.sse + w.r * R.sse_r; }

OffsetProblem make_problem(const std::vector<Timestamp>& est_t, const std::vector<Pose>& est,
                           const std::vector<Timestamp>& gt_t, const std::vector<Pose>& gt, AlignType align) {
  if (align != AlignType::kSim3 && align != AlignType::kPosYaw) align = AlignType::kSe3;
  const double rate = median_rate_hz(gt_t);
  OffsetProblem pb{est_t, est, {}, from_seconds(rate > 0 ? 3.0 / rate : 1e-3), align};
  pb.gt.reserve(gt_t.size());
  for (std::size_t i = 0; i < gt_t.size(); ++i)
    if (pb.gt.empty() || gt_t[i] > pb.gt.back().t_ns) pb.gt.push_back({gt_t[i], gt[i]});
  return pb;
}

/// Gauss–Newton on the offset from `tau` over both blocks, each weighted by its residual variance, the
/// alignment re-fitted at each step; steps clamped to ±max_step. Returns the offset and whether it converged
/// within max_iter steps.
std::pair<double, bool> refine_offset(const OffsetProblem& pb, double tau, int max_iter, double max_step, int& iters) {
  for (iters = 1; iters <= max_iter; ++iters) {
    const OffsetResiduals R = pb.residuals(tau);
    const OffsetWeights w = weights_of(R, true);  // the weights of the σ: one cost, minimised and measured
    double num = 0.0, den = 0.0;
    for (std::size_t k = 0; k < R.size(); ++k) {
      num += w.p * R.v[k].dot(R.r[k]) + w.r * R.w[k].dot(R.rr[k]);
      den += w.p * R.v[k].squaredNorm() + w.r * R.w[k].squaredNorm();
    }
    if (!(den > 0)) return {tau, false};  // no overlap, or no motion
    const double step = std::clamp(num / den, -max_step, max_step);
    tau += step;
    if (std::abs(step) < 1e-7) return {tau, true};
  }
  return {tau, false};
}

/// 1σ of the offset at `tau` from the curvature of the weighted cost (weights fixed at tau, each block's
/// over its effective samples) with the alignment re-fitted (it absorbs part of a shift); nan where the
/// curvature is not positive. Also the pairs used and the APE RMSE there.
double offset_sigma(const OffsetProblem& pb, double tau, std::size_t* n_pairs, double* rmse) {
  // One residual set alive at a time (each is ~200 B a pose while built: an hour at IMU rate is 1.4 M poses).
  OffsetWeights w;
  double cost0 = 0.0;
  {
    const OffsetResiduals R0 = pb.residuals(tau);
    const auto n = static_cast<double>(R0.size());
    *n_pairs = R0.size();
    *rmse = n > 0 ? std::sqrt(R0.sse / n) : kNan;
    if (n <= 7) return kNan;
    w = weights_of(R0, true);
    cost0 = weighted_cost(R0, w);
  }
  const double h = std::max(2.0 * dt_seconds(0, pb.max_gap_ns) / 3.0, 0.002);
  const double cost_plus = weighted_cost(pb.residuals(tau + h), w);
  const double cost_minus = weighted_cost(pb.residuals(tau - h), w);
  const double curv = (cost_plus - 2.0 * cost0 + cost_minus) / (h * h);
  return curv > 0 ? std::sqrt(2.0 / curv) : kNan;
}

}  // namespace

TrajectoryOffset estimate_trajectory_offset(const std::vector<Timestamp>& est_t, const std::vector<Pose>& est,
                                            const std::vector<Timestamp>& gt_t, const std::vector<Pose>& gt,
                                            AlignType align, double max_offset_s) {
  TrajectoryOffset o;
  const auto period = [](const std::vector<Timestamp>& t) {
    const double r = median_rate_hz(t);
    return r > 0 ? 1.0 / r : 0.0;
  };
  const math::RateSignal se = math::pose_rate_signal(est_t, est, period(est_t));
  const math::RateSignal sg = math::pose_rate_signal(gt_t, gt, period(gt_t));
  const bool gt_denser = median_rate_hz(gt_t) >= median_rate_hz(est_t);
  const math::RateSignal& binned = gt_denser ? sg : se;
  const math::RateSignal& interp = gt_denser ? se : sg;
  const double grid = std::min(interp.max_gap_s / 3.0, 0.005);
  o.coarse = math::correlate_rates(binned, interp, max_offset_s, grid);
  o.coarse_offset_s = gt_denser ? o.coarse.offset_s : -o.coarse.offset_s;
  o.offset_s = o.coarse_offset_s;
  o.sigma_s = kNan;
  const OffsetProblem pb = make_problem(est_t, est, gt_t, gt, align);
  const auto [tau, converged] = refine_offset(pb, o.coarse_offset_s, 50, grid, o.iterations);
  if (!converged || std::abs(tau - o.coarse_offset_s) > 10 * grid + 0.05) return o;  // the coarse value stands
  o.offset_s = tau;
  o.refined = true;
  o.sigma_s = offset_sigma(pb, tau, &o.n_pairs, &o.ape_rmse_m);
  return o;
}

OffsetCheck check_trajectory_offset(const std::vector<Timestamp>& est_t, const std::vector<Pose>& est,
                                    const std::vector<Timestamp>& gt_t, const std::vector<Pose>& gt, AlignType align,
                                    double offset_s) {
  OffsetCheck c;
  const OffsetProblem pb = make_problem(est_t, est, gt_t, gt, align);
  int iters = 0;
  const auto [tau, converged] = refine_offset(pb, offset_s, 8, 0.1, iters);
  if (!converged) return c;
  std::size_t n = 0;
  double rmse = 0.0;
  c.sigma_s = offset_sigma(pb, tau, &n, &rmse);
  c.shift_s = tau - offset_s;
  c.valid = std::isfinite(c.sigma_s);
  return c;
}

}  // namespace roe::eval
