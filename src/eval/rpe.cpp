#include "roe/eval/rpe.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "roe/core/error.hpp"
#include "roe/math/so3.hpp"

namespace roe::eval {

namespace {

constexpr double kPi = 3.14159265358979323846;

/// Angle (rad) of the rotation between two orientations.
double angle_rad(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return math::log_quat(a.conjugate() * b).norm();
}

/// For a non-decreasing sequence `v` and each start i, the first j > i whose v[j] − v[i] is closest to
/// `delta` (on a tie the earlier index), kept when |v[j] − v[i] − delta| ≤ tol. O(n log n).
std::vector<std::pair<std::size_t, std::size_t>> closest_pairs(const std::vector<double>& v, double delta,
                                                               double tol) {
  std::vector<std::pair<std::size_t, std::size_t>> out;
  if (v.size() < 2) return out;
  for (std::size_t i = 0; i + 1 < v.size(); ++i) {
    const double target = v[i] + delta;
    const auto first = v.begin() + static_cast<std::ptrdiff_t>(i + 1);
    // Right candidate: the first index with v ≥ target (every earlier one is below it).
    const auto right = std::lower_bound(first, v.end(), target);
    std::size_t best = v.size();
    double best_err = std::numeric_limits<double>::infinity();
    // The error as evo computes it, |(v[j] − v[i]) − delta|, so that boundary cases agree.
    const auto err = [&](double vj) { return std::abs((vj - v[i]) - delta); };
    if (right != first) {
      // Left candidate: the largest value below target, at the first index holding that value.
      const double left_value = *(right - 1);
      const auto left = std::lower_bound(first, right, left_value);
      best = static_cast<std::size_t>(left - v.begin());
      best_err = err(left_value);
    }
    if (right != v.end() && err(*right) < best_err) {
      best = static_cast<std::size_t>(right - v.begin());
      best_err = err(*right);
    }
    if (best < v.size() && best_err <= tol) out.emplace_back(i, best);
  }
  return out;
}

std::vector<std::pair<std::size_t, std::size_t>> neighbours(const std::vector<std::size_t>& ids) {
  std::vector<std::pair<std::size_t, std::size_t>> out;
  for (std::size_t k = 1; k < ids.size(); ++k) out.emplace_back(ids[k - 1], ids[k]);
  return out;
}

}  // namespace

std::string to_string(DeltaUnit u) {
  switch (u) {
    case DeltaUnit::kFrames: return "f";
    case DeltaUnit::kMeters: return "m";
    case DeltaUnit::kSeconds: return "s";
    case DeltaUnit::kDegrees: return "deg";
    case DeltaUnit::kRadians: return "rad";
  }
  return "?";
}

DeltaUnit parse_delta_unit(const std::string& n) {
  if (n == "f" || n == "frames") return DeltaUnit::kFrames;
  if (n == "m" || n == "meters" || n == "metres") return DeltaUnit::kMeters;
  if (n == "s" || n == "seconds") return DeltaUnit::kSeconds;
  if (n == "deg" || n == "degrees") return DeltaUnit::kDegrees;
  if (n == "rad" || n == "radians") return DeltaUnit::kRadians;
  throw InputError(fmt::format("unknown RPE delta unit '{}' (expected f, m, s, deg or rad)", n),
                   {"", 0, 0, "rpe-unit"});
}

std::string to_string(PairsFrom p) { return p == PairsFrom::kEstimate ? "est" : "gt"; }

PairsFrom parse_pairs_from(const std::string& n) {
  if (n == "est" || n == "estimate") return PairsFrom::kEstimate;
  if (n == "gt" || n == "groundtruth" || n == "reference") return PairsFrom::kGroundTruth;
  throw InputError(fmt::format("unknown RPE pair source '{}' (expected est or gt)", n),
                   {"", 0, 0, "rpe-pairs-from"});
}

void check_rpe_options(const RpeOptions& o) {
  if (!std::isfinite(o.delta) || !(o.delta > 0.0))
    throw InputError(fmt::format("the RPE delta must be a number > 0, got {}", o.delta), {"", 0, 0, "rpe-delta"});
  if (o.unit == DeltaUnit::kFrames && (o.delta != std::floor(o.delta) || o.delta > 1e12))
    throw InputError(fmt::format("an RPE delta in frames must be an integer, got {}", o.delta),
                     {"", 0, 0, "rpe-delta"});
  if (o.unit == DeltaUnit::kDegrees && o.delta > 180.0)
    throw InputError(fmt::format("an RPE delta in degrees must be ≤ 180 (a rotation angle), got {}", o.delta),
                     {"", 0, 0, "rpe-delta"});
  if (o.unit == DeltaUnit::kRadians && o.delta > kPi)
    throw InputError(fmt::format("an RPE delta in radians must be ≤ π (a rotation angle), got {}", o.delta),
                     {"", 0, 0, "rpe-delta"});
  if (!std::isfinite(o.rel_tol) || o.rel_tol < 0.0)
    throw InputError(fmt::format("the RPE tolerance must be ≥ 0, got {}", o.rel_tol), {"", 0, 0, "rpe-tol"});
}

std::vector<std::pair<std::size_t, std::size_t>> rpe_index_pairs(const std::vector<Pose>& poses,
                                                                 const std::vector<Timestamp>& t_ns,
                                                                 const RpeOptions& o) {
  check_rpe_options(o);
  const std::size_t n = poses.size();
  if (o.unit == DeltaUnit::kSeconds && t_ns.size() != n)
    throw InputError(fmt::format("RPE: {} stamps for {} poses", t_ns.size(), n));
  std::vector<std::pair<std::size_t, std::size_t>> out;
  if (n < 2) return out;
  const double tol = o.rel_tol * o.delta;
  switch (o.unit) {
    case DeltaUnit::kFrames: {
      const auto d = static_cast<std::size_t>(o.delta);
      if (o.all_pairs) {
        for (std::size_t i = 0; i + d < n; ++i) out.emplace_back(i, i + d);
      } else {
        for (std::size_t i = 0; i + d < n; i += d) out.emplace_back(i, i + d);
      }
      return out;
    }
    case DeltaUnit::kMeters: {
      if (o.all_pairs) {
        std::vector<double> dist(n, 0.0);
        for (std::size_t k = 1; k < n; ++k) dist[k] = dist[k - 1] + (poses[k].p - poses[k - 1].p).norm();
        return closest_pairs(dist, o.delta, tol);
      }
      std::vector<std::size_t> ids;
      double walked = 0.0;
      for (std::size_t k = 0; k < n; ++k) {
        if (k > 0) walked += (poses[k].p - poses[k - 1].p).norm();
        if (walked >= o.delta) {
          ids.push_back(k);
          walked = 0.0;
        }
      }
      return neighbours(ids);
    }
    case DeltaUnit::kDegrees:
    case DeltaUnit::kRadians: {
      const double delta = o.unit == DeltaUnit::kDegrees ? o.delta * kPi / 180.0 : o.delta;
      const double tol_rad = o.unit == DeltaUnit::kDegrees ? tol * kPi / 180.0 : tol;
      if (o.all_pairs) {
        for (std::size_t i = 0; i + 1 < n; ++i)
          for (std::size_t j = i + 1; j < n; ++j) {
            const double a = angle_rad(poses[i].q, poses[j].q);
            if (a >= delta - tol_rad && a <= delta + tol_rad) out.emplace_back(i, j);
          }
        return out;
      }
      double turned = 0.0;
      std::size_t start = 0;
      for (std::size_t k = 1; k < n; ++k) {
        turned += angle_rad(poses[k - 1].q, poses[k].q);
        if (turned >= delta) {
          out.emplace_back(start, k);
          turned = 0.0;
          start = k;
        }
      }
      return out;
    }
    case DeltaUnit::kSeconds: {
      for (std::size_t k = 1; k < n; ++k)
        if (t_ns[k] < t_ns[k - 1])
          throw InputError(fmt::format("RPE: stamps decrease at matched pair {}", k));
      if (o.all_pairs) {
        std::vector<double> t(n);
        for (std::size_t k = 0; k < n; ++k) t[k] = dt_seconds(t_ns[0], t_ns[k]);
        return closest_pairs(t, o.delta, tol);
      }
      const Timestamp step = from_seconds(o.delta);
      std::vector<std::size_t> ids{0};
      for (std::size_t k = 1; k < n; ++k)
        if (t_ns[k] - t_ns[ids.back()] >= step) ids.push_back(k);
      return neighbours(ids);
    }
  }
  return out;
}

RpeResult compute_rpe(const std::vector<Pose>& est, const std::vector<Pose>& gt,
                      const std::vector<Timestamp>& t_est, const std::vector<Timestamp>& t_gt,
                      const RpeOptions& o) {
  if (est.size() != gt.size() || t_est.size() != est.size() || t_gt.size() != gt.size())
    throw InputError(fmt::format("RPE needs matched pairs: {} estimate poses, {} ground-truth poses, {}/{} stamps",
                                 est.size(), gt.size(), t_est.size(), t_gt.size()));
  RpeResult r;
  r.options = o;
  const bool from_gt = o.pairs_from == PairsFrom::kGroundTruth;
  const auto ids = rpe_index_pairs(from_gt ? gt : est, from_gt ? t_gt : t_est, o);
  // Cumulative ground-truth path, for each pair's length.
  std::vector<double> path(gt.size(), 0.0);
  for (std::size_t k = 1; k < gt.size(); ++k) path[k] = path[k - 1] + (gt[k].p - gt[k - 1].p).norm();
  std::vector<double> tn, an, pct;
  tn.reserve(ids.size());
  an.reserve(ids.size());
  for (const auto& [i, j] : ids) {
    RpePair p;
    p.i = i;
    p.j = j;
    const Pose Q = gt[i].inverse() * gt[j];
    const Pose P = est[i].inverse() * est[j];
    const Pose E = Q.inverse() * P;
    p.dp = E.p;
    p.trans_m = E.p.norm();
    p.rot_deg = math::log_quat(E.q).norm() * 180.0 / kPi;
    p.path_gt_m = path[j] - path[i];
    p.trans_pct = p.path_gt_m > 0.0 ? 100.0 * p.trans_m / p.path_gt_m : std::numeric_limits<double>::quiet_NaN();
    tn.push_back(p.trans_m);
    an.push_back(p.rot_deg);
    if (p.path_gt_m > 0.0) pct.push_back(p.trans_pct);
    r.pairs.push_back(p);
  }
  r.trans_m = compute_stats(tn);
  r.rot_deg = compute_stats(an);
  r.trans_pct = compute_stats(pct);
  return r;
}

}  // namespace roe::eval
