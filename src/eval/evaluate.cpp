// One evaluation: association -> alignment -> APE -> RPE -> per-object traces (notes/eval.md §7).
#include "roe/eval/evaluate.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "roe/core/error.hpp"
#include "roe/core/parallel.hpp"
#include "roe/math/euler.hpp"
#include "roe/math/so3.hpp"

namespace roe::eval {

namespace {

/// Length of the path through the positions position(0), position(1), ..., position(n - 1).
template <typename PositionAt>
double path_length(std::size_t n, const PositionAt& position) {
  double L = 0.0;
  if (n == 0) return L;
  Eigen::Vector3d prev = position(0);
  for (std::size_t i = 1; i < n; ++i) {
    const Eigen::Vector3d p = position(i);
    L += (p - prev).norm();
    prev = p;
  }
  return L;
}

void warn_duplicates(const Association& a, AssocPolicy policy, std::vector<std::string>& w) {
  if (a.n_duplicate_est)
    w.push_back(fmt::format("the estimate has {} duplicated time stamp(s) with different poses; {}",
                            a.n_duplicate_est,
                            policy == AssocPolicy::kNearest
                                ? "policy 'nearest' keeps every pose (as evo does); --assoc unique "
                                  "keeps the first of each (as cnspy does)"
                                : "policy 'unique' keeps the first pose of each (as cnspy does)"));
  if (a.n_duplicate_gt)
    w.push_back(fmt::format("the ground truth has {} duplicated time stamp(s); the first pose of each is used",
                            a.n_duplicate_gt));
}

/// The matched estimate covariances in the aligned frame. A matched pose without one (a run that records σ
/// after each image only) gets a nan covariance: its NEES is nan and left out of the ANEES, which a warning
/// says is over the poses that have one. Empty (with a warning) when no matched pose has a covariance.
std::vector<PoseCovariance> aligned_covariances(const EstimateInput& est, const Report& r,
                                                std::vector<std::string>& w) {
  std::vector<PoseCovariance> cov;
  if (est.cov.empty()) return cov;
  const Association& a = r.association;
  std::size_t with = 0;
  for (std::size_t k = 0; k < a.size(); ++k) with += est.cov[a.est_index[k]].has_value() ? 1 : 0;
  if (with == 0) {
    w.push_back("NEES not computed: no matched estimate pose has a covariance");
    return {};
  }
  if (with < a.size())
    w.push_back(fmt::format("NEES over the {} of {} matched poses that have a covariance (the estimate records it at "
                            "those poses only)",
                            with, a.size()));
  PoseCovariance none;
  none.P_p.setConstant(std::numeric_limits<double>::quiet_NaN());
  none.P_theta.setConstant(std::numeric_limits<double>::quiet_NaN());
  for (std::size_t k = 0; k < a.size(); ++k) {
    const std::optional<PoseCovariance>& c = est.cov[a.est_index[k]];
    cov.push_back(c ? align_covariance(*c, r.alignment.R, r.alignment.s) : none);
  }
  return cov;
}

ObjectFit fit(const std::vector<Pose>& est, const std::vector<Pose>& gt, EulerMetric euler) {
  ObjectFit f;
  f.n = est.size();
  if (est.empty()) return f;
  const ApeResult a = compute_ape(est, gt, {}, 0, euler);
  f.pos_rmse_m = a.pos_rmse_m;
  f.rpy_rmse_deg = a.rpy_rmse_deg;
  f.ape_trans_rmse_m = a.trans_m.rmse;
  f.ape_rot_rmse_deg = a.rot_deg.rmse;
  return f;
}

/// One object's trace: aligns its detections (appended to `aligned`) and fits them to the ground truth.
ObjectReport object_report(int id, const std::vector<const DetectionPose*>& rows, const Alignment& al,
                           const GroundTruthInput& gt, const AssociationOptions& ao, EulerMetric euler,
                           std::vector<DetectionPose>& aligned) {
  ObjectReport obj;
  obj.object_id = id;
  obj.n_detections = rows.size();
  std::vector<Timestamp> ts;
  std::vector<Pose> ps;
  std::vector<bool> accepted;
  for (const DetectionPose* r : rows) {
    ++obj.counts[r->status];
    const bool valid = r->T_W_I.p.allFinite();
    aligned.push_back(*r);
    if (!valid) continue;
    aligned.back().T_W_I = al.apply(r->T_W_I);
    ts.push_back(r->t_ns);
    ps.push_back(aligned.back().T_W_I);
    accepted.push_back(r->status == "accepted" || r->status == "initialized");
  }
  obj.n_valid_pose = ts.size();
  // Each trace against the ground truth, with the same association options (unique stamps per object).
  const Association ar = ts.empty() ? Association{} : associate(ts, gt.t_ns, ao);
  obj.n_matched = ar.size();
  for (const bool only_accepted : {false, true}) {
    std::vector<Pose> e2, g2;
    for (std::size_t k = 0; k < ar.size(); ++k) {
      if (only_accepted && !accepted[ar.est_index[k]]) continue;
      e2.push_back(ps[ar.est_index[k]]);
      g2.push_back(gt.poses[ar.gt_index[k]]);
    }
    (only_accepted ? obj.accepted : obj.all) = fit(e2, g2, euler);
  }
  return obj;
}

void add_objects(const EstimateInput& est, const GroundTruthInput& gt, Report& r) {
  if (!est.detections) return;
  r.has_detections = true;
  std::map<int, std::vector<const DetectionPose*>> by_obj;
  for (const DetectionPose& d : *est.detections) by_obj[d.object_id].push_back(&d);
  for (const auto& [id, rows] : by_obj)
    r.objects.push_back(
        object_report(id, rows, r.alignment, gt, r.params.assoc, r.params.euler, r.detections_aligned));
}

/// The σ calibration of the detections, with the ground truth's poses as T_W_I (the first pose of a
/// repeated stamp, as the association uses).
void add_detection_calibration(const EstimateInput& est, const GroundTruthInput& gt, Report& r) {
  if (!est.detection_sigmas) return;
  const DetectionSigmaInput& in = *est.detection_sigmas;
  DetectionTruth truth;
  truth.T_I_C = in.T_I_C;
  truth.camera_time_offset_s = in.camera_time_offset_s;
  truth.T_W_O = in.T_W_O;
  for (std::size_t i = 0; i < gt.t_ns.size(); ++i)
    if (truth.T_W_I.empty() || gt.t_ns[i] > truth.T_W_I.back().t_ns) truth.T_W_I.push_back({gt.t_ns[i], gt.poses[i]});
  r.detection_calibration = calibrate_detection_sigmas(in.detections, truth);
  for (const std::string& w : r.detection_calibration->warnings) r.warnings.push_back("detection sigmas: " + w);
}

/// NEES in the estimator's gauge (GaugeConsistency): the raw estimate and its own covariance.
void add_gauge_consistency(const EstimateInput& est, Report& r) {
  if (!est.gauge || r.cov.empty()) return;  // r.cov empty: no matched pose has a covariance
  GaugeConsistency g;
  g.truth = *est.gauge;
  const Pose T_Wg_Wt = g.truth.T_Wt_Wg.inverse();
  double sp = 0.0, sr = 0.0;
  std::size_t np = 0, nr = 0;
  for (std::size_t k = 0; k < r.n_pairs(); ++k) {
    if (r.t_est(k) < g.truth.t_from_ns) continue;
    const std::size_t ie = r.association.est_index[k];
    if (!est.cov[ie]) continue;  // no covariance at this pose
    ++g.n;
    const Nees e = pose_nees((*r.est_poses)[ie], T_Wg_Wt * r.gt(k), *est.cov[ie]);
    if (std::isfinite(e.pos)) sp += e.pos, ++np;
    if (std::isfinite(e.rot)) sr += e.rot, ++nr;
  }
  if (np > 0) g.anees_p = sp / static_cast<double>(np);
  if (nr > 0) g.anees_r = sr / static_cast<double>(nr);
  if (g.n == 0) r.warnings.push_back("NEES in the estimator's gauge not computed: no matched pose after the anchor's "
                                     "first sight");
  r.gauge = g;
}

/// The constant body-frame rotation after the alignment and the APE without it (BodyRotationFit).
void add_body_rotation(Report& r, unsigned threads) {
  if (!r.params.fit_body_rotation) return;
  BodyRotationFit b;
  b.q_off = mean_rotation(r.n_pairs(), [&r](std::size_t k) { return r.error(k).q_err; });
  b.angle_deg = math::log_quat(b.q_off).norm() * math::kDegPerRad;
  b.rpy_deg = math::euler_zyx(b.q_off.toRotationMatrix()) * math::kDegPerRad;
  const Eigen::Quaterniond q_off = b.q_off;
  b.ape = compute_ape(
      r.n_pairs(),
      [&r, q_off](std::size_t k) {
        Pose e = r.est_aligned(k);
        e.q = (e.q * q_off).normalized();
        return std::pair<Pose, Pose>(e, r.gt(k));
      },
      {}, threads, r.params.euler);
  r.body_rotation = b;
}

void add_rpe(Report& r) {
  if (r.params.rpe.empty()) return;
  // The RPE walks the matched pairs in many orders: copies of them, only here.
  const std::size_t n = r.n_pairs();
  std::vector<Pose> est(n), gt(n);
  std::vector<Timestamp> t_est(n), t_gt(n);
  parallel_ranges(n, kPairsPerTask, r.params.threads ? r.params.threads : available_cpus(),
                  [&](std::size_t b, std::size_t e) {
                    for (std::size_t k = b; k < e; ++k) {
                      est[k] = r.est_aligned(k);
                      gt[k] = r.gt(k);
                      t_est[k] = r.t_est(k);
                      t_gt[k] = r.t_gt(k);
                    }
                  });
  for (const RpeOptions& ro : r.params.rpe) {
    r.rpe.push_back(compute_rpe(est, gt, t_est, t_gt, ro));
    if (r.rpe.back().pairs.empty())
      r.warnings.push_back(fmt::format("RPE delta {} {}: no pair of matched poses is that far apart{}", ro.delta,
                                       to_string(ro.unit),
                                       ro.all_pairs ? fmt::format(" (within {} %)", 100.0 * ro.rel_tol) : ""));
  }
}

}  // namespace

std::vector<std::string> check_params(const EvalParams& p) {
  std::vector<std::string> warnings;
  if (!(p.assoc.max_dt_s >= 0.0) || !std::isfinite(p.assoc.max_dt_s))
    throw InputError(fmt::format("--max-dt must be ≥ 0, got {}", p.assoc.max_dt_s), {"", 0, 0, "max-dt"});
  if (p.n_align == 0 || p.n_align < -1)
    throw InputError(fmt::format("--n-align must be -1 (all) or ≥ 1, got {}", p.n_align),
                     {"", 0, 0, "n-align"});
  for (std::size_t i = 0; i < p.rpe.size(); ++i) {
    check_rpe_options(p.rpe[i]);
    for (std::size_t j = 0; j < i; ++j)
      if (p.rpe[j].delta == p.rpe[i].delta)  // two identical blocks would collide in rpe.csv and --summary
        throw InputError(fmt::format("--rpe-delta lists {} twice", p.rpe[i].delta), {"", 0, 0, "rpe-delta"});
  }
  if (p.n_align != -1 && (p.align == AlignType::kOrigin || p.align == AlignType::kNone)) {
    // evo ignores --n_to_align with --align_origin; say so instead.
    warnings.push_back(fmt::format("--n-align {} is ignored with --align {}: {}", p.n_align, to_string(p.align),
                                   p.align == AlignType::kOrigin
                                       ? "origin alignment uses the first matched pose pair by definition"
                                       : "nothing is aligned"));
  }
  return warnings;
}

Report evaluate(const EstimateInput& est, const GroundTruthInput& gt, const EvalParams& params) {
  Report r;
  r.params = params;
  r.n_est = est.t_ns.size();
  r.n_gt = gt.t_ns.size();
  const AssociationOptions& ao = params.assoc;

  r.association = associate(est.t_ns, gt.t_ns, ao);
  const Association& a = r.association;
  warn_duplicates(a, ao.policy, r.warnings);
  if (a.size() == 0) throw InputError(explain_no_match(est.t_ns, gt.t_ns, ao), {est.source});
  for (Timestamp d : a.dt_ns) r.max_abs_dt_s = std::max(r.max_abs_dt_s, std::abs(to_seconds(d)));
  // The most pairs to expect: the sparser stream's poses inside the span both trajectories cover (a
  // ground truth covering a longer session than the estimate is not a matching problem).
  r.overlap = overlap(est.t_ns, gt.t_ns, ao);
  const Overlap& ov = r.overlap;
  if (a.size() < ov.n_max() / 2) {
    r.warnings.push_back(fmt::format(
        "only {} of at most {} poses were matched ({} estimate and {} ground-truth poses lie in the span "
        "[{:.6f}, {:.6f}] s both cover): check --max-dt / --t-offset",
        a.size(), ov.n_max(), ov.n_est, ov.n_gt, to_seconds(ov.begin_ns), to_seconds(ov.end_ns)));
  }

  const unsigned threads = params.threads ? params.threads : available_cpus();
  r.alignment = compute_alignment(params.align, est.poses, a.est_index, gt.poses, a.gt_index, params.n_align, threads);
  r.alignment_q = r.alignment.q();
  r.est_t_ns = &est.t_ns;
  r.est_poses = &est.poses;
  r.gt_t_ns = &gt.t_ns;
  r.gt_poses = &gt.poses;
  r.cov = aligned_covariances(est, r, r.warnings);
  r.ape = compute_ape(
      r.n_pairs(), [&r](std::size_t k) { return std::pair<Pose, Pose>(r.est_aligned(k), r.gt(k)); }, r.cov, threads,
      params.euler);
  add_gauge_consistency(est, r);
  add_body_rotation(r, threads);
  if (params.euler != EulerMetric::kError)
    r.warnings.push_back(fmt::format(
        "--euler {}: the per-axis Euler figures are differences of absolute angles, not a rotation error ({:.2f} % "
        "of the pairs jumped by 360 deg on some axis); the rotation error's figures are given beside them",
        to_string(params.euler), 100.0 * r.ape.jump_share_any));
  if ((params.align == AlignType::kSe3 || params.align == AlignType::kSim3) && params.n_align < 0 &&
      r.ape.pos_mean_m.cwiseAbs().maxCoeff() > 1e-6)
    r.warnings.push_back("internal check: the mean position error after Umeyama is not ~0");
  if (params.align == AlignType::kNone)
    r.warnings.push_back("no alignment: the results depend on the arbitrary world frames of both trajectories");

  // Relative pose error of the aligned pairs (only a Sim(3) scale changes it), one block per delta.
  add_rpe(r);
  add_objects(est, gt, r);
  add_detection_calibration(est, gt, r);
  parallel_for(2, threads, [&r](std::size_t k) {  // independent sums
    const auto& poses = *(k == 0 ? r.est_poses : r.gt_poses);
    const auto& index = k == 0 ? r.association.est_index : r.association.gt_index;
    (k == 0 ? r.path_length_est_m : r.path_length_gt_m) = path_length(r.n_pairs(), [&](std::size_t i) {
      const Eigen::Vector3d& p = poses[index[i]].p;
      return k == 0 ? r.alignment.apply(p) : p;  // the aligned estimate's position, as est_aligned() has it
    });
  });
  return r;
}

}  // namespace roe::eval
