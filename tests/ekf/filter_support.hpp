#pragma once
// Shared helpers of the filter accuracy/consistency tests: simulated datasets from the sim library,
// association of the estimate with the ground truth, SE(3) alignment (roe::eval), and the true state
// expressed in the filter's gauge (for NEES).
#include <catch2/catch.hpp>

#include <Eigen/Core>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <vector>

#include "roe/app/run.hpp"
#include "roe/app/simulate.hpp"
#include "roe/math/distributions.hpp"
#include "roe/eval/align.hpp"
#include "roe/math/euler.hpp"
#include "roe/math/so3.hpp"
#include "roe/sim/simulator.hpp"
#include "support/plain_config.hpp"

namespace roe::test {

inline Dataset simulate_preset(const std::string& preset, std::uint64_t seed, double duration_s) {
  sim::SimConfig c = app::sim_config_from_preset(preset);
  c.duration_s = duration_s;
  return sim::simulate(c, seed);
}

/// The real EuRoC V1_02 snippet of ../shared/data (its IMU and ground truth) with 4 synthesised objects
/// (seed 1), or nothing when ../shared/data is absent (the caller WARNs and returns).
inline std::optional<Dataset> euroc_snippet_with_objects() {
  const auto mav0 = std::filesystem::path(ROE_SHARED_DATA_DIR) / "euroc_v102_snippet" / "mav0";
  if (!std::filesystem::exists(mav0)) return std::nullopt;
  app::SimulateOptions so;
  so.from_groundtruth = mav0.string();
  so.objects = 4;
  so.seed = 1;
  return app::simulate_dataset(so).dataset;
}

/// Ground-truth state at each estimate row (same stamps: the estimate is written at the IMU stamps,
/// the simulated ground truth is at the IMU stamps too). Rows without a truth stamp are dropped.
struct Matched {
  std::vector<const app::RecordedState*> est;
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

inline const TruthObject& truth_object(const Dataset& d, int id) {
  for (const auto& o : d.manifest.truth->objects)
    if (o.id == id) return o;
  FAIL("object " << id << " not in truth");
  return d.manifest.truth->objects.front();
}

struct MonteCarlo {
  double anees = 0.0;         ///< time-averaged NEES of the IMU pose (6 dof)
  double lo = 0.0, hi = 0.0;  ///< two-sided 95 % bounds of the time-averaged NEES
  double rejection_rate = 0.0;
  std::size_t gated = 0;
  double pos_rms_m = 0.0;  ///< RMS of the IMU position error in the filter's gauge, over runs and rows
  double sigma_scale_sum = 0.0;  ///< sum over runs of the final factor on the detections' σ
  /// Per run, the final extrinsics' NEES over their reported per-axis σ (run.json final: [δp_I_C; δθ_I_C],
  /// θ on the right), and per non-anchor object its T_A_O's relative to the anchor (objects.csv's last σ_A_O,
  /// the truth's T_A_O against the estimate's, both right-perturbed as math::pose_difference).
  std::vector<double> extrinsics_nees, objects_nees;
};

/// N runs of `preset` (seeds 100..100+N−1) with the per-detection σ the simulator wrote (configured
/// noise = simulated noise); NEES of the IMU pose in the filter's gauge, after skip_s. `smoother` is
/// "rts" (RunConfig::estimator "smoother": the smoothed estimate and its covariance) or "none".
/// `edit_config` and `edit_data` (optional) change the run config and each simulated dataset.
inline MonteCarlo monte_carlo(const std::string& preset, int N, double duration, double skip_s,
                              const std::string& smoother = "none",
                              const std::function<void(app::RunConfig&)>& edit_config = {},
                              const std::function<void(Dataset&)>& edit_data = {}) {
  app::RunConfig cfg = test::plain_config();
  cfg.filter.use_detection_sigmas = true;
  cfg.filter.init_sigma_v_mps = 1.0;
  cfg.estimator = smoother == "rts" ? store::Estimator::kSmoother : store::Estimator::kFilter;  // RunConfig::estimator (issue 48)
  if (edit_config) edit_config(cfg);
  std::vector<double> nees_sum;  // per time step, summed over runs
  std::size_t rejected = 0, rows = 0;
  double sq = 0.0;
  MonteCarlo mc;
  for (int run = 0; run < N; ++run) {
    Dataset d = simulate_preset(preset, 100 + run, duration);
    if (edit_data) edit_data(d);
    const app::RunOutput r = app::run_dataset(d, "sim", cfg);
    mc.sigma_scale_sum += r.summary.detection_sigma_scale;
    for (double nis : r.summary.nis) {
      ++mc.gated;
      if (nis > r.health.nis.gate) ++rejected;
    }
    if (d.manifest.truth) {
      const Pose& Tt = d.manifest.truth->T_I_C;
      const Pose& Te = r.summary.final_T_I_C;
      Eigen::Matrix<double, 6, 1> e;
      e << Tt.p - Te.p, math::log_quat(Te.q.conjugate() * Tt.q);
      if ((r.summary.final_sigma_I_C.array() > 0.0).all())
        mc.extrinsics_nees.push_back(e.cwiseQuotient(r.summary.final_sigma_I_C).squaredNorm());
      const int a = r.summary.anchor.id;
      std::map<int, const app::ObjectRow*> last;
      for (const auto& row : r.objects) last[row.object_id] = &row;
      if (last.count(a))
        for (const auto& [id, row] : last) {
          if (id == a || !(row->sigma_A_O.array() > 0.0).all()) continue;
          const Pose T_A_O_est = last.at(a)->T_O_W * row->T_O_W.inverse();
          const Pose T_A_O_true = truth_object(d, a).T_W_O.inverse() * truth_object(d, id).T_W_O;
          mc.objects_nees.push_back(math::pose_difference(T_A_O_est, T_A_O_true).cwiseQuotient(row->sigma_A_O).squaredNorm());
        }
    }
    const Pose T_Wp_Wt = gauge_position_yaw(r.summary.final_T_O_W.at(r.summary.anchor.id), truth_object(d, r.summary.anchor.id).T_W_O);
    const auto m = match(r, d, skip_s);
    if (nees_sum.empty()) nees_sum.assign(m.est.size(), 0.0);
    REQUIRE(m.est.size() >= nees_sum.size() - 2);
    for (std::size_t k = 0; k < nees_sum.size() && k < m.est.size(); ++k) {
      const Pose T_true = T_Wp_Wt * m.gt[k]->T_W_I;
      const auto& s = *m.est[k];
      Eigen::Matrix<double, 6, 1> e;
      e.head<3>() = T_true.p - s.x.p_W_I;
      e.tail<3>() = math::log_quat(s.x.q_W_I.conjugate() * T_true.q);
      nees_sum[k] += e.dot(s.pose_cov.ldlt().solve(e));
      sq += e.head<3>().squaredNorm();
      ++rows;
    }
  }
  for (double v : nees_sum) mc.anees += v / N;
  mc.anees /= nees_sum.size();
  mc.lo = math::chi2_quantile(0.025, 6.0 * N) / N;
  mc.hi = math::chi2_quantile(0.975, 6.0 * N) / N;
  mc.rejection_rate = static_cast<double>(rejected) / mc.gated;
  mc.pos_rms_m = std::sqrt(sq / rows);
  return mc;
}

}  // namespace roe::test
