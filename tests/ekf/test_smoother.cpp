// The fixed-interval RTS smoother (ekf/smoother.hpp) over recorded filter runs: what the recording must
// not change, what RTS must give exactly (the last state, the constant states), that it never adds
// uncertainty, and what it buys on simulated sequences (accuracy, consistency, the anchor's gauge).
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <string>

#include "filter_support.hpp"
#include "roe/ekf/smoother.hpp"

using namespace roe;
using ekf::Vec3;
using ekf::Vec6;

namespace {

app::RunConfig matched_config(const std::string& smoother) {
  app::RunConfig cfg = test::plain_config();
  cfg.filter.use_detection_sigmas = true;
  cfg.estimator = smoother == "rts" ? store::Estimator::kSmoother : store::Estimator::kFilter;  // RunConfig::estimator (issue 48)
  return cfg;
}

double rot_diff(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return math::log_quat(a.conjugate() * b).norm();
}

}  // namespace

TEST_CASE("smoother: the recording leaves the filter's estimate bit for bit unchanged", "[ekf][smoother]") {
  const Dataset d = test::simulate_preset("matched", 3, 10.0);
  const app::RunOutput plain = app::run_dataset(d, "sim", matched_config("none"));
  const app::RunOutput smoothed = app::run_dataset(d, "sim", matched_config("rts"));
  REQUIRE(plain.filter_states.empty());
  REQUIRE(smoothed.smoothed);
  REQUIRE(smoothed.filter_states.size() == plain.states.size());
  for (std::size_t k = 0; k < plain.states.size(); ++k) {
    const auto& a = plain.states[k];
    const auto& b = smoothed.filter_states[k];
    REQUIRE(a.t_ns == b.t_ns);
    REQUIRE(a.x.p_W_I == b.x.p_W_I);
    REQUIRE(a.x.q_W_I.coeffs() == b.x.q_W_I.coeffs());
    REQUIRE(a.sigma == b.sigma);
  }
  REQUIRE(plain.summary.final_T_I_C.p == smoothed.summary.final_T_I_C.p);
}

TEST_CASE("smoother: exact at the end, constant states at their final estimate, never less certain",
          "[ekf][smoother]") {
  Dataset d = test::simulate_preset("matched", 4, 15.0);
  // No detections in the last second: the rows after the last update are pure prediction.
  auto& dets = d.detections.at("sim");
  const Timestamp t_end = d.imu.back().t_ns - from_seconds(1.0);
  dets.erase(std::remove_if(dets.begin(), dets.end(), [&](const Detection& x) { return x.t_ns > t_end; }),
             dets.end());
  const app::RunOutput r = app::run_dataset(d, "sim", matched_config("rts"));
  REQUIRE(r.states.size() == r.filter_states.size());
  REQUIRE(r.states.size() > 1000);
  // After the last update the smoothed estimate is the filtered one, and its covariance, re-propagated by
  // the smoother from the last update with the recorded transitions and the same process noise, is the
  // filter's own (a wrong noise or transition in the re-propagation shows here).
  const auto& lf = r.filter_states.back();
  std::size_t after = 0;
  for (std::size_t k = 0; k < r.states.size(); ++k) {
    if (r.states[k].t_ns <= t_end + from_seconds(0.05)) continue;
    ++after;
    const auto& s = r.states[k];
    const auto& f = r.filter_states[k];
    CHECK((s.x.p_W_I - f.x.p_W_I).norm() < 1e-9);
    CHECK(rot_diff(s.x.q_W_I, f.x.q_W_I) < 1e-9);
    for (int i = 0; i < 21; ++i) CHECK(s.sigma(i) == Approx(f.sigma(i)).epsilon(1e-6).margin(1e-12));
  }
  CHECK(after > 150);
  // Extrinsics have no process noise: their smoothed estimate and σ are the final filtered ones at
  // every time (the RTS gain's constant-state rows; a wrong transpose or Φ breaks this).
  double max_dp = 0.0, max_dth = 0.0, max_dsig = 0.0;
  for (const auto& s : r.states) {
    max_dp = std::max(max_dp, (s.T_I_C.p - r.summary.final_T_I_C.p).norm());
    max_dth = std::max(max_dth, rot_diff(s.T_I_C.q, r.summary.final_T_I_C.q));
    for (int i = 15; i < 21; ++i) max_dsig = std::max(max_dsig, std::abs(s.sigma(i) / lf.sigma(i) - 1.0));
  }
  const double sigma_p = lf.sigma.segment<3>(15).minCoeff();
  WARN("smoothed extrinsics vs final filtered: max " << max_dp << " m (final σ " << sigma_p << " m), "
                                                     << max_dth << " rad, σ ratio −1 up to " << max_dsig);
  CHECK(max_dp < 0.01 * sigma_p);
  CHECK(max_dth < 1e-4);
  CHECK(max_dsig < 1e-4);
  // P_s = P_f − C (P⁻ − P_s) Cᵀ ≤ P_f: no smoothed σ exceeds the filtered σ at the same time.
  std::size_t worse = 0;
  for (std::size_t k = 0; k < r.states.size(); ++k)
    for (int i = 0; i < 15; ++i)
      if (r.states[k].sigma(i) > r.filter_states[k].sigma(i) * (1.0 + 1e-6) + 1e-12) ++worse;
  CHECK(worse == 0);
}

TEST_CASE("smoother: noise-free preset matches the truth", "[ekf][smoother][sim]") {
  const Dataset d = test::simulate_preset("noise-free", 1, 30.0);
  app::RunConfig cfg = test::plain_config();
  cfg.estimator = store::Estimator::kSmoother;
  const app::RunOutput r = app::run_dataset(d, "sim", cfg);
  const test::Accuracy a = test::accuracy(test::match(r, d));
  INFO("position RMSE " << a.pos_rmse.transpose() << " m, Euler RMSE " << a.euler_rmse.transpose() << " deg");
  CHECK(a.pos_rmse.maxCoeff() < 1e-3);
  CHECK(a.euler_rmse.maxCoeff() < 0.01);
}

// Consistency and gain on `matched` (configured noise = simulated noise): the smoothed IMU pose's
// time-averaged NEES over 20 runs lies in the two-sided 95 % χ² bounds, and its position error is well
// below the filter's on the same runs (measured 2026-12-01: see docs/RESULTS.md §3).
TEST_CASE("smoother: matched Monte-Carlo NEES inside the 95 % bounds, error below the filter's",
          "[ekf][smoother][sim][mc]") {
  const test::MonteCarlo f = test::monte_carlo("matched", 20, 20.0, 3.0, "none");
  const test::MonteCarlo s = test::monte_carlo("matched", 20, 20.0, 3.0, "rts");
  WARN("matched MC: filter NEES " << f.anees << ", position RMS " << f.pos_rms_m << " m; smoother NEES "
                                  << s.anees << " (bounds " << s.lo << ", " << s.hi << "), position RMS "
                                  << s.pos_rms_m << " m");
  CHECK(s.anees > s.lo);
  CHECK(s.anees < s.hi);
  CHECK(s.pos_rms_m < 0.9 * f.pos_rms_m);
}

// The anchor's first sight re-defines W; the states before it are smoothed in the old W and moved
// into the new one (γ_s). Here the anchor is initialised only after 15 agreeing detections while the
// other objects update the filter (require_anchor false), so a wrong or missing shift leaves a jump.
TEST_CASE("smoother: the states before the anchor's first sight join the rest without a jump",
          "[ekf][smoother]") {
  const Dataset d = test::simulate_preset("matched", 5, 10.0);
  app::RunConfig cfg = matched_config("rts");
  cfg.filter.require_anchor = false;
  cfg.filter.init_min_detections = 15;
  const app::RunOutput r = app::run_dataset(d, "sim", cfg);
  REQUIRE(r.states.size() > 100);
  Timestamp t_anchor = 0;
  for (const auto& p : r.reprojection)
    if (p.object_id == r.summary.anchor.id && p.outcome.status == ekf::DetectionStatus::kInitialized)
      t_anchor = p.t_ns;
  REQUIRE(t_anchor > r.states.front().t_ns);
  // The largest change between consecutive rows, across the anchor's initialisation and elsewhere
  // (second differences, so the motion itself cancels).
  double jump_at = 0.0, jump_elsewhere = 0.0;
  for (std::size_t k = 2; k < r.states.size(); ++k) {
    const Vec3 dd = r.states[k].x.p_W_I - 2.0 * r.states[k - 1].x.p_W_I + r.states[k - 2].x.p_W_I;
    const bool across = r.states[k - 2].t_ns <= t_anchor && r.states[k].t_ns >= t_anchor;
    (across ? jump_at : jump_elsewhere) = std::max(across ? jump_at : jump_elsewhere, dd.norm());
  }
  WARN("second difference of the smoothed position across the anchor's first sight "
       << jump_at << " m, elsewhere max " << jump_elsewhere);
  CHECK(jump_at <= 2.0 * jump_elsewhere + 1e-4);
}

// Every anchor gauge (the anchor's first sight removes 6, 3 or 4 directions: B has fewer rows than the
// augmented state) and the paper's residual frame: the backward pass goes through, the states before
// the anchor join without a jump, and no σ grows.
TEST_CASE("smoother: every anchor gauge and the paper's residual frame", "[ekf][smoother]") {
  const Dataset d = test::simulate_preset("matched", 6, 8.0);
  for (const auto gauge :
       {ekf::AnchorGauge::kPose, ekf::AnchorGauge::kPosition, ekf::AnchorGauge::kPositionYaw}) {
    for (const auto frame : {ekf::ResidualFrame::kObject, ekf::ResidualFrame::kCamera}) {
      app::RunConfig cfg = matched_config("rts");
      cfg.filter.anchor_gauge = gauge;
      cfg.filter.residual_frame = frame;
      cfg.filter.require_anchor = false;
      cfg.filter.init_min_detections = 10;
      INFO("gauge " << ekf::to_string(gauge) << ", residual frame " << ekf::to_string(frame));
      const app::RunOutput r = app::run_dataset(d, "sim", cfg);
      std::size_t worse = 0;
      double max_dd = 0.0;
      for (std::size_t k = 0; k < r.states.size(); ++k) {
        for (int i = 0; i < 21; ++i)
          if (r.states[k].sigma(i) > r.filter_states[k].sigma(i) * (1.0 + 1e-6) + 1e-12) ++worse;
        if (k >= 2)
          max_dd = std::max(
              max_dd, (r.states[k].x.p_W_I - 2.0 * r.states[k - 1].x.p_W_I + r.states[k - 2].x.p_W_I).norm());
      }
      CHECK(worse == 0);
      CHECK(max_dd < 1e-3);  // no jump anywhere (a 200 Hz step's second difference is ~1e-5 m here)
      CHECK((r.states.back().x.p_W_I - r.filter_states.back().x.p_W_I).norm() < 0.05);
    }
  }
}

namespace {

struct NullObserver : ekf::FilterObserver {};

/// The textbook RTS over a recording, with full matrices at every IMU step: the transition diag(F, I), the
/// gain C = P(t) Fᵀ P(t⁺)⁻¹ from a Cholesky solve, δ(t) = C δ(t⁺), P_s(t) = P(t) + C (P_s(t⁺) − P(t⁺)) Cᵀ.
/// Updates pass the smoothed estimate unchanged; augmentations and the anchor's change of W follow
/// smoother.hpp's definitions. Slow (n³ per IMU step), written for checking ekf::smooth's algebra.
std::vector<ekf::SmoothedState> dense_rts(const ekf::FilterRecording& rec, const ekf::ImuNoiseParams& noise) {
  using MatX = Eigen::MatrixXd;
  using VecX = Eigen::VectorXd;
  const auto& nodes = rec.nodes;
  std::vector<ekf::SmoothedState> out(rec.steps.size() + 1);
  const auto row = [](Timestamp t, const ekf::CoreState& x, const ekf::StateEstimate& xe, const MatX& P) {
    ekf::SmoothedState s;
    s.t_ns = t;
    s.x = x;
    s.T_I_C = xe.T_I_C;
    for (int i = 0; i < ekf::kCore; ++i) s.sigma(i) = std::sqrt(std::max(0.0, P(i, i)));
    if (xe.extr_offset >= 0)
      for (int i = 0; i < 6; ++i) s.sigma(ekf::kCore + i) = std::sqrt(std::max(0.0, P(xe.extr_offset + i, xe.extr_offset + i)));
    const int idx[6] = {ekf::kP, ekf::kP + 1, ekf::kP + 2, ekf::kTheta, ekf::kTheta + 1, ekf::kTheta + 2};
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < 6; ++c) s.pose_cov(r, c) = P(idx[r], idx[c]);
    return s;
  };
  // The full covariance at node j (a propagation node: re-propagated from the node before it).
  std::vector<std::vector<MatX>> seg_P(nodes.size());
  for (std::size_t j = 1; j < nodes.size(); ++j) {
    if (nodes[j].kind != ekf::RecordedNode::Kind::kPropagate) continue;
    MatX P = nodes[j - 1].P;
    const Eigen::Index n = P.rows();
    seg_P[j].push_back(P);
    for (std::size_t s = nodes[j].first_step; s < nodes[j].steps; ++s) {
      MatX F = MatX::Identity(n, n);
      F.topLeftCorner<ekf::kCore, ekf::kCore>() = rec.steps[s].F.dense();
      P = (F * P * F.transpose()).eval();
      Eigen::Block<MatX, ekf::kCore, ekf::kCore> Pcc = P.topLeftCorner<ekf::kCore, ekf::kCore>();
      ekf::add_process_noise(noise, rec.steps[s].F.dt, Pcc);
      P = (0.5 * (P + P.transpose())).eval();
      seg_P[j].push_back(P);
    }
  }
  // A decay node (Gauss–Markov detection-error states): P_y = B P_u Bᵀ + diag(1 − b²), B = diag(b).
  std::vector<MatX> dec_P(nodes.size());
  const auto P_at = [&](std::size_t j) -> MatX {
    if (nodes[j].kind == ekf::RecordedNode::Kind::kPropagate) return seg_P[j].back();
    if (nodes[j].kind == ekf::RecordedNode::Kind::kDecay) return dec_P[j];
    return nodes[j].P;
  };
  for (std::size_t j = 1; j < nodes.size(); ++j) {
    if (nodes[j].kind != ekf::RecordedNode::Kind::kDecay) continue;
    const MatX B = nodes[j].decay.asDiagonal();
    dec_P[j] = B * P_at(j - 1) * B.transpose();
    dec_P[j].diagonal().array() += 1.0 - nodes[j].decay.array().square();
  }
  ekf::StateEstimate xs = nodes.back().x;
  MatX Ps = P_at(nodes.size() - 1);
  Pose shift;
  std::size_t anchor_steps = 0;
  for (std::size_t j = nodes.size() - 1; j >= 1; --j) {
    const auto& nd = nodes[j];
    if (nd.kind == ekf::RecordedNode::Kind::kDecay) {
      // The linear link y = B u + w: C = P_u Bᵀ P_y⁻¹ (full matrices, an explicit solve).
      const MatX Pu = P_at(j - 1), Py = dec_P[j];
      const MatX B = nd.decay.asDiagonal();
      const MatX C = Py.llt().solve(B * Pu).transpose();
      ekf::StateEstimate xu = nodes[j - 1].x;
      ekf::boxplus(xu, C * ekf::boxminus(xs, nd.x));
      const MatX Psu = Pu + C * (Ps - Py) * C.transpose();
      xs = xu;
      Ps = 0.5 * (Psu + Psu.transpose());
    } else if (nd.kind == ekf::RecordedNode::Kind::kAugment) {
      const MatX Pu = P_at(j - 1);
      const Eigen::Index n = Pu.rows();
      const VecX d = ekf::boxminus(xs, nd.x);
      MatX B = nd.append_only ? MatX::Identity(nd.P.rows(), n) : nd.B;
      if (nd.append_only) B.bottomRows(nd.P.rows() - n).setZero();
      // C = P_u Bᵀ P_y⁻¹ (with B = [I; 0] for a plain append, whose cross terms the filter's P holds).
      const MatX C = nd.append_only ? MatX(MatX::Identity(n, nd.P.rows()))
                                    : MatX(nd.P.llt().solve(B * Pu).transpose());
      ekf::StateEstimate xu = nodes[j - 1].x;
      ekf::boxplus(xu, C * d);
      const MatX Psu = nd.append_only ? MatX(Ps.topLeftCorner(n, n)) : MatX(Pu + C * (Ps - nd.P) * C.transpose());
      if (nd.anchor) {
        shift = Pose(xs.x.q_W_I, xs.x.p_W_I) * Pose(xu.x.q_W_I, xu.x.p_W_I).inverse();
        anchor_steps = nd.steps;
      }
      xs = xu;
      Ps = 0.5 * (Psu + Psu.transpose());
    } else if (nd.kind == ekf::RecordedNode::Kind::kPropagate) {
      const auto& Pk = seg_P[j];  // Pk[k]: after k steps of the segment
      const std::size_t m = Pk.size() - 1;
      const ekf::StateEstimate& xa = nodes[j - 1].x;
      VecX delta = ekf::boxminus(xs, nd.x);
      MatX Pss = Ps;
      for (std::size_t k = m; k-- > 0;) {
        const Eigen::Index n = Pk[k].rows();
        MatX F = MatX::Identity(n, n);
        F.topLeftCorner<ekf::kCore, ekf::kCore>() = rec.steps[nd.first_step + k].F.dense();
        const MatX C = Pk[k + 1].llt().solve(F * Pk[k]).transpose();
        delta = (C * delta).eval();
        Pss = (Pk[k] + C * (Pss - Pk[k + 1]) * C.transpose()).eval();
        if (k > 0) {
          ekf::CoreState x = rec.steps[nd.first_step + k - 1].x;
          ekf::boxplus_core(x, delta.head<ekf::kCore>());
          out[nd.first_step + k] = row(rec.steps[nd.first_step + k - 1].t_ns, x, xa, Pss);
        }
      }
      // Row of the segment's last step (at b) from the smoothed b.
      {
        ekf::CoreState x = rec.steps[nd.steps - 1].x;
        ekf::boxplus_core(x, ekf::boxminus(xs, nd.x).head<ekf::kCore>());
        out[nd.steps] = row(rec.steps[nd.steps - 1].t_ns, x, xa, Ps);
      }
      ekf::StateEstimate xa_s = xa;
      ekf::boxplus(xa_s, delta);
      xs = xa_s;
      Ps = 0.5 * (Pss + Pss.transpose());
    }
  }
  out[0] = row(xs.t_ns, xs.x, xs, Ps);
  for (std::size_t k = 0; k <= anchor_steps && anchor_steps > 0 && k < out.size(); ++k) {
    auto& x = out[k].x;
    x.p_W_I = shift.q * x.p_W_I + shift.p;
    x.v_W_I = shift.q * x.v_W_I;
    x.q_W_I = (shift.q * x.q_W_I).normalized();
  }
  return out;
}

}  // namespace

TEST_CASE("smoother: equals the textbook RTS with full matrices at every IMU step, on any thread count",
          "[ekf][smoother]") {
  const Dataset d = test::simulate_preset("matched", 6, 4.0);
  const auto images = ekf::group_images(d.detections.at("sim"));
  const ekf::FilterOptions opt = matched_config("rts").filter;
  const auto& imu_noise = d.manifest.imu->noise;
  const ekf::ImuNoiseParams noise{imu_noise.gyro_noise_density, imu_noise.gyro_random_walk,
                                  imu_noise.accel_noise_density, imu_noise.accel_random_walk};
  NullObserver obs;
  ekf::FilterRecording rec;
  ekf::run_filter(d.imu, images, opt, noise, d.manifest.camera->T_I_C, obs, &rec);
  REQUIRE(rec.steps.size() > 700);

  const ekf::SmootherResult one = ekf::smooth(rec, noise, {1});
  const ekf::SmootherResult two = ekf::smooth(rec, noise, {2});
  const std::vector<ekf::SmoothedState> ref = dense_rts(rec, noise);
  REQUIRE(one.states.size() == ref.size());
  REQUIRE(two.states.size() == ref.size());
  double max_dp = 0, max_dth = 0, max_dsig = 0, max_dcov = 0;
  for (std::size_t k = 0; k < ref.size(); ++k) {
    const auto &a = one.states[k], &b = two.states[k], &r = ref[k];
    // The second thread changes nothing, bit for bit.
    REQUIRE(a.t_ns == b.t_ns);
    REQUIRE(a.x.p_W_I == b.x.p_W_I);
    REQUIRE(a.x.q_W_I.coeffs() == b.x.q_W_I.coeffs());
    REQUIRE(a.sigma == b.sigma);
    REQUIRE(a.pose_cov == b.pose_cov);
    REQUIRE(a.t_ns == r.t_ns);
    max_dp = std::max({max_dp, (a.x.p_W_I - r.x.p_W_I).norm(), (a.x.v_W_I - r.x.v_W_I).norm()});
    max_dth = std::max(max_dth, rot_diff(a.x.q_W_I, r.x.q_W_I));
    max_dsig = std::max(max_dsig, ((a.sigma - r.sigma).array().abs() / (r.sigma.array() + 1e-12)).maxCoeff());
    max_dcov = std::max(max_dcov, (a.pose_cov - r.pose_cov).norm() / r.pose_cov.norm());
  }
  // Measured (2026-12-02): position 2.2e-14 m, rotation 4.2e-15 rad, σ 2.0e-9 relative.
  INFO("position " << max_dp << " m, rotation " << max_dth << " rad, sigma " << max_dsig << " rel, pose cov "
                   << max_dcov << " rel");
  CHECK(max_dp < 1e-9);
  CHECK(max_dth < 1e-9);
  CHECK(max_dsig < 1e-6);
  CHECK(max_dcov < 1e-6);
}

namespace {

/// A filter run with its recording, the IMU noise it used and its image times.
struct Recorded {
  ekf::FilterRecording rec;
  ekf::ImuNoiseParams noise;
  std::vector<Timestamp> image_times;
};

Recorded record(const Dataset& d, const ekf::FilterOptions& opt) {
  Recorded r;
  const auto images = ekf::group_images(d.detections.at("sim"));
  const auto& n = d.manifest.imu->noise;
  r.noise = {n.gyro_noise_density, n.gyro_random_walk, n.accel_noise_density, n.accel_random_walk};
  NullObserver obs;
  ekf::run_filter(d.imu, images, opt, r.noise, d.manifest.camera->T_I_C, obs, &r.rec);
  for (const auto& im : images) r.image_times.push_back(im.t_ns);
  return r;
}

/// ekf::smooth's IMU-rate means (from the segment's two ends, issue 41) against the textbook RTS, and the
/// covariance asked for only at the image times against the covariance at every step.
void check_means_and_sparse_covariance(const Recorded& r, double max_dcov_sparse_rel = 5e-8) {
  const ekf::SmootherResult full = ekf::smooth(r.rec, r.noise, {1});
  const ekf::SmootherResult sparse = ekf::smooth(r.rec, r.noise, {2, &r.image_times});
  const std::vector<ekf::SmoothedState> ref = dense_rts(r.rec, r.noise);
  REQUIRE(full.states.size() == ref.size());
  REQUIRE(sparse.states.size() == ref.size());
  double max_dp = 0, max_dv = 0, max_dth = 0, max_dsig = 0, max_dsig_sparse = 0, max_dcov_sparse = 0;
  std::size_t with_cov = 0;
  for (std::size_t k = 0; k < ref.size(); ++k) {
    const auto &a = full.states[k], &s = sparse.states[k], &e = ref[k];
    REQUIRE(a.t_ns == e.t_ns);
    // Relative to the size of the quantity (at least 1 m, 1 m/s).
    max_dp = std::max(max_dp, (a.x.p_W_I - e.x.p_W_I).norm() / std::max(1.0, e.x.p_W_I.norm()));
    max_dv = std::max(max_dv, (a.x.v_W_I - e.x.v_W_I).norm() / std::max(1.0, e.x.v_W_I.norm()));
    max_dth = std::max(max_dth, rot_diff(a.x.q_W_I, e.x.q_W_I));
    max_dsig = std::max(max_dsig, ((a.sigma - e.sigma).array().abs() / (e.sigma.array() + 1e-12)).maxCoeff());
    // The mean does not depend on where the covariance is asked for, bit for bit.
    REQUIRE(s.t_ns == a.t_ns);
    REQUIRE(s.x.p_W_I == a.x.p_W_I);
    REQUIRE(s.x.v_W_I == a.x.v_W_I);
    REQUIRE(s.x.q_W_I.coeffs() == a.x.q_W_I.coeffs());
    REQUIRE(s.x.b_g == a.x.b_g);
    REQUIRE(s.x.b_a == a.x.b_a);
    const bool asked =
        k == 0 || std::binary_search(r.image_times.begin(), r.image_times.end(), a.t_ns);
    if (asked) {
      ++with_cov;
      // At a segment's end (an update's time) the sparse pass takes P_s,b of the backward pass instead of
      // P_cc(b) + G_b M G_bᵀ (the same matrix in exact arithmetic, smoother.cpp), and skips M: round-off.
      REQUIRE(s.sigma.allFinite());
      max_dsig_sparse =
          std::max(max_dsig_sparse, ((s.sigma - a.sigma).array().abs() / (a.sigma.array() + 1e-300)).maxCoeff());
      max_dcov_sparse = std::max(max_dcov_sparse, (s.pose_cov - a.pose_cov).norm() / a.pose_cov.norm());
    } else {
      REQUIRE(s.sigma.array().isNaN().all());
      REQUIRE(s.pose_cov.array().isNaN().all());
    }
  }
  INFO("position " << max_dp << " rel, velocity " << max_dv << " rel, rotation " << max_dth << " rad, sigma "
                   << max_dsig << " rel; " << with_cov << " of " << ref.size() << " rows with a covariance; the "
                   << "sparse pass's sigma " << max_dsig_sparse << " rel, pose covariance " << max_dcov_sparse
                   << " rel from the all-steps pass");
  // The sparse pass's covariance at a segment's end is the backward recursion's own P_s,b; the all-steps pass
  // re-forms it as P_cc(b) + G_b M G_bᵀ through P_b⁻⁻¹ (entries up to 10⁶ times the gyro bias variance), whose
  // round-off is what differs. Measured (2026-12-03): paper-seq4 8 s σ 1.5e-9, pose covariance 1.2e-9
  // relative; EuRoC snippet σ 1.7e-7 (gyro bias; 2.9e-8 in p, v, θ), pose covariance 7.5e-9 relative.
  CHECK(max_dsig_sparse < 1e-6);
  CHECK(max_dcov_sparse < max_dcov_sparse_rel);
  CHECK(with_cov > r.image_times.size() / 2);
  CHECK(with_cov < ref.size() / 4);
  CHECK(max_dp < 1e-9);
  CHECK(max_dv < 1e-9);
  CHECK(max_dth < 1e-9);
  // σ: the textbook pass's own inversions of n x n covariances at every step (2e-9 relative measured on
  // "matched" 4 s, 2.3e-6 on the EuRoC snippet's 40 s); the σ path itself is the one of issue 24, and the
  // covariance at an asked time is compared with the all-steps pass above. Measured on the EuRoC snippet
  // (2026-12-03): position 7.0e-13, velocity 4.4e-13 relative, rotation 3.1e-14 rad.
  CHECK(max_dsig < 1e-5);
}

}  // namespace

TEST_CASE("smoother: IMU-rate means from the segment ends equal the textbook RTS on paper-seq4, covariance only where asked",
          "[ekf][smoother]") {
  const Dataset d = test::simulate_preset("paper-seq4", 1, 8.0);
  const Recorded r = record(d, matched_config("rts").filter);
  REQUIRE(r.rec.steps.size() > 1500);
  check_means_and_sparse_covariance(r);
}

TEST_CASE("smoother: IMU-rate means from the segment ends equal the textbook RTS on the EuRoC snippet",
          "[ekf][smoother][euroc]") {
  const auto snippet = test::euroc_snippet_with_objects();
  if (!snippet) {
    WARN("skipped: the EuRoC snippet is absent");
    return;
  }
  const Dataset& d = *snippet;
  // roe run's built-in filter (camera-frame residual, split gate, learned σ scale) without the re-lock: its
  // covariance inflation enters the segment's Q in ekf::smooth (filter.cpp, relock_lost_position), which the
  // textbook pass above does not model.
  ekf::FilterOptions opt = app::RunConfig{}.filter;
  opt.relock_after_s = 0.0;
  const Recorded r = record(d, opt);
  REQUIRE(r.rec.steps.size() > 5000);
  check_means_and_sparse_covariance(r);
}

// The Gauss–Markov detection-error states (docs/filter.md §17) decay between an object's detections: the
// recording holds each decay as a link y = diag(b) u + w without its covariance, and ekf::smooth must equal the
// textbook RTS of the augmented model (full matrices, an explicit solve per link) on a preset whose errors are
// correlated in time.
TEST_CASE("smoother: with Gauss-Markov detection-error states equals the textbook RTS over the decay links",
          "[ekf][smoother][gauss_markov]") {
  const Dataset d = test::simulate_preset("paper-real-seq1", 2, 6.0);
  ekf::FilterOptions opt = app::RunConfig{}.filter;
  opt.relock_after_s = 0.0;  // its inflation is not modelled by the textbook pass (see the EuRoC case)
  opt.detection_error_states = true;
  opt.detection_error_correlation_s = 3.0;
  const Recorded r = record(d, opt);
  std::size_t decays = 0;
  for (const auto& nd : r.rec.nodes) {
    if (nd.kind != ekf::RecordedNode::Kind::kDecay) continue;
    ++decays;
    CHECK(nd.P.size() == 0);
    CHECK((nd.decay.array() < 1.0).count() % 6 == 0);
  }
  INFO(decays << " decay links");
  CHECK(decays > 100);
  for (const auto& o : r.rec.nodes.back().x.objects) CHECK(o.err_offset >= 0);
  // The sparse pass re-forms nothing through the decay links (both passes take them alike); its pose covariance
  // differs from the all-steps pass's by the round-off of the larger state (measured 1.0e-7 relative, 2026-12-07).
  check_means_and_sparse_covariance(r, 5e-7);
}

namespace {

/// A spill of its own (a string), counting what goes through it.
struct CountingSpill : ekf::RecordingSpill {
  std::string bytes;
  mutable std::size_t reads = 0;
  std::uint64_t append(const void* data, std::size_t n) override {
    const std::uint64_t at = bytes.size();
    bytes.append(static_cast<const char*>(data), n);
    return at;
  }
  void read(std::uint64_t offset, void* data, std::size_t n) const override {
    REQUIRE(offset + n <= bytes.size());
    std::memcpy(data, bytes.data() + offset, n);
    ++reads;
  }
};

/// The segments as a sink receives them.
struct Segments : ekf::SmoothedStates {
  std::vector<std::vector<ekf::SmoothedState>> got;
  void segment(const std::vector<ekf::SmoothedState>& states) override { got.push_back(states); }
};

bool same_state(const ekf::SmoothedState& a, const ekf::SmoothedState& b) {
  const auto same = [](const auto& x, const auto& y) {  // bit for bit, nan included
    return std::memcmp(x.data(), y.data(), sizeof(double) * static_cast<std::size_t>(x.size())) == 0;
  };
  return a.t_ns == b.t_ns && same(a.x.p_W_I, b.x.p_W_I) && same(a.x.v_W_I, b.x.v_W_I) &&
         same(a.x.q_W_I.coeffs(), b.x.q_W_I.coeffs()) && same(a.x.b_g, b.x.b_g) && same(a.x.b_a, b.x.b_a) &&
         same(a.T_I_C.p, b.T_I_C.p) && same(a.T_I_C.q.coeffs(), b.T_I_C.q.coeffs()) && same(a.sigma, b.sigma) &&
         same(a.pose_cov, b.pose_cov);
}

}  // namespace

// roe run smooths an hour of a 400 Hz IMU without holding it (issue 53): the recording goes through a spill
// (a temporary file there) and the smoothed states to a sink as the backward pass produces them.
TEST_CASE("smoother: through any spill and to a sink, segment by segment from the last, the same states bit for bit",
          "[ekf][smoother][spill]") {
  const Dataset d = test::simulate_preset("paper-seq4", 1, 8.0);  // the anchor's first sight after the start
  const auto images = ekf::group_images(d.detections.at("sim"));
  const ekf::FilterOptions opt = matched_config("rts").filter;
  const auto& n = d.manifest.imu->noise;
  const ekf::ImuNoiseParams noise{n.gyro_noise_density, n.gyro_random_walk, n.accel_noise_density, n.accel_random_walk};
  NullObserver obs;
  ekf::FilterRecording in_memory;
  ekf::run_filter(d.imu, images, opt, noise, d.manifest.camera->T_I_C, obs, &in_memory);
  CountingSpill spill;
  ekf::FilterRecording spilled(&spill);
  ekf::run_filter(d.imu, images, opt, noise, d.manifest.camera->T_I_C, obs, &spilled);
  REQUIRE(spilled.steps.size() == in_memory.steps.size());
  REQUIRE(spilled.steps.size() > ekf::StepLog::kChunk + 500);  // whole chunks in the spill, and a tail
  // The steps (63 doubles each) and every dense covariance are in the spill, not in the recording.
  std::size_t covariances = 0;
  for (const auto& nd : spilled.nodes) covariances += static_cast<std::size_t>(nd.P.size());
  CHECK(spill.bytes.size() >= 8 * (63 * (spilled.steps.size() - ekf::StepLog::kChunk) + covariances -
                                   static_cast<std::size_t>(spilled.nodes.back().P.size())));
  // Read back as recorded: a step and a node.
  const std::size_t mid = spilled.steps.size() / 2;
  CHECK(spilled.steps[mid].t_ns == spilled.steps.time(mid));
  CHECK(spilled.steps[mid].F.dense() == in_memory.steps[mid].F.dense());
  CHECK(spilled.nodes[5].P == in_memory.nodes[5].P);

  const ekf::SmootherResult ref = ekf::smooth(in_memory, noise, {1});
  CHECK(ref.gauge_shift.p.norm() > 0.0);  // the states before the anchor's first sight moved
  for (const unsigned threads : {1u, 2u}) {
    INFO(threads << " thread(s)");
    Segments seg;
    spill.reads = 0;
    const Pose shift = ekf::smooth(spilled, noise, seg, {threads});
    CHECK(spill.reads > 0);
    CHECK(shift.p == ref.gauge_shift.p);
    REQUIRE(seg.got.size() > 100);
    CHECK(seg.got.back().size() == 1);  // the initial state, last
    std::vector<ekf::SmoothedState> all;
    for (std::size_t k = seg.got.size(); k-- > 0;) {
      REQUIRE_FALSE(seg.got[k].empty());
      for (std::size_t i = 1; i < seg.got[k].size(); ++i) REQUIRE(seg.got[k][i - 1].t_ns < seg.got[k][i].t_ns);
      if (k + 1 < seg.got.size()) REQUIRE(seg.got[k + 1].back().t_ns < seg.got[k].front().t_ns);  // from the last
      all.insert(all.end(), seg.got[k].begin(), seg.got[k].end());
    }
    REQUIRE(all.size() == ref.states.size());
    std::size_t differ = 0;
    for (std::size_t k = 0; k < all.size(); ++k) differ += same_state(all[k], ref.states[k]) ? 0 : 1;
    CHECK(differ == 0);
  }
}
