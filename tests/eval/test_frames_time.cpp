// Frames and time between two trajectories (issue 50): --t-offset auto (eval/time_offset.hpp), the body
// pose given or fitted (eval/body_pose.hpp), the crop and alignment windows, --assoc interpolate and the
// alignment's tilt, on the real EuRoC V1_02 pair of ../shared/data/eval (evo's test data: ground truth at
// 200 Hz and a real estimate; skipped when absent) and on synthetic tracks.
#include <catch2/catch.hpp>
#include <filesystem>
#include <random>

#include "roe/core/error.hpp"
#include "roe/eval/body_pose.hpp"
#include "roe/eval/evaluate.hpp"
#include "roe/eval/time_offset.hpp"
#include "roe/io/trajectory_io.hpp"
#include "roe/math/rate_correlation.hpp"
#include "roe/math/so3.hpp"

using namespace roe;
using namespace roe::eval;
namespace fs = std::filesystem;

namespace {

struct Pair {
  io::Trajectory gt, est;
};

/// evo's EuRoC V1_02 pair (ground truth and a real estimate), or nullopt when ../shared is absent.
std::optional<Pair> v102() {
  const fs::path data = fs::path(ROE_SHARED_DATA_DIR) / "eval";
  if (!fs::exists(data / "V102.txt")) return std::nullopt;
  return Pair{io::read_trajectory(data / "V102_groundtruth.csv"), io::read_trajectory(data / "V102.txt")};
}

Report run(const std::vector<Timestamp>& et, const std::vector<Pose>& ep, const std::vector<Timestamp>& gt_t,
           const std::vector<Pose>& gp, const EvalParams& p) {
  static const std::vector<std::optional<PoseCovariance>> no_cov;
  return evaluate({et, ep, no_cov, nullptr, "est"}, {gt_t, gp}, p);
}

bool has_warning(const Report& r, const std::string& what) {
  for (const auto& w : r.warnings)
    if (w.find(what) != std::string::npos) return true;
  return false;
}

std::vector<Timestamp> shifted(std::vector<Timestamp> t, double s) {
  for (auto& x : t) x += from_seconds(s);
  return t;
}

}  // namespace

TEST_CASE("t-offset auto recovers a 0.2 s shift of a real EuRoC estimate and its APE", "[eval][offset][real]") {
  const auto d = v102();
  if (!d) {
    WARN("skipped: ../shared/data/eval/V102.txt is absent");
    return;
  }
  EvalParams p;
  const Report clean = run(d->est.t_ns, d->est.poses, d->gt.t_ns, d->gt.poses, p);
  CHECK_FALSE(has_warning(clean, "look time-shifted"));
  p.auto_offset = true;
  const Report clean_auto = run(d->est.t_ns, d->est.poses, d->gt.t_ns, d->gt.poses, p);
  REQUIRE(clean_auto.time_offset);
  const double tau0 = clean_auto.time_offset->offset_s;
  CHECK(std::abs(tau0) < 0.005);  // the pair shares one clock
  CHECK(std::abs(tau0) < 3.0 * clean_auto.time_offset->sigma_s);
  // The estimate's stamps moved 0.2 s early: t_gt = t_est' + 0.2.
  const std::vector<Timestamp> early = shifted(d->est.t_ns, -0.2);
  EvalParams p0;
  const Report bad = run(early, d->est.poses, d->gt.t_ns, d->gt.poses, p0);
  CHECK(bad.ape.trans_m.rmse > 1.1 * clean.ape.trans_m.rmse);
  CHECK(has_warning(bad, "look time-shifted"));
  CHECK(has_warning(bad, "--t-offset auto"));
  const Report fixed = run(early, d->est.poses, d->gt.t_ns, d->gt.poses, p);
  REQUIRE(fixed.time_offset);
  const TrajectoryOffset& o = *fixed.time_offset;
  INFO("offset " << o.offset_s << " sigma " << o.sigma_s << " coarse " << o.coarse_offset_s);
  CHECK(o.refined);
  CHECK(std::abs(o.offset_s - 0.2) < 0.005);
  CHECK(std::abs(o.offset_s - 0.2 - tau0) < 0.001);
  CHECK(std::isfinite(o.sigma_s));
  CHECK(o.sigma_s > 0);
  CHECK(fixed.params.assoc.offset_s == o.offset_s);
  CHECK(std::abs(fixed.ape.trans_m.rmse / clean.ape.trans_m.rmse - 1.0) < 0.01);
  CHECK(std::abs(fixed.ape.rot_deg.rmse / clean.ape.rot_deg.rmse - 1.0) < 0.01);
  // Late by 0.35 s works the same way.
  const Report late = run(shifted(d->est.t_ns, 0.35), d->est.poses, d->gt.t_ns, d->gt.poses, p);
  CHECK(std::abs(late.time_offset->offset_s + 0.35 - tau0) < 0.001);
}

TEST_CASE("t-offset auto: sigma against the truth over seeds (NEES)", "[eval][offset][nees]") {
  // A smooth 3-D motion at 200 Hz (the truth) and a 20 Hz estimate of it with correlated (AR(1)) position and
  // orientation errors and an offset; ((tau - truth) / sigma)^2 averages 1 for an honest sigma.
  const auto truth_at = [](double t) {
    const Eigen::Vector3d p(2 * std::sin(0.5 * t), 1.5 * std::sin(0.8 * t + 1), 0.5 * std::sin(1.3 * t));
    const Eigen::Vector3d w(0.4 * std::sin(0.7 * t), 0.3 * std::cos(0.9 * t), 1.1 * std::sin(0.35 * t));
    return Pose(math::exp_quat(w), p);
  };
  std::vector<Timestamp> gt_t;
  std::vector<Pose> gt;
  for (int i = 0; i <= 60 * 200; ++i) gt_t.push_back(i * 5'000'000LL), gt.push_back(truth_at(i * 0.005));
  double nees = 0.0;
  const int seeds = 30;
  for (int seed = 0; seed < seeds; ++seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> n01(0.0, 1.0);
    const double true_offset = 0.1 + 0.01 * seed;
    std::vector<Timestamp> et;
    std::vector<Pose> ep;
    Eigen::Vector3d drift = Eigen::Vector3d::Zero(), tilt = Eigen::Vector3d::Zero();
    for (int k = 20; k < 55 * 20; ++k) {
      const double t = k * 0.05;
      drift = 0.9 * drift + 0.01 * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
      tilt = 0.9 * tilt + 0.002 * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));  // ~0.25 deg, correlated
      Pose x = truth_at(t);
      x.p += drift;
      x.q = (x.q * math::exp_quat(tilt)).normalized();
      et.push_back(from_seconds(t - true_offset)), ep.push_back(x);  // t_gt = t_est + offset
    }
    const TrajectoryOffset o = estimate_trajectory_offset(et, ep, gt_t, gt, AlignType::kSe3, 1.0);
    REQUIRE(o.refined);
    nees += std::pow((o.offset_s - true_offset) / o.sigma_s, 2);
  }
  nees /= seeds;
  INFO("mean NEES of the offset over " << seeds << " seeds: " << nees);
  // chi2(30)/30 two-sided 99 % bounds: [0.43, 1.79].
  CHECK(nees > 0.43);
  CHECK(nees < 1.79);
}

TEST_CASE("the rate correlator: one definition for mocap-IMU and estimate-GT offsets", "[eval][offset]") {
  // A rate signal and its copy 0.123 s later: the peak says so, the parabola refines below the grid.
  math::RateSignal a, b;
  for (int i = 0; i < 4000; ++i) {
    const double t = i * 0.005;
    a.t_s.push_back(t), a.value.push_back(1.0 + std::sin(1.7 * t) + 0.5 * std::sin(4.1 * t));
  }
  b = a;
  b.origin_ns = -123'000'000;  // b's clock reads 0.123 s less for the same instant: t_a = t_b + 0.123
  const math::RateCorrelation c = math::correlate_rates(a, b, 0.5, 0.005);
  CHECK(std::abs(c.offset_s - 0.123) < 0.002);
  CHECK(c.correlation > 0.99);
  CHECK_FALSE(c.peak_at_edge);
  math::RateSignal flat = a;
  std::fill(flat.value.begin(), flat.value.end(), 1.0);
  CHECK_THROWS_AS(math::correlate_rates(flat, b, 0.5, 0.005), DataError);
}

namespace {

/// The real ground truth seen through a mocap body B whose pose in the IMU is T_I_B: T_W_B = T_W_I·T_I_B.
std::vector<Pose> through_body(const std::vector<Pose>& T_W_I, const Pose& T_B_I) {
  std::vector<Pose> out;
  for (const Pose& x : T_W_I) out.push_back(x * T_B_I.inverse());
  return out;
}

}  // namespace

TEST_CASE("fit-body-pose recovers a 14 cm lever arm and a 5 deg rotation on real EuRoC data", "[eval][body][real]") {
  const auto d = v102();
  if (!d) {
    WARN("skipped: ../shared/data/eval/V102.txt is absent");
    return;
  }
  const Pose T_B_I(math::exp_quat(Eigen::Vector3d(0.03, -0.05, 0.06).normalized() * (5.0 * M_PI / 180.0)),
                   Eigen::Vector3d(0.10, -0.06, 0.08));  // |p| = 14.1 cm
  REQUIRE(std::abs(T_B_I.p.norm() - 0.14) < 0.002);
  const std::vector<Pose> gt_B = through_body(d->gt.poses, T_B_I);
  const auto rot_deg = [](const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
    return math::log_quat(a.conjugate() * b).norm() * 180.0 / M_PI;
  };
  EvalParams p;
  const Report clean = run(d->est.t_ns, d->est.poses, d->gt.t_ns, d->gt.poses, p);
  const Report body = run(d->est.t_ns, d->est.poses, d->gt.t_ns, gt_B, p);
  CHECK(body.ape.trans_m.rmse > 1.05 * clean.ape.trans_m.rmse);  // the lever arm shows, silently before
  SECTION("given exactly") {
    p.gt_body_pose = T_B_I;
    const Report given = run(d->est.t_ns, d->est.poses, d->gt.t_ns, gt_B, p);
    CHECK(given.ape.trans_m.rmse == Approx(clean.ape.trans_m.rmse).epsilon(1e-9));
    CHECK(given.ape.rot_deg.rmse == Approx(clean.ape.rot_deg.rmse).epsilon(1e-6));
  }
  SECTION("fitted on the real estimate: the injected pose on top of the estimate's own body") {
    // The real estimate's body is not exactly the ground truth's (Y0, fitted on the clean pair); the fit
    // against the moved ground truth must find T_B_I·Y0, and the APE of the clean fit.
    p.fit_body_pose = true;
    const Report fit0 = run(d->est.t_ns, d->est.poses, d->gt.t_ns, d->gt.poses, p);
    const Report fit = run(d->est.t_ns, d->est.poses, d->gt.t_ns, gt_B, p);
    REQUIRE(fit.body_pose);
    REQUIRE(fit0.body_pose);
    const Pose want = T_B_I * fit0.body_pose->T_B_I;
    INFO("Y0 " << fit0.body_pose->T_B_I.p.transpose() << ", fit " << fit.body_pose->T_B_I.p.transpose() << ", want "
               << want.p.transpose() << ", sigma " << fit.body_pose->sigma_p_m.transpose());
    CHECK(fit.body_pose->verdict == "observable");
    CHECK((fit.body_pose->T_B_I.p - want.p).norm() < 0.005);
    CHECK(rot_deg(fit.body_pose->T_B_I.q, want.q) < 0.3);
    CHECK(std::abs(fit.ape.trans_m.rmse / fit0.ape.trans_m.rmse - 1.0) < 0.01);
    CHECK(std::abs(fit.ape.rot_deg.rmse / fit0.ape.rot_deg.rmse - 1.0) < 0.01);
    CHECK(std::abs(fit.ape.trans_m.rmse / clean.ape.trans_m.rmse - 1.0) < 0.05);
  }
  SECTION("fitted on an estimate in the ground truth's own body: recovered absolutely") {
    // The real ground truth at 20 Hz with correlated position errors (AR(1) 0.95, 2 mm steps: 6 mm rms) and
    // 0.2 deg of orientation noise: the true body pose is T_B_I itself.
    std::mt19937 rng(5);
    std::normal_distribution<double> n01(0.0, 1.0);
    std::vector<Timestamp> et;
    std::vector<Pose> ep;
    Eigen::Vector3d drift = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < d->gt.size(); i += 10) {
      drift = 0.95 * drift + 0.002 * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
      Pose x = d->gt.poses[i];
      x.p += drift;
      x.q = (x.q * math::exp_quat(0.2 * M_PI / 180.0 * Eigen::Vector3d(n01(rng), n01(rng), n01(rng)))).normalized();
      et.push_back(d->gt.t_ns[i]), ep.push_back(x);
    }
    EvalParams q;
    const Report ref = run(et, ep, d->gt.t_ns, d->gt.poses, q);
    q.fit_body_pose = true;
    const Report fit = run(et, ep, d->gt.t_ns, gt_B, q);
    REQUIRE(fit.body_pose);
    const BodyPoseFit& f = *fit.body_pose;
    INFO("p " << f.T_B_I.p.transpose() << " sigma " << f.sigma_p_m.transpose() << " rot sigma " << f.sigma_rot_deg);
    CHECK((f.T_B_I.p - T_B_I.p).norm() < 0.005);
    CHECK(rot_deg(f.T_B_I.q, T_B_I.q) < 0.3);
    for (int i = 0; i < 3; ++i) CHECK(std::abs(f.T_B_I.p[i] - T_B_I.p[i]) < 4.0 * f.sigma_p_m[i]);
    CHECK(std::abs(fit.ape.trans_m.rmse / ref.ape.trans_m.rmse - 1.0) < 0.01);
    CHECK(std::abs(fit.ape.rot_deg.rmse / ref.ape.rot_deg.rmse - 1.0) < 0.05);
  }
}

TEST_CASE("fit-body-pose: a planar motion leaves the lever arm along the rotation axis unobservable", "[eval][body]") {
  // Yaw only: the lever arm's z (the axis it turns about) is a constant offset the alignment absorbs.
  std::vector<Timestamp> t;
  std::vector<Pose> truth;
  for (int i = 0; i < 2000; ++i) {
    const double s = i * 0.01;
    t.push_back(i * 10'000'000LL);
    truth.push_back(Pose(math::exp_quat(Eigen::Vector3d(0, 0, 0.8 * std::sin(0.6 * s))),
                         Eigen::Vector3d(std::cos(0.3 * s), std::sin(0.5 * s), 0.0)));
  }
  const Pose T_B_I(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.1, 0.05, 0.2));
  EvalParams p;
  p.fit_body_pose = true;
  const Report r = run(t, truth, t, through_body(truth, T_B_I), p);
  REQUIRE(r.body_pose);
  CHECK(r.body_pose->lever_arm_rank == 2);
  CHECK(r.body_pose->verdict.rfind("partly unobservable", 0) == 0);
  CHECK(std::abs(r.body_pose->T_B_I.p.x() - 0.1) < 1e-6);
  CHECK(std::abs(r.body_pose->T_B_I.p.y() - 0.05) < 1e-6);
  CHECK(std::abs(r.body_pose->T_B_I.p.z()) < 1e-9);  // min-norm: set to 0, not guessed
  CHECK(has_warning(r, "lever arm partly unobservable"));
  // No rotation at all: nothing observable.
  std::vector<Pose> still = truth;
  for (Pose& x : still) x.q = Eigen::Quaterniond::Identity();
  const Report n = run(t, still, t, through_body(still, T_B_I), p);
  CHECK(n.body_pose->lever_arm_rank == 0);
  CHECK(n.body_pose->verdict.rfind("unobservable", 0) == 0);
  // Bad combinations are usage errors.
  EvalParams both = p;
  both.gt_body_pose = T_B_I;
  CHECK_THROWS_AS(check_params(both), InputError);
  EvalParams origin = p;
  origin.align = AlignType::kOrigin;
  CHECK_THROWS_AS(check_params(origin), InputError);
}

TEST_CASE("parse_pose_text: x,y,z,qx,qy,qz,qw", "[eval][body]") {
  const Pose x = parse_pose_text("0.1,-0.2,0.3,0,0,0.7071068,0.7071068", "gt-body-pose");
  CHECK(x.p.isApprox(Eigen::Vector3d(0.1, -0.2, 0.3)));
  CHECK(std::abs(x.q.z() - std::sqrt(0.5)) < 1e-6);
  CHECK_THROWS_AS(parse_pose_text("0.1,0.2,0.3,0,0,0", "gt-body-pose"), InputError);
  CHECK_THROWS_AS(parse_pose_text("0.1,0.2,0.3,0,0,0,2", "gt-body-pose"), InputError);
  CHECK_THROWS_AS(parse_pose_text("0.1,a,0.3,0,0,0,1", "gt-body-pose"), InputError);
}

TEST_CASE("crop, alignment window and interpolated association on the real EuRoC pair", "[eval][window][real]") {
  const auto d = v102();
  if (!d) {
    WARN("skipped: ../shared/data/eval/V102.txt is absent");
    return;
  }
  EvalParams p;
  const Report all = run(d->est.t_ns, d->est.poses, d->gt.t_ns, d->gt.poses, p);
  const Timestamp t0 = d->est.t_ns.front() + from_seconds(20.0), t1 = d->est.t_ns.front() + from_seconds(40.0);
  SECTION("--t-start / --t-end keep the pairs inside, and evaluate them as if cropped") {
    p.t_start_ns = t0, p.t_end_ns = t1;
    const Report c = run(d->est.t_ns, d->est.poses, d->gt.t_ns, d->gt.poses, p);
    std::vector<Timestamp> et;
    std::vector<Pose> ep;
    for (std::size_t i = 0; i < d->est.size(); ++i)
      if (d->est.t_ns[i] >= t0 - 5'000'000 && d->est.t_ns[i] <= t1 + 5'000'000) et.push_back(d->est.t_ns[i]), ep.push_back(d->est.poses[i]);
    EvalParams q;
    const Report by_hand = run(et, ep, d->gt.t_ns, d->gt.poses, q);
    INFO("cropped " << c.n_pairs() << " by hand " << by_hand.n_pairs());
    CHECK(c.n_pairs() + c.n_cropped == all.n_pairs());
    for (std::size_t k = 0; k < c.n_pairs(); ++k) {
      CHECK(c.t_gt(k) >= t0);
      CHECK(c.t_gt(k) <= t1);
    }
    if (c.n_pairs() == by_hand.n_pairs()) CHECK(c.ape.trans_m.rmse == Approx(by_hand.ape.trans_m.rmse).epsilon(1e-12));
    EvalParams bad;
    bad.t_start_ns = t1, bad.t_end_ns = t0;
    CHECK_THROWS_AS(check_params(bad), InputError);
  }
  SECTION("--align-window fits on the window and scores every pair") {
    p.align_window_ns = std::pair{t0, t1};
    const Report w = run(d->est.t_ns, d->est.poses, d->gt.t_ns, d->gt.poses, p);
    CHECK(w.n_pairs() == all.n_pairs());
    CHECK(w.alignment.n_used < static_cast<int>(all.n_pairs()));
    CHECK(w.alignment.n_used > 100);
    CHECK(w.ape.trans_m.rmse > all.ape.trans_m.rmse);  // Umeyama on all pairs minimises exactly this
    p.align_window_ns = std::pair{t0 - from_seconds(1e4), t0 - from_seconds(9e3)};
    CHECK_THROWS_AS(run(d->est.t_ns, d->est.poses, d->gt.t_ns, d->gt.poses, p), InputError);
  }
  SECTION("--assoc interpolate: the ground truth at the estimate's stamps (evo #439)") {
    p.assoc.policy = AssocPolicy::kInterpolate;
    const Report ip = run(d->est.t_ns, d->est.poses, d->gt.t_ns, d->gt.poses, p);
    // The 4 duplicated stamps share one truth; a stamp the ground truth does not bracket is left out.
    CHECK(ip.n_pairs() >= all.n_pairs() - 5);
    for (std::size_t k = 0; k < ip.n_pairs(); ++k) CHECK(ip.t_gt(k) == ip.t_est(k));
    // The estimate's stamps are within 1 us of the ground truth's here: the same figures to 1e-4 m.
    CHECK(std::abs(ip.ape.trans_m.rmse - all.ape.trans_m.rmse) < 1e-3);
    // Between samples the interpolated truth is exact for a uniform motion: a sparse ground truth of a line.
  }
}

TEST_CASE("the alignment's tilt is reported and warned about above 1 deg, naming posyaw", "[eval][tilt]") {
  std::vector<Timestamp> t;
  std::vector<Pose> gt, est;
  const Eigen::Quaterniond tilt = math::exp_quat(Eigen::Vector3d(3.0 * M_PI / 180.0, 0, 0));
  for (int i = 0; i < 500; ++i) {
    const double s = i * 0.02;
    t.push_back(i * 20'000'000LL);
    gt.push_back(Pose(math::exp_quat(Eigen::Vector3d(0, 0, 0.5 * s)), Eigen::Vector3d(std::cos(s), std::sin(s), 0.1 * std::sin(3 * s))));
    // The estimate's positions tilted by 3 deg about x, its orientations not: an SE(3) fit tilts them back.
    Pose e = gt.back();
    e.p = tilt * e.p;
    est.push_back(e);
  }
  EvalParams p;
  p.check_offset = false;
  const Report r = run(t, est, t, gt, p);
  CHECK(r.tilt_deg == Approx(3.0).margin(1e-6));
  CHECK(has_warning(r, "--align posyaw"));
  REQUIRE(r.posyaw_rot_rmse_deg);
  CHECK(*r.posyaw_rot_rmse_deg < 0.1);  // posyaw leaves the orientations as they are (its yaw ~0)
  CHECK(r.ape.rot_deg.rmse == Approx(3.0).margin(1e-6));
  const Report flat = run(t, gt, t, gt, p);
  CHECK(flat.tilt_deg < 1e-6);
  CHECK_FALSE(has_warning(flat, "tilts"));
}

TEST_CASE("a ground truth far sparser than the estimate is named as possibly swapped", "[eval][swapped]") {
  std::vector<Timestamp> dense_t, sparse_t;
  std::vector<Pose> dense, sparse;
  for (int i = 0; i < 4000; ++i) {
    const double s = i * 0.005;
    dense_t.push_back(i * 5'000'000LL);
    dense.push_back(Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(std::cos(s), std::sin(s), 0.1 * s)));
    if (i % 40 == 0) sparse_t.push_back(dense_t.back()), sparse.push_back(dense.back());
  }
  EvalParams p;
  p.check_offset = false;
  CHECK(has_warning(run(dense_t, dense, sparse_t, sparse, p), "check that --gt names the ground truth"));
  CHECK_FALSE(has_warning(run(sparse_t, sparse, dense_t, dense, p), "check that --gt names the ground truth"));
}

namespace {

/// The definition of effective_sample_fraction, summed lag by lag (O(n · lags)): what the FFT must equal.
double effective_fraction_direct(const std::vector<Eigen::Vector3d>& r) {
  const std::size_t n = r.size();
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& x : r) mean += x;
  mean /= static_cast<double>(n);
  double c0 = 0.0;
  for (const auto& x : r) c0 += (x - mean).squaredNorm();
  double sum = 0.0;
  for (std::size_t lag = 1; lag < n / 2; ++lag) {
    double c = 0.0;
    for (std::size_t k = 0; k + lag < n; ++k) c += (r[k] - mean).dot(r[k + lag] - mean);
    if (c / c0 < 0.05) break;
    sum += c / c0;
  }
  return 1.0 / (1.0 + 2.0 * sum);
}

/// A 3-D AR(1) series x_k = φ x_{k−1} + e_k plus an offset (the mean must not matter).
std::vector<Eigen::Vector3d> ar1(std::size_t n, double phi, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> e(0.0, 1.0);
  std::vector<Eigen::Vector3d> r(n);
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  for (auto& v : r) {
    x = phi * x + Eigen::Vector3d(e(rng), e(rng), e(rng));
    v = x + Eigen::Vector3d(5.0, -3.0, 0.5);
  }
  return r;
}

}  // namespace

TEST_CASE("effective_sample_fraction equals its lag-by-lag definition", "[eval][time_offset]") {
  // White (no lag counted), short-correlated, and drifting series whose correlation spans half the series
  // (where a circular, unpadded FFT would fold the far lags onto the near ones), sizes that are and are not
  // powers of two.
  for (const auto& [n, phi] : std::vector<std::pair<std::size_t, double>>{
           {4, 0.0}, {7, 0.5}, {256, 0.0}, {1000, 0.9}, {1024, 0.99}, {3001, 0.999}, {5000, 0.9999}}) {
    const auto r = ar1(n, phi, static_cast<unsigned>(n));
    const double fast = effective_sample_fraction(r), direct = effective_fraction_direct(r);
    INFO("n " << n << " phi " << phi);
    CHECK(fast == Approx(direct).epsilon(1e-9));
    CHECK(fast > 0.0);
    CHECK(fast <= 1.0);
  }
  // AR(1) with φ = 0.8 over 200 000 samples: ρ_k = φ^k summed while ≥ 0.05 (k ≤ 13) is 3.784, so the
  // fraction is 1 / (1 + 2 · 3.784) = 0.1167 (to the series' sampling error).
  const double f = effective_sample_fraction(ar1(200000, 0.8, 3));
  double s = 0.0;
  for (double rho = 0.8; rho >= 0.05; rho *= 0.8) s += rho;
  CHECK(f == Approx(1.0 / (1.0 + 2.0 * s)).epsilon(0.03));
  CHECK(effective_sample_fraction({Eigen::Vector3d::Ones(), Eigen::Vector3d::Ones(), Eigen::Vector3d::Ones(),
                                   Eigen::Vector3d::Ones(), Eigen::Vector3d::Ones()}) == 1.0);  // no variance
}
