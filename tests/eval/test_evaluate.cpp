// eval::evaluate, the I/O-free evaluation (association -> alignment -> APE -> RPE -> per-object traces):
// its typed report on trajectories built here, with figures known in closed form.
#include <catch2/catch.hpp>
#include <cmath>

#include "roe/core/error.hpp"
#include "roe/eval/evaluate.hpp"

using namespace roe;
using namespace roe::eval;

namespace {

struct Pair {
  std::vector<Timestamp> t;
  std::vector<Pose> gt, est;
};

/// A helix sampled at 10 Hz; the estimate is the ground truth in another frame (yaw 90°, shifted) with
/// a ±2 cm alternating error along z.
Pair helix(int n) {
  Pair p;
  const Pose T_E_G(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ())),
                   Eigen::Vector3d(1, 2, 3));
  for (int i = 0; i < n; ++i) {
    const double s = 0.1 * i;
    p.t.push_back(1'000'000'000LL + 100'000'000LL * i);
    const Pose g(Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * s, Eigen::Vector3d::UnitZ())),
                 Eigen::Vector3d(std::cos(s), std::sin(1.3 * s), 0.2 * s));
    p.gt.push_back(g);
    Pose e = T_E_G * g;
    e.p.z() += (i % 2) ? 0.02 : -0.02;
    p.est.push_back(e);
  }
  return p;
}

}  // namespace

TEST_CASE("evaluate: association, SE(3) alignment and APE in one typed report", "[eval][evaluate]") {
  const Pair p = helix(200);
  const std::vector<std::optional<PoseCovariance>> no_cov;
  EvalParams params;
  params.rpe.push_back(RpeOptions{});
  const Report r = evaluate({p.t, p.est, no_cov, nullptr, "est"}, {p.t, p.gt}, params);
  CHECK(r.n_est == 200);
  CHECK(r.association.size() == 200);
  CHECK(r.alignment.n_used == 200);
  // The alternating ±2 cm along z survives any rigid alignment almost unchanged.
  CHECK(r.ape.trans_m.rmse == Approx(0.02).epsilon(0.02));
  CHECK(r.ape.pos_rmse_m.x() < 1e-3);
  CHECK(r.ape.pos_rmse_m.z() == Approx(0.02).epsilon(0.02));
  CHECK(r.n_pairs() == 200);
  CHECK(r.rpe.size() == 1);
  CHECK(r.path_length_gt_m > 0.0);
  CHECK_FALSE(r.has_detections);
  CHECK(r.warnings.empty());
  CHECK(r.align_type() == AlignType::kSe3);
}

TEST_CASE("evaluate: per-object traces report all detections and the accepted ones apart", "[eval][evaluate]") {
  const Pair p = helix(100);
  // Object 7: every detection is the true pose (after the estimate's frame change) except every 4th,
  // rejected by the filter and 0.5 m off along x.
  const Pose T_E_G(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ())),
                   Eigen::Vector3d(1, 2, 3));
  std::vector<DetectionPose> det;
  for (std::size_t i = 0; i < p.t.size(); ++i) {
    DetectionPose d;
    d.t_ns = p.t[i];
    d.object_id = 7;
    d.T_W_I = T_E_G * p.gt[i];
    d.status = i % 4 == 0 ? "rejected" : "accepted";
    if (i % 4 == 0) d.T_W_I.p += T_E_G.q * Eigen::Vector3d(0.5, 0, 0);
    det.push_back(d);
  }
  DetectionPose none;  // a detection that gave no pose: counted, never matched
  none.t_ns = p.t.back();
  none.object_id = 9;
  none.status = "no_pose";
  none.T_W_I.p.setConstant(std::nan(""));
  det.push_back(none);
  const std::vector<std::optional<PoseCovariance>> no_cov;
  const Report r = evaluate({p.t, p.est, no_cov, &det, "est"}, {p.t, p.gt}, EvalParams{});
  REQUIRE(r.objects.size() == 2);
  const ObjectReport& o = r.objects[0];
  CHECK(o.object_id == 7);
  CHECK(o.n_detections == 100);
  CHECK(o.counts.at("rejected") == 25);
  CHECK(o.all.n == 100);
  CHECK(o.accepted.n == 75);
  // All: 25 of 100 are 0.5 m off along x -> RMSE 0.5 · √0.25 = 0.25 m (± the alignment's small error).
  CHECK(o.all.ape_trans_rmse_m == Approx(0.25).epsilon(0.05));
  CHECK(o.accepted.ape_trans_rmse_m < 0.03);
  CHECK(r.objects[1].n_valid_pose == 0);
  CHECK(r.objects[1].all.n == 0);
  CHECK(r.detections_aligned.size() == det.size());
}

TEST_CASE("evaluate: no match and bad parameters are InputErrors naming the source or the option",
          "[eval][evaluate]") {
  const Pair p = helix(20);
  std::vector<Timestamp> late = p.t;
  for (auto& t : late) t += 3'600'000'000'000LL;
  const std::vector<std::optional<PoseCovariance>> no_cov;
  try {
    (void)evaluate({late, p.est, no_cov, nullptr, "my_est.tum"}, {p.t, p.gt}, EvalParams{});
    FAIL("no exception");
  } catch (const InputError& e) {
    CHECK(e.context().file == "my_est.tum");
  }
  EvalParams bad;
  bad.n_align = 0;
  CHECK_THROWS_AS(check_params(bad), InputError);
  bad = EvalParams{};
  bad.rpe = {RpeOptions{}, RpeOptions{}};
  CHECK_THROWS_WITH(check_params(bad), Catch::Contains("twice"));
  EvalParams origin;
  origin.align = AlignType::kOrigin;
  origin.n_align = 5;
  CHECK(check_params(origin).size() == 1);  // --n-align is ignored with origin: said, not silent
}

TEST_CASE("evaluate: the report is the same bit for bit on any number of threads, and as on copied pairs",
          "[eval][evaluate]") {
  // 40000 poses: several parallel tasks. The estimate at every third ground-truth stamp (shifted by
  // 2 ms), so the pairs' indices differ from 0, 1, 2, ...
  const Pair p = helix(40000);
  std::vector<Timestamp> t_est;
  std::vector<Pose> est;
  for (std::size_t i = 0; i < p.t.size(); i += 3) {
    t_est.push_back(p.t[i] + 2'000'000);
    est.push_back(p.est[i]);
  }
  const std::vector<std::optional<PoseCovariance>> no_cov;
  for (const AlignType type : {AlignType::kSe3, AlignType::kSim3, AlignType::kPosYaw, AlignType::kOrigin}) {
    CAPTURE(to_string(type));
    EvalParams params;
    params.align = type;
    params.rpe.push_back(RpeOptions{});
    params.threads = 1;
    const Report one = evaluate({t_est, est, no_cov, nullptr, "est"}, {p.t, p.gt}, params);
    params.threads = 3;
    const Report three = evaluate({t_est, est, no_cov, nullptr, "est"}, {p.t, p.gt}, params);
    REQUIRE(one.n_pairs() == est.size());
    REQUIRE(three.n_pairs() == est.size());
    CHECK(one.association.gt_index[100] == 300);
    CHECK(one.alignment.R == three.alignment.R);
    CHECK(one.alignment.t == three.alignment.t);
    CHECK(one.alignment.s == three.alignment.s);
    CHECK(one.ape.trans_m.rmse == three.ape.trans_m.rmse);
    CHECK(one.ape.trans_m.median == three.ape.trans_m.median);
    CHECK(one.ape.rot_deg.mean == three.ape.rot_deg.mean);
    CHECK(one.ape.pos_rmse_m == three.ape.pos_rmse_m);
    CHECK(one.ape.rpy_rmse_deg == three.ape.rpy_rmse_deg);
    CHECK(one.path_length_est_m == three.path_length_est_m);
    CHECK(one.path_length_gt_m == three.path_length_gt_m);
    CHECK(one.rpe[0].trans_m.rmse == three.rpe[0].trans_m.rmse);
    // The same as on copies of the matched pairs, aligned in place (the evaluation before 2026-12-02).
    std::vector<Pose> pe, pg;
    for (std::size_t k = 0; k < one.n_pairs(); ++k) {
      pe.push_back(est[one.association.est_index[k]]);
      pg.push_back(p.gt[one.association.gt_index[k]]);
    }
    const Alignment al = compute_alignment(type, pe, pg);
    CHECK(al.R == one.alignment.R);
    CHECK(al.t == one.alignment.t);
    if (type == AlignType::kSe3 || type == AlignType::kSim3) {  // and as on positions copied into a matrix
      Eigen::Matrix3Xd x(3, static_cast<Eigen::Index>(pe.size())), y(3, static_cast<Eigen::Index>(pe.size()));
      for (std::size_t k = 0; k < pe.size(); ++k) {
        x.col(static_cast<Eigen::Index>(k)) = pe[k].p;
        y.col(static_cast<Eigen::Index>(k)) = pg[k].p;
      }
      const Alignment u = umeyama_alignment(x, y, type == AlignType::kSim3);
      CHECK(u.R == one.alignment.R);
      CHECK(u.t == one.alignment.t);
      CHECK(u.s == one.alignment.s);
    }
    apply_alignment(al, pe);
    bool same_poses = true;
    for (std::size_t k = 0; k < pe.size(); ++k) {
      const Pose a = one.est_aligned(k);
      same_poses = same_poses && a.p == pe[k].p && a.q.coeffs() == pe[k].q.coeffs() && one.gt(k).p == pg[k].p &&
                   one.t_est(k) == t_est[one.association.est_index[k]];
    }
    CHECK(same_poses);
    const ApeResult ape = compute_ape(pe, pg, {}, 1);
    CHECK(ape.trans_m.rmse == one.ape.trans_m.rmse);
    CHECK(ape.rot_deg.median == one.ape.rot_deg.median);
    CHECK(ape.rpy_rmse_deg == one.ape.rpy_rmse_deg);
    const PoseError e = one.error(777);
    CHECK(e.dp == pose_error(pe[777], pg[777]).dp);
  }
}

TEST_CASE("evaluate: a duplicated ground-truth stamp uses its first pose, as the warning says", "[eval][evaluate]") {
  // A dense estimate and a sparse ground truth (the shorter one) with one duplicated row far off (x = 9 m):
  // the figures are those without the duplicate, and the warning names it.
  Pair p = helix(60);
  std::vector<Timestamp> t_est;
  std::vector<Pose> est;
  for (std::size_t i = 0; i + 1 < p.t.size(); ++i)
    for (int k = 0; k < 4; ++k) {  // 4 estimate poses per ground-truth pose: the ground truth is the shorter
      t_est.push_back(p.t[i] + 25'000'000LL * k);
      est.push_back(k == 0 ? p.est[i] : math::interpolate(p.est[i], p.est[i + 1], 0.25 * k));
    }
  const std::vector<std::optional<PoseCovariance>> no_cov;
  EvalParams params;
  params.threads = 1;
  const Report clean = evaluate({t_est, est, no_cov, nullptr, "est"}, {p.t, p.gt}, params);
  std::vector<Timestamp> t_dup = p.t;
  std::vector<Pose> gt_dup = p.gt;
  Pose far = p.gt[30];
  far.p.x() = 9.0;
  t_dup.insert(t_dup.begin() + 31, p.t[30]);
  gt_dup.insert(gt_dup.begin() + 31, far);
  const Report dup = evaluate({t_est, est, no_cov, nullptr, "est"}, {t_dup, gt_dup}, params);
  CHECK(dup.n_pairs() == clean.n_pairs());
  CHECK(dup.ape.pos_rmse_m == clean.ape.pos_rmse_m);
  CHECK(dup.ape.trans_m.rmse == clean.ape.trans_m.rmse);
  bool warned = false;
  for (const auto& w : dup.warnings)
    warned = warned || w.find("1 duplicated time stamp(s); the first pose of each is used") != std::string::npos;
  CHECK(warned);
}

TEST_CASE("evaluate: NEES over the matched poses that have a covariance, and a warning saying how many",
          "[eval][evaluate]") {
  const Pair p = helix(200);
  PoseCovariance c;
  c.P_p = Eigen::Matrix3d::Identity() * 0.02 * 0.02;
  c.P_theta = Eigen::Matrix3d::Identity() * 1e-4;
  const std::vector<std::optional<PoseCovariance>> all(200, c);
  std::vector<std::optional<PoseCovariance>> some(200);
  for (std::size_t i = 0; i < 200; i += 3) some[i] = c;  // as roe run's output level standard: some poses only
  const Report r_all = evaluate({p.t, p.est, all, nullptr, "est"}, {p.t, p.gt}, EvalParams{});
  const Report r_some = evaluate({p.t, p.est, some, nullptr, "est"}, {p.t, p.gt}, EvalParams{});
  REQUIRE(r_all.ape.anees_p);
  REQUIRE(r_some.ape.anees_p);
  // The ANEES is the mean of the per-pose NEES of the poses with a covariance (the same poses, the same
  // alignment: the covariance does not enter it).
  double sp = 0.0, sr = 0.0;
  std::size_t n = 0;
  for (std::size_t k = 0; k < r_all.n_pairs(); ++k) {
    if (!some[r_all.association.est_index[k]]) {
      CHECK(std::isnan(r_some.ape.nees[k].pos));
      continue;
    }
    sp += r_all.ape.nees[k].pos;
    sr += r_all.ape.nees[k].rot;
    CHECK(r_some.ape.nees[k].pos == r_all.ape.nees[k].pos);
    ++n;
  }
  CHECK(n == 67);
  CHECK(*r_some.ape.anees_p == Approx(sp / n).epsilon(1e-12));
  CHECK(*r_some.ape.anees_r == Approx(sr / n).epsilon(1e-12));
  REQUIRE(r_some.warnings.size() == 1);
  CHECK(r_some.warnings[0] == "NEES over the 67 of 200 matched poses that have a covariance (the estimate records it at "
                              "those poses only)");
  CHECK(r_all.warnings.empty());
  // No matched pose with a covariance: no NEES, and a warning.
  const std::vector<std::optional<PoseCovariance>> none(200);
  const Report r_none = evaluate({p.t, p.est, none, nullptr, "est"}, {p.t, p.gt}, EvalParams{});
  CHECK(r_none.cov.empty());
  CHECK_FALSE(r_none.ape.anees_p);
  REQUIRE(r_none.warnings.size() == 1);
  CHECK(r_none.warnings[0] == "NEES not computed: no matched estimate pose has a covariance");
}
