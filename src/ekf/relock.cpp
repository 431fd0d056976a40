#include "roe/ekf/relock.hpp"

#include <algorithm>
#include <cmath>
#include <map>

namespace roe::ekf {

LockoutMonitor::LockoutMonitor(double after_s, int min_detections, double agree)
    : after_ns_(after_s > 0.0 ? from_seconds(after_s) : 0), min_detections_(std::max(min_detections, 3)),
      agree_(agree) {}

void LockoutMonitor::accepted(Timestamp t) {
  since_ns_ = t;
  started_ = true;
  samples_.clear();
}

void LockoutMonitor::refused(Timestamp t, int object_id, const Eigen::Vector3d& offset) {
  if (!enabled() || !offset.allFinite()) return;
  if (!started_) {
    since_ns_ = t;
    started_ = true;
  }
  // The line fit describes a drift over about after_s; older evidence is dropped (bounded memory over a
  // long lock-out).
  const Timestamp keep_from = t - 2 * after_ns_;
  samples_.erase(samples_.begin(), std::find_if(samples_.begin(), samples_.end(),
                                                [&](const Sample& s) { return s.t >= keep_from; }));
  samples_.push_back({t, object_id, offset});
}

std::optional<Relock> LockoutMonitor::check(Timestamp now) const {
  if (!enabled() || !started_ || now - since_ns_ < after_ns_) return std::nullopt;
  const int n = static_cast<int>(samples_.size());
  if (n < min_detections_) return std::nullopt;
  std::map<int, int> per_object;
  for (const auto& s : samples_) ++per_object[s.object_id];

  // e(t) = a + b t (t in s relative to now), per axis by least squares.
  double t_mean = 0.0;
  Eigen::Vector3d e_mean = Eigen::Vector3d::Zero();
  for (const auto& s : samples_) {
    t_mean += to_seconds(s.t - now);
    e_mean += s.e;
  }
  t_mean /= n;
  e_mean /= n;
  double s_tt = 0.0;
  Eigen::Vector3d s_te = Eigen::Vector3d::Zero();
  for (const auto& s : samples_) {
    const double dt = to_seconds(s.t - now) - t_mean;
    s_tt += dt * dt;
    s_te += dt * (s.e - e_mean);
  }
  const Eigen::Vector3d b = s_tt > 0.0 ? Eigen::Vector3d(s_te / s_tt) : Eigen::Vector3d::Zero();
  const Eigen::Vector3d a = e_mean - b * t_mean;

  // Residuals about the line: their spread, and each object's mean (the objects must agree).
  double ss = 0.0;
  std::map<int, Eigen::Vector3d> mean_residual;
  for (const auto& s : samples_) {
    const Eigen::Vector3d r = s.e - (a + b * to_seconds(s.t - now));
    ss += r.squaredNorm();
    auto [it, fresh] = mean_residual.try_emplace(s.object_id, Eigen::Vector3d::Zero());
    it->second += r / per_object[s.object_id];
  }
  for (const auto& [id, r] : mean_residual)
    if (r.norm() > agree_) return std::nullopt;
  const double sigma = std::sqrt(ss / (3.0 * std::max(n - 2, 1)));
  // Standard error of the intercept at t = now (per axis); the offset must stand out of it (|a|/se is about
  // χ₃ for offsets scattered about zero: P(χ²₃ > 16) = 0.1 %).
  const double se = sigma * std::sqrt(1.0 / n + (s_tt > 0.0 ? t_mean * t_mean / s_tt : 0.0));
  if (!(a.norm() > 4.0 * se)) return std::nullopt;

  Relock r;
  r.since_ns = since_ns_;
  r.offset = a;
  r.drift_per_s = b;
  r.residual_sigma = sigma;
  r.detections = n;
  r.objects = static_cast<int>(per_object.size());
  return r;
}

}  // namespace roe::ekf
