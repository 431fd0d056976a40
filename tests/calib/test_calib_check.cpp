// The verdicts of calib/calib_check.hpp on hand-made inputs: each check's limit from both sides,
// what is skipped when, and the anchor-relative (gauge-free) object comparison.
#include <catch2/catch.hpp>
#include "check_lookup.hpp"
#include <cmath>
#include <random>

#include "roe/calib/calib_check.hpp"
#include "roe/core/error.hpp"
#include "roe/math/so3.hpp"

using namespace roe;
using calib::CheckStatus;

namespace {

constexpr double kDeg = M_PI / 180.0;
const Timestamp kT0 = 5'000'000'000;

/// A converged run: 30 s of extrinsics at the truth with σ 2 mm / 0.2°, three objects.
calib::CalibInput good_input() {
  calib::CalibInput in;
  in.prior_T_I_C = Pose(math::exp_quat(Eigen::Vector3d(0.01, 0.02, -0.01)), Eigen::Vector3d(0.02, -0.01, 0.03));
  in.prior_sigma << 0.02, 0.02, 0.02, 2 * kDeg, 2 * kDeg, 2 * kDeg;
  for (int k = 0; k <= 300; ++k) {
    calib::ExtrinsicsSample s;
    s.t_ns = kT0 + Timestamp{k} * 100'000'000;
    s.T_I_C = in.prior_T_I_C;
    s.sigma << 0.002, 0.002, 0.002, 0.2 * kDeg, 0.2 * kDeg, 0.2 * kDeg;
    in.extrinsics.push_back(s);
  }
  const Pose T_W_O[3] = {Pose(math::exp_quat(Eigen::Vector3d(0, 0, 0.5)), Eigen::Vector3d(1, 0, 0)),
                         Pose(math::exp_quat(Eigen::Vector3d(0.2, 0, -1)), Eigen::Vector3d(0, 2, 0.1)),
                         Pose(math::exp_quat(Eigen::Vector3d(0, 0.3, 2)), Eigen::Vector3d(-1, 1, 0))};
  for (int i = 0; i < 3; ++i) {
    calib::ObjectEstimate o;
    o.id = i + 1;
    o.anchor = i == 0;
    o.T_O_W = T_W_O[i].inverse();
    if (!o.anchor) o.sigma_A_O << 0.005, 0.005, 0.005, 0.5 * kDeg, 0.5 * kDeg, 0.5 * kDeg;
    o.detections = 100;
    in.objects.push_back(o);
    in.true_T_W_O[o.id] = T_W_O[i];
  }
  in.true_T_I_C = in.prior_T_I_C;
  calib::TimeOffsetEstimate e;
  e.valid = true;
  e.offset_s = 0.002;
  e.sigma_s = 0.001;
  e.detections = 500;
  in.time_offset = e;
  return in;
}

const calib::CheckResult& get(const calib::CalibReport& r, const std::string& name) {
  return test::check_named(r, name);
}
double value(const calib::CheckResult& c, const std::string& key) { return test::check_value(c, key); }

}  // namespace

TEST_CASE("calib-check: a converged run passes all seven checks, in the documented order", "[calib]") {
  const auto r = calib::check_calibration(good_input());
  const std::vector<std::string> names = {"extrinsics.sigma", "extrinsics.settled", "extrinsics.prior",
                                          "objects.sigma",    "truth.extrinsics",   "truth.objects",
                                          "camera.time_offset"};
  REQUIRE(r.checks.size() == names.size());
  for (std::size_t i = 0; i < names.size(); ++i) {
    INFO(r.checks[i].name << ": " << r.checks[i].message);
    CHECK(r.checks[i].name == names[i]);
    CHECK(r.checks[i].status == CheckStatus::kPass);
  }
  CHECK_FALSE(r.failed());
  CHECK_FALSE(r.undecided());
}

TEST_CASE("calib-check: extrinsics.sigma is unobservable on either axis group beyond its limit, never a failure",
          "[calib]") {
  auto in = good_input();
  in.extrinsics.back().sigma(1) = 0.0101;  // p_y
  auto rep = calib::check_calibration(in);
  CHECK(get(rep, "extrinsics.sigma").status == CheckStatus::kUnobservable);
  CHECK(rep.unobservable());
  CHECK_FALSE(rep.failed());  // not calibrated is not wrong: nothing contradicts the estimate
  in.extrinsics.back().sigma(1) = 0.0099;
  CHECK(get(calib::check_calibration(in), "extrinsics.sigma").status == CheckStatus::kPass);
  in.extrinsics.back().sigma(5) = 1.01 * kDeg;  // θ_z
  const auto c = get(calib::check_calibration(in), "extrinsics.sigma");
  CHECK(c.status == CheckStatus::kUnobservable);
  CHECK(std::string(calib::to_string(c.status)) == "unobservable");
  CHECK(value(c, "sigma_rot_z_deg") == Approx(1.01));
  // A translation σ that stayed near the prior is named for what it is.
  in = good_input();
  in.extrinsics.back().sigma(0) = 0.015;
  CHECK_THAT(get(calib::check_calibration(in), "extrinsics.sigma").message, Catch::Contains("hardly observed"));
}

TEST_CASE("calib-check: extrinsics.settled looks only at the last 20 % (at least 2 s)", "[calib]") {
  auto in = good_input();  // 30 s: the window is the last 6 s
  // A jump of 6 mm 7 s before the end is outside the window ...
  in.extrinsics[300 - 70].T_I_C.p.x() += 0.006;
  auto c = get(calib::check_calibration(in), "extrinsics.settled");
  CHECK(c.status == CheckStatus::kPass);
  CHECK(value(c, "window_s") == Approx(6.0));
  // ... 5 s before the end it is inside.
  in.extrinsics[300 - 50].T_I_C.p.x() += 0.006;
  CHECK(get(calib::check_calibration(in), "extrinsics.settled").status == CheckStatus::kFail);
  // A rotation of 0.6° inside the window fails too; 0.4° does not.
  in = good_input();
  in.extrinsics[290].T_I_C.q = in.extrinsics[290].T_I_C.q * math::exp_quat(Eigen::Vector3d(0, 0.4 * kDeg, 0));
  CHECK(get(calib::check_calibration(in), "extrinsics.settled").status == CheckStatus::kPass);
  in.extrinsics[290].T_I_C.q = in.extrinsics[290].T_I_C.q * math::exp_quat(Eigen::Vector3d(0, 0.2 * kDeg, 0));
  CHECK(get(calib::check_calibration(in), "extrinsics.settled").status == CheckStatus::kFail);
  // A run shorter than twice the minimum window cannot be judged.
  in = good_input();
  in.extrinsics.resize(31);  // 3 s
  CHECK(get(calib::check_calibration(in), "extrinsics.settled").status == CheckStatus::kInconclusive);
}

TEST_CASE("calib-check: extrinsics.settled fails a move beyond the limits only when beyond its shrinking σ too",
          "[calib]") {
  // 5 s before the end σ was 10 mm on p_x (2 mm at the end): a consistent filter may still move by
  // ~9.8 mm (σ of P_s − P_end) from there. 6 mm is beyond the 5 mm limit but explained (0.61 σ);
  // 45 mm is not (4.6 σ > 3.34, the bound for 0.99 over six axes and the whole window).
  auto in = good_input();
  in.extrinsics[250].sigma(0) = 0.010;
  in.extrinsics[250].T_I_C.p.x() += 0.006;
  auto c = get(calib::check_calibration(in), "extrinsics.settled");
  CHECK(c.status == CheckStatus::kWithinSigma);  // beyond the limit, explained by σ: its own status
  CHECK(std::string(calib::to_string(c.status)) == "within-sigma");
  CHECK(value(c, "z") == Approx(0.006 / std::sqrt(0.0001 - 0.000004)).epsilon(1e-6));
  CHECK(value(c, "limit_z") == Approx(3.3415).epsilon(1e-4));  // P(|N(0,1)| > z) = 0.01 / 12
  CHECK_THAT(c.message, Catch::Contains("still converging"));
  in.extrinsics[250].T_I_C.p.x() += 0.039;
  c = get(calib::check_calibration(in), "extrinsics.settled");
  CHECK(c.status == CheckStatus::kFail);
  CHECK_THAT(c.message, Catch::Contains("a drift"));
  CHECK_THAT(c.message, Catch::Contains("p_x"));
  // A lower confidence makes the bound tighter (2.64 at 0.9): 30 mm (3.06 σ) fails there only.
  in.extrinsics[250].T_I_C.p.x() -= 0.015;
  CHECK(get(calib::check_calibration(in), "extrinsics.settled").status == CheckStatus::kWithinSigma);
  calib::CalibThresholds t;
  t.confidence = 0.9;
  CHECK(get(calib::check_calibration(in, t), "extrinsics.settled").status == CheckStatus::kFail);
}

namespace {

/// A consistent filter's extrinsics trace: 40 s at 10 Hz whose σ shrinks as information accrues
/// (σ² = σ0² / (1 + t / 2 s)), the estimate a Gaussian martingale that moves between samples by
/// N(0, P_{i−1} − P_i) per axis, the six axes' moves correlated by `rho`, plus a drift that grows
/// linearly over the last 8 s (the settle window) to `drift_sigmas` times σ of P_start − P_end on p_x.
calib::CalibInput consistent_trace(std::mt19937& rng, double rho, double drift_sigmas) {
  calib::CalibInput in;
  in.prior_T_I_C = Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero());
  Vector6d s0;
  s0 << 0.02, 0.02, 0.02, 2 * kDeg, 2 * kDeg, 2 * kDeg;
  in.prior_sigma = s0;
  const int n = 400;
  const auto sigma_at = [&](int i) { return Vector6d(s0 / std::sqrt(1.0 + 0.1 * i / 2.0)); };
  std::normal_distribution<double> g(0.0, 1.0);
  Vector6d x = Vector6d::Zero();
  const Vector6d v_window = sigma_at(n - 80).cwiseAbs2() - sigma_at(n).cwiseAbs2();
  for (int i = 0; i <= n; ++i) {
    if (i > 0) {
      const double common = g(rng);
      const Vector6d dv = sigma_at(i - 1).cwiseAbs2() - sigma_at(i).cwiseAbs2();
      for (int k = 0; k < 6; ++k)
        x(k) += std::sqrt(dv(k)) * (std::sqrt(rho) * common + std::sqrt(1.0 - rho) * g(rng));
    }
    Vector6d shown = x;
    if (i > n - 80) shown(0) += drift_sigmas * std::sqrt(v_window(0)) * (i - (n - 80)) / 80.0;
    calib::ExtrinsicsSample e;
    e.t_ns = kT0 + Timestamp{i} * 100'000'000;
    e.T_I_C = Pose(math::exp_quat(shown.tail<3>()), shown.head<3>());
    e.sigma = sigma_at(i);
    in.extrinsics.push_back(e);
  }
  return in;
}

}  // namespace

TEST_CASE("calib-check: extrinsics.settled fails about one consistent run in a hundred, not more, and finds drifts",
          "[calib]") {
  // Every sample of the window is beyond tiny absolute limits, so the σ test alone decides. The
  // earlier rule (any of the window's 80 samples beyond χ²₆(0.99) of its own P_s − P_end, axes summed
  // as if independent) failed 28 of 300 such runs with independent axes and 168 of 300 with axes
  // correlated at 0.9 (and 3 of 40 `matched` runs with per-detection σ); the one test over the
  // window and the six axes must stay near 1 % (measured 3 and 2 of 300; at most 6) either way.
  calib::CalibThresholds t;
  t.max_drift_p_m = 1e-9;
  t.max_drift_rot_deg = 1e-9;
  std::mt19937 rng(7);
  for (const double rho : {0.0, 0.9}) {
    int fails = 0;
    const int runs = 300;
    for (int k = 0; k < runs; ++k)
      fails += get(calib::check_calibration(consistent_trace(rng, rho, 0.0), t), "extrinsics.settled").status ==
               CheckStatus::kFail;
    INFO("axes correlated at " << rho << ": " << fails << " of " << runs << " consistent runs fail");
    CHECK(fails <= 6);
  }
  // A drift over the window of 6 σ (of the information gained in it) on one axis: found nearly always.
  int found = 0;
  for (int k = 0; k < 50; ++k)
    found += get(calib::check_calibration(consistent_trace(rng, 0.0, 6.0), t), "extrinsics.settled").status ==
             CheckStatus::kFail;
  INFO(found << " of 50 drifts found");
  CHECK(found >= 45);
}

TEST_CASE("calib-check: extrinsics.prior is the Mahalanobis distance over P_prior - P_final against chi2 at 99 %",
          "[calib]") {
  auto in = good_input();  // prior σ 20 mm / 2°, final 2 mm / 0.2°
  // 80 mm on p_x: d² = 0.08² / (0.02² − 0.002²) = 16.16 < 16.81 passes; 84 mm: 17.82 fails.
  in.extrinsics.back().T_I_C.p.x() += 0.08;
  auto c = get(calib::check_calibration(in), "extrinsics.prior");
  CHECK(value(c, "d2") == Approx(0.0064 / 0.000396).epsilon(1e-9));
  CHECK(value(c, "dof") == 6.0);
  CHECK(value(c, "limit_d2") == Approx(16.8119).epsilon(1e-4));
  CHECK(c.status == CheckStatus::kPass);
  in.extrinsics.back().T_I_C.p.x() += 0.004;
  CHECK(get(calib::check_calibration(in), "extrinsics.prior").status == CheckStatus::kFail);
  // The rotation counts in the prior's frame: 6° about y and 6° about z give d² = 2 · 36/3.96.
  in = good_input();
  in.extrinsics.back().T_I_C.q = in.prior_T_I_C.q * math::exp_quat(Eigen::Vector3d(0, 6 * kDeg, 6 * kDeg));
  c = get(calib::check_calibration(in), "extrinsics.prior");
  CHECK(value(c, "d2") == Approx(72.0 / 3.96).epsilon(1e-6));
  CHECK(c.status == CheckStatus::kFail);
  calib::CalibThresholds loose;
  loose.confidence = 0.999;  // χ²₆ = 22.46
  CHECK(get(calib::check_calibration(in, loose), "extrinsics.prior").status == CheckStatus::kPass);
  // The shift a consistent filter makes shrinks with the information it gained: with the final σ at
  // 18 mm of 20 (little learnt) the same 80 mm is d² = 0.0064 / (0.0004 − 0.000324) = 84.
  in = good_input();
  in.extrinsics.back().sigma.head<3>().setConstant(0.018);
  in.extrinsics.back().T_I_C.p.x() += 0.08;
  c = get(calib::check_calibration(in), "extrinsics.prior");
  CHECK(value(c, "d2") == Approx(0.0064 / 0.000076).epsilon(1e-6));
  CHECK(c.status == CheckStatus::kFail);
  // Axes the data hardly informed (σ above ~95 % of the prior's) are left out; none informed: no verdict.
  in.extrinsics.back().sigma.head<3>().setConstant(0.0196);
  c = get(calib::check_calibration(in), "extrinsics.prior");
  CHECK(value(c, "dof") == 3.0);
  CHECK(value(c, "limit_d2") == Approx(11.3449).epsilon(1e-4));
  CHECK(c.status == CheckStatus::kPass);
  in.extrinsics.back().sigma.tail<3>().setConstant(1.96 * kDeg);
  c = get(calib::check_calibration(in), "extrinsics.prior");
  CHECK(c.status == CheckStatus::kInconclusive);
  CHECK_THAT(c.message, Catch::Contains("hardly informed"));
}

TEST_CASE("calib-check: extrinsics held fixed skip the extrinsics checks but not the truth", "[calib]") {
  auto in = good_input();
  in.extrinsics_estimated = false;
  in.extrinsics.back().T_I_C.p.x() += 0.02;  // the (fixed) prior is 2 cm off the truth
  in.true_T_I_C = in.prior_T_I_C;
  in.true_T_I_C->p.x() -= 0.02;
  const auto r = calib::check_calibration(in);
  for (const char* n : {"extrinsics.sigma", "extrinsics.settled", "extrinsics.prior"})
    CHECK(get(r, n).status == CheckStatus::kSkipped);
  const auto& t = get(r, "truth.extrinsics");
  CHECK(t.status == CheckStatus::kFail);
  CHECK_THAT(t.message, Catch::Contains("prior's error"));
  CHECK_FALSE(r.undecided());  // not applicable is not undecided: --strict does not fail on it
}

TEST_CASE("calib-check: objects.sigma checks initialised non-anchor objects and lists the others", "[calib]") {
  auto in = good_input();
  calib::ObjectEstimate never;
  never.id = 9;
  never.detections = 2;
  in.objects.push_back(never);
  auto c = get(calib::check_calibration(in), "objects.sigma");
  CHECK(c.status == CheckStatus::kPass);
  CHECK_THAT(c.message, Catch::Contains("9 (2 detection(s))"));
  CHECK(value(c, "never_initialised") == 1.0);
  in.objects[2].sigma_A_O(4) = 2.1 * kDeg;
  c = get(calib::check_calibration(in), "objects.sigma");
  CHECK(c.status == CheckStatus::kUnobservable);
  CHECK_THAT(c.message, Catch::Contains("object 3"));
  // An anchor that never entered the state leaves no σ relative to it (objects.csv then has zeros).
  auto no_anchor = in;
  no_anchor.anchor_id = 1;
  // (An anchor id 0 is an object id like any other.)
  no_anchor.objects[0].T_O_W.reset();
  c = get(calib::check_calibration(no_anchor), "objects.sigma");
  CHECK(c.status == CheckStatus::kInconclusive);
  CHECK_THAT(c.message, Catch::Contains("the anchor (object 1) never entered the state"));
  CHECK(get(calib::check_calibration(no_anchor), "truth.objects").status == CheckStatus::kInconclusive);
  // Only the anchor in the state: nothing to judge.
  in.objects.resize(1);
  CHECK(get(calib::check_calibration(in), "objects.sigma").status == CheckStatus::kSkipped);
}

TEST_CASE("calib-check: truth.objects compares poses relative to the anchor, whatever W is", "[calib]") {
  auto in = good_input();
  // The filter's W is the truth's W moved by an arbitrary rigid transform: T_O_W' = T_O_W · T_W_W'.
  const Pose T_W_Wp(math::exp_quat(Eigen::Vector3d(0.3, -0.2, 1.1)), Eigen::Vector3d(4, -2, 1));
  for (auto& o : in.objects) o.T_O_W = *o.T_O_W * T_W_Wp;
  auto c = get(calib::check_calibration(in), "truth.objects");
  CHECK(c.status == CheckStatus::kPass);
  CHECK(value(c, "error_p_max_m") < 1e-9);
  // Object 3 moved by 6 cm in its own frame relative to the truth: fails (limit 5 cm); 4 cm passes.
  auto moved = in;
  moved.objects[2].T_O_W = Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.06, 0, 0)) * *moved.objects[2].T_O_W;
  c = get(calib::check_calibration(moved), "truth.objects");
  CHECK(value(c, "error_p_max_m") == Approx(0.06).epsilon(1e-6));
  CHECK(c.status == CheckStatus::kFail);
  // Per object, for scripts: its error and its NEES over the per-axis σ.
  CHECK(value(c, "object_3_error_p_m") == Approx(0.06).epsilon(1e-6));
  CHECK(value(c, "object_3_nees") ==
        Approx(std::pow(0.06 / moved.objects[2].sigma_A_O(0), 2)).epsilon(1e-6));
  CHECK(value(c, "object_3_symmetric") == 0.0);
  // An anchor the dataset marks symmetric, without a models_info: poses relative to it are defined only
  // up to an unknown symmetry, so not a failure but inconclusive.
  auto marked = moved;
  marked.symmetric_ids = {1};
  CHECK(get(calib::check_calibration(marked), "truth.objects").status == CheckStatus::kInconclusive);
  // ... unless its σ explains it: 6 cm with σ 3 cm per axis is NEES 4.
  moved.objects[2].sigma_A_O.head<3>().setConstant(0.03);
  c = get(calib::check_calibration(moved), "truth.objects");
  CHECK(c.status == CheckStatus::kWithinSigma);
  CHECK(value(c, "beyond_limits_within_sigma") == 1.0);
  moved = in;
  moved.objects[2].T_O_W = Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0.04, 0)) * *moved.objects[2].T_O_W;
  CHECK(get(calib::check_calibration(moved), "truth.objects").status == CheckStatus::kPass);
  // Without a true pose for the anchor, nothing can be compared.
  in.true_T_W_O.erase(1);
  CHECK(get(calib::check_calibration(in), "truth.objects").status == CheckStatus::kSkipped);
  in.true_T_W_O.clear();
  in.true_T_I_C.reset();
  const auto r = calib::check_calibration(in);
  CHECK(get(r, "truth.objects").status == CheckStatus::kSkipped);
  CHECK(get(r, "truth.extrinsics").status == CheckStatus::kSkipped);
  CHECK_THAT(get(r, "truth.extrinsics").message, Catch::Contains("no true T_I_C"));
  // Without a dataset the reason is that, not a missing truth.
  in = good_input();
  in.dataset_absent_reason = "--no-dataset";
  for (const char* n : {"truth.extrinsics", "truth.objects"}) {
    CHECK(get(calib::check_calibration(in), n).status == CheckStatus::kSkipped);
    CHECK(get(calib::check_calibration(in), n).message == "--no-dataset");
  }
}

TEST_CASE("calib-check: truth.objects compares a symmetric object with its equivalent true pose nearest the estimate",
          "[calib][symmetry]") {
  // Object 2 two-fold about an axis through an offset point, object 3 a body of revolution about a tilted
  // axis: the filter may hold either as T_A_O · S (it started from a flipped or turned detection). With
  // their symmetries described the check compares with the nearest equivalent; without, it fails.
  auto in = good_input();
  ObjectSymmetry two_fold, spin;
  const Eigen::Vector3d o(0.01, -0.02, 0.03);
  const Eigen::Quaterniond qf = math::exp_quat(M_PI * Eigen::Vector3d::UnitZ());
  two_fold.discrete = {Pose(qf, o - qf * o)};
  ContinuousSymmetry c;
  c.axis = Eigen::Vector3d(0.3, -0.2, 1.0).normalized();
  c.offset = Eigen::Vector3d(0.0, 0.01, -0.02);
  spin.continuous = c;
  const Eigen::Quaterniond qs = math::exp_quat(2.1 * c.axis);
  const Pose S3(qs, c.offset - qs * c.offset);
  // T_O_W of an estimate held as T_A_O · S: T_W_O · S, i.e. T_O_W ← S⁻¹ · T_O_W.
  in.objects[1].T_O_W = two_fold.discrete[0].inverse() * *in.objects[1].T_O_W;
  in.objects[2].T_O_W = S3.inverse() * *in.objects[2].T_O_W;
  auto r = get(calib::check_calibration(in), "truth.objects");
  CHECK(r.status == CheckStatus::kFail);
  CHECK(value(r, "error_rot_max_deg") > 100.0);
  in.symmetries = {{2, two_fold}, {3, spin}};
  r = get(calib::check_calibration(in), "truth.objects");
  CHECK(r.status == CheckStatus::kPass);
  CHECK(value(r, "error_p_max_m") < 1e-9);
  CHECK(value(r, "error_rot_max_deg") < 1e-6);
  // A real error stays an error: 6 cm on the symmetric object fails.
  auto moved = in;
  moved.objects[2].T_O_W = Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.06, 0, 0)) * *moved.objects[2].T_O_W;
  CHECK(get(calib::check_calibration(moved), "truth.objects").status == CheckStatus::kFail);
  // A symmetric anchor leaves the anchor-relative poses defined only up to its symmetry.
  in.symmetries[1] = two_fold;
  r = get(calib::check_calibration(in), "truth.objects");
  CHECK(r.status == CheckStatus::kInconclusive);
  CHECK_THAT(r.message, Catch::Contains("anchor (object 1) is symmetric"));
}

TEST_CASE("calib-check: truth.extrinsics fails beyond the limits and the sigma", "[calib]") {
  auto in = good_input();
  in.extrinsics.back().T_I_C.p.z() += 0.011;
  auto c = get(calib::check_calibration(in), "truth.extrinsics");
  CHECK(c.status == CheckStatus::kFail);
  CHECK(value(c, "nees_diag") == Approx(std::pow(0.011 / 0.002, 2)).epsilon(1e-6));
  // The same error with σ 6 mm (NEES 3.4): beyond the limit but consistent, so a pass that says so.
  in.extrinsics.back().sigma.head<3>().setConstant(0.006);
  c = get(calib::check_calibration(in), "truth.extrinsics");
  CHECK(c.status == CheckStatus::kWithinSigma);
  CHECK_THAT(c.message, Catch::Contains("within its σ"));
  {
    calib::CalibReport rep;
    rep.checks.push_back(c);
    CHECK_FALSE(rep.failed());  // not a failure: exit 0 unless --strict (app/calib_check)
    CHECK(rep.within_sigma());
    CHECK_FALSE(rep.undecided());
  }
  in = good_input();
  in.extrinsics.back().T_I_C.q = in.extrinsics.back().T_I_C.q * math::exp_quat(Eigen::Vector3d(0.9 * kDeg, 0, 0));
  CHECK(get(calib::check_calibration(in), "truth.extrinsics").status == CheckStatus::kPass);
  in.extrinsics.back().T_I_C.q = in.extrinsics.back().T_I_C.q * math::exp_quat(Eigen::Vector3d(0.2 * kDeg, 0, 0));
  CHECK(get(calib::check_calibration(in), "truth.extrinsics").status == CheckStatus::kFail);
}

TEST_CASE("calib-check: camera.time_offset decides only with confidence: |d| - z sigma fails, |d| + z sigma passes",
          "[calib]") {
  auto in = good_input();
  const auto status = [&](double est, double sigma, double declared) {
    in.time_offset->offset_s = est;
    in.time_offset->sigma_s = sigma;
    in.declared_time_offset_s = declared;
    return get(calib::check_calibration(in), "camera.time_offset").status;
  };
  // Limit 10 ms, z = 2.326 at the default confidence 0.99 (one-sided).
  CHECK(status(0.007, 0.001, 0.0) == CheckStatus::kPass);           // 7 + 2.3 <= 10
  CHECK(status(0.009, 0.001, 0.0) == CheckStatus::kInconclusive);   // 9 + 2.3 > 10: could be beyond
  CHECK(status(0.011, 0.001, 0.0) == CheckStatus::kInconclusive);   // 11 − 2.3 < 10: could be within
  CHECK(status(-0.013, 0.001, 0.0) == CheckStatus::kFail);          // 13 − 2.3 > 10, either sign
  CHECK(status(0.043, 0.001, 0.03) == CheckStatus::kFail);          // relative to the declared offset
  CHECK(status(0.035, 0.001, 0.03) == CheckStatus::kPass);
  CHECK(status(0.030, 0.009, 0.0) == CheckStatus::kInconclusive);   // 30 − 20.9 < 10
  CHECK(status(0.035, 0.009, 0.0) == CheckStatus::kFail);           // 35 − 20.9 > 10
  CHECK(status(0.002, 0.003, 0.0) == CheckStatus::kPass);           // 2 + 7.0 <= 10
  CHECK(status(0.002, 0.0035, 0.0) == CheckStatus::kInconclusive);  // 2 + 8.1 > 10
  CHECK(value(get(calib::check_calibration(in), "camera.time_offset"), "z") == Approx(2.3263).epsilon(1e-4));
  calib::CalibThresholds t95;
  t95.confidence = 0.95;  // z = 1.645
  in.time_offset->offset_s = 0.008;
  in.time_offset->sigma_s = 0.001;
  CHECK(get(calib::check_calibration(in), "camera.time_offset").status == CheckStatus::kInconclusive);
  CHECK(get(calib::check_calibration(in, t95), "camera.time_offset").status == CheckStatus::kPass);
  in.time_offset->valid = false;
  in.time_offset->reason = "the camera hardly turns";
  auto c = get(calib::check_calibration(in), "camera.time_offset");
  CHECK(c.status == CheckStatus::kInconclusive);
  CHECK_THAT(c.message, Catch::Contains("hardly turns"));
  // Lowest at the edge of the search: fails when the evidence against the declared offset is beyond
  // χ²₁(0.99) = 6.63, else no verdict.
  in.time_offset->at_edge = true;
  in.time_offset->edge_stable = true;
  in.time_offset->edge_offset_s = 0.1;
  in.time_offset->edge_evidence = 7.0;
  c = get(calib::check_calibration(in), "camera.time_offset");
  CHECK(c.status == CheckStatus::kFail);
  CHECK_THAT(c.message, Catch::Contains("lies beyond the search"));
  // An edge that a part of the data carries alone (the jackknife's replicates are lowest elsewhere)
  // is no evidence, however strong.
  in.time_offset->edge_stable = false;
  in.time_offset->edge_evidence = 50.0;
  CHECK(get(calib::check_calibration(in), "camera.time_offset").status == CheckStatus::kInconclusive);
  in.time_offset->edge_stable = true;
  in.time_offset->edge_evidence = 7.0;
  in.time_offset->edge_evidence = 6.0;
  CHECK(get(calib::check_calibration(in), "camera.time_offset").status == CheckStatus::kInconclusive);
  // A search narrower than the limit (edge at 5 ms): strong evidence, but not of an offset beyond it.
  in.time_offset->edge_offset_s = 0.005;
  in.time_offset->edge_evidence = 50.0;
  CHECK(get(calib::check_calibration(in), "camera.time_offset").status == CheckStatus::kInconclusive);
  in.time_offset.reset();
  in.time_offset_absent_reason = "--no-dataset";
  const auto r = calib::check_calibration(in);
  CHECK(get(r, "camera.time_offset").status == CheckStatus::kSkipped);
  CHECK(get(r, "camera.time_offset").message == "--no-dataset");
}

TEST_CASE("calib-check: thresholds must be positive and the trace must not be empty", "[calib]") {
  calib::CalibThresholds t;
  t.max_err_p_m = 0.0;
  CHECK_THROWS_AS(calib::check_calibration(good_input(), t), InputError);
  t = {};
  t.settle_fraction = 1.5;
  CHECK_THROWS_AS(calib::check_calibration(good_input(), t), InputError);
  t = {};
  t.confidence = 1.0;
  CHECK_THROWS_AS(calib::check_calibration(good_input(), t), InputError);
  t.confidence = 0.5;  // z = 0: no decision possible
  CHECK_THROWS_AS(calib::check_calibration(good_input(), t), InputError);
  auto in = good_input();
  in.extrinsics.clear();
  CHECK_THROWS_AS(calib::check_calibration(in), InputError);
}

TEST_CASE("calib-check: camera.time_offset from the run's online state, the correlation as the independent check",
          "[calib][time_offset]") {
  auto in = good_input();  // the correlation: 2 ± 1 ms
  const auto check = [&](double online, double sigma, double declared) {
    in.online_time_offset = calib::CalibInput::OnlineTimeOffset{online, sigma};
    in.declared_time_offset_s = declared;
    return get(calib::check_calibration(in), "camera.time_offset");
  };
  // The verdict is the online estimate's, under the same rule (limit 10 ms, z = 2.326).
  CHECK(check(0.003, 0.0005, 0.0).status == CheckStatus::kPass);
  CHECK(value(check(0.003, 0.0005, 0.0), "online_estimate_s") == 0.003);
  CHECK(value(check(0.003, 0.0005, 0.0), "estimate_s") == 0.002);  // the correlation's, beside it
  CHECK(check(0.009, 0.0005, 0.0).status == CheckStatus::kInconclusive);  // 9 + 1.2 > 10
  // A declared offset 30 ms off that the run found: fail, naming the estimate (the correlation agrees).
  in.time_offset->offset_s = 0.031;
  const auto far = check(0.030, 0.0005, 0.0);
  CHECK(far.status == CheckStatus::kFail);
  CHECK_THAT(far.message, Catch::Contains("0.0300") && Catch::Contains("consistent"));
  CHECK(check(0.030, 0.0005, 0.030).status == CheckStatus::kPass);  // relative to the declared offset
  // The two estimators disagree beyond their σ and the limit: fail, whatever the online verdict alone says.
  in.time_offset->offset_s = 0.050;
  const auto bad = check(0.030, 0.0005, 0.030);
  CHECK(bad.status == CheckStatus::kFail);
  CHECK_THAT(bad.message, Catch::Contains("DISAGREES"));
  // No correlation estimate: the online verdict alone, saying why the independent check is missing.
  in.time_offset->valid = false;
  in.time_offset->reason = "the camera hardly turns";
  const auto alone = check(0.030, 0.0005, 0.030);
  CHECK(alone.status == CheckStatus::kPass);
  CHECK_THAT(alone.message, Catch::Contains("hardly turns"));
  // A run without the state: the correlation decides, as before.
  in.online_time_offset.reset();
  in.time_offset->valid = true;
  in.time_offset->offset_s = 0.002;
  in.declared_time_offset_s = 0.0;
  const calib::CalibReport report = calib::check_calibration(in);
  CHECK(get(report, "camera.time_offset").status == CheckStatus::kPass);
  for (const auto& [k, v] : get(report, "camera.time_offset").values) CHECK(k != "online_estimate_s");
}
