// The Gauss–Markov detection-error states (FilterOptions::detection_error_states, docs/filter.md §17): the
// error model at one detection (its stationary covariance, the factors' axes, the simulator's conventions) and
// the filter's consistency on a preset whose detection errors are correlated in time and drawn from the σ the
// detections carry (`matched-correlated`: `matched` with τ = 1 s), against the white model on the same runs.
#include <catch2/catch.hpp>
#include <random>

#include "filter_support.hpp"
#include "roe/ekf/measurement.hpp"
#include "roe/math/so3.hpp"

using namespace roe;
using ekf::Mat3;
using ekf::Mat6;
using ekf::Vec3;
using ekf::Vec6;

TEST_CASE("Gauss-Markov error model: stationary covariance s Sigma_C, rotation factors on the object's axes",
          "[ekf][gauss_markov]") {
  std::mt19937_64 g(7);
  std::normal_distribution<double> N(0.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    const Pose T_C_O(math::exp_quat(Vec3(N(g), N(g), N(g))), Vec3(0.2 * N(g), 0.2 * N(g), 1.0 + std::abs(N(g))));
    // A ray-aligned translation covariance (the filter's depth model) and an isotropic rotation σ.
    const double s_lat = 0.03, s_ray = 0.12, s_rot = 0.1;
    const Vec3 u = T_C_O.p.normalized();
    Mat6 cov_C = Mat6::Zero();
    cov_C.topLeftCorner<3, 3>() = s_lat * s_lat * Mat3::Identity() + (s_ray * s_ray - s_lat * s_lat) * u * u.transpose();
    cov_C.bottomRightCorner<3, 3>() = s_rot * s_rot * Mat3::Identity();
    const double share = 0.7;
    const Mat6 G = ekf::gauss_markov_error_jacobian(cov_C, T_C_O.R(), share);
    // Stationary covariance of G x, x ~ N(0, I): the correlated share of Σ_C, whatever the object's attitude.
    CHECK((G * G.transpose() - share * cov_C).cwiseAbs().maxCoeff() < 1e-12);
    // The simulator's rotation error R_C_O Exp(δθ) with δθ = σ x_θ on the object's axes is, in the camera
    // residual (left error, camera axes), R_C_O δθ: G's rotation block times x_θ, up to √s.
    const Vec3 x_th(N(g), N(g), N(g));
    const Eigen::Quaterniond q_meas = T_C_O.q * math::exp_quat(1e-4 * s_rot * x_th);
    const Vec3 left = math::log_quat(q_meas * T_C_O.q.conjugate());
    CHECK((left - 1e-4 * G.bottomRightCorner<3, 3>() * x_th / std::sqrt(share)).norm() < 1e-10);
    CHECK(G.topRightCorner<3, 3>().cwiseAbs().maxCoeff() < 1e-12);  // translation and rotation factors apart
    CHECK(G.bottomLeftCorner<3, 3>().cwiseAbs().maxCoeff() < 1e-12);
  }
}

namespace {

void with_error_states(app::RunConfig& cfg) {
  cfg.filter.detection_error_states = true;
  cfg.filter.detection_error_correlation_s = 1.0;  // the preset's τ
  cfg.filter.detection_error_correlated_share = 0.95;
}

}  // namespace

// Consistency of the IMU pose with correlated detection errors (configured σ = simulated σ, τ the simulated
// one), filter and smoother, against the white model on the same runs. Measured (2026-12-07, 8 runs × 20 s):
// time-averaged NEES 16.6 (filter) and 17.7 (smoother) with the error states, 124 with the white model, two-sided
// 95 % bounds [3.8, 8.6]: the error states remove most of the white model's overconfidence but not all of it
// (docs/filter.md §17: what is left is not explained; what was ruled out is listed there). The test holds what is established: the
// error states bring the NEES within a factor 3 of the bound where the white model is 14 times over it, and
// the smoother improves on the filter.
TEST_CASE("matched-correlated Monte-Carlo: Gauss-Markov error states remove most of the white model's overconfidence",
          "[ekf][gauss_markov][sim][mc]") {
  const int N = 8;
  const test::MonteCarlo gm = test::monte_carlo("matched-correlated", N, 20.0, 3.0, "none", with_error_states);
  const test::MonteCarlo gm_s = test::monte_carlo("matched-correlated", N, 20.0, 3.0, "rts", with_error_states);
  const test::MonteCarlo white = test::monte_carlo("matched-correlated", N, 20.0, 3.0, "rts");
  WARN("matched-correlated: error states filter NEES " << gm.anees << ", smoother " << gm_s.anees << " (bounds "
                                                       << gm.lo << ", " << gm.hi << "), position RMS " << gm.pos_rms_m
                                                       << " / " << gm_s.pos_rms_m << " m; white smoother NEES "
                                                       << white.anees << ", position RMS " << white.pos_rms_m << " m");
  CHECK(white.anees > 10.0 * white.hi);
  CHECK(gm.anees > gm.lo);
  CHECK(gm.anees < 3.0 * gm.hi);
  CHECK(gm_s.anees < 3.0 * gm_s.hi);
  CHECK(gm_s.anees < 0.25 * white.anees);
  CHECK(gm_s.pos_rms_m < gm.pos_rms_m);
}

// The online σ scale of §14 (adapt_detection_sigma_scale, on in configs/default.json) learns from the NIS, which
// with the error states runs below χ² even when the σ are right; learnt, it shrank every σ (and G with it) and
// made the states overconfident (scale 0.6 and object NEES 80–280 on a clean paper-real replica, docs/filter.md
// §17). With the states the scale is not learnt: the same runs as above, with the scale asked for, keep scale 1
// and the NEES of the runs without it.
TEST_CASE("Gauss-Markov error states: the online sigma scale is not learnt from their NIS",
          "[ekf][gauss_markov][sim][mc]") {
  const int N = 8;
  const test::MonteCarlo plain = test::monte_carlo("matched-correlated", N, 20.0, 3.0, "none", with_error_states);
  const test::MonteCarlo asked = test::monte_carlo("matched-correlated", N, 20.0, 3.0, "none", [](app::RunConfig& c) {
    with_error_states(c);
    c.filter.adapt_detection_sigma_scale = true;
  });
  WARN("matched-correlated, error states: NEES " << plain.anees << " without the scale, " << asked.anees
                                                 << " with it asked for (mean scale " << asked.sigma_scale_sum / N << ")");
  CHECK(asked.sigma_scale_sum / N == Approx(1.0));
  CHECK(asked.anees == Approx(plain.anees));
}
