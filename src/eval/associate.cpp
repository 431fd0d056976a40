#include "roe/eval/associate.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <utility>

#include "roe/core/error.hpp"

namespace roe::eval {

std::string to_string(AssocPolicy p) {
  return p == AssocPolicy::kUnique ? "unique" : p == AssocPolicy::kInterpolate ? "interpolate" : "nearest";
}

AssocPolicy parse_assoc_policy(const std::string& name) {
  if (name == "nearest") return AssocPolicy::kNearest;
  if (name == "unique") return AssocPolicy::kUnique;
  if (name == "interpolate") return AssocPolicy::kInterpolate;
  throw InputError(fmt::format("unknown association policy '{}' (expected nearest, unique or interpolate)", name),
                   {"", 0, 0, "assoc"});
}

namespace {

constexpr double kSecondsPerDay = 86400.0;

void check_sorted(const std::vector<Timestamp>& t, const char* which) {
  for (std::size_t i = 1; i < t.size(); ++i) {
    if (t[i] < t[i - 1]) {
      throw InputError(
          fmt::format("{} stamps decrease at pose {} ({:.9f} s after {:.9f} s); sort the file first", which,
                      i + 1, to_seconds(t[i]), to_seconds(t[i - 1])));
    }
  }
}

Timestamp seconds_to_ns_checked(double s, const char* what) {
  if (!std::isfinite(s) || std::abs(s) > 9.0e9) {
    throw InputError(fmt::format("{} = {} s is not a usable time", what, s), {"", 0, 0, what});
  }
  return from_seconds(s);
}

/// Index of the element of sorted `s` (+ shift) nearest to `t`; on equal distance the earlier one,
/// and for a run of equal stamps its first element (numpy argmin semantics). `from` is where the search
/// starts: a lower bound of the answer's insertion point (0, or what the previous call with a smaller or
/// equal `t - shift` left there); it is advanced to the insertion point of `t - shift`.
std::size_t nearest(const std::vector<Timestamp>& s, Timestamp shift, Timestamp t, std::size_t& from) {
  // lower_bound on s[i] + shift >= t  <=>  s[i] >= t - shift, galloping from `from` (the association's
  // keys increase, so each search is short)
  const Timestamp key = t - shift;
  std::size_t lo = from, step = 1;
  while (lo + step < s.size() && s[lo + step] < key) lo += step, step *= 2;
  const auto first = s.begin() + static_cast<std::ptrdiff_t>(lo);
  const auto last = s.begin() + static_cast<std::ptrdiff_t>(std::min(s.size(), lo + step + 1));
  std::size_t j = static_cast<std::size_t>(std::lower_bound(first, last, key) - s.begin());
  from = j;
  if (j == s.size()) {
    j = s.size() - 1;
  } else if (j > 0) {
    const Timestamp d_next = s[j] - key;
    const Timestamp d_prev = key - s[j - 1];
    if (d_prev <= d_next) j = j - 1;
  }
  const Timestamp v = s[j];
  while (j > 0 && s[j - 1] == v) --j;
  return j;
}

std::size_t count_duplicates(const std::vector<Timestamp>& t) {
  std::size_t n = 0;
  for (std::size_t i = 1; i < t.size(); ++i) n += (t[i] == t[i - 1]);
  return n;
}

/// first index of the run of equal stamps each index belongs to
std::vector<std::size_t> run_ids(const std::vector<Timestamp>& t) {
  std::vector<std::size_t> r(t.size());
  for (std::size_t i = 0; i < t.size(); ++i) r[i] = (i > 0 && t[i] == t[i - 1]) ? r[i - 1] : i;
  return r;
}

// The checks associate() and overlap() share: a valid max_dt, sorted stamps. Returns max_dt and the
// offset in ns.
std::pair<Timestamp, Timestamp> checked_inputs(const std::vector<Timestamp>& t_est, const std::vector<Timestamp>& t_gt,
                                               const AssociationOptions& options) {
  if (!std::isfinite(options.max_dt_s) || options.max_dt_s < 0.0) {
    throw InputError(fmt::format("max_dt must be a finite value ≥ 0, got {}", options.max_dt_s),
                     {"", 0, 0, "max_dt"});
  }
  check_sorted(t_est, "estimate");
  check_sorted(t_gt, "ground-truth");
  return {seconds_to_ns_checked(options.max_dt_s, "max_dt"), seconds_to_ns_checked(options.offset_s, "t_offset")};
}

}  // namespace

Association associate(const std::vector<Timestamp>& t_est, const std::vector<Timestamp>& t_gt,
                      const AssociationOptions& options) {
  const auto [max_dt, offset] = checked_inputs(t_est, t_gt, options);

  Association a;
  a.n_duplicate_est = count_duplicates(t_est);
  a.n_duplicate_gt = count_duplicates(t_gt);
  if (t_est.empty() || t_gt.empty()) return a;

  // evo: iterate over the shorter trajectory (the estimate when both have the same length).
  const bool est_short = t_est.size() <= t_gt.size();
  const std::size_t n_short = est_short ? t_est.size() : t_gt.size();
  a.est_index.reserve(n_short);
  a.gt_index.reserve(n_short);
  a.dt_ns.reserve(n_short);
  std::size_t from = 0;  // the stamps of the shorter one increase: so do the insertion points
  for (std::size_t k = 0; k < n_short; ++k) {
    std::size_t ie, ig;
    if (est_short) {
      ie = k;
      ig = nearest(t_gt, 0, t_est[k] + offset, from);
    } else {
      // A repeated ground-truth stamp: its first pose is the ground truth at that time (the warning
      // evaluate() gives says so); the later poses of the run are not paired.
      if (k > 0 && t_gt[k] == t_gt[k - 1]) continue;
      ig = k;
      ie = nearest(t_est, offset, t_gt[k], from);
    }
    const Timestamp dt = t_gt[ig] - (t_est[ie] + offset);
    if (std::abs(dt) <= max_dt) {
      a.est_index.push_back(ie);
      a.gt_index.push_back(ig);
      a.dt_ns.push_back(dt);
    }
  }

  if (options.policy == AssocPolicy::kUnique && !a.est_index.empty()) {
    const std::size_t n = a.est_index.size();
    std::vector<std::size_t> order(n);
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
      return std::abs(a.dt_ns[x]) < std::abs(a.dt_ns[y]);
    });
    const auto est_run = run_ids(t_est);
    const auto gt_run = run_ids(t_gt);
    std::vector<char> used_est(t_est.size(), 0), used_gt(t_gt.size(), 0), keep(n, 0);
    for (std::size_t k : order) {
      const std::size_t re = est_run[a.est_index[k]], rg = gt_run[a.gt_index[k]];
      if (used_est[re] || used_gt[rg]) continue;
      used_est[re] = used_gt[rg] = 1;
      keep[k] = 1;
    }
    Association u;
    u.n_duplicate_est = a.n_duplicate_est;
    u.n_duplicate_gt = a.n_duplicate_gt;
    for (std::size_t k = 0; k < n; ++k) {
      if (!keep[k]) continue;
      u.est_index.push_back(a.est_index[k]);
      u.gt_index.push_back(a.gt_index[k]);
      u.dt_ns.push_back(a.dt_ns[k]);
    }
    u.n_dropped_unique = n - u.size();
    return u;
  }
  return a;
}

Overlap overlap(const std::vector<Timestamp>& t_est, const std::vector<Timestamp>& t_gt,
                const AssociationOptions& options) {
  const auto [max_dt, offset] = checked_inputs(t_est, t_gt, options);
  Overlap o;
  if (t_est.empty() || t_gt.empty()) return o;
  // In 128 bits: max_dt and the offset may be up to ~9e18 ns and epoch stamps are ~1.7e18 ns, so the
  // span's ends can lie outside int64 (they are clamped where they are stored or compared).
  using Wide = __int128;
  const Wide begin = std::max(Wide{t_est.front()} + offset, Wide{t_gt.front()}) - max_dt;
  const Wide end = std::min(Wide{t_est.back()} + offset, Wide{t_gt.back()}) + max_dt;
  if (begin > end) return o;
  const auto clamp = [](Wide v) {
    return static_cast<Timestamp>(std::clamp<Wide>(v, std::numeric_limits<Timestamp>::min(),
                                                   std::numeric_limits<Timestamp>::max()));
  };
  o.begin_ns = clamp(begin);
  o.end_ns = clamp(end);
  const auto count = [&](const std::vector<Timestamp>& t, Wide lo, Wide hi) {
    return static_cast<std::size_t>(std::upper_bound(t.begin(), t.end(), clamp(hi)) -
                                    std::lower_bound(t.begin(), t.end(), clamp(lo)));
  };
  o.n_est = count(t_est, begin - offset, end - offset);
  o.n_gt = count(t_gt, begin, end);
  return o;
}

std::string explain_no_match(const std::vector<Timestamp>& t_est, const std::vector<Timestamp>& t_gt,
                             const AssociationOptions& options) {
  if (t_est.empty()) return "the estimate has no poses";
  if (t_gt.empty()) return "the ground truth has no poses";
  const Timestamp offset = seconds_to_ns_checked(options.offset_s, "t_offset");
  const auto [emin, emax] = std::minmax_element(t_est.begin(), t_est.end());
  const auto [gmin, gmax] = std::minmax_element(t_gt.begin(), t_gt.end());
  const double e0 = to_seconds(*emin + offset), e1 = to_seconds(*emax + offset);
  const double g0 = to_seconds(*gmin), g1 = to_seconds(*gmax);
  // Closest distance over all estimate stamps (gt sorted: binary search).
  std::vector<Timestamp> gs(t_gt);
  std::sort(gs.begin(), gs.end());
  Timestamp best = std::numeric_limits<Timestamp>::max();
  for (Timestamp te : t_est) {
    std::size_t from = 0;
    const std::size_t j = nearest(gs, 0, te + offset, from);
    best = std::min(best, static_cast<Timestamp>(std::abs(gs[j] - (te + offset))));
  }
  std::string msg = fmt::format(
      "no estimate stamp is within max_dt = {} s of a ground-truth stamp (t_offset = {} s). "
      "Estimate stamps (with offset) span [{:.6f}, {:.6f}] s ({} poses), ground truth [{:.6f}, {:.6f}] s "
      "({} poses); the closest pair is {:.6g} s apart.",
      options.max_dt_s, options.offset_s, e0, e1, t_est.size(), g0, g1, t_gt.size(), to_seconds(best));
  // Likely causes.
  const double me = std::max(std::abs(e0), std::abs(e1)), mg = std::max(std::abs(g0), std::abs(g1));
  const double es = e1 - e0, gs_span = g1 - g0;
  // A unit mix-up shows as ranges that line up once one of them is scaled by 1e3, 1e6 or 1e9: the
  // scaled start lies near the other start, or the scaled range overlaps the other with the starts
  // close, AND the scaled span is comparable with the other span (within a factor 100: a ground truth
  // may cover a longer session than the estimate). Without the span test a trajectory in relative
  // time (starting near 0) "lines up" with any epoch-time one scaled by 1e-9.
  if (me > 0.0 && mg > 0.0) {
    for (int p : {3, 6, 9}) {
      for (int sign : {1, -1}) {
        const double f = std::pow(10.0, sign * p);
        const double s0 = e0 * f, s1 = e1 * f;
        const double tol = 0.01 * std::max(std::abs(g0), std::abs(s0)) + (g1 - g0);
        const bool lines_up =
            std::abs(s0 - g0) <= tol || (s0 <= g1 && g0 <= s1 && std::abs(s0 - g0) <= 0.5 * std::abs(g0));
        const double ss = es * f;
        const bool spans_match =
            es <= 0.0 || gs_span <= 0.0 || (ss <= 100.0 * gs_span && gs_span <= 100.0 * ss);
        if (lines_up && spans_match) {
          const char* unit = p == 9 ? "nanoseconds" : p == 6 ? "microseconds" : "milliseconds";
          msg += fmt::format(
              " The {} stamps line up with the {} stamps only when scaled by 1e{}: one file probably "
              "stores {} where seconds are expected (ns vs s mix-up); convert it or pass the right "
              "--est-format/--gt-format.",
              sign > 0 ? "estimate" : "ground-truth", sign > 0 ? "ground-truth" : "estimate", p, unit);
          return msg;
        }
      }
    }
  }
  // Relative vs epoch time: one trajectory starts within a day of 0 (time since the start of a
  // recording, e.g. a motion-capture take) and the other at an epoch time (1973 .. 2286 in seconds).
  const auto relative = [](double t0) { return std::abs(t0) <= kSecondsPerDay; };
  const auto epoch = [](double t0) { return t0 >= 1e8 && t0 < 1e10; };
  const double suggested = g0 - e0 + options.offset_s;  // aligns the starts (offset already included in e0)
  if ((relative(e0) && epoch(g0)) || (relative(g0) && epoch(e0))) {
    const bool gt_rel = relative(g0);
    msg += fmt::format(
        " The {} starts near 0 s (time since the start of its recording) while the {} uses absolute "
        "(epoch) time: they are on different clocks, not in different units. --t-offset {:.9f} aligns "
        "the starts (the true offset also includes any delay between the two recordings' starts).",
        gt_rel ? "ground truth" : "estimate", gt_rel ? "estimate" : "ground truth", suggested);
    if (gt_rel) {
      msg += fmt::format(
          " For a motion-capture take imported into a dataset, the clock offset belongs in the dataset: "
          "re-import it with `roe import mocap FILE --into DATASET --time-offset S` (t_imu = t_mocap + S; "
          "S = {:.9f} aligns the starts) or with --estimate-offset, which estimates S from the IMU.",
          -suggested);
    }
    return msg;
  }
  const bool overlap = e0 <= g1 && g0 <= e1;
  if (!overlap) {
    msg += fmt::format(
        " The time ranges do not overlap (different clocks or recordings?); if the clocks differ by a "
        "constant, pass it as --t-offset (e.g. {:.9f} aligns the starts).",
        suggested);
  } else {
    msg +=
        " The ranges overlap, so the stamps are sparser than max_dt or offset by a constant: increase "
        "--max-dt or set --t-offset.";
  }
  return msg;
}

}  // namespace roe::eval
