#include "roe/calib/calib_check.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <fmt/format.h>

#include "roe/core/error.hpp"
#include "roe/math/distributions.hpp"
#include "roe/ekf/symmetry.hpp"
#include "roe/math/so3.hpp"

namespace roe::calib {
namespace {

constexpr double kDeg = 180.0 / M_PI;

double max_p(const Vector6d& s) { return s.head<3>().maxCoeff(); }
double max_rot_deg(const Vector6d& s) { return s.tail<3>().maxCoeff() * kDeg; }

CheckResult skipped(std::string name, std::string why) {
  return {std::move(name), CheckStatus::kSkipped, std::move(why), {}};
}

std::string id_list(const std::vector<std::string>& items) {
  std::string s;
  for (const auto& i : items) s += (s.empty() ? "" : "; ") + i;
  return s;
}

CheckResult extrinsics_sigma(const CalibInput& in, const CalibThresholds& th) {
  const std::string name = "extrinsics.sigma";
  if (!in.extrinsics_estimated) return skipped(name, "extrinsics held fixed (estimate_extrinsics: false)");
  const Vector6d& s = in.extrinsics.back().sigma;
  CheckResult r{name, CheckStatus::kPass, "", {}};
  const double sp = max_p(s), sr = max_rot_deg(s);
  r.status = sp <= th.max_sigma_p_m && sr <= th.max_sigma_rot_deg ? CheckStatus::kPass : CheckStatus::kUnobservable;
  r.message = fmt::format("final σ {:.1f} mm / {:.2f}° (largest axis; prior {:.1f} mm / {:.2f}°), limits {:.1f} mm / {:.2f}°",
                          sp * 1e3, sr, max_p(in.prior_sigma) * 1e3, max_rot_deg(in.prior_sigma),
                          th.max_sigma_p_m * 1e3, th.max_sigma_rot_deg);
  // Beyond the limit is "not calibrated", never "wrong": a σ cannot contradict the data (the error checks
  // and extrinsics.prior say when the data disagree with the estimate).
  if (r.status == CheckStatus::kUnobservable)
    r.message += sp > th.max_sigma_p_m && sp > 0.5 * max_p(in.prior_sigma)
                     ? ": unobservable, the translation was hardly observed (more rotation about several axes helps)"
                     : ": unobservable, not observed well enough by this motion";
  r.values = {{"sigma_p_x_m", s(0)},       {"sigma_p_y_m", s(1)},         {"sigma_p_z_m", s(2)},
              {"sigma_rot_x_deg", s(3) * kDeg}, {"sigma_rot_y_deg", s(4) * kDeg}, {"sigma_rot_z_deg", s(5) * kDeg},
              {"limit_p_m", th.max_sigma_p_m}, {"limit_rot_deg", th.max_sigma_rot_deg}};
  return r;
}

CheckResult inconclusive(std::string name, std::string why) {
  return {std::move(name), CheckStatus::kInconclusive, std::move(why), {}};
}

CheckResult extrinsics_settled(const CalibInput& in, const CalibThresholds& th) {
  const std::string name = "extrinsics.settled";
  if (!in.extrinsics_estimated) return skipped(name, "extrinsics held fixed (estimate_extrinsics: false)");
  if (in.batch_termination) {  // one solution of the whole recording: settled = the solve converged
    const bool converged = in.batch_termination->rfind("CONVERGENCE", 0) == 0;
    return {name, converged ? CheckStatus::kPass : CheckStatus::kInconclusive,
            (converged ? "the batch solve converged (" : "the batch solve stopped without converging (") +
                *in.batch_termination + "): a batch estimate has no history to drift in",
            {}};
  }
  const auto& tr = in.extrinsics;
  const double duration = dt_seconds(tr.front().t_ns, tr.back().t_ns);
  // The run must leave a settle window of at least --settle-min before its last --settle-min (a larger
  // --settle-fraction deliberately examines more of the run, up to all of it).
  if (duration < 2.0 * th.settle_min_s)
    return inconclusive(name, fmt::format("the run is {:.1f} s long, shorter than twice the minimum settle window "
                                          "(--settle-min {:.1f} s)",
                                          duration, th.settle_min_s));
  const double window = std::min(duration, std::max(th.settle_min_s, th.settle_fraction * duration));
  const Timestamp from = tr.back().t_ns - from_seconds(window);
  const auto& fin = tr.back();
  // A consistent filter's estimate of a constant is a Gaussian martingale: its moves over disjoint
  // intervals are independent, and from time s to the end it moves by an amount of covariance
  // P_s − P_end (the information gained in between). Per axis k, the move back from the end, d_k(s),
  // is then a sum of independent symmetric steps, and Lévy's inequality bounds its largest excursion
  // over the window by twice the chance of its last value: P(max_s |d_k(s)| ≥ c) ≤ 2 P(|d_k(start)| ≥ c),
  // with variance v_k = P_start,k − P_end,k (here the largest over the window, which is the start's
  // for a filter whose σ only shrinks). Over six axes, whatever their correlations (states.csv has
  // no cross terms), the false-alarm rate of max_k max_s |d_k(s)| / √v_k > z stays below
  // α = 1 − confidence when P(|N(0,1)| > z) = α / 12 (6 axes, times 2 for the excursion): z = 3.34
  // at 0.99. One test for the whole window, so the many samples in it do not multiply the false
  // alarms (the earlier rule, a χ²₆ per sample, failed 3 of 40 consistent runs).
  Vector6d v = Vector6d::Zero();
  const Vector6d v_end = fin.sigma.cwiseProduct(fin.sigma);
  for (const auto& s : tr)
    if (s.t_ns >= from) v = v.cwiseMax(s.sigma.cwiseProduct(s.sigma) - v_end);
  const double alpha = 1.0 - th.confidence;
  const double limit_z = std::sqrt(math::chi2_quantile(1.0 - alpha / 12.0, 1.0));
  double dp = 0.0, dr = 0.0, z_beyond = 0.0;
  int worst = -1;
  double worst_t = 0.0;
  bool beyond = false;
  for (const auto& s : tr) {
    if (s.t_ns < from) continue;
    const Vector6d d = math::pose_difference(fin.T_I_C, s.T_I_C);
    const double p = d.head<3>().norm(), r = d.tail<3>().norm() * kDeg;
    dp = std::max(dp, p);
    dr = std::max(dr, r);
    if (p <= th.max_drift_p_m && r <= th.max_drift_rot_deg) continue;
    beyond = true;
    for (int k = 0; k < 6; ++k) {
      const double z = v(k) > 0 ? std::abs(d(k)) / std::sqrt(v(k))
                                : (d(k) != 0.0 ? std::numeric_limits<double>::infinity() : 0.0);
      if (worst < 0 || z > z_beyond) z_beyond = z, worst = k, worst_t = dt_seconds(s.t_ns, fin.t_ns);
    }
  }
  const bool drift = beyond && z_beyond > limit_z;
  static const char* axes[6] = {"p_x", "p_y", "p_z", "θ_x", "θ_y", "θ_z"};
  CheckResult r{name, drift ? CheckStatus::kFail : beyond ? CheckStatus::kWithinSigma : CheckStatus::kPass, "", {}};
  r.message = fmt::format("over the last {:.1f} s the estimate stays within {:.1f} mm / {:.2f}° of its final value, "
                          "limits {:.1f} mm / {:.2f}°",
                          window, dp * 1e3, dr, th.max_drift_p_m * 1e3, th.max_drift_rot_deg);
  if (drift)
    r.message += fmt::format(": it moved further than its σ shrank ({} {:.1f} s before the end at {:.1f} σ of "
                             "P_start − P_end > {:.2f}, the bound for confidence {} over 6 axes), a drift",
                             axes[worst], worst_t, z_beyond, limit_z, th.confidence);
  else if (beyond)
    r.message += fmt::format(": beyond the limits, but no further than its σ shrank (largest {:.1f} σ of P_start − "
                             "P_end <= {:.2f}): still converging, see extrinsics.sigma",
                             z_beyond, limit_z);
  r.values = {{"window_s", window},
              {"drift_p_m", dp},
              {"drift_rot_deg", dr},
              {"limit_p_m", th.max_drift_p_m},
              {"limit_rot_deg", th.max_drift_rot_deg},
              {"z", z_beyond},
              {"limit_z", limit_z}};
  return r;
}

CheckResult extrinsics_prior(const CalibInput& in, const CalibThresholds& th) {
  const std::string name = "extrinsics.prior";
  if (!in.extrinsics_estimated) return skipped(name, "extrinsics held fixed (estimate_extrinsics: false)");
  if (!(in.prior_sigma.array() > 0).all())
    return skipped(name, "the prior has a zero standard deviation on some axis");
  const auto& fin = in.extrinsics.back();
  const Vector6d d = math::pose_difference(in.prior_T_I_C, fin.T_I_C);
  // A consistent filter moves from the prior by an amount of covariance P_prior − P_final (per axis
  // here); axes the data hardly informed (final σ above ~95 % of the prior's) are left out.
  double d2 = 0.0, worst_z = 0.0;
  int dof = 0, worst = -1;
  for (int k = 0; k < 6; ++k) {
    const double v0 = in.prior_sigma(k) * in.prior_sigma(k);
    const double v = v0 - fin.sigma(k) * fin.sigma(k);
    if (v < 0.1 * v0) continue;
    const double z = d(k) / std::sqrt(v);
    d2 += z * z;
    ++dof;
    if (worst < 0 || std::abs(z) > worst_z) worst_z = std::abs(z), worst = k;
  }
  const std::string moved = fmt::format("moved {:.1f} mm / {:.2f}° from the prior", d.head<3>().norm() * 1e3,
                                        d.tail<3>().norm() * kDeg);
  if (dof == 0)
    return inconclusive(name, moved + "; the data hardly informed the extrinsics (σ above 95 % of the prior's on "
                                      "every axis), so the shift says nothing");
  const double limit = math::chi2_quantile(th.confidence, dof);
  CheckResult r{name, d2 <= limit ? CheckStatus::kPass : CheckStatus::kFail, "", {}};
  static const char* axes[6] = {"p_x", "p_y", "p_z", "θ_x", "θ_y", "θ_z"};
  static const char* sub[7] = {"₀", "₁", "₂", "₃", "₄", "₅", "₆"};
  r.message = fmt::format("{}, d² = {:.2f} against P_prior − P_final over {} axes (largest {} at {:.1f} σ), "
                          "limit χ²{}({}) = {:.2f}",
                          moved, d2, dof, axes[worst], worst_z, sub[dof], th.confidence, limit);
  if (r.status == CheckStatus::kFail)
    r.message += ": the data disagree with the prior calibration (a wrong camchain, frame or camera?)";
  r.values = {{"shift_p_m", d.head<3>().norm()}, {"shift_rot_deg", d.tail<3>().norm() * kDeg}, {"d2", d2},
              {"dof", static_cast<double>(dof)}, {"limit_d2", limit}};
  return r;
}

/// T_A_O of object `o` from its T_O_W and the anchor's T_A_W: T_A_O = T_A_W · T_O_W⁻¹.
Pose relative_to_anchor(const Pose& T_A_W, const Pose& T_O_W) { return T_A_W * T_O_W.inverse(); }

const ObjectEstimate* find_anchor(const CalibInput& in) {
  for (const auto& o : in.objects)
    if (o.anchor && o.T_O_W) return &o;
  return nullptr;
}

CheckResult objects_sigma(const CalibInput& in, const CalibThresholds& th) {
  const std::string name = "objects.sigma";
  std::vector<std::string> never, over;
  std::size_t checked = 0;
  double wp = 0.0, wr = 0.0;
  for (const auto& o : in.objects) {
    if (o.anchor) continue;
    if (!o.T_O_W) {
      never.push_back(fmt::format("{} ({} detection(s))", o.id, o.detections));
      continue;
    }
    ++checked;
    const double sp = max_p(o.sigma_A_O), sr = max_rot_deg(o.sigma_A_O);
    wp = std::max(wp, sp);
    wr = std::max(wr, sr);
    if (sp > th.max_object_sigma_p_m || sr > th.max_object_sigma_rot_deg)
      over.push_back(fmt::format("object {}: {:.1f} mm / {:.2f}°", o.id, sp * 1e3, sr));
  }
  const std::string not_in = never.empty() ? "" : "; never entered the state (not checked): " + id_list(never);
  if (checked == 0) return skipped(name, "no object besides the anchor entered the state" + not_in);
  if (!find_anchor(in))
    return inconclusive(name, (in.anchor_id ? fmt::format("the anchor (object {}) never entered the state", *in.anchor_id)
                                            : std::string("the run has no anchor")) +
                                  ", so there is no σ relative to it" + not_in);
  CheckResult r{name, over.empty() ? CheckStatus::kPass : CheckStatus::kUnobservable, "", {}};
  r.message = over.empty() ? fmt::format("{} object(s) relative to the anchor: largest σ {:.1f} mm / {:.2f}°, limits "
                                         "{:.1f} mm / {:.2f}°",
                                         checked, wp * 1e3, wr, th.max_object_sigma_p_m * 1e3,
                                         th.max_object_sigma_rot_deg)
                           : fmt::format("unobservable: σ relative to the anchor beyond {:.1f} mm / {:.2f}°: {}",
                                         th.max_object_sigma_p_m * 1e3, th.max_object_sigma_rot_deg, id_list(over));
  r.message += not_in;
  r.values = {{"objects", static_cast<double>(checked)},
              {"never_initialised", static_cast<double>(never.size())},
              {"sigma_p_max_m", wp},
              {"sigma_rot_max_deg", wr},
              {"limit_p_m", th.max_object_sigma_p_m},
              {"limit_rot_deg", th.max_object_sigma_rot_deg}};
  return r;
}

CheckResult truth_extrinsics(const CalibInput& in, const CalibThresholds& th) {
  const std::string name = "truth.extrinsics";
  if (!in.dataset_absent_reason.empty()) return skipped(name, in.dataset_absent_reason);
  if (!in.true_T_I_C) return skipped(name, "the dataset has no true T_I_C (roe.json truth)");
  const auto& last = in.extrinsics.back();
  const Vector6d e = math::pose_difference(*in.true_T_I_C, last.T_I_C);
  const double ep = e.head<3>().norm(), er = e.tail<3>().norm() * kDeg;
  const bool beyond = ep > th.max_err_p_m || er > th.max_err_rot_deg;
  // Beyond the limits fails only when beyond the σ too (NEES over the per-axis σ); without σ (the
  // extrinsics held fixed) the limits alone decide.
  const bool have_sigma = (last.sigma.array() > 0).all();
  const double nees = have_sigma ? e.cwiseQuotient(last.sigma).squaredNorm() : 0.0;
  const double limit_nees = math::chi2_quantile(th.confidence, 6.0);
  const bool fail = beyond && (!have_sigma || nees > limit_nees);
  CheckResult r{name, fail ? CheckStatus::kFail : beyond ? CheckStatus::kWithinSigma : CheckStatus::kPass, "", {}};
  r.message = fmt::format("error {:.1f} mm / {:.2f}°, limits {:.1f} mm / {:.2f}°", ep * 1e3, er, th.max_err_p_m * 1e3,
                          th.max_err_rot_deg);
  if (have_sigma) r.message += fmt::format(", NEES {:.1f} (per-axis σ; χ²₆({}) = {:.2f})", nees, th.confidence, limit_nees);
  if (beyond && !fail) r.message += ": beyond the limits but within its σ (see extrinsics.sigma)";
  if (fail && have_sigma) r.message += ": beyond the limits and its σ";
  if (!in.extrinsics_estimated) r.message += "; extrinsics held fixed, so this is the prior's error";
  r.values = {{"error_p_m", ep}, {"error_rot_deg", er}, {"limit_p_m", th.max_err_p_m},
              {"limit_rot_deg", th.max_err_rot_deg}};
  if (have_sigma) {
    r.values.emplace_back("nees_diag", nees);
    r.values.emplace_back("limit_nees", limit_nees);
  }
  return r;
}

CheckResult truth_objects(const CalibInput& in, const CalibThresholds& th) {
  const std::string name = "truth.objects";
  if (!in.dataset_absent_reason.empty()) return skipped(name, in.dataset_absent_reason);
  if (in.true_T_W_O.empty()) return skipped(name, "the dataset has no true object poses (roe.json truth)");
  const ObjectEstimate* anchor = find_anchor(in);
  if (!anchor) return inconclusive(name, "the run has no initialised anchor to compare relative to");
  const auto ta = in.true_T_W_O.find(anchor->id);
  if (ta == in.true_T_W_O.end())
    return skipped(name, fmt::format("the truth has no pose for the anchor (object {})", anchor->id));
  const auto anchor_sym = in.symmetries.find(anchor->id);
  const bool anchor_marked =
      std::find(in.symmetric_ids.begin(), in.symmetric_ids.end(), anchor->id) != in.symmetric_ids.end();
  if ((anchor_sym != in.symmetries.end() && !anchor_sym->second.empty()) || anchor_marked)
    return inconclusive(name, fmt::format("the anchor (object {}) is symmetric: poses relative to it are defined "
                                          "only up to its symmetry",
                                          anchor->id));
  const Pose T_A_W = *anchor->T_O_W;
  std::vector<std::string> over, missing;
  std::vector<std::pair<std::string, double>> per_object;
  std::size_t checked = 0, explained = 0;
  double wp = 0.0, wr = 0.0;
  const double limit_nees = math::chi2_quantile(th.confidence, 6.0);
  for (const auto& o : in.objects) {
    if (o.anchor || !o.T_O_W) continue;
    const auto t = in.true_T_W_O.find(o.id);
    if (t == in.true_T_W_O.end()) {
      missing.push_back(std::to_string(o.id));
      continue;
    }
    ++checked;
    const Pose est = relative_to_anchor(T_A_W, *o.T_O_W);
    Pose tru = ta->second.inverse() * t->second;
    // A symmetric object: the equivalent true pose T_A_O · S nearest the estimate (z = T_O_A).
    const auto sym = in.symmetries.find(o.id);
    const bool symmetric = sym != in.symmetries.end() && !sym->second.empty();
    if (symmetric) tru = ekf::nearest_equivalent(est.inverse(), tru.inverse(), sym->second).inverse();
    const Vector6d e = math::pose_difference(tru, est);
    const double ep = e.head<3>().norm(), er = e.tail<3>().norm() * kDeg;
    wp = std::max(wp, ep);
    wr = std::max(wr, er);
    const bool have_sigma = (o.sigma_A_O.array() > 0).all();
    const double nees = have_sigma ? e.cwiseQuotient(o.sigma_A_O).squaredNorm() : 0.0;
    // Per object, for scripts (scripts/calib-truth-table.py): the error, its NEES over the per-axis σ
    // (0 without σ) and whether it was compared through a symmetry.
    const std::string key = fmt::format("object_{}_", o.id);
    per_object.insert(per_object.end(), {{key + "error_p_m", ep}, {key + "error_rot_deg", er}, {key + "nees", nees},
                                         {key + "symmetric", symmetric ? 1.0 : 0.0}});
    if (ep <= th.max_object_err_p_m && er <= th.max_object_err_rot_deg) continue;
    if (have_sigma && nees <= limit_nees) {
      ++explained;
      continue;
    }
    over.push_back(have_sigma ? fmt::format("object {}: {:.1f} mm / {:.2f}° (NEES {:.1f})", o.id, ep * 1e3, er, nees)
                              : fmt::format("object {}: {:.1f} mm / {:.2f}°", o.id, ep * 1e3, er));
  }
  const std::string no_truth = missing.empty() ? "" : "; no true pose for object(s) " + id_list(missing);
  if (checked == 0) return skipped(name, "no initialised object besides the anchor has a true pose" + no_truth);
  CheckResult r{name, !over.empty() ? CheckStatus::kFail : explained ? CheckStatus::kWithinSigma : CheckStatus::kPass,
                "", {}};
  r.message = over.empty()
                  ? fmt::format("{} object(s) relative to the anchor: largest error {:.1f} mm / {:.2f}°, limits "
                                "{:.1f} mm / {:.2f}°",
                                checked, wp * 1e3, wr, th.max_object_err_p_m * 1e3, th.max_object_err_rot_deg)
                  : fmt::format("error relative to the anchor beyond {:.1f} mm / {:.2f}° and its σ (χ²₆({}) = {:.2f}): {}",
                                th.max_object_err_p_m * 1e3, th.max_object_err_rot_deg, th.confidence, limit_nees,
                                id_list(over));
  if (explained)
    r.message += fmt::format("; {} object(s) beyond the limits but within their σ (see objects.sigma)", explained);
  r.message += no_truth;
  r.values = {{"objects", static_cast<double>(checked)}, {"error_p_max_m", wp}, {"error_rot_max_deg", wr},
              {"limit_p_m", th.max_object_err_p_m}, {"limit_rot_deg", th.max_object_err_rot_deg},
              {"beyond_limits_within_sigma", static_cast<double>(explained)}, {"limit_nees", limit_nees}};
  r.values.insert(r.values.end(), per_object.begin(), per_object.end());
  return r;
}

/// The one-sided z of `confidence`, and camera.time_offset's rule for a difference d ± σ from the declared
/// offset: fail when |d| − zσ is beyond the limit, pass when |d| + zσ is within it; in between the estimate is
/// too uncertain (both the online state and the detection–gyro correlation are judged by it).
double time_offset_z(const CalibThresholds& th) { return std::sqrt(math::chi2_quantile(2.0 * th.confidence - 1.0, 1.0)); }
CheckStatus time_offset_status(double d, double sigma, double z, double lim) {
  if (std::abs(d) - z * sigma > lim) return CheckStatus::kFail;
  if (std::abs(d) + z * sigma <= lim) return CheckStatus::kPass;
  return CheckStatus::kInconclusive;
}

/// camera.time_offset from the run's online state t̂_d ± σ (CalibInput::online_time_offset): the same rule as the
/// correlation's estimate below (pass / fail only with `confidence`), and the correlation, where it has an
/// estimate, as the independent check: the two disagreeing beyond their joint σ and the limit fails.
CheckResult online_time_offset_check(const CalibInput& in, const CalibThresholds& th) {
  const CalibInput::OnlineTimeOffset& o = *in.online_time_offset;
  CheckResult r{"camera.time_offset", CheckStatus::kInconclusive, "", {}};
  const double d = o.value_s - in.declared_time_offset_s;
  const double lim = th.max_time_offset_s, z = time_offset_z(th);
  r.status = time_offset_status(d, o.sigma_s, z, lim);
  r.message = fmt::format("the run estimated {:+.2f} ± {:.2f} ms online (dataset declares {:+.1f} ms): difference "
                          "{:+.2f} ± {:.2f} ms ({:.2f} σ for confidence {}), limit {:.1f} ms",
                          o.value_s * 1e3, o.sigma_s * 1e3, in.declared_time_offset_s * 1e3, d * 1e3,
                          z * o.sigma_s * 1e3, z, th.confidence, lim * 1e3);
  if (r.status == CheckStatus::kFail)
    r.message += fmt::format(" (roe run compensated it; set camera.time_offset_s to {:.4f} s?)", o.value_s);
  else if (r.status == CheckStatus::kInconclusive)
    r.message += ": too uncertain to decide";
  r.values = {{"online_estimate_s", o.value_s}, {"online_sigma_s", o.sigma_s}, {"declared_s", in.declared_time_offset_s},
              {"difference_s", d}, {"limit_s", lim}, {"z", z}};
  if (in.time_offset && in.time_offset->valid) {
    const TimeOffsetEstimate& e = *in.time_offset;
    const double c = e.offset_s - o.value_s, sc = std::hypot(e.sigma_s, o.sigma_s);
    const bool disagree = std::abs(c) - z * sc > lim;
    r.message += fmt::format("; independent check, detection-gyro correlation: {:+.1f} ± {:.1f} ms, {} ({:+.1f} ± "
                             "{:.1f} ms from the online estimate)",
                             e.offset_s * 1e3, e.sigma_s * 1e3, disagree ? "DISAGREES" : "consistent", c * 1e3,
                             z * sc * 1e3);
    if (disagree) r.status = CheckStatus::kFail;
    r.values.insert(r.values.end(), {{"estimate_s", e.offset_s}, {"sigma_s", e.sigma_s}, {"online_minus_correlation_s", -c}});
  } else {
    r.message += in.time_offset ? "; the detection-gyro correlation has no estimate (" + in.time_offset->reason + ")"
                                : "; the detection-gyro correlation was not run";
  }
  return r;
}

CheckResult camera_time_offset(const CalibInput& in, const CalibThresholds& th) {
  const std::string name = "camera.time_offset";
  if (in.online_time_offset) return online_time_offset_check(in, th);
  if (!in.time_offset)
    return skipped(name, in.time_offset_absent_reason.empty() ? "not estimated" : in.time_offset_absent_reason);
  const TimeOffsetEstimate& e = *in.time_offset;
  CheckResult r{name, CheckStatus::kInconclusive, "", {}};
  const std::string left_out =
      (e.symmetric_excluded ? fmt::format(" ({} detections of symmetric objects left out)", e.symmetric_excluded) : "") +
      (e.symmetric_used ? fmt::format(" ({} detections of symmetric objects used through their symmetry)", e.symmetric_used)
                        : "");
  if (!e.valid) {
    // The cost still falling at the edge of the search, with a likelihood ratio against the
    // declared offset beyond χ²₁: the offset is more than the search away from it.
    // Only when the search reaches beyond the limit does "beyond the search" mean "beyond the limit".
    const double limit_lr = math::chi2_quantile(th.confidence, 1.0);
    if (e.at_edge && e.edge_stable && e.edge_evidence > limit_lr &&
        std::abs(e.edge_offset_s - in.declared_time_offset_s) > th.max_time_offset_s) {
      r.status = CheckStatus::kFail;
      r.message = fmt::format("the cost is lowest at the edge of the search, {:+.1f} ms, and far lower than at the "
                              "declared {:+.1f} ms (likelihood ratio {:.1f} > χ²₁({}) = {:.2f}): the offset lies "
                              "beyond the search (widen --time-offset-search to estimate it)",
                              e.edge_offset_s * 1e3, in.declared_time_offset_s * 1e3, e.edge_evidence, th.confidence,
                              limit_lr);
      r.values = {{"edge_s", e.edge_offset_s}, {"declared_s", in.declared_time_offset_s},
                  {"edge_evidence", e.edge_evidence}, {"limit_evidence", limit_lr}};
      return r;
    }
    r.message = "no estimate: " + e.reason + left_out;
    return r;
  }
  const double d = e.offset_s - in.declared_time_offset_s;
  const double lim = th.max_time_offset_s, z = time_offset_z(th);
  r.status = time_offset_status(d, e.sigma_s, z, lim);  // decided only with `confidence` (one-sided)
  r.message = fmt::format("estimated {:+.1f} ± {:.1f} ms from {} detections{} (dataset declares {:+.1f} ms): "
                          "difference {:+.1f} ± {:.1f} ms ({:.2f} σ for confidence {}), limit {:.1f} ms",
                          e.offset_s * 1e3, e.sigma_s * 1e3, e.detections, left_out, in.declared_time_offset_s * 1e3,
                          d * 1e3, z * e.sigma_s * 1e3, z, th.confidence, lim * 1e3);
  if (r.status == CheckStatus::kFail)
    r.message += fmt::format(": the camera stamps disagree with the gyro (set camera.time_offset_s to {:.4f} s?)",
                             e.offset_s);
  else if (r.status == CheckStatus::kInconclusive)
    r.message += ": too uncertain to decide (more rotation, or less noisy detections, would tell)";
  r.values = {{"estimate_s", e.offset_s},         {"sigma_s", e.sigma_s},
              {"sigma_curvature_s", e.sigma_curvature_s}, {"sigma_cluster_s", e.sigma_cluster_s},
              {"sigma_jackknife_s", e.sigma_jackknife_s}, {"symmetric_excluded", static_cast<double>(e.symmetric_excluded)},
              {"symmetric_used", static_cast<double>(e.symmetric_used)},
              {"declared_s", in.declared_time_offset_s}, {"difference_s", d},
              {"limit_s", lim},                   {"z", z},
              {"rms_rate_deg_s", e.rms_rate_deg_s}, {"residual_correlation", e.residual_correlation}};
  return r;
}

void require_positive(double v, const char* what) {
  if (!(v > 0) || !std::isfinite(v)) throw InputError(fmt::format("{} must be a positive number (got {})", what, v));
}

}  // namespace

const char* to_string(CheckStatus s) {
  switch (s) {
    case CheckStatus::kPass: return "pass";
    case CheckStatus::kFail: return "fail";
    case CheckStatus::kInconclusive: return "inconclusive";
    case CheckStatus::kSkipped: return "skipped";
    case CheckStatus::kWithinSigma: return "within-sigma";
    case CheckStatus::kUnobservable: return "unobservable";
  }
  return "?";
}

bool CalibReport::failed() const {
  return std::any_of(checks.begin(), checks.end(), [](const CheckResult& c) { return c.status == CheckStatus::kFail; });
}

bool CalibReport::within_sigma() const {
  return std::any_of(checks.begin(), checks.end(),
                     [](const CheckResult& c) { return c.status == CheckStatus::kWithinSigma; });
}

bool CalibReport::unobservable() const {
  return std::any_of(checks.begin(), checks.end(),
                     [](const CheckResult& c) { return c.status == CheckStatus::kUnobservable; });
}

bool CalibReport::undecided() const {
  return std::any_of(checks.begin(), checks.end(),
                     [](const CheckResult& c) { return c.status == CheckStatus::kInconclusive; });
}

CalibReport check_calibration(const CalibInput& in, const CalibThresholds& th) {
  require_positive(th.max_sigma_p_m, "max_sigma_p_m");
  require_positive(th.max_sigma_rot_deg, "max_sigma_rot_deg");
  require_positive(th.settle_min_s, "settle_min_s");
  require_positive(th.max_drift_p_m, "max_drift_p_m");
  require_positive(th.max_drift_rot_deg, "max_drift_rot_deg");
  require_positive(th.max_object_sigma_p_m, "max_object_sigma_p_m");
  require_positive(th.max_object_sigma_rot_deg, "max_object_sigma_rot_deg");
  require_positive(th.max_err_p_m, "max_err_p_m");
  require_positive(th.max_err_rot_deg, "max_err_rot_deg");
  require_positive(th.max_object_err_p_m, "max_object_err_p_m");
  require_positive(th.max_object_err_rot_deg, "max_object_err_rot_deg");
  require_positive(th.max_time_offset_s, "max_time_offset_s");
  if (!(th.settle_fraction > 0 && th.settle_fraction <= 1))
    throw InputError(fmt::format("settle_fraction must be in (0, 1] (got {})", th.settle_fraction));
  if (!(th.confidence > 0.5 && th.confidence < 1))
    throw InputError(fmt::format("confidence must be in (0.5, 1) (got {})", th.confidence));
  using Check = CheckResult (*)(const CalibInput&, const CalibThresholds&);
  static const std::pair<const char*, Check> checks[] = {
      {"extrinsics.sigma", extrinsics_sigma}, {"extrinsics.settled", extrinsics_settled},
      {"extrinsics.prior", extrinsics_prior}, {"objects.sigma", objects_sigma},
      {"truth.extrinsics", truth_extrinsics}, {"truth.objects", truth_objects},
      {"camera.time_offset", camera_time_offset}};
  CalibReport rep;
  if (!in.estimate_absent_reason.empty()) {  // nothing to judge: every check says why
    for (const auto& [name, check] : checks) rep.checks.push_back(inconclusive(name, "cannot judge: " + in.estimate_absent_reason));
    return rep;
  }
  if (in.extrinsics.empty()) throw InputError("the run has no extrinsics trace (states.csv has no row)");
  for (const auto& [name, check] : checks) {
    rep.checks.push_back(check(in, th));
    ROE_CHECK(rep.checks.back().name == name, "calib-check: a check's name differs from its entry in the table");
  }
  return rep;
}

}  // namespace roe::calib
