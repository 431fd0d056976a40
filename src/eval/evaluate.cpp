// One evaluation: association -> alignment -> APE -> RPE -> per-object traces (notes/eval.md §7).
#include "roe/eval/evaluate.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "roe/core/error.hpp"
#include "roe/core/parallel.hpp"
#include "roe/eval/interpolate.hpp"
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
  cov.reserve(a.size());
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

/// --kitti: the devkit's drift figures over the aligned pairs, in order.
void add_kitti(Report& r) {
  std::vector<Pose> est(r.n_pairs()), gt(r.n_pairs());
  for (std::size_t k = 0; k < r.n_pairs(); ++k) est[k] = r.est_aligned(k), gt[k] = r.gt(k);
  r.kitti = kitti_drift(est, gt);
  if (r.kitti->n_segments == 0)
    r.warnings.push_back(fmt::format("--kitti: no segment of 100 m or more (the ground truth's path is {:.1f} m)",
                                     r.path_length_gt_m));
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
  if (p.fit_body_pose && p.gt_body_pose)
    throw InputError("--fit-body-pose and --gt-body-pose both set the body pose: pass one", {"", 0, 0, "fit-body-pose"});
  if (p.fit_body_pose && p.align != AlignType::kSe3 && p.align != AlignType::kSim3 && p.align != AlignType::kPosYaw)
    throw InputError(fmt::format("--fit-body-pose needs a fitted alignment (se3, sim3 or posyaw), not --align {}",
                                 to_string(p.align)),
                     {"", 0, 0, "fit-body-pose"});
  if (p.t_start_ns && p.t_end_ns && *p.t_start_ns > *p.t_end_ns)
    throw InputError(fmt::format("--t-start {:.9f} lies after --t-end {:.9f}", to_seconds(*p.t_start_ns),
                                 to_seconds(*p.t_end_ns)),
                     {"", 0, 0, "t-start"});
  if (p.align_window_ns && p.align_window_ns->first > p.align_window_ns->second)
    throw InputError("--align-window T0:T1 needs T0 <= T1", {"", 0, 0, "align-window"});
  if (p.auto_offset && !(p.auto_offset_max_s > 0))
    throw InputError("--t-offset-max must be > 0", {"", 0, 0, "t-offset-max"});
  if (p.n_align != -1 && (p.align == AlignType::kOrigin || p.align == AlignType::kNone)) {
    // evo ignores --n_to_align with --align_origin; say so instead.
    warnings.push_back(fmt::format("--n-align {} is ignored with --align {}: {}", p.n_align, to_string(p.align),
                                   p.align == AlignType::kOrigin
                                       ? "origin alignment uses the first matched pose pair by definition"
                                       : "nothing is aligned"));
  }
  return warnings;
}

namespace {

bool in_window(Timestamp t, const std::optional<Timestamp>& lo, const std::optional<Timestamp>& hi) {
  return (!lo || t >= *lo) && (!hi || t <= *hi);
}

/// The ground truth the pairs index, with T_B_I applied to every pose when given.
void apply_body_pose(const GroundTruthInput& gt, const std::optional<Pose>& T_B_I, Report& r) {
  r.gt_t_ns = &gt.t_ns;
  r.gt_poses = &gt.poses;
  if (!T_B_I) return;
  auto p = std::make_shared<std::vector<Pose>>(gt.poses);
  for (Pose& x : *p) x = x * *T_B_I;
  r.owned_gt_poses = p;
  r.gt_poses = p.get();
}

/// --assoc interpolate: the ground truth resampled at every estimate stamp + offset (where it brackets the
/// stamp without a gap over 3 median periods).
void resample_ground_truth(const EstimateInput& est, Report& r) {
  if (r.params.assoc.policy != AssocPolicy::kInterpolate) return;
  const double rate = median_rate_hz(*r.gt_t_ns);
  const Timestamp max_gap = from_seconds(rate > 0 ? 3.0 / rate : 0.0);
  std::vector<StampedPose> sp;
  for (std::size_t i = 0; i < r.gt_t_ns->size(); ++i)
    if (sp.empty() || (*r.gt_t_ns)[i] > sp.back().t_ns) sp.push_back({(*r.gt_t_ns)[i], (*r.gt_poses)[i]});
  auto t = std::make_shared<std::vector<Timestamp>>();
  auto p = std::make_shared<std::vector<Pose>>();
  const Timestamp off = from_seconds(r.params.assoc.offset_s);
  for (const Timestamp te : est.t_ns) {
    if (!t->empty() && te + off <= t->back()) continue;  // a duplicated estimate stamp: one truth
    if (const auto x = interpolate_pose_at(sp, te + off, max_gap)) t->push_back(te + off), p->push_back(*x);
  }
  r.owned_gt_t_ns = t, r.owned_gt_poses = p;
  r.gt_t_ns = t.get(), r.gt_poses = p.get();
}

/// --t-start / --t-end: drops the pairs whose ground-truth stamp lies outside.
void crop_pairs(Report& r) {
  if (!r.params.t_start_ns && !r.params.t_end_ns) return;
  Association& a = r.association;
  Association kept = a;
  kept.est_index.clear(), kept.gt_index.clear(), kept.dt_ns.clear();
  for (std::size_t k = 0; k < a.size(); ++k)
    if (in_window((*r.gt_t_ns)[a.gt_index[k]], r.params.t_start_ns, r.params.t_end_ns))
      kept.est_index.push_back(a.est_index[k]), kept.gt_index.push_back(a.gt_index[k]), kept.dt_ns.push_back(a.dt_ns[k]);
  r.n_cropped = a.size() - kept.size();
  a = std::move(kept);
}

/// --t-offset auto, or the check that warns when the pairs look time-shifted.
void resolve_time_offset(const EstimateInput& est, Report& r) {
  const EvalParams& p = r.params;
  if (p.auto_offset) {
    r.time_offset =
        estimate_trajectory_offset(est.t_ns, est.poses, *r.gt_t_ns, *r.gt_poses, p.align, p.auto_offset_max_s);
    r.params.assoc.offset_s = r.time_offset->offset_s;
    const TrajectoryOffset& o = *r.time_offset;
    if (!o.refined)
      r.warnings.push_back(fmt::format("--t-offset auto: the APE refinement did not converge; the angular-rate "
                                       "correlation's {:.4f} s is used (correlation {:.2f})",
                                       o.offset_s, o.coarse.correlation));
    if (o.coarse.peak_at_edge)
      r.warnings.push_back(fmt::format("--t-offset auto: the correlation peaks at the edge of the ±{} s searched: "
                                       "the offset may lie beyond it",
                                       p.auto_offset_max_s));
    return;
  }
  // The check needs a ground truth dense enough to interpolate (not KITTI rows stamped by index).
  if (!p.check_offset || median_rate_hz(*r.gt_t_ns) < 10.0 || est.t_ns.size() < 20) return;
  try {
    r.offset_check = check_trajectory_offset(est.t_ns, est.poses, *r.gt_t_ns, *r.gt_poses, p.align, p.assoc.offset_s);
  } catch (const DataError&) {
    return;  // no alignment at some step: nothing to say
  }
  const OffsetCheck& c = *r.offset_check;
  if (c.valid && std::abs(c.shift_s) >= 0.01 && std::abs(c.shift_s) > 5.0 * c.sigma_s)
    r.warnings.push_back(fmt::format(
        "the pairs look time-shifted: the APE is smallest with the estimate stamps moved by {:+.4f} s (± {:.4f} s) "
        "from the offset evaluated ({} s): pass --t-offset auto to estimate and apply it, or --t-offset S",
        c.shift_s, c.sigma_s, p.assoc.offset_s));
}

/// --fit-body-pose: T_B_I from the pairs, applied to the ground truth the pairs index.
void fit_body(Report& r) {
  if (!r.params.fit_body_pose) return;
  const Association& a = r.association;
  r.body_pose = fit_body_pose(*r.est_poses, a.est_index, *r.gt_poses, a.gt_index, r.params.align, r.params.n_align);
  auto p = std::make_shared<std::vector<Pose>>(*r.gt_poses);
  for (Pose& x : *p) x = x * r.body_pose->T_B_I;
  r.owned_gt_poses = p;
  r.gt_poses = p.get();
  if (r.body_pose->lever_arm_rank < 3) r.warnings.push_back("--fit-body-pose: lever arm " + r.body_pose->verdict);
}

/// The alignment, from the pairs inside --align-window when one is given.
Alignment fit_alignment(const Report& r, unsigned threads) {
  const Association& a = r.association;
  const EvalParams& p = r.params;
  if (!p.align_window_ns) return compute_alignment(p.align, *r.est_poses, a.est_index, *r.gt_poses, a.gt_index, p.n_align, threads);
  std::vector<std::size_t> ei, gi;
  for (std::size_t k = 0; k < a.size(); ++k)
    if (in_window((*r.gt_t_ns)[a.gt_index[k]], p.align_window_ns->first, p.align_window_ns->second))
      ei.push_back(a.est_index[k]), gi.push_back(a.gt_index[k]);
  if (ei.empty())
    throw InputError(fmt::format("--align-window {:.3f}:{:.3f}: no matched pair lies in it (the pairs span {:.3f} to "
                                 "{:.3f} s)",
                                 to_seconds(p.align_window_ns->first), to_seconds(p.align_window_ns->second),
                                 to_seconds((*r.gt_t_ns)[a.gt_index.front()]), to_seconds((*r.gt_t_ns)[a.gt_index.back()])),
                     {"", 0, 0, "align-window"});
  return compute_alignment(p.align, *r.est_poses, ei, *r.gt_poses, gi, p.n_align, threads);
}

/// The alignment's tilt, and a warning naming --align posyaw above kTiltWarningDeg (SE(3)/Sim(3) only).
void check_tilt(Report& r, unsigned threads) {
  r.tilt_deg = alignment_tilt_deg(r.alignment);
  const AlignType t = r.alignment.type;
  if ((t != AlignType::kSe3 && t != AlignType::kSim3) || r.tilt_deg <= kTiltWarningDeg) return;
  const Association& a = r.association;
  try {
    const Alignment py = compute_alignment(AlignType::kPosYaw, *r.est_poses, a.est_index, *r.gt_poses, a.gt_index,
                                           r.params.n_align, threads);
    const Eigen::Quaterniond q = py.q();
    r.posyaw_rot_rmse_deg = compute_ape(r.n_pairs(), [&](std::size_t k) {
                              return std::pair<Pose, Pose>(aligned_pose(py, q, (*r.est_poses)[a.est_index[k]]), r.gt(k));
                            }, {}, threads, r.params.euler).rot_deg.rmse;
  } catch (const DataError&) {
  }
  r.warnings.push_back(fmt::format(
      "the {} alignment tilts the estimate's z axis by {:.2f} deg against the ground truth's: where both worlds are "
      "gravity-aligned (z up, as for visual-inertial estimates) that tilt is an error the alignment makes, and it "
      "enters every rotation figure (rotation RMSE {:.3f} deg; {}): consider --align posyaw",
      to_string(t), r.tilt_deg, r.ape.rot_deg.rmse,
      r.posyaw_rot_rmse_deg ? fmt::format("{:.3f} deg with --align posyaw", *r.posyaw_rot_rmse_deg)
                            : std::string("posyaw is not determined by these pairs")));
}

/// A swapped estimate and ground truth: the "ground truth" much sparser than the "estimate".
void check_swapped(Report& r) {
  const Overlap& ov = r.overlap;
  if (ov.n_gt >= 10 && ov.n_est >= 20 * ov.n_gt)
    r.warnings.push_back(fmt::format(
        "the estimate has {} poses and the ground truth {} in the span both cover ({:.0f} times fewer): a ground truth "
        "is usually the denser stream; check that --gt names the ground truth (evo's form takes the reference first)",
        ov.n_est, ov.n_gt, static_cast<double>(ov.n_est) / static_cast<double>(ov.n_gt)));
}

}  // namespace

Report evaluate(const EstimateInput& est, const GroundTruthInput& gt, const EvalParams& params) {
  Report r;
  r.params = params;
  r.n_est = est.t_ns.size();
  r.n_gt = gt.t_ns.size();
  apply_body_pose(gt, params.gt_body_pose, r);
  resolve_time_offset(est, r);
  resample_ground_truth(est, r);  // at the estimate's stamps + the offset resolved
  const AssociationOptions& ao = r.params.assoc;
  r.association = associate(est.t_ns, *r.gt_t_ns, ao);
  const Association& a = r.association;
  warn_duplicates(a, ao.policy, r.warnings);
  if (a.size() == 0) throw InputError(explain_no_match(est.t_ns, *r.gt_t_ns, ao), {est.source});
  r.overlap = overlap(est.t_ns, *r.gt_t_ns, ao);
  crop_pairs(r);
  if (a.size() == 0)
    throw InputError("no matched pair lies between --t-start and --t-end", {"", 0, 0, "t-start"});
  for (Timestamp d : a.dt_ns) r.max_abs_dt_s = std::max(r.max_abs_dt_s, std::abs(to_seconds(d)));
  // The most pairs to expect: the sparser stream's poses inside the span both trajectories cover (a
  // ground truth covering a longer session than the estimate is not a matching problem).
  const Overlap& ov = r.overlap;
  if (a.size() + r.n_cropped < ov.n_max() / 2) {
    r.warnings.push_back(fmt::format(
        "only {} of at most {} poses were matched ({} estimate and {} ground-truth poses lie in the span "
        "[{:.6f}, {:.6f}] s both cover): check --max-dt / --t-offset",
        a.size() + r.n_cropped, ov.n_max(), ov.n_est, ov.n_gt, to_seconds(ov.begin_ns), to_seconds(ov.end_ns)));
  }
  check_swapped(r);
  r.est_t_ns = &est.t_ns;
  r.est_poses = &est.poses;
  fit_body(r);
  const unsigned threads = params.threads ? params.threads : available_cpus();
  r.alignment = fit_alignment(r, threads);
  r.alignment_q = r.alignment.q();
  r.cov = aligned_covariances(est, r, r.warnings);
  r.ape = compute_ape(
      r.n_pairs(), [&r](std::size_t k) { return std::pair<Pose, Pose>(r.est_aligned(k), r.gt(k)); }, r.cov, threads,
      params.euler);
  check_tilt(r, threads);
  add_gauge_consistency(est, r);
  add_body_rotation(r, threads);
  if (params.euler != EulerMetric::kError)
    r.warnings.push_back(fmt::format(
        "--euler {}: the per-axis Euler figures are differences of absolute angles, not a rotation error ({:.2f} % "
        "of the pairs jumped by 360 deg on some axis); the rotation error's figures are given beside them",
        to_string(params.euler), 100.0 * r.ape.jump_share_any));
  if ((params.align == AlignType::kSe3 || params.align == AlignType::kSim3) && params.n_align < 0 &&
      !params.align_window_ns && r.ape.pos_mean_m.cwiseAbs().maxCoeff() > 1e-6)
    r.warnings.push_back("internal check: the mean position error after Umeyama is not ~0");
  if (params.align == AlignType::kNone)
    r.warnings.push_back("no alignment: the results depend on the arbitrary world frames of both trajectories");

  // Relative pose error of the aligned pairs (only a Sim(3) scale changes it), one block per delta.
  add_rpe(r);
  add_objects(est, gt, r);  // the detections against the ground truth as given
  add_detection_calibration(est, gt, r);
  parallel_for(2, threads, [&r](std::size_t k) {  // independent sums
    const auto& poses = *(k == 0 ? r.est_poses : r.gt_poses);
    const auto& index = k == 0 ? r.association.est_index : r.association.gt_index;
    (k == 0 ? r.path_length_est_m : r.path_length_gt_m) = path_length(r.n_pairs(), [&](std::size_t i) {
      const Eigen::Vector3d& p = poses[index[i]].p;
      return k == 0 ? r.alignment.apply(p) : p;  // the aligned estimate's position, as est_aligned() has it
    });
  });
  if (params.kitti) add_kitti(r);  // after the path lengths, which its warning quotes
  return r;
}

}  // namespace roe::eval
