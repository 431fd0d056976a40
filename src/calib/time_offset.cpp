#include "roe/calib/time_offset.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <limits>
#include <map>
#include <optional>

#include "roe/core/parallel.hpp"
#include "roe/ekf/symmetry.hpp"
#include "roe/math/so3.hpp"

namespace roe::calib {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;
/// Blocks of windows of the delete-a-block jackknife (fewer when there are fewer windows).
constexpr std::size_t kJackknifeBlocks = 10;
/// Candidates per side of a parabola fit at the least (the coarse-to-fine search's sub-grid for a fit).
constexpr double kFitPointsPerSide = 12.0;

/// The gyro's integrated rotation R_I0_I(t) at the IMU stamps (midpoint rule), slerped in between.
class GyroRotation {
 public:
  GyroRotation(const std::vector<ImuSample>& imu, const Eigen::Vector3d& bias) : imu_(imu) {
    q_.reserve(imu.size());
    q_.push_back(Eigen::Quaterniond::Identity());
    for (std::size_t k = 0; k + 1 < imu.size(); ++k) {
      const double dt = dt_seconds(imu[k].t_ns, imu[k + 1].t_ns);
      const Eigen::Vector3d w = 0.5 * (imu[k].gyro + imu[k + 1].gyro) - bias;
      q_.push_back((q_.back() * math::exp_quat(w * dt)).normalized());
    }
    // The parts of Eigen's slerp between neighbours that do not depend on the interpolation parameter,
    // computed once instead of at every call (at() is called for every detection at every candidate
    // offset); at() then gives bit for bit what q_[k].slerp(u, q_[k + 1]) gives.
    arc_.reserve(q_.size());
    const double one = 1.0 - Eigen::NumTraits<double>::epsilon();
    for (std::size_t k = 0; k + 1 < q_.size(); ++k) {
      Arc a;
      const double d = q_[k].dot(q_[k + 1]);
      a.negative = d < 0.0;
      a.linear = std::abs(d) >= one;
      if (!a.linear) {
        a.theta = std::acos(std::abs(d));
        a.sin_theta = std::sin(a.theta);
      }
      arc_.push_back(a);
    }
  }
  Timestamp begin() const { return imu_.front().t_ns; }
  Timestamp end() const { return imu_.back().t_ns; }
  /// R_I0_I at t (inside [begin, end]).
  Eigen::Quaterniond at(Timestamp t) const {
    auto it = std::upper_bound(imu_.begin(), imu_.end(), t,
                               [](Timestamp a, const ImuSample& s) { return a < s.t_ns; });
    std::size_t k = it == imu_.begin() ? 0 : static_cast<std::size_t>(it - imu_.begin()) - 1;
    if (k + 1 >= imu_.size()) return q_.back();
    const double span = dt_seconds(imu_[k].t_ns, imu_[k + 1].t_ns);
    const double u = span > 0 ? dt_seconds(imu_[k].t_ns, t) / span : 0.0;
    const Arc& a = arc_[k];
    double scale0 = 1.0 - u, scale1 = u;
    if (!a.linear) {
      scale0 = std::sin((1.0 - u) * a.theta) / a.sin_theta;
      scale1 = std::sin(u * a.theta) / a.sin_theta;
    }
    if (a.negative) scale1 = -scale1;
    return Eigen::Quaterniond(scale0 * q_[k].coeffs() + scale1 * q_[k + 1].coeffs());
  }
  /// |ω − b| at the IMU sample nearest to t.
  double rate(Timestamp t, const Eigen::Vector3d& bias) const {
    auto it = std::lower_bound(imu_.begin(), imu_.end(), t,
                               [](const ImuSample& s, Timestamp a) { return s.t_ns < a; });
    if (it == imu_.end()) --it;
    return (it->gyro - bias).norm();
  }

 private:
  struct Arc {
    bool linear = false, negative = false;
    double theta = 0.0, sin_theta = 0.0;
  };
  const std::vector<ImuSample>& imu_;
  std::vector<Eigen::Quaterniond> q_;
  std::vector<Arc> arc_;  ///< arc_[k]: from q_[k] to q_[k + 1]
};

/// Mean of unit quaternions (chordal) over the entries flagged in use, each sign aligned with `ref`
/// (a point of the cluster, so that no entry is near-orthogonal to it).
Eigen::Quaterniond mean_rotation(const std::vector<Eigen::Quaterniond>& q, const std::vector<char>& use,
                                 const Eigen::Quaterniond& ref) {
  Eigen::Vector4d s = Eigen::Vector4d::Zero();
  for (std::size_t i = 0; i < q.size(); ++i) {
    if (!use[i]) continue;
    const double sign = ref.coeffs().dot(q[i].coeffs()) < 0 ? -1.0 : 1.0;
    s += sign * q[i].coeffs();
  }
  if (s.norm() < 1e-12) return ref;
  Eigen::Quaterniond m;
  m.coeffs() = s.normalized();
  return m;
}

struct Window {
  std::vector<const Detection*> dets;
  /// The object's symmetry (null: none described). Each A_i is then replaced by its equivalent nearest
  /// the window's reference (with a continuous symmetry: turned about the axis to the nearest angle, which
  /// leaves no residual about the axis to first order).
  const ObjectSymmetry* sym = nullptr;
  /// The detection the window's mean starts from: the one with the most others within the truncation
  /// angle at the centre of the search (a robust point of the cluster, never an outlier when most
  /// detections agree). Fixed for every candidate offset, so that the cost does not jump when the
  /// start would change.
  std::size_t ref = 0;
};

/// The object orientation A = R_I0_O of a symmetric object turned to its equivalent A · S nearest `ref`
/// (the filter's choice, ekf::nearest_equivalent, on the rotations: z = A⁻¹, z' = S⁻¹ z).
Eigen::Quaterniond nearest_to(const Eigen::Quaterniond& ref, const Eigen::Quaterniond& A, const ObjectSymmetry* sym) {
  if (!sym) return A;
  const Eigen::Vector3d o = Eigen::Vector3d::Zero();
  return ekf::nearest_equivalent(Pose(ref.conjugate(), o), Pose(A.conjugate(), o), *sym).q.conjugate();
}

/// The index of the window's detection with the most others within `truncate_deg` of it at the offset
/// `shift` (the first such on ties); a symmetric object's others are compared through their equivalent
/// nearest it.
std::size_t robust_start(const GyroRotation& gyro, const Eigen::Quaterniond& q_I_C, const Window& w, Timestamp shift,
                         double truncate_deg) {
  std::vector<Eigen::Quaterniond> A;
  for (const Detection* d : w.dets) A.push_back(gyro.at(d->t_ns + shift) * q_I_C * d->T_C_O.q);
  std::size_t best = 0, most = 0;
  for (std::size_t i = 0; i < A.size(); ++i) {
    std::size_t k = 0;
    for (std::size_t j = 0; j < A.size(); ++j)
      k += math::angle_between(A[i], nearest_to(A[i], A[j], w.sym)) * kRadToDeg <= truncate_deg;
    if (k > most) best = i, most = k;
  }
  return best;
}

/// Cost terms of one candidate offset: truncated sum of squared angles [deg²] (in total and per
/// window), and the untruncated inlier sum and count (for the residual RMS and the curvature-based
/// standard error).
struct Cost {
  double truncated = 0.0, inlier_sum = 0.0;
  std::vector<double> per_window;
  std::size_t inliers = 0;
  double lag1_num = 0.0, lag1_den = 0.0;  ///< Σ e_i·e_{i+1} and Σ |e_i|² over consecutive inlier pairs
};

Cost evaluate(const GyroRotation& gyro, const Eigen::Quaterniond& q_I_C, const std::vector<Window>& windows,
              Timestamp shift, double truncate_deg) {
  Cost c;
  const double trunc2 = truncate_deg * truncate_deg;
  std::vector<Eigen::Quaterniond> A;
  std::vector<char> use;
  std::vector<Eigen::Vector3d> phi;
  std::vector<double> tau;
  c.per_window.reserve(windows.size());
  for (const auto& w : windows) {
    const double before = c.truncated;
    A.clear();
    tau.clear();
    for (const Detection* d : w.dets) {
      A.push_back(gyro.at(d->t_ns + shift) * q_I_C * d->T_C_O.q);
      tau.push_back(dt_seconds(w.dets.front()->t_ns, d->t_ns));
    }
    const std::size_t n = A.size();
    if (w.sym)
      for (std::size_t i = 0; i < n; ++i) A[i] = nearest_to(A[w.ref], A[i], w.sym);
    use.assign(n, 1);
    phi.assign(n, Eigen::Vector3d::Zero());
    // The window's mean orientation: from its robust start, the mean of the detections within the
    // truncation of it, then again over those within the truncation of that mean.
    Eigen::Quaterniond m = A[w.ref];
    for (int pass = 0; pass < 2; ++pass) {
      for (std::size_t i = 0; i < n; ++i) use[i] = math::angle_between(m, A[i]) * kRadToDeg <= truncate_deg;
      if (std::find(use.begin(), use.end(), 1) != use.end()) m = mean_rotation(A, use, A[w.ref]);
    }
    for (std::size_t i = 0; i < n; ++i) phi[i] = math::log_quat(m.conjugate() * A[i]) * kRadToDeg;
    // A constant plus a linear drift per window (a residual gyro bias), fitted twice over the inliers.
    Eigen::Vector3d c0 = Eigen::Vector3d::Zero(), beta = Eigen::Vector3d::Zero();
    for (int pass = 0; pass < 2; ++pass) {
      double s0 = 0, s1 = 0, s2 = 0;
      Eigen::Vector3d y0 = Eigen::Vector3d::Zero(), y1 = Eigen::Vector3d::Zero();
      for (std::size_t i = 0; i < n; ++i) {
        if (!use[i]) continue;
        s0 += 1;
        s1 += tau[i];
        s2 += tau[i] * tau[i];
        y0 += phi[i];
        y1 += tau[i] * phi[i];
      }
      const double det = s0 * s2 - s1 * s1;
      if (s0 >= 3 && det > 1e-12 * s0 * s0) {
        c0 = (s2 * y0 - s1 * y1) / det;
        beta = (s0 * y1 - s1 * y0) / det;
      } else if (s0 > 0) {
        c0 = y0 / s0;
        beta.setZero();
      }
      for (std::size_t i = 0; i < n; ++i) use[i] = (phi[i] - c0 - beta * tau[i]).squaredNorm() <= trunc2;
    }
    Eigen::Vector3d prev = Eigen::Vector3d::Zero();
    bool prev_in = false;
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d e = phi[i] - c0 - beta * tau[i];
      const double a2 = e.squaredNorm();
      c.truncated += std::min(a2, trunc2);
      const bool in = a2 <= trunc2;
      if (in) {
        c.inlier_sum += a2;
        ++c.inliers;
        if (prev_in) {
          c.lag1_num += prev.dot(e);
          c.lag1_den += 0.5 * (prev.squaredNorm() + a2);
        }
        prev = e;
      }
      prev_in = in;
    }
    c.per_window.push_back(c.truncated - before);
  }
  return c;
}

}  // namespace

TimeOffsetEstimate estimate_camera_time_offset(const std::vector<ImuSample>& imu, const Eigen::Vector3d& gyro_bias,
                                               const Eigen::Quaterniond& q_I_C,
                                               const std::vector<Detection>& detections,
                                               const TimeOffsetOptions& o) {
  TimeOffsetEstimate e;
  if (!(o.search_s > 0) || !(o.step_s > 0) || o.step_s > o.search_s || !(o.window_s > 0) ||
      !(o.truncate_deg > 0) || !(o.fit_halfwidth_s > 0)) {
    e.reason = "invalid options (search, step, window and truncation must be positive, step <= search)";
    return e;
  }
  if (imu.size() < 2) {
    e.reason = "fewer than 2 IMU samples";
    return e;
  }
  if (!std::isfinite(o.centre_s) || std::abs(o.centre_s) > 10.0) {
    e.reason = fmt::format("the declared offset {} s is not a plausible camera-IMU offset", o.centre_s);
    return e;
  }
  const GyroRotation gyro(imu, gyro_bias);
  const Timestamp lo = from_seconds(o.centre_s - o.search_s) - 1, hi = from_seconds(o.centre_s + o.search_s) + 1;

  // Windows per object over the detections whose every shifted stamp lies inside the IMU span.
  // Objects with a described symmetry are used through it; symmetric objects without one are left out
  // (docs/calib-check.md §3): their rotation is known only up to a symmetry the dataset does not describe.
  std::map<int, std::vector<const Detection*>> per_object;
  const auto symmetry_of = [&](int id) -> const ObjectSymmetry* {
    const auto it = o.symmetries.find(id);
    return it == o.symmetries.end() || it->second.empty() ? nullptr : &it->second;
  };
  for (const auto& d : detections) {
    const bool described = symmetry_of(d.object_id) != nullptr;
    if (!described &&
        std::find(o.symmetric_ids.begin(), o.symmetric_ids.end(), d.object_id) != o.symmetric_ids.end()) {
      ++e.symmetric_excluded;
      continue;
    }
    e.symmetric_used += described;
    if (d.t_ns + lo >= gyro.begin() && d.t_ns + hi <= gyro.end()) per_object[d.object_id].push_back(&d);
  }
  std::vector<Window> windows;
  const Timestamp win = from_seconds(o.window_s), declared = from_seconds(o.centre_s);
  double rate2 = 0.0;
  for (auto& [id, v] : per_object) {
    std::stable_sort(v.begin(), v.end(), [](const Detection* a, const Detection* b) { return a->t_ns < b->t_ns; });
    std::size_t i = 0;
    while (i < v.size()) {
      Window w;
      w.sym = symmetry_of(id);
      const Timestamp start = v[i]->t_ns;
      while (i < v.size() && v[i]->t_ns - start < win) w.dets.push_back(v[i++]);
      if (w.dets.size() < o.min_window) continue;
      for (const Detection* d : w.dets) {
        const double r = gyro.rate(d->t_ns + declared, gyro_bias);
        rate2 += r * r;
      }
      w.ref = robust_start(gyro, q_I_C, w, declared, o.truncate_deg);
      e.detections += w.dets.size();
      windows.push_back(std::move(w));
    }
  }
  e.windows = windows.size();
  if (e.detections < o.min_detections) {
    e.reason = fmt::format("{} detection(s) in windows of >= {} inside the IMU span; at least {} are needed",
                           e.detections, o.min_window, o.min_detections);
    return e;
  }
  e.rms_rate_deg_s = std::sqrt(rate2 / static_cast<double>(e.detections)) * kRadToDeg;
  if (e.rms_rate_deg_s < o.min_rate_deg_s) {
    e.reason = fmt::format("the camera hardly turns while it sees objects (RMS gyro rate {:.1f} deg/s < {:.1f}): "
                           "the offset is not observable",
                           e.rms_rate_deg_s, o.min_rate_deg_s);
    return e;
  }

  const auto n = static_cast<int>(std::llround(o.search_s / o.step_s));
  for (int k = -n; k <= n; ++k) e.grid_s.push_back(o.centre_s + k * o.step_s);
  const std::size_t N = e.grid_s.size();
  // Coarse to fine (docs/calib-check.md §3): the cost is evaluated on every `coarse_stride`-th candidate
  // of the grid, then at the full step only where the estimate looks: around each lowest point and
  // inside the parabola fits whose width asks for it. The candidates are evaluated on demand, once each,
  // in parallel batches; each into its own slot, so the result does not depend on the thread count.
  const std::size_t S = std::clamp<std::size_t>(o.coarse_stride, 1, N - 1);
  e.cost.assign(N, std::numeric_limits<double>::quiet_NaN());
  std::vector<std::vector<double>> per_window(N);  // [grid point][window]
  std::vector<char> done(N, 0);
  const unsigned threads = o.threads ? o.threads : available_cpus();
  const auto ensure = [&](const std::vector<std::size_t>& ks) {
    std::vector<std::size_t> todo;
    for (const std::size_t k : ks)
      if (!done[k]) done[k] = 1, todo.push_back(k);
    parallel_for(todo.size(), threads, [&](std::size_t i) {
      Cost c = evaluate(gyro, q_I_C, windows, from_seconds(e.grid_s[todo[i]]), o.truncate_deg);
      e.cost[todo[i]] = c.truncated;
      per_window[todo[i]] = std::move(c.per_window);
    });
  };
  // The candidates of a sub-grid of every `stride`-th point (and the search's upper edge).
  const auto on_grid = [&](std::size_t k, std::size_t stride) { return k % stride == 0 || k + 1 == N; };
  // A fit over ±half uses every stride-th candidate, at least kFitPointsPerSide per side (finer only where
  // the window is narrow: coarse points average the roughness of a wide window as well as fine ones).
  const auto stride_for = [&](double half) {
    return std::clamp<std::size_t>(static_cast<std::size_t>(half / (kFitPointsPerSide * o.step_s)), 1, S);
  };
  const auto window_points = [&](double centre, double half, std::size_t stride) {
    std::vector<std::size_t> ks;
    for (std::size_t k = 0; k < N; ++k)
      if (on_grid(k, stride) && std::abs(e.grid_s[k] - centre) <= half + 1e-12) ks.push_back(k);
    ensure(ks);
    return ks;
  };
  {
    std::vector<std::size_t> coarse;
    for (std::size_t k = 0; k < N; ++k)
      if (on_grid(k, S)) coarse.push_back(k);
    ensure(coarse);
  }
  // The blocks of the delete-a-block jackknife: K blocks of windows, contiguous in time (so that
  // windows of objects seen together go together). value(b, k) is the cost at candidate k without block
  // b (b = K: with every window).
  const std::size_t G = windows.size(), K = std::min<std::size_t>(kJackknifeBlocks, G);
  std::vector<std::size_t> order(G);
  for (std::size_t w = 0; w < G; ++w) order[w] = w;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return windows[a].dets.front()->t_ns < windows[b].dets.front()->t_ns;
  });
  const auto value = [&](std::size_t b, std::size_t k) {
    double c = e.cost[k];
    for (std::size_t j = b < K ? b * G / K : 0; b < K && j < (b + 1) * G / K; ++j) c -= per_window[k][order[j]];
    return c;
  };
  // The lowest candidate of a cost: the lowest coarse one, then (`refine`) the lowest of the full-step
  // candidates between its coarse neighbours (the first on ties). The jackknife's replicates start
  // their fits from the coarse one: a fit over ±fit_halfwidth_s does not depend on where it starts.
  const auto lowest = [&](std::size_t b, bool refine) {
    std::size_t best = 0;
    for (std::size_t k = 0; k < N; ++k)
      if (on_grid(k, S) && value(b, k) < value(b, best)) best = k;
    if (!refine) return best;
    std::vector<std::size_t> near;
    for (std::size_t k = best >= S - 1 ? best - (S - 1) : 0; k < N && k <= best + (S - 1); ++k) near.push_back(k);
    ensure(near);
    for (const std::size_t k : near)
      if (value(b, k) < value(b, best) || (value(b, k) == value(b, best) && k < best)) best = k;
    return best;
  };
  const std::size_t best = lowest(K, true);
  // Residual variance per scalar residual at a grid point (3 per detection; 6 per window absorbed by
  // the constant and the drift) and the variance inflation (1 + ρ)/(1 − ρ) for their lag-1
  // correlation ρ between consecutive detections of a window. False when there are too few residuals.
  const auto residual_stats = [&](std::size_t at, Cost& cb, double& s2, double& inflation) {
    cb = evaluate(gyro, q_I_C, windows, from_seconds(e.grid_s[at]), o.truncate_deg);
    const double dof = 3.0 * static_cast<double>(cb.inliers) - 6.0 * static_cast<double>(windows.size()) - 1.0;
    if (dof <= 0) return false;
    const double rho = cb.lag1_den > 0 ? std::clamp(cb.lag1_num / cb.lag1_den, 0.0, 0.95) : 0.0;
    s2 = cb.inlier_sum / dof;
    inflation = (1.0 + rho) / (1.0 - rho);
    return true;
  };
  const auto block_text = [&](std::size_t b) {
    const std::size_t w0 = b * G / K, w1 = (b + 1) * G / K;
    return fmt::format("without the windows from {:.1f} s to {:.1f} s (block {} of {})",
                       dt_seconds(gyro.begin(), windows[order[w0]].dets.front()->t_ns),
                       dt_seconds(gyro.begin(), windows[order[w1 - 1]].dets.back()->t_ns), b + 1, K);
  };
  if (best == 0 || best + 1 == N) {
    e.reason = fmt::format("the cost is lowest at the edge of the search ({:+.1f} ms ± {:.1f} ms): the offset may "
                           "lie beyond it",
                           o.centre_s * 1e3, o.search_s * 1e3);
    e.offset_s = e.grid_s[best];
    e.at_edge = true;
    e.edge_offset_s = e.grid_s[best];
    Cost cb;
    double s2 = 0.0, inflation = 1.0;
    ensure({static_cast<std::size_t>(n)});
    if (residual_stats(best, cb, s2, inflation) && s2 > 0)
      e.edge_evidence = (e.cost[static_cast<std::size_t>(n)] - e.cost[best]) / (s2 * inflation);
    // The edge is evidence only when no part of the data carries it alone: without any one block the
    // cost must still be lowest there.
    e.edge_stable = true;
    for (std::size_t b = 0; K >= 2 && b < K && e.edge_stable; ++b) {
      if (lowest(b, true) != best) {
        e.edge_stable = false;
        e.reason += "; but not stably: " + block_text(b) + " it is lowest elsewhere";
      }
    }
    return e;
  }
  // The cost is rough on the scale of the grid step (inlier sets change, the gyro is sampled), so the
  // minimum and the curvature come from a parabola fitted to it. The window is re-centred on the fitted
  // minimum until it stays, and its half-width is ±3σ of a first fit over ±fit_halfwidth_s (at least
  // ten grid steps): wide enough to average the roughness, narrow enough that the cost's departure
  // from a parabola (it is not quadratic over tens of ms when the motion is fast) does not bias the
  // vertex.
  const auto fit = [&](std::size_t b, double centre, double half, double& curv) {
    double base = std::numeric_limits<double>::infinity();  // a constant, for the conditioning
    for (std::size_t k = 0; k < N; ++k)
      if (done[k]) base = std::min(base, value(b, k));
    for (int iter = 0; iter < 8; ++iter) {
      Eigen::Matrix3d NtN = Eigen::Matrix3d::Zero();
      Eigen::Vector3d r = Eigen::Vector3d::Zero();
      for (const std::size_t k : window_points(centre, half, stride_for(half))) {
        const double x = e.grid_s[k] - centre;
        const Eigen::Vector3d f(1.0, x, x * x);
        NtN += f * f.transpose();
        r += f * (value(b, k) - base);
      }
      const Eigen::Vector3d abc = NtN.ldlt().solve(r);
      curv = 2.0 * abc(2);  // d²cost/dδ² [deg²/s²]
      if (!(curv > 0)) return centre;
      const double next = centre - abc(1) / curv;
      const bool settled = std::abs(next - centre) < 0.25 * o.step_s;
      centre = next;
      if (settled || std::abs(centre - o.centre_s) > o.search_s) break;
    }
    return centre;
  };
  // The whole estimate (lowest grid point, a fit over ±fit_halfwidth_s, then over ±`half`) of the cost
  // without block b; false when it has no minimum inside the search.
  const auto estimate = [&](std::size_t b, double half, double& offset) {
    const std::size_t low = lowest(b, false);
    if (low == 0 || low + 1 == N) return false;
    double c = 0.0;
    offset = fit(b, fit(b, e.grid_s[low], o.fit_halfwidth_s, c), half, c);
    return c > 0 && std::abs(offset - o.centre_s) <= o.search_s;
  };
  // The curvature-based standard error at an offset: var(δ) = 2 s² / cost'', inflated for the
  // residuals' lag-1 correlation; −1 when there are too few residuals.
  const auto sigma_at = [&](double offset, double curv, Cost& cb) {
    const double u = std::round((offset - o.centre_s + o.search_s) / o.step_s);
    const auto at = std::min(static_cast<std::size_t>(std::max(0.0, u)), N - 1);
    double s2 = 0.0, inflation = 1.0;
    if (!residual_stats(at, cb, s2, inflation) || !(curv > 0)) return -1.0;
    return std::sqrt(2.0 * s2 / curv * inflation);
  };
  // The cluster-robust standard error: each window's slope at the vertex, from the same least-squares
  // parabola as the total (the fit is linear in the costs, so the windows' slopes add up to the
  // total's, ≈ 0 at its vertex); var(δ) = G/(G−1) Σ_w slope_w² / cost''².
  const auto cluster_sigma = [&](double centre, double half, double curv) {
    if (G < 2 || !(curv > 0)) return 0.0;
    Eigen::Matrix3d NtN = Eigen::Matrix3d::Zero();
    std::vector<Eigen::Vector3d> r(G, Eigen::Vector3d::Zero());
    for (const std::size_t k : window_points(centre, half, stride_for(half))) {
      const double x = e.grid_s[k] - centre;
      const Eigen::Vector3d f(1.0, x, x * x);
      NtN += f * f.transpose();
      for (std::size_t w = 0; w < G; ++w) r[w] += f * per_window[k][w];
    }
    const auto ldlt = NtN.ldlt();
    double sum2 = 0.0;
    for (std::size_t w = 0; w < G; ++w) sum2 += std::pow(ldlt.solve(r[w])(1), 2);
    return std::sqrt(static_cast<double>(G) / static_cast<double>(G - 1) * sum2) / curv;
  };
  const auto not_observable = [&]() {
    e.reason = "the cost has no minimum near its lowest point: the offset is not observable from this motion";
    return e;
  };
  double curv = 0.0;
  Cost cb;
  double centre = fit(K, e.grid_s[best], o.fit_halfwidth_s, curv);
  if (!(curv > 0)) return not_observable();
  const double sigma1 = sigma_at(centre, curv, cb);
  if (sigma1 < 0) {
    e.reason = "too few inlier detections per window for an estimate";
    return e;
  }
  const double half = std::clamp(3.0 * std::max(sigma1, cluster_sigma(centre, o.fit_halfwidth_s, curv)),
                                 10.0 * o.step_s, o.fit_halfwidth_s);
  centre = fit(K, centre, half, curv);
  if (!(curv > 0)) return not_observable();
  e.offset_s = centre;
  if (std::abs(e.offset_s - o.centre_s) > o.search_s) {
    e.reason = fmt::format("the fitted minimum lies outside the search ({:+.1f} ms ± {:.1f} ms): the offset may "
                           "lie beyond it",
                           o.centre_s * 1e3, o.search_s * 1e3);
    return e;
  }
  e.sigma_curvature_s = sigma_at(centre, curv, cb);
  if (e.sigma_curvature_s < 0) {
    e.reason = "too few inlier detections per window for an estimate";
    return e;
  }
  e.sigma_cluster_s = cluster_sigma(centre, half, curv);
  // The delete-a-block jackknife: the whole estimate again with each of K blocks of windows (contiguous
  // in time, so that windows of objects seen together go together) left out. Both standard errors
  // above are local to the vertex; when the cost is jagged (a dip made by a few windows, inlier sets
  // that change with the offset) they can be far too small, and the replicates show it by moving.
  // var(δ) = (K−1)/K Σ_b (δ_b − δ̄)². A replicate without a minimum inside the search means the
  // minimum rests on a part of the data: no estimate.
  {
    std::vector<double> replicate;
    for (std::size_t b = 0; K >= 2 && b < K; ++b) {
      double offset = 0.0;
      if (!estimate(b, half, offset)) {
        e.reason = "the minimum is not stable: " + block_text(b) + " the cost has no minimum inside the search";
        return e;
      }
      replicate.push_back(offset);
    }
    if (replicate.size() >= 2) {
      double mean = 0.0, ss = 0.0;
      for (double r : replicate) mean += r / static_cast<double>(replicate.size());
      for (double r : replicate) ss += (r - mean) * (r - mean);
      e.sigma_jackknife_s = std::sqrt((static_cast<double>(K) - 1.0) / static_cast<double>(K) * ss);
    }
  }
  e.sigma_s = std::max({e.sigma_curvature_s, e.sigma_cluster_s, e.sigma_jackknife_s});
  e.rms_residual_deg = cb.inliers ? std::sqrt(cb.inlier_sum / static_cast<double>(cb.inliers)) : 0.0;
  e.residual_correlation = cb.lag1_den > 0 ? std::clamp(cb.lag1_num / cb.lag1_den, 0.0, 0.95) : 0.0;
  e.valid = true;
  return e;
}

}  // namespace roe::calib
