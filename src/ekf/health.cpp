#include "roe/ekf/health.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "roe/math/distributions.hpp"
#include "roe/math/euler.hpp"
#include "roe/math/se3.hpp"

namespace roe::ekf {
namespace {

std::string why_never_initialised(const DetectionCounts& c, const FilterOptions& o) {
  std::vector<std::string> why;
  if (c.pending_init)
    why.push_back(fmt::format("{} awaited initialisation ({} agreeing consecutive detections needed, "
                              "init_min_detections)",
                              c.pending_init, o.init_min_detections));
  if (c.rejected_no_main) why.push_back(fmt::format("{} had no initialised anchor in their image", c.rejected_no_main));
  if (c.rejected_no_imu) why.push_back(fmt::format("{} lay outside the IMU stream", c.rejected_no_imu));
  if (c.rejected_score) why.push_back(fmt::format("{} scored below min_score", c.rejected_score));
  return fmt::format("{}", fmt::join(why, "; "));
}

double quantile(const std::vector<double>& sorted, double p) {
  const double h = p * static_cast<double>(sorted.size() - 1);
  const std::size_t lo = static_cast<std::size_t>(std::floor(h));
  const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (h - static_cast<double>(lo)) * (sorted[hi] - sorted[lo]);
}

std::string seconds_at(Timestamp t, Timestamp t0) { return fmt::format("{:.2f} s", to_seconds(t - t0)); }

}  // namespace

std::vector<std::string> run_warnings(const FilterRunSummary& s, const FilterOptions& o) {
  std::vector<std::string> out;
  if (s.anchor.automatic && s.anchor.id >= 0)
    out.push_back(fmt::format("anchor chosen automatically: object {} (first seen at {}, detected in {} images)",
                              s.anchor.id, seconds_at(s.anchor.t_ns, s.t_first_ns), s.anchor.images));
  DetectionCounts total;
  for (const auto& [id, c] : s.counts) {
    total += c;
    if (c.initialized == 0 && c.detections > 0)
      out.push_back(fmt::format("object {} was detected {} times but never initialised: {}", id, c.detections,
                                why_never_initialised(c, o)));
  }
  if (total.rejected_no_imu > 0)
    out.push_back(fmt::format("{} detections lie outside the IMU stream and were skipped", total.rejected_no_imu));
  // The paper's rule (require_anchor) wastes most of a recording whose camera leaves the anchor often,
  // e.g. a flight that sweeps a room: say so, and name the switch. A rejected_no_main detection either
  // lacks the anchor in its image or comes before the anchor is initialised: they are told apart.
  const std::size_t no_anchor = total.rejected_no_main - s.no_main_anchor_pending;
  if (o.require_anchor && total.detections > 0 && 4 * no_anchor >= total.detections)
    out.push_back(fmt::format(
        "{} of {} detections ({:.0f} %) were rejected because their image lacks the anchor object {} "
        "(filter.require_anchor is true, the paper's rule); require_anchor false updates from every "
        "initialised object{}",
        no_anchor, total.detections, 100.0 * static_cast<double>(no_anchor) / static_cast<double>(total.detections),
        s.anchor.id,
        s.no_main_anchor_pending
            ? fmt::format(" ({} more were in images with the anchor, before it was initialised)",
                          s.no_main_anchor_pending)
            : std::string()));
  if (s.updates == 0) out.push_back("no update was made: the trajectory is IMU dead reckoning");
  // A re-lock repairs the estimate from then on; before it the estimate was wrong (and the health figures
  // count that stretch as dead reckoning when it was the position that was lost).
  for (const auto& e : s.relocks)
    out.push_back(fmt::format("the position estimate was lost from {} (every detection refused; {} detections of "
                              "{} object(s) agreed on an offset of {:.3g} m) and was re-locked at {}",
                              seconds_at(e.what.since_ns, s.t_first_ns), e.what.detections, e.what.objects,
                              e.what.offset.norm(), seconds_at(e.t_ns, s.t_first_ns)));
  // A refused init_gyro_bias_from_rest is not a warning: the default asks for it and a handheld recording
  // starts moving; run.json's init.gyro_bias_from / gyro_bias_rest_refused say what happened and why.
  const auto calib = calibration_warnings(s);
  out.insert(out.end(), calib.begin(), calib.end());
  return out;
}

std::vector<std::string> calibration_warnings(const FilterRunSummary& s) {
  std::vector<std::string> out;
  // The extrinsics: the shift from the prior per axis, in prior σ (axes held fixed have σ 0: none).
  const Vector6d d = math::pose_difference(s.prior_T_I_C, s.final_T_I_C);
  static const char* axes[6] = {"p_x", "p_y", "p_z", "θ_x", "θ_y", "θ_z"};
  std::vector<std::string> beyond;
  for (int k = 0; k < 6; ++k)
    if (s.prior_sigma_I_C(k) > 0.0 && std::abs(d(k)) > kCalibrationMoveSigmas * s.prior_sigma_I_C(k))
      beyond.push_back(fmt::format("{} {:.1f} σ", axes[k], std::abs(d(k)) / s.prior_sigma_I_C(k)));
  if (!beyond.empty())
    out.push_back(fmt::format(
        "the extrinsics moved {:.1f} mm / {:.2f}° from their prior, beyond {} prior σ on {} (final σ {:.1f} mm / "
        "{:.2f}°): a wrong prior, or detection errors absorbed by the calibration (docs/filter.md §15); roe "
        "calib-check tells which",
        d.head<3>().norm() * 1e3, d.tail<3>().norm() / math::kRadPerDeg, kCalibrationMoveSigmas,
        fmt::join(beyond, ", "), s.final_sigma_I_C.head<3>().maxCoeff() * 1e3,
        s.final_sigma_I_C.tail<3>().maxCoeff() / math::kRadPerDeg));
  // Object-worlds: the median rotation residual of each object's last gated detections.
  for (const auto& [id, res] : s.rot_residual_deg) {
    if (res.size() < kRotationResidualWindow / 2) continue;
    std::vector<double> last(res.end() - static_cast<std::ptrdiff_t>(std::min(res.size(), kRotationResidualWindow)),
                             res.end());
    std::nth_element(last.begin(), last.begin() + last.size() / 2, last.end());
    const double med = last[last.size() / 2];
    if (med > kRotationResidualWarnDeg)
      out.push_back(fmt::format(
          "object {} keeps a rotation residual of {:.0f}° (median of its last {} gated detections): its "
          "object-world disagrees with what is detected; a flipped pose of a symmetric object (give its "
          "models_info) or a wrong initialisation",
          id, med, last.size()));
  }
  return out;
}

NisStats nis_stats(std::vector<double> nis, double gate) {
  NisStats n;
  n.gate = gate;
  n.count = nis.size();
  if (nis.empty()) return n;
  std::sort(nis.begin(), nis.end());
  double sum = 0.0;
  std::size_t above = 0;
  for (double x : nis) {
    sum += x;
    above += x > gate;
  }
  n.mean = sum / static_cast<double>(nis.size());
  n.median = quantile(nis, 0.5);
  n.p25 = quantile(nis, 0.25);
  n.p75 = quantile(nis, 0.75);
  n.p95 = quantile(nis, 0.95);
  n.max = nis.back();
  n.fraction_above_gate = static_cast<double>(above) / static_cast<double>(nis.size());
  n.median_ratio = n.median / math::chi2_quantile(0.5, 6.0);
  return n;
}

RunHealth assess_health(const FilterRunSummary& s, const FilterOptions& options, const HealthLimits& limits) {
  RunHealth h;
  const Timestamp t0 = s.t_first_ns, t1 = s.t_last_ns;
  h.duration_s = to_seconds(t1 - t0);
  h.accepted_updates = s.update_times.size();
  h.nis = nis_stats(s.nis, math::chi2_quantile(options.chi2_confidence, 6.0));
  // Supported time: after each accepted update, up to support_window_s or the next update.
  const Timestamp window = from_seconds(std::max(0.0, limits.support_window_s));
  Timestamp supported = 0, prev = t0;
  h.dead_reckoning_from_ns = t0;
  h.dead_reckoning_to_ns = t1;
  Timestamp longest = -1;
  for (std::size_t i = 0; i <= s.update_times.size(); ++i) {
    const Timestamp next = i < s.update_times.size() ? std::clamp(s.update_times[i], t0, t1) : t1;
    if (i > 0) supported += std::min(next - prev, window);
    if (next - prev > longest) {
      longest = next - prev;
      h.dead_reckoning_from_ns = prev;
      h.dead_reckoning_to_ns = next;
    }
    prev = next;
  }
  h.longest_dead_reckoning_s = to_seconds(longest);
  h.supported_fraction = t1 > t0 ? static_cast<double>(supported) / static_cast<double>(t1 - t0) : 0.0;

  const std::string where = fmt::format("{} → {} of the {:.2f} s trajectory", seconds_at(h.dead_reckoning_from_ns, t0),
                                        seconds_at(h.dead_reckoning_to_ns, t0), h.duration_s);
  if (h.accepted_updates == 0)
    h.problems.push_back(fmt::format("no detection was accepted: the whole {:.2f} s trajectory is IMU dead reckoning",
                                     h.duration_s));
  if (h.accepted_updates > 0 && h.supported_fraction < limits.min_supported_fraction)
    h.problems.push_back(fmt::format(
        "only {:.1f} % of the trajectory lies within {:g} s after an accepted update (health.min_supported_fraction "
        "{:g} %); the last accepted update is at {}",
        100.0 * h.supported_fraction, limits.support_window_s, 100.0 * limits.min_supported_fraction,
        seconds_at(s.update_times.back(), t0)));
  if (h.accepted_updates > 0 && limits.max_dead_reckoning_s >= 0.0 &&
      h.longest_dead_reckoning_s > limits.max_dead_reckoning_s)
    h.problems.push_back(fmt::format("{:.2f} s without an accepted update ({}; health.max_dead_reckoning_s {:g}): "
                                     "the estimate there is IMU dead reckoning",
                                     h.longest_dead_reckoning_s, where, limits.max_dead_reckoning_s));
  if (limits.max_nis_median_ratio > 0.0 && h.nis.count >= 30 && h.nis.median_ratio > limits.max_nis_median_ratio)
    h.problems.push_back(fmt::format(
        "the median NIS is {:.1f}, {:.1f} times the χ²₆ median (health.max_nis_median_ratio {:g}): the filter is "
        "far more confident than its detections allow (measurement σ too small, or a wrong object map)",
        h.nis.median, h.nis.median_ratio, limits.max_nis_median_ratio));
  return h;
}

}  // namespace roe::ekf
