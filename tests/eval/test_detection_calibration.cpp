// Detection uncertainty calibration (eval/detection_calibration.hpp): known σ scales recovered from
// detections simulated in memory by the simulator's PoET error model, reference values from scipy.
#include <catch2/catch.hpp>
#include <cmath>

#include "roe/core/error.hpp"
#include "roe/eval/detection_calibration.hpp"
#include "roe/math/so3.hpp"
#include "support/scaled_sigma_detections.hpp"

using namespace roe;

namespace {

// scipy 1.10.1 (Debian bookworm python3-scipy): stats.chi2.cdf([1, 4, 9], 1) and stats.chi2.ppf(p, 6).
constexpr double kWithin[3] = {0.6826894921370859, 0.9544997361036415, 0.9973002039367398};
// stats.chi2.cdf(np.array([1, 4, 9]) / s**2, 1) for s = 2 and s = 0.5: the fractions when the true
// errors are s times the reported σ.
constexpr double kWithinS2[3] = {0.3829249225480261, 0.6826894921370859, 0.8663855974622842};
constexpr double kWithinS05[3] = {0.9544997361036415, 0.9999366575163338, 0.9999999980268247};
constexpr double kChi26Ppf[5] = {1.6353828943279067, 3.4545988357210384, 5.348120627447118, 7.840804120585122,
                                 12.591587243743977};

/// A ground-truth trajectory (circle, 100 Hz, 60 s), camera looking at the centre, objects near it.
eval::DetectionTruth make_truth() {
  eval::DetectionTruth t;
  for (int k = 0; k <= 6000; ++k) {
    const double a = 0.01 * k * 0.2;
    const Eigen::Vector3d p(2.0 * std::cos(a), 2.0 * std::sin(a), 1.0 + 0.2 * std::sin(3 * a));
    // IMU x axis towards the centre (the camera, T_I_C below, looks along the IMU x axis).
    const Eigen::Vector3d x = (-p).normalized(), z = Eigen::Vector3d::UnitZ().cross(x).normalized();
    Eigen::Matrix3d R;
    R << x, z.cross(x), z;
    t.T_W_I.push_back({from_seconds(0.01 * k), Pose(Eigen::Quaterniond(R), p)});
  }
  Eigen::Matrix3d R_I_C;  // camera z (optical axis) = IMU x
  R_I_C << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  t.T_I_C = Pose(Eigen::Quaterniond(R_I_C), Eigen::Vector3d(0.05, 0.01, -0.02));
  t.T_W_O[1] = Pose(Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized())),
                    Eigen::Vector3d(0.1, -0.1, 0.9));
  t.T_W_O[4] = Pose(Eigen::Quaterniond(Eigen::AngleAxisd(-1.1, Eigen::Vector3d(0, 1, 1).normalized())),
                    Eigen::Vector3d(-0.2, 0.1, 1.2));
  return t;
}

/// Detections at 10 Hz of both objects with the simulator's Gaussian errors (camera axes, no outliers,
/// white) and reported σ = the true σ / scale, i.e. errors drawn with σ_true = scale · σ_reported.
std::vector<Detection> simulate(const eval::DetectionTruth& truth, double scale, std::uint64_t seed, double offset_s = 0.0) {
  test::ScaledSigmaDetector detect(scale, seed);
  std::vector<Detection> out;
  for (std::size_t k = 10; k + 10 < truth.T_W_I.size(); k += 10) {
    for (const auto& [id, T_W_O] : truth.T_W_O) {
      const Pose T_C_O = eval::true_T_C_O(truth.T_W_I[k].T, truth.T_I_C, T_W_O);
      out.push_back(detect(truth.T_W_I[k].t_ns - from_seconds(offset_s), id, T_C_O));
    }
  }
  return out;
}

}  // namespace

TEST_CASE("true T_C_O and the detection error follow the sigma columns' convention", "[detection_calibration]") {
  const Pose T_W_I(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())), Eigen::Vector3d(1, 2, 3));
  const Pose T_I_C(Eigen::Quaterniond(Eigen::AngleAxisd(-0.5, Eigen::Vector3d::UnitX())), Eigen::Vector3d(0.1, 0, 0));
  const Pose T_W_O(Eigen::Quaterniond::Identity(), Eigen::Vector3d(2, 2, 3));
  const Pose T = eval::true_T_C_O(T_W_I, T_I_C, T_W_O);
  // x_W of the object origin, mapped back through the camera pose, is T.p.
  const Eigen::Vector3d p_W_C = T_W_I.p + T_W_I.R() * T_I_C.p;
  const Eigen::Matrix3d R_W_C = T_W_I.R() * T_I_C.R();
  CHECK((T.p - R_W_C.transpose() * (T_W_O.p - p_W_C)).norm() < 1e-12);
  CHECK((T.R() - R_W_C.transpose()).norm() < 1e-12);
  // t_meas = t + n_t, R_meas = Exp(n_r) R → e = (n_t, n_r).
  const Eigen::Vector3d n_t(0.01, -0.02, 0.03), n_r(0.02, 0.01, -0.04);
  const Pose meas(Eigen::Quaterniond(math::exp_so3(n_r) * T.R()), T.p + n_t);
  const Vector6d e = eval::detection_error(meas, T);
  CHECK((e.head<3>() - n_t).norm() < 1e-12);
  CHECK((e.tail<3>() - n_r).norm() < 1e-12);
}

TEST_CASE("reference values are scipy's chi2", "[detection_calibration]") {
  for (int k = 0; k < 3; ++k) CHECK(eval::expected_within()[static_cast<std::size_t>(k)] == Approx(kWithin[k]).epsilon(1e-10));
  for (int k = 0; k < 5; ++k)
    CHECK(eval::chi2_6_quantiles()[static_cast<std::size_t>(k)] == Approx(kChi26Ppf[k]).epsilon(1e-9));
  CHECK(eval::nis_gate() == Approx(kChi26Ppf[4]).epsilon(1e-9));
}

TEST_CASE("quantiles, KS distance and scales of a small NIS sample match numpy/scipy", "[detection_calibration]") {
  // NIS 0.5, 1.7, ... (z on one axis, σ = 1); numpy.quantile (linear) and scipy.stats.kstest(nis, 'chi2', (6,))
  // (numpy 1.24.2, scipy 1.10.1).
  const double nis[8] = {0.5, 1.7, 3.2, 4.4, 5.9, 7.3, 9.8, 14.1};
  std::vector<eval::DetectionResidual> rs;
  for (double v : nis) {
    eval::DetectionResidual r;
    r.error[0] = std::sqrt(v);
    r.sigma.setOnes();
    rs.push_back(r);
  }
  const eval::SigmaCalibration c = eval::calibrate(rs);
  CHECK(c.n == 8);
  CHECK(c.nis_mean == Approx(46.9 / 8));
  const double q[5] = {0.92, 2.825, 5.15, 7.925, 12.594999999999997};
  for (int k = 0; k < 5; ++k) CHECK(c.nis_quantiles[static_cast<std::size_t>(k)] == Approx(q[k]).epsilon(1e-12));
  CHECK(c.ks_statistic == Approx(0.19512126827162185).epsilon(1e-9));
  // scipy.stats.kstwobign.sf((sqrt(8) + 0.12 + 0.11 / sqrt(8)) * D): Stephens' finite-n form of Kolmogorov's limit.
  CHECK(c.ks_p_value == Approx(0.8860959176645062).epsilon(1e-6));
  CHECK(c.frac_above_gate == Approx(1.0 / 8));  // 14.1 > 12.59
  CHECK(c.sigma_scale == Approx(std::sqrt(46.9 / 48)));
  CHECK(c.sigma_scale_t == Approx(std::sqrt(46.9 / 24)));
  CHECK(c.sigma_scale_r == 0.0);
  CHECK(c.sigma_scale_median == Approx(std::sqrt(5.15 / kChi26Ppf[2])));
  // |z| = √NIS on one translation axis, 0 on the other five.
  CHECK(c.within_t[0] == Approx((1.0 + 16.0) / 24));  // NIS 0.5 on x, and the zero y and z axes of all eight
}

TEST_CASE("a simulated σ scale of 0.5 and 2.0 is recovered within 20 %, the fractions are scipy's", "[detection_calibration]") {
  const eval::DetectionTruth truth = make_truth();
  std::uint64_t seed = 7;
  for (const auto& [scale, within] : {std::pair{1.0, kWithin}, std::pair{0.5, kWithinS05}, std::pair{2.0, kWithinS2}}) {
    INFO("scale " << scale);
    const auto dets = simulate(truth, scale, seed++);  // independent draws per scale
    const eval::DetectionCalibration cal = eval::calibrate_detection_sigmas(dets, truth);
    REQUIRE(cal.all.n == dets.size());  // 1198: every detection compared
    const auto& a = cal.all;
    CHECK(std::abs(a.sigma_scale / scale - 1.0) < 0.2);   // the criterion
    CHECK(std::abs(a.sigma_scale / scale - 1.0) < 0.03);  // what 7188 normalised errors give
    CHECK(a.sigma_scale_lo < scale);
    CHECK(a.sigma_scale_hi > scale);
    CHECK(std::abs(a.sigma_scale_t / scale - 1.0) < 0.05);
    CHECK(std::abs(a.sigma_scale_r / scale - 1.0) < 0.05);
    CHECK(std::abs(a.sigma_scale_median / scale - 1.0) < 0.1);
    CHECK(a.nis_mean == Approx(6.0 * scale * scale).epsilon(0.06));
    for (std::size_t k = 0; k < 3; ++k) {
      CHECK(a.within_t[k] == Approx(within[k]).margin(0.02));
      CHECK(a.within_r[k] == Approx(within[k]).margin(0.02));
    }
    REQUIRE(cal.objects.size() == 2);
    for (const auto& o : cal.objects) CHECK(std::abs(o.cal.sigma_scale / scale - 1.0) < 0.2);
    if (scale == 1.0) {
      CHECK(a.ks_p_value > 0.01);
      CHECK(a.frac_above_gate == Approx(0.05).margin(0.02));
    } else {
      CHECK(a.ks_p_value < 1e-6);
    }
  }
}

TEST_CASE("detections without sigma, truth or time are counted and named, camera offset applied", "[detection_calibration]") {
  eval::DetectionTruth truth = make_truth();
  truth.camera_time_offset_s = 2.0;
  auto dets = simulate(truth, 1.0, 3, 2.0);  // camera stamps 2 s behind the IMU clock
  dets[0].sigma.reset();
  dets[1].object_id = 9;  // no true pose
  dets[2].t_ns = from_seconds(500.0);  // after the ground truth
  eval::DetectionCalibration cal = eval::calibrate_detection_sigmas(dets, truth);
  CHECK(cal.n_without_sigma == 1);
  CHECK(cal.n_without_object_truth == 1);
  CHECK(cal.n_outside_truth == 1);
  CHECK(cal.all.n == dets.size() - 3);
  CHECK(cal.warnings.size() == 3);
  CHECK(std::abs(cal.all.sigma_scale - 1.0) < 0.05);  // the offset was applied: errors stay at σ
  // Without the offset the truth is 2 s (0.4 rad of the circle) off: the errors include the motion.
  truth.camera_time_offset_s = 0.0;
  cal = eval::calibrate_detection_sigmas(dets, truth);
  CHECK(cal.n_outside_truth > 10);  // the first 2 s of camera stamps precede the ground truth
  CHECK(cal.all.sigma_scale > 1.5);
  // Nothing to compare: an InputError that says why.
  for (auto& d : dets) d.sigma.reset();
  CHECK_THROWS_WITH(eval::calibrate_detection_sigmas(dets, truth), Catch::Contains("carries sigmas"));
}
