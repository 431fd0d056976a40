// The truth in the estimator's gauge (eval/gauge.hpp).
#include "roe/eval/gauge.hpp"

#include <cmath>

#include "roe/math/so3.hpp"

namespace roe::eval {

std::string to_string(GaugeKind g) { return g == GaugeKind::kPose ? "pose" : "position_yaw"; }

Pose estimator_gauge(GaugeKind kind, const Pose& T_O_W_est, const Pose& T_Wt_O_true) {
  if (kind == GaugeKind::kPose) return T_Wt_O_true * T_O_W_est;
  const Pose T_O_Wt = T_Wt_O_true.inverse();
  // ψ with (Log(R̂ᵀ R_O_Wt Rz(ψ)))_z = 0: d/dψ of that component is ≈ 1 near the solution.
  double psi = 0.0;
  for (int it = 0; it < 50; ++it) {
    const Eigen::Matrix3d R = T_O_Wt.R() * math::exp_so3(Eigen::Vector3d(0, 0, psi));
    const double r = math::log_so3(T_O_W_est.R().transpose() * R).z();
    psi -= r;
    if (std::abs(r) < 1e-13) break;
  }
  const Eigen::Matrix3d Rz = math::exp_so3(Eigen::Vector3d(0, 0, psi));
  // p_O_Wg = R_O_Wt t + p_O_Wt must equal the estimate's p_O_W.
  const Eigen::Vector3d t = T_O_Wt.R().transpose() * (T_O_W_est.p - T_O_Wt.p);
  return Pose(Rz, t);
}

}  // namespace roe::eval
