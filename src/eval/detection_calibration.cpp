// Calibration of per-detection σ against the ground truth (docs/eval.md, "Detection uncertainty calibration").
#include "roe/eval/detection_calibration.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "roe/core/error.hpp"
#include "roe/math/distributions.hpp"
#include "roe/eval/interpolate.hpp"
#include "roe/math/so3.hpp"

namespace roe::eval {

namespace {

/// Linear-interpolated sample quantile (numpy's default, "linear") of sorted values.
double quantile_sorted(const std::vector<double>& v, double p) {
  if (v.empty()) return 0.0;
  const double h = p * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(h));
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (h - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

/// Kolmogorov's asymptotic p-value of a one-sample KS distance d over n samples, with Stephens' finite-n
/// correction λ = (√n + 0.12 + 0.11/√n) d.
double ks_p_value(double d, std::size_t n) {
  const double sn = std::sqrt(static_cast<double>(n));
  const double lambda = (sn + 0.12 + 0.11 / sn) * d;
  if (lambda < 0.2) return 1.0;
  double sum = 0.0;
  for (int j = 1; j <= 100; ++j) {
    const double term = std::exp(-2.0 * j * j * lambda * lambda);
    sum += (j % 2 ? 1.0 : -1.0) * term;
    if (term < 1e-12) break;
  }
  return std::clamp(2.0 * sum, 0.0, 1.0);
}

}  // namespace

Pose true_T_C_O(const Pose& T_W_I, const Pose& T_I_C, const Pose& T_W_O) { return (T_W_I * T_I_C).inverse() * T_W_O; }

Vector6d detection_error(const Pose& T_C_O_meas, const Pose& T_C_O_true) {
  Vector6d e;
  e.head<3>() = T_C_O_meas.p - T_C_O_true.p;
  e.tail<3>() = math::log_quat(T_C_O_meas.q * T_C_O_true.q.conjugate());
  return e;
}

std::array<double, 3> expected_within() {
  return {math::chi2_cdf(1.0, 1.0), math::chi2_cdf(4.0, 1.0), math::chi2_cdf(9.0, 1.0)};
}

std::array<double, 5> chi2_6_quantiles() {
  std::array<double, 5> q{};
  for (std::size_t i = 0; i < q.size(); ++i) q[i] = math::chi2_quantile(kNisProbabilities[i], 6.0);
  return q;
}

double nis_gate() { return math::chi2_quantile(0.95, 6.0); }

SigmaCalibration calibrate(const std::vector<DetectionResidual>& residuals) {
  SigmaCalibration c;
  c.n = residuals.size();
  if (c.n == 0) return c;
  const double n = static_cast<double>(c.n);
  const double gate = nis_gate();
  std::vector<double> nis;
  nis.reserve(c.n);
  double sum_t = 0.0, sum_r = 0.0;
  std::array<std::size_t, 3> in_t{}, in_r{};
  std::size_t above = 0;
  for (const DetectionResidual& r : residuals) {
    const Vector6d z = r.error.cwiseQuotient(r.sigma);
    for (int i = 0; i < 6; ++i)
      for (int k = 0; k < 3; ++k)
        if (std::abs(z[i]) <= k + 1.0) ++(i < 3 ? in_t : in_r)[static_cast<std::size_t>(k)];
    sum_t += z.head<3>().squaredNorm();
    sum_r += z.tail<3>().squaredNorm();
    nis.push_back(z.squaredNorm());
    if (nis.back() > gate) ++above;
  }
  for (std::size_t k = 0; k < 3; ++k) {
    c.within_t[k] = static_cast<double>(in_t[k]) / (3.0 * n);
    c.within_r[k] = static_cast<double>(in_r[k]) / (3.0 * n);
  }
  const double sum = sum_t + sum_r;
  c.nis_mean = sum / n;
  c.frac_above_gate = static_cast<double>(above) / n;
  std::sort(nis.begin(), nis.end());
  for (std::size_t i = 0; i < c.nis_quantiles.size(); ++i) c.nis_quantiles[i] = quantile_sorted(nis, kNisProbabilities[i]);
  // KS distance of the empirical CDF (a step at each sorted value) from χ²₆.
  for (std::size_t i = 0; i < nis.size(); ++i) {
    const double F = math::chi2_cdf(nis[i], 6.0);
    c.ks_statistic = std::max({c.ks_statistic, static_cast<double>(i + 1) / n - F, F - static_cast<double>(i) / n});
  }
  c.ks_p_value = ks_p_value(c.ks_statistic, c.n);
  // Errors N(0, s² diag σ²): the likelihood in s² peaks at Σ NIS / (6n); Σ NIS / s² ~ χ²_{6n}.
  const double dof = 6.0 * n;
  c.sigma_scale = std::sqrt(sum / dof);
  c.sigma_scale_lo = std::sqrt(sum / math::chi2_quantile(0.975, dof));
  c.sigma_scale_hi = std::sqrt(sum / math::chi2_quantile(0.025, dof));
  c.sigma_scale_t = std::sqrt(sum_t / (3.0 * n));
  c.sigma_scale_r = std::sqrt(sum_r / (3.0 * n));
  c.sigma_scale_median = std::sqrt(quantile_sorted(nis, 0.5) / math::chi2_quantile(0.5, 6.0));
  return c;
}

DetectionCalibration calibrate_detection_sigmas(const std::vector<Detection>& detections, const DetectionTruth& truth) {
  DetectionCalibration out;
  out.n_detections = detections.size();
  const Timestamp offset = from_seconds(truth.camera_time_offset_s);
  std::map<int, std::vector<DetectionResidual>> by_object;
  std::map<int, std::size_t> no_truth;
  for (const Detection& d : detections) {
    if (!d.sigma) {
      ++out.n_without_sigma;
      continue;
    }
    const auto obj = truth.T_W_O.find(d.object_id);
    if (obj == truth.T_W_O.end()) {
      ++out.n_without_object_truth;
      ++no_truth[d.object_id];
      continue;
    }
    const auto T_W_I = interpolate_pose_at(truth.T_W_I, d.t_ns + offset, truth.max_gap_ns);
    if (!T_W_I) {
      ++out.n_outside_truth;
      continue;
    }
    DetectionResidual r;
    r.t_ns = d.t_ns;
    r.object_id = d.object_id;
    r.error = detection_error(d.T_C_O, true_T_C_O(*T_W_I, truth.T_I_C, obj->second));
    r.sigma = *d.sigma;
    r.nis = r.error.cwiseQuotient(r.sigma).squaredNorm();
    out.residuals.push_back(r);
    by_object[d.object_id].push_back(r);
  }
  if (out.residuals.empty()) {
    const std::size_t with_sigma = out.n_detections - out.n_without_sigma;
    throw InputError(
        with_sigma == 0
            ? fmt::format("none of the {} detections carries sigmas: nothing to calibrate", out.n_detections)
            : fmt::format("none of the {} detections with sigmas can be compared with the truth ({} of objects "
                          "without a true pose, {} outside the ground truth's time span or in its gaps)",
                          with_sigma, out.n_without_object_truth, out.n_outside_truth));
  }
  for (const auto& [id, rows] : by_object) out.objects.push_back({id, calibrate(rows)});
  out.all = calibrate(out.residuals);
  if (out.n_without_sigma)
    out.warnings.push_back(fmt::format("{} of {} detections carry no sigmas and are left out of the calibration",
                                       out.n_without_sigma, out.n_detections));
  for (const auto& [id, count] : no_truth)
    out.warnings.push_back(
        fmt::format("object {} has no true pose (roe.json truth.objects): its {} detection(s) are left out", id, count));
  if (out.n_outside_truth)
    out.warnings.push_back(fmt::format("{} detection(s) lie outside the ground truth's time span or in a gap of more "
                                       "than {} s and are left out",
                                       out.n_outside_truth, to_seconds(truth.max_gap_ns)));
  return out;
}

}  // namespace roe::eval
