#pragma once
// Shared helpers of the filter accuracy/consistency tests: simulated datasets from the sim library,
// association of the estimate with the ground truth, SE(3) alignment (roe::eval), and the true state
// expressed in the filter's gauge (for NEES).
#include <Eigen/Core>
#include <map>
#include <vector>

#include "roe/app/run.hpp"
#include "roe/app/simulate.hpp"
#include "roe/eval/align.hpp"
#include "roe/math/euler.hpp"
#include "roe/math/so3.hpp"
#include "roe/sim/simulator.hpp"

namespace roe::test {

inline Dataset simulate_preset(const std::string& preset, std::uint64_t seed, double duration_s) {
  sim::SimConfig c = app::sim_config_from_preset(preset);
  c.duration_s = duration_s;
  return sim::simulate(c, seed);
}

/// Ground-truth state at each estimate row (same stamps: the estimate is written at the IMU stamps,
/// the simulated ground truth is at the IMU stamps too). Rows without a truth stamp are dropped.
struct Matched {
  std::vector<const app::StateRow*> est;
  std::vector<const ImuState*> gt;
};
inline Matched match(const app::RunOutput& r, const Dataset& d, double skip_s = 0.0) {
  std::map<Timestamp, const ImuState*> by_t;
  for (const auto& g : d.groundtruth) by_t[g.t_ns] = &g;
  Matched m;
  const Timestamp t0 = r.states.empty() ? 0 : r.states.front().t_ns;
  for (const auto& s : r.states) {
    if (dt_seconds(t0, s.t_ns) < skip_s) continue;
    auto it = by_t.find(s.t_ns);
    if (it == by_t.end()) continue;
    m.est.push_back(&s);
    m.gt.push_back(it->second);
  }
  return m;
}

struct Accuracy {
  Eigen::Vector3d pos_rmse = Eigen::Vector3d::Zero();    ///< m per axis
  Eigen::Vector3d euler_rmse = Eigen::Vector3d::Zero();  ///< deg roll, pitch, yaw
  double max_pos_err = 0.0, max_rot_err_deg = 0.0;
  eval::Alignment alignment;
};

/// Per-axis position and ZYX-Euler RMSE after an SE(3) Umeyama alignment (roe::eval).
inline Accuracy accuracy(const Matched& m) {
  const int n = static_cast<int>(m.est.size());
  Eigen::Matrix3Xd X(3, n), Y(3, n);
  for (int i = 0; i < n; ++i) {
    X.col(i) = m.est[i]->x.p_W_I;
    Y.col(i) = m.gt[i]->T_W_I.p;
  }
  Accuracy a;
  a.alignment = eval::umeyama_alignment(X, Y, false);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d e = a.alignment.apply(X.col(i)) - Y.col(i);
    a.pos_rmse += e.cwiseProduct(e);
    a.max_pos_err = std::max(a.max_pos_err, e.norm());
    const Eigen::Matrix3d R_est = a.alignment.R * m.est[i]->x.q_W_I.toRotationMatrix();
    const Eigen::Matrix3d E = R_est.transpose() * m.gt[i]->T_W_I.R();
    Eigen::Vector3d rpy = math::euler_zyx(E) * math::kDegPerRad;
    a.euler_rmse += rpy.cwiseProduct(rpy);
    a.max_rot_err_deg = std::max(a.max_rot_err_deg, math::log_so3(E).norm() * math::kDegPerRad);
  }
  a.pos_rmse = (a.pos_rmse / n).cwiseSqrt();
  a.euler_rmse = (a.euler_rmse / n).cwiseSqrt();
  return a;
}

/// The true IMU pose expressed in the filter's world W' for the position_yaw gauge: W' is gravity
/// aligned, and the anchor's true T_O_W' has the estimated position p̂ and zero yaw error relative to
/// the estimate R̂ (z-component of Log(R̂ᵀ R_true) = 0). Returns T_W'_Wt.
inline Pose gauge_position_yaw(const Pose& T_O_W_est, const Pose& T_Wt_O_true) {
  const Pose T_O_Wt = T_Wt_O_true.inverse();
  double psi = 0.0;
  for (int it = 0; it < 20; ++it) {
    const Eigen::Matrix3d R = T_O_Wt.R() * math::exp_so3(Eigen::Vector3d(0, 0, psi));
    psi -= math::log_so3(T_O_W_est.R().transpose() * R).z();
  }
  const Eigen::Matrix3d Rz = math::exp_so3(Eigen::Vector3d(0, 0, psi));
  const Eigen::Vector3d t = T_O_Wt.R().transpose() * (T_O_W_est.p - T_O_Wt.p);
  const Pose T_Wt_Wp(Rz, t);
  return T_Wt_Wp.inverse();
}

}  // namespace roe::test
