#include "roe/sim/pose_groundtruth.hpp"

#include <Eigen/Dense>
#include <algorithm>

#include "roe/core/error.hpp"

namespace roe::sim {

namespace {
double seconds_between(Timestamp a, Timestamp b) { return static_cast<double>(b - a) * 1e-9; }

/// The slope at τ = 0 of the least-squares quadratic p(τ) = a + bτ + cτ² through (τ_j, p_j).
Eigen::Vector3d quadratic_slope(const std::vector<StampedPose>& poses, std::size_t k, std::size_t lo, std::size_t hi) {
  const auto n = static_cast<Eigen::Index>(hi - lo + 1);
  Eigen::MatrixXd A(n, 3);
  Eigen::MatrixXd P(n, 3);
  for (std::size_t j = lo; j <= hi; ++j) {
    const double tau = seconds_between(poses[k].t_ns, poses[j].t_ns);
    const auto r = static_cast<Eigen::Index>(j - lo);
    A.row(r) << 1.0, tau, tau * tau;
    P.row(r) = (poses[j].T.p - poses[k].T.p).transpose();  // relative: no cancellation in the fit
  }
  const Eigen::MatrixXd coef = A.colPivHouseholderQr().solve(P);
  return coef.row(1).transpose();
}
}  // namespace

std::vector<ImuState> states_from_poses(const std::vector<StampedPose>& poses, const VelocityFromPosesConfig& config) {
  if (poses.size() < 2) throw DataError("the ground truth has fewer than 2 poses");
  const auto h = static_cast<Timestamp>(config.half_window_s * 1e9);
  std::vector<ImuState> out(poses.size());
  std::size_t lo = 0, hi = 0;
  for (std::size_t k = 0; k < poses.size(); ++k) {
    while (poses[k].t_ns - poses[lo].t_ns > h) ++lo;
    hi = std::max(hi, k);
    while (hi + 1 < poses.size() && poses[hi + 1].t_ns - poses[k].t_ns <= h) ++hi;
    ImuState& s = out[k];
    s.t_ns = poses[k].t_ns;
    s.T_W_I = poses[k].T;
    if (hi - lo + 1 >= 3) {
      s.v_W_I = quadratic_slope(poses, k, lo, hi);
    } else {  // an isolated pose (a gap on both sides of the window): its neighbours' difference
      const std::size_t a = k == 0 ? 0 : k - 1, b = k + 1 == poses.size() ? k : k + 1;
      s.v_W_I = (poses[b].T.p - poses[a].T.p) / seconds_between(poses[a].t_ns, poses[b].t_ns);
    }
  }
  return out;
}

}  // namespace roe::sim
