// The KITTI odometry drift figures (eval/kitti.hpp).
#include "roe/eval/kitti.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "roe/core/error.hpp"

namespace roe::eval {

namespace {

/// The devkit's rotation error: the angle from the trace, clamped.
double devkit_angle(const Eigen::Matrix3d& R) {
  return std::acos(std::max(std::min(0.5 * (R.trace() - 1.0), 1.0), -1.0));
}

}  // namespace

KittiDrift kitti_drift(const std::vector<Pose>& est, const std::vector<Pose>& gt) {
  if (est.size() != gt.size()) throw InputError("kitti_drift: the estimate and the ground truth differ in length");
  const std::size_t n = gt.size();
  std::vector<double> dist(n, 0.0);
  for (std::size_t i = 1; i < n; ++i) dist[i] = dist[i - 1] + (gt[i].p - gt[i - 1].p).norm();
  KittiDrift d;
  double st = 0.0, sr = 0.0;
  for (const double L : kKittiLengthsM) {
    KittiLength kl;
    kl.length_m = L;
    double lt = 0.0, lr = 0.0;
    for (std::size_t i = 0; i < n; i += kKittiStepFrames) {
      const auto it = std::upper_bound(dist.begin() + static_cast<std::ptrdiff_t>(i), dist.end(), dist[i] + L);
      if (it == dist.end()) continue;  // the path ends before L
      const std::size_t j = static_cast<std::size_t>(it - dist.begin());
      const Pose E = (est[i].inverse() * est[j]).inverse() * (gt[i].inverse() * gt[j]);
      lt += E.p.norm() / L;
      lr += devkit_angle(E.R()) / L;
      ++kl.n_segments;
    }
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const auto m = static_cast<double>(kl.n_segments);
    kl.t_rel_pct = kl.n_segments ? 100.0 * lt / m : nan;
    kl.r_rel_deg_per_100m = kl.n_segments ? lr / m * (180.0 / M_PI) * 100.0 : nan;
    d.per_length.push_back(kl);
    d.n_segments += kl.n_segments;
    st += lt, sr += lr;
  }
  const auto m = static_cast<double>(d.n_segments);
  d.t_rel_pct = d.n_segments ? 100.0 * st / m : std::numeric_limits<double>::quiet_NaN();
  d.r_rel_deg_per_100m = d.n_segments ? sr / m * (180.0 / M_PI) * 100.0 : std::numeric_limits<double>::quiet_NaN();
  return d;
}

}  // namespace roe::eval
