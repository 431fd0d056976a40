#include "roe/calib/calib_check.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>

#include "roe/core/error.hpp"
#include "roe/ekf/chi2.hpp"
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
  r.status = sp <= th.max_sigma_p_m && sr <= th.max_sigma_rot_deg ? CheckStatus::kPass : CheckStatus::kFail;
  r.message = fmt::format("final σ {:.1f} mm / {:.2f}° (largest axis; prior {:.1f} mm / {:.2f}°), limits {:.1f} mm / {:.2f}°",
                          sp * 1e3, sr, max_p(in.prior_sigma) * 1e3, max_rot_deg(in.prior_sigma),
                          th.max_sigma_p_m * 1e3, th.max_sigma_rot_deg);
  if (r.status == CheckStatus::kFail)
    r.message += sp > th.max_sigma_p_m && sp > 0.5 * max_p(in.prior_sigma)
                     ? ": the translation was hardly observed (more rotation about several axes helps)"
                     : ": not observed well enough";
  r.values = {{"sigma_p_x_m", s(0)},       {"sigma_p_y_m", s(1)},         {"sigma_p_z_m", s(2)},
              {"sigma_rot_x_deg", s(3) * kDeg}, {"sigma_rot_y_deg", s(4) * kDeg}, {"sigma_rot_z_deg", s(5) * kDeg},
              {"limit_p_m", th.max_sigma_p_m}, {"limit_rot_deg", th.max_sigma_rot_deg}};
  return r;
}

CheckResult extrinsics_settled(const CalibInput& in, const CalibThresholds& th) {
  const std::string name = "extrinsics.settled";
  if (!in.extrinsics_estimated) return skipped(name, "extrinsics held fixed (estimate_extrinsics: false)");
  const auto& tr = in.extrinsics;
  const double duration = dt_seconds(tr.front().t_ns, tr.back().t_ns);
  if (duration < 2.0 * th.settle_min_s)
    return skipped(name, fmt::format("the run is {:.1f} s long, shorter than twice the settle window ({:.1f} s)",
                                     duration, th.settle_min_s));
  const double window = std::min(duration, std::max(th.settle_min_s, th.settle_fraction * duration));
  const Timestamp from = tr.back().t_ns - from_seconds(window);
  const Pose& fin = tr.back().T_I_C;
  double dp = 0.0, dr = 0.0;
  for (const auto& s : tr) {
    if (s.t_ns < from) continue;
    dp = std::max(dp, (s.T_I_C.p - fin.p).norm());
    dr = std::max(dr, math::angle_between(s.T_I_C.q, fin.q) * kDeg);
  }
  CheckResult r{name, CheckStatus::kPass, "", {}};
  r.status = dp <= th.max_drift_p_m && dr <= th.max_drift_rot_deg ? CheckStatus::kPass : CheckStatus::kFail;
  r.message = fmt::format("over the last {:.1f} s the estimate stays within {:.1f} mm / {:.2f}° of its final value, "
                          "limits {:.1f} mm / {:.2f}°",
                          window, dp * 1e3, dr, th.max_drift_p_m * 1e3, th.max_drift_rot_deg);
  if (r.status == CheckStatus::kFail) r.message += ": still moving at the end of the run";
  r.values = {{"window_s", window},
              {"drift_p_m", dp},
              {"drift_rot_deg", dr},
              {"limit_p_m", th.max_drift_p_m},
              {"limit_rot_deg", th.max_drift_rot_deg}};
  return r;
}

CheckResult extrinsics_prior(const CalibInput& in, const CalibThresholds& th) {
  const std::string name = "extrinsics.prior";
  if (!in.extrinsics_estimated) return skipped(name, "extrinsics held fixed (estimate_extrinsics: false)");
  if (!(in.prior_sigma.array() > 0).all())
    return skipped(name, "the prior has a zero standard deviation on some axis");
  const Pose& fin = in.extrinsics.back().T_I_C;
  Vector6d d;
  d.head<3>() = fin.p - in.prior_T_I_C.p;
  d.tail<3>() = math::log_quat(in.prior_T_I_C.q.conjugate() * fin.q);
  const Vector6d z = d.cwiseQuotient(in.prior_sigma);
  const double d2 = z.squaredNorm();
  const double limit = ekf::chi2_quantile(th.prior_confidence, 6.0);
  CheckResult r{name, CheckStatus::kPass, "", {}};
  r.status = d2 <= limit ? CheckStatus::kPass : CheckStatus::kFail;
  Eigen::Index worst = 0;
  z.cwiseAbs().maxCoeff(&worst);
  static const char* axes[6] = {"p_x", "p_y", "p_z", "θ_x", "θ_y", "θ_z"};
  r.message = fmt::format("moved {:.1f} mm / {:.2f}° from the prior, Mahalanobis d² = {:.2f} (largest {} at {:.1f} σ), "
                          "limit χ²₆({}) = {:.2f}",
                          d.head<3>().norm() * 1e3, d.tail<3>().norm() * kDeg, d2, axes[worst], std::abs(z(worst)),
                          th.prior_confidence, limit);
  if (r.status == CheckStatus::kFail)
    r.message += ": the data disagree with the prior calibration (a wrong camchain, frame or camera?)";
  r.values = {{"shift_p_m", d.head<3>().norm()}, {"shift_rot_deg", d.tail<3>().norm() * kDeg}, {"d2", d2},
              {"limit_d2", limit}};
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
  CheckResult r{name, over.empty() ? CheckStatus::kPass : CheckStatus::kFail, "", {}};
  r.message = over.empty() ? fmt::format("{} object(s) relative to the anchor: largest σ {:.1f} mm / {:.2f}°, limits "
                                         "{:.1f} mm / {:.2f}°",
                                         checked, wp * 1e3, wr, th.max_object_sigma_p_m * 1e3,
                                         th.max_object_sigma_rot_deg)
                           : fmt::format("σ relative to the anchor beyond {:.1f} mm / {:.2f}°: {}",
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
  if (!in.true_T_I_C) return skipped(name, "the dataset has no true T_I_C (roe.json truth)");
  const auto& last = in.extrinsics.back();
  Vector6d e;
  e.head<3>() = last.T_I_C.p - in.true_T_I_C->p;
  e.tail<3>() = math::log_quat(in.true_T_I_C->q.conjugate() * last.T_I_C.q);
  const double ep = e.head<3>().norm(), er = e.tail<3>().norm() * kDeg;
  CheckResult r{name, ep <= th.max_err_p_m && er <= th.max_err_rot_deg ? CheckStatus::kPass : CheckStatus::kFail,
                "", {}};
  double nees = 0.0;
  bool have_sigma = (last.sigma.array() > 0).all();
  if (have_sigma) nees = e.cwiseQuotient(last.sigma).squaredNorm();
  r.message = fmt::format("error {:.1f} mm / {:.2f}°, limits {:.1f} mm / {:.2f}°", ep * 1e3, er, th.max_err_p_m * 1e3,
                          th.max_err_rot_deg);
  if (have_sigma) r.message += fmt::format(" (NEES {:.1f} with the per-axis σ, 6 dof)", nees);
  if (!in.extrinsics_estimated) r.message += "; extrinsics held fixed, so this is the prior's error";
  r.values = {{"error_p_m", ep}, {"error_rot_deg", er}, {"limit_p_m", th.max_err_p_m},
              {"limit_rot_deg", th.max_err_rot_deg}};
  if (have_sigma) r.values.emplace_back("nees_diag", nees);
  return r;
}

CheckResult truth_objects(const CalibInput& in, const CalibThresholds& th) {
  const std::string name = "truth.objects";
  if (in.true_T_W_O.empty()) return skipped(name, "the dataset has no true object poses (roe.json truth)");
  const ObjectEstimate* anchor = find_anchor(in);
  if (!anchor) return skipped(name, "the run has no initialised anchor");
  const auto ta = in.true_T_W_O.find(anchor->id);
  if (ta == in.true_T_W_O.end())
    return skipped(name, fmt::format("the truth has no pose for the anchor (object {})", anchor->id));
  const Pose T_A_W = *anchor->T_O_W;
  std::vector<std::string> over, missing;
  std::size_t checked = 0;
  double wp = 0.0, wr = 0.0;
  for (const auto& o : in.objects) {
    if (o.anchor || !o.T_O_W) continue;
    const auto t = in.true_T_W_O.find(o.id);
    if (t == in.true_T_W_O.end()) {
      missing.push_back(std::to_string(o.id));
      continue;
    }
    ++checked;
    const Pose est = relative_to_anchor(T_A_W, *o.T_O_W);
    const Pose tru = ta->second.inverse() * t->second;
    const double ep = (est.p - tru.p).norm(), er = math::angle_between(est.q, tru.q) * kDeg;
    wp = std::max(wp, ep);
    wr = std::max(wr, er);
    if (ep > th.max_object_err_p_m || er > th.max_object_err_rot_deg)
      over.push_back(fmt::format("object {}: {:.1f} mm / {:.2f}°", o.id, ep * 1e3, er));
  }
  const std::string no_truth = missing.empty() ? "" : "; no true pose for object(s) " + id_list(missing);
  if (checked == 0) return skipped(name, "no initialised object besides the anchor has a true pose" + no_truth);
  CheckResult r{name, over.empty() ? CheckStatus::kPass : CheckStatus::kFail, "", {}};
  r.message = over.empty()
                  ? fmt::format("{} object(s) relative to the anchor: largest error {:.1f} mm / {:.2f}°, limits "
                                "{:.1f} mm / {:.2f}°",
                                checked, wp * 1e3, wr, th.max_object_err_p_m * 1e3, th.max_object_err_rot_deg)
                  : fmt::format("error relative to the anchor beyond {:.1f} mm / {:.2f}°: {}",
                                th.max_object_err_p_m * 1e3, th.max_object_err_rot_deg, id_list(over));
  r.message += no_truth;
  r.values = {{"objects", static_cast<double>(checked)}, {"error_p_max_m", wp}, {"error_rot_max_deg", wr},
              {"limit_p_m", th.max_object_err_p_m}, {"limit_rot_deg", th.max_object_err_rot_deg}};
  return r;
}

CheckResult camera_time_offset(const CalibInput& in, const CalibThresholds& th) {
  const std::string name = "camera.time_offset";
  if (!in.time_offset)
    return skipped(name, in.time_offset_absent_reason.empty() ? "not estimated" : in.time_offset_absent_reason);
  const TimeOffsetEstimate& e = *in.time_offset;
  CheckResult r{name, CheckStatus::kInconclusive, "", {}};
  if (!e.valid) {
    r.message = "no estimate: " + e.reason;
    return r;
  }
  const double d = e.offset_s - in.declared_time_offset_s;
  const double lim = th.max_time_offset_s;
  // Fail only on a difference both beyond the limit and significant (3σ); pass only when the
  // estimate is precise enough (σ within the limit) and within it.
  if (std::abs(d) > lim && std::abs(d) > 3.0 * e.sigma_s)
    r.status = CheckStatus::kFail;
  else if (std::abs(d) <= lim && e.sigma_s <= lim)
    r.status = CheckStatus::kPass;
  r.message = fmt::format("estimated {:+.1f} ± {:.1f} ms from {} detections (dataset declares {:+.1f} ms): "
                          "difference {:+.1f} ms, limit {:.1f} ms",
                          e.offset_s * 1e3, e.sigma_s * 1e3, e.detections, in.declared_time_offset_s * 1e3, d * 1e3,
                          lim * 1e3);
  if (r.status == CheckStatus::kFail)
    r.message += fmt::format(": the camera stamps disagree with the gyro (set camera.time_offset_s to {:.4f} s?)",
                             e.offset_s);
  else if (r.status == CheckStatus::kInconclusive)
    r.message += ": the estimate is too uncertain to decide (more rotation, or less noisy detections, would tell)";
  r.values = {{"estimate_s", e.offset_s},         {"sigma_s", e.sigma_s},
              {"declared_s", in.declared_time_offset_s}, {"difference_s", d},
              {"limit_s", lim},                   {"rms_rate_deg_s", e.rms_rate_deg_s},
              {"residual_correlation", e.residual_correlation}};
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
  }
  return "?";
}

bool CalibReport::failed() const {
  return std::any_of(checks.begin(), checks.end(), [](const CheckResult& c) { return c.status == CheckStatus::kFail; });
}

bool CalibReport::all_decided() const {
  return std::all_of(checks.begin(), checks.end(), [](const CheckResult& c) {
    return c.status == CheckStatus::kPass || c.status == CheckStatus::kFail;
  });
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
  if (!(th.prior_confidence > 0 && th.prior_confidence < 1))
    throw InputError(fmt::format("prior_confidence must be in (0, 1) (got {})", th.prior_confidence));
  if (in.extrinsics.empty()) throw InputError("the run has no extrinsics trace (states.csv has no row)");
  CalibReport rep;
  rep.checks.push_back(extrinsics_sigma(in, th));
  rep.checks.push_back(extrinsics_settled(in, th));
  rep.checks.push_back(extrinsics_prior(in, th));
  rep.checks.push_back(objects_sigma(in, th));
  rep.checks.push_back(truth_extrinsics(in, th));
  rep.checks.push_back(truth_objects(in, th));
  rep.checks.push_back(camera_time_offset(in, th));
  return rep;
}

}  // namespace roe::calib
