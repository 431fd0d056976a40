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

/// Why the options cannot give an estimate, or "" when they can.
std::string invalid_options(const TimeOffsetOptions& o, std::size_t imu_samples) {
  if (!(o.search_s > 0) || !(o.step_s > 0) || o.step_s > o.search_s || !(o.window_s > 0) ||
      !(o.truncate_deg > 0) || !(o.fit_halfwidth_s > 0))
    return "invalid options (search, step, window and truncation must be positive, step <= search)";
  if (imu_samples < 2) return "fewer than 2 IMU samples";
  if (!std::isfinite(o.centre_s) || std::abs(o.centre_s) > 10.0)
    return fmt::format("the declared offset {} s is not a plausible camera-IMU offset", o.centre_s);
  return "";
}

/// Windows per object over the detections whose every shifted stamp lies inside the IMU span. Objects with
/// a described symmetry are used through it; symmetric objects without one are left out (docs/calib-check.md
/// §3): their rotation is known only up to a symmetry the dataset does not describe. Counts what it used and
/// left out in `e`; `rate2` receives the sum of the squared gyro rates at the used detections.
std::vector<Window> make_windows(const GyroRotation& gyro, const Eigen::Vector3d& gyro_bias,
                                 const Eigen::Quaterniond& q_I_C, const std::vector<Detection>& detections,
                                 const TimeOffsetOptions& o, TimeOffsetEstimate& e, double& rate2) {
  const Timestamp lo = from_seconds(o.centre_s - o.search_s) - 1, hi = from_seconds(o.centre_s + o.search_s) + 1;
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
  rate2 = 0.0;
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
  return windows;
}

/// The search over the grid of candidate offsets: the cost evaluated on demand (coarse to fine), parabola
/// fits to it, their standard errors, and the same estimate without each block of windows (jackknife).
/// Writes the grid and the costs into the estimate it is given.
class OffsetSearch {
 public:
  OffsetSearch(const GyroRotation& gyro, const Eigen::Quaterniond& q_I_C, const std::vector<Window>& windows,
               const TimeOffsetOptions& o, TimeOffsetEstimate& e)
      : gyro_(gyro), q_I_C_(q_I_C), windows_(windows), o_(o), e_(e) {
    n_ = static_cast<int>(std::llround(o.search_s / o.step_s));
    for (int k = -n_; k <= n_; ++k) e.grid_s.push_back(o.centre_s + k * o.step_s);
    N_ = e.grid_s.size();
    // Coarse to fine (docs/calib-check.md §3): the cost is evaluated on every `coarse_stride`-th candidate
    // of the grid, then at the full step only where the estimate looks: around each lowest point and
    // inside the parabola fits whose width asks for it. The candidates are evaluated on demand, once each,
    // in parallel batches; each into its own slot, so the result does not depend on the thread count.
    S_ = std::clamp<std::size_t>(o.coarse_stride, 1, N_ - 1);
    e.cost.assign(N_, std::numeric_limits<double>::quiet_NaN());
    per_window_.resize(N_);
    done_.assign(N_, 0);
    threads_ = o.threads ? o.threads : available_cpus();
    std::vector<std::size_t> coarse;
    for (std::size_t k = 0; k < N_; ++k)
      if (on_grid(k, S_)) coarse.push_back(k);
    ensure(coarse);
    // The blocks of the delete-a-block jackknife: K blocks of windows, contiguous in time (so that
    // windows of objects seen together go together).
    G_ = windows.size();
    K_ = std::min<std::size_t>(kJackknifeBlocks, G_);
    order_.resize(G_);
    for (std::size_t w = 0; w < G_; ++w) order_[w] = w;
    std::stable_sort(order_.begin(), order_.end(), [&](std::size_t a, std::size_t b) {
      return windows[a].dets.front()->t_ns < windows[b].dets.front()->t_ns;
    });
  }

  std::size_t size() const { return N_; }
  std::size_t blocks() const { return K_; }
  std::size_t centre_index() const { return static_cast<std::size_t>(n_); }
  std::size_t window_count() const { return G_; }

  /// Evaluates the candidates not yet evaluated.
  void ensure(const std::vector<std::size_t>& ks) {
    std::vector<std::size_t> todo;
    for (const std::size_t k : ks)
      if (!done_[k]) done_[k] = 1, todo.push_back(k);
    parallel_for(todo.size(), threads_, [&](std::size_t i) {
      Cost c = evaluate(gyro_, q_I_C_, windows_, from_seconds(e_.grid_s[todo[i]]), o_.truncate_deg);
      e_.cost[todo[i]] = c.truncated;
      per_window_[todo[i]] = std::move(c.per_window);
    });
  }

  /// The cost at candidate k without block b (b = K: with every window).
  double value(std::size_t b, std::size_t k) const {
    double c = e_.cost[k];
    for (std::size_t j = b < K_ ? b * G_ / K_ : 0; b < K_ && j < (b + 1) * G_ / K_; ++j) c -= per_window_[k][order_[j]];
    return c;
  }

  /// The lowest candidate of a cost: the lowest coarse one, then (`refine`) the lowest of the full-step
  /// candidates between its coarse neighbours (the first on ties). The jackknife's replicates start
  /// their fits from the coarse one: a fit over ±fit_halfwidth_s does not depend on where it starts.
  std::size_t lowest(std::size_t b, bool refine) {
    std::size_t best = 0;
    for (std::size_t k = 0; k < N_; ++k)
      if (on_grid(k, S_) && value(b, k) < value(b, best)) best = k;
    if (!refine) return best;
    std::vector<std::size_t> near;
    for (std::size_t k = best >= S_ - 1 ? best - (S_ - 1) : 0; k < N_ && k <= best + (S_ - 1); ++k) near.push_back(k);
    ensure(near);
    for (const std::size_t k : near)
      if (value(b, k) < value(b, best) || (value(b, k) == value(b, best) && k < best)) best = k;
    return best;
  }

  /// Residual variance per scalar residual at a grid point (3 per detection; 6 per window absorbed by
  /// the constant and the drift) and the variance inflation (1 + ρ)/(1 − ρ) for their lag-1
  /// correlation ρ between consecutive detections of a window. False when there are too few residuals.
  bool residual_stats(std::size_t at, Cost& cb, double& s2, double& inflation) const {
    cb = evaluate(gyro_, q_I_C_, windows_, from_seconds(e_.grid_s[at]), o_.truncate_deg);
    const double dof = 3.0 * static_cast<double>(cb.inliers) - 6.0 * static_cast<double>(windows_.size()) - 1.0;
    if (dof <= 0) return false;
    const double rho = cb.lag1_den > 0 ? std::clamp(cb.lag1_num / cb.lag1_den, 0.0, 0.95) : 0.0;
    s2 = cb.inlier_sum / dof;
    inflation = (1.0 + rho) / (1.0 - rho);
    return true;
  }

  std::string block_text(std::size_t b) const {
    const std::size_t w0 = b * G_ / K_, w1 = (b + 1) * G_ / K_;
    return fmt::format("without the windows from {:.1f} s to {:.1f} s (block {} of {})",
                       dt_seconds(gyro_.begin(), windows_[order_[w0]].dets.front()->t_ns),
                       dt_seconds(gyro_.begin(), windows_[order_[w1 - 1]].dets.back()->t_ns), b + 1, K_);
  }

  /// The cost is rough on the scale of the grid step (inlier sets change, the gyro is sampled), so the
  /// minimum and the curvature come from a parabola fitted to it. The window is re-centred on the fitted
  /// minimum until it stays, and its half-width is ±3σ of a first fit over ±fit_halfwidth_s (at least
  /// ten grid steps): wide enough to average the roughness, narrow enough that the cost's departure
  /// from a parabola (it is not quadratic over tens of ms when the motion is fast) does not bias the
  /// vertex.
  double fit(std::size_t b, double centre, double half, double& curv) {
    double base = std::numeric_limits<double>::infinity();  // a constant, for the conditioning
    for (std::size_t k = 0; k < N_; ++k)
      if (done_[k]) base = std::min(base, value(b, k));
    for (int iter = 0; iter < 8; ++iter) {
      Eigen::Matrix3d NtN = Eigen::Matrix3d::Zero();
      Eigen::Vector3d r = Eigen::Vector3d::Zero();
      for (const std::size_t k : window_points(centre, half, stride_for(half))) {
        const double x = e_.grid_s[k] - centre;
        const Eigen::Vector3d f(1.0, x, x * x);
        NtN += f * f.transpose();
        r += f * (value(b, k) - base);
      }
      const Eigen::Vector3d abc = NtN.ldlt().solve(r);
      curv = 2.0 * abc(2);  // d²cost/dδ² [deg²/s²]
      if (!(curv > 0)) return centre;
      const double next = centre - abc(1) / curv;
      const bool settled = std::abs(next - centre) < 0.25 * o_.step_s;
      centre = next;
      if (settled || std::abs(centre - o_.centre_s) > o_.search_s) break;
    }
    return centre;
  }

  /// The whole estimate (lowest grid point, a fit over ±fit_halfwidth_s, then over ±`half`) of the cost
  /// without block b; false when it has no minimum inside the search.
  bool estimate(std::size_t b, double half, double& offset) {
    const std::size_t low = lowest(b, false);
    if (low == 0 || low + 1 == N_) return false;
    double c = 0.0;
    offset = fit(b, fit(b, e_.grid_s[low], o_.fit_halfwidth_s, c), half, c);
    return c > 0 && std::abs(offset - o_.centre_s) <= o_.search_s;
  }

  /// The curvature-based standard error at an offset: var(δ) = 2 s² / cost'', inflated for the
  /// residuals' lag-1 correlation; −1 when there are too few residuals.
  double sigma_at(double offset, double curv, Cost& cb) const {
    const double u = std::round((offset - o_.centre_s + o_.search_s) / o_.step_s);
    const auto at = std::min(static_cast<std::size_t>(std::max(0.0, u)), N_ - 1);
    double s2 = 0.0, inflation = 1.0;
    if (!residual_stats(at, cb, s2, inflation) || !(curv > 0)) return -1.0;
    return std::sqrt(2.0 * s2 / curv * inflation);
  }

  /// The cluster-robust standard error: each window's slope at the vertex, from the same least-squares
  /// parabola as the total (the fit is linear in the costs, so the windows' slopes add up to the
  /// total's, ≈ 0 at its vertex); var(δ) = G/(G−1) Σ_w slope_w² / cost''².
  double cluster_sigma(double centre, double half, double curv) {
    if (G_ < 2 || !(curv > 0)) return 0.0;
    Eigen::Matrix3d NtN = Eigen::Matrix3d::Zero();
    std::vector<Eigen::Vector3d> r(G_, Eigen::Vector3d::Zero());
    for (const std::size_t k : window_points(centre, half, stride_for(half))) {
      const double x = e_.grid_s[k] - centre;
      const Eigen::Vector3d f(1.0, x, x * x);
      NtN += f * f.transpose();
      for (std::size_t w = 0; w < G_; ++w) r[w] += f * per_window_[k][w];
    }
    const auto ldlt = NtN.ldlt();
    double sum2 = 0.0;
    for (std::size_t w = 0; w < G_; ++w) sum2 += std::pow(ldlt.solve(r[w])(1), 2);
    return std::sqrt(static_cast<double>(G_) / static_cast<double>(G_ - 1) * sum2) / curv;
  }

 private:
  /// The candidates of a sub-grid of every `stride`-th point (and the search's upper edge).
  bool on_grid(std::size_t k, std::size_t stride) const { return k % stride == 0 || k + 1 == N_; }
  /// A fit over ±half uses every stride-th candidate, at least kFitPointsPerSide per side (finer only where
  /// the window is narrow: coarse points average the roughness of a wide window as well as fine ones).
  std::size_t stride_for(double half) const {
    return std::clamp<std::size_t>(static_cast<std::size_t>(half / (kFitPointsPerSide * o_.step_s)), 1, S_);
  }
  std::vector<std::size_t> window_points(double centre, double half, std::size_t stride) {
    std::vector<std::size_t> ks;
    for (std::size_t k = 0; k < N_; ++k)
      if (on_grid(k, stride) && std::abs(e_.grid_s[k] - centre) <= half + 1e-12) ks.push_back(k);
    ensure(ks);
    return ks;
  }

  const GyroRotation& gyro_;
  const Eigen::Quaterniond& q_I_C_;
  const std::vector<Window>& windows_;
  const TimeOffsetOptions& o_;
  TimeOffsetEstimate& e_;
  int n_ = 0;                 ///< candidates each side of the centre
  std::size_t N_ = 0, S_ = 1;  ///< grid size, coarse stride
  std::size_t G_ = 0, K_ = 0;  ///< windows, jackknife blocks
  unsigned threads_ = 1;
  std::vector<std::vector<double>> per_window_;  ///< [grid point][window]
  std::vector<char> done_;
  std::vector<std::size_t> order_;  ///< windows in time order
};

/// The lowest candidate is the edge of the search: the offset may lie beyond it. Says how strongly the
/// cost points there, and whether it does without any one block of windows too.
TimeOffsetEstimate& edge_result(OffsetSearch& search, std::size_t best, const TimeOffsetOptions& o,
                                TimeOffsetEstimate& e) {
  e.reason = fmt::format("the cost is lowest at the edge of the search ({:+.1f} ms ± {:.1f} ms): the offset may "
                         "lie beyond it",
                         o.centre_s * 1e3, o.search_s * 1e3);
  e.offset_s = e.grid_s[best];
  e.at_edge = true;
  e.edge_offset_s = e.grid_s[best];
  Cost cb;
  double s2 = 0.0, inflation = 1.0;
  const std::size_t centre = search.centre_index();
  search.ensure({centre});
  if (search.residual_stats(best, cb, s2, inflation) && s2 > 0)
    e.edge_evidence = (e.cost[centre] - e.cost[best]) / (s2 * inflation);
  // The edge is evidence only when no part of the data carries it alone: without any one block the
  // cost must still be lowest there.
  e.edge_stable = true;
  const std::size_t K = search.blocks();
  for (std::size_t b = 0; K >= 2 && b < K && e.edge_stable; ++b) {
    if (search.lowest(b, true) != best) {
      e.edge_stable = false;
      e.reason += "; but not stably: " + search.block_text(b) + " it is lowest elsewhere";
    }
  }
  return e;
}

/// The delete-a-block jackknife: the whole estimate again with each of K blocks of windows (contiguous
/// in time, so that windows of objects seen together go together) left out. Both standard errors
/// of the vertex are local to it; when the cost is jagged (a dip made by a few windows, inlier sets
/// that change with the offset) they can be far too small, and the replicates show it by moving.
/// var(δ) = (K−1)/K Σ_b (δ_b − δ̄)². A replicate without a minimum inside the search means the
/// minimum rests on a part of the data: false, with the reason in `e`.
bool jackknife(OffsetSearch& search, double half, TimeOffsetEstimate& e) {
  const std::size_t K = search.blocks();
  std::vector<double> replicate;
  for (std::size_t b = 0; K >= 2 && b < K; ++b) {
    double offset = 0.0;
    if (!search.estimate(b, half, offset)) {
      e.reason = "the minimum is not stable: " + search.block_text(b) + " the cost has no minimum inside the search";
      return false;
    }
    replicate.push_back(offset);
  }
  if (replicate.size() >= 2) {
    double mean = 0.0, ss = 0.0;
    for (double r : replicate) mean += r / static_cast<double>(replicate.size());
    for (double r : replicate) ss += (r - mean) * (r - mean);
    e.sigma_jackknife_s = std::sqrt((static_cast<double>(K) - 1.0) / static_cast<double>(K) * ss);
  }
  return true;
}

/// The vertex of the cost near its lowest candidate `best` and its three standard errors.
TimeOffsetEstimate& vertex_result(OffsetSearch& search, std::size_t best, const TimeOffsetOptions& o,
                                  TimeOffsetEstimate& e) {
  const auto not_observable = [&]() -> TimeOffsetEstimate& {
    e.reason = "the cost has no minimum near its lowest point: the offset is not observable from this motion";
    return e;
  };
  const std::size_t K = search.blocks();
  double curv = 0.0;
  Cost cb;
  double centre = search.fit(K, e.grid_s[best], o.fit_halfwidth_s, curv);
  if (!(curv > 0)) return not_observable();
  const double sigma1 = search.sigma_at(centre, curv, cb);
  if (sigma1 < 0) {
    e.reason = "too few inlier detections per window for an estimate";
    return e;
  }
  const double half = std::clamp(3.0 * std::max(sigma1, search.cluster_sigma(centre, o.fit_halfwidth_s, curv)),
                                 10.0 * o.step_s, o.fit_halfwidth_s);
  centre = search.fit(K, centre, half, curv);
  if (!(curv > 0)) return not_observable();
  e.offset_s = centre;
  if (std::abs(e.offset_s - o.centre_s) > o.search_s) {
    e.reason = fmt::format("the fitted minimum lies outside the search ({:+.1f} ms ± {:.1f} ms): the offset may "
                           "lie beyond it",
                           o.centre_s * 1e3, o.search_s * 1e3);
    return e;
  }
  e.sigma_curvature_s = search.sigma_at(centre, curv, cb);
  if (e.sigma_curvature_s < 0) {
    e.reason = "too few inlier detections per window for an estimate";
    return e;
  }
  e.sigma_cluster_s = search.cluster_sigma(centre, half, curv);
  if (!jackknife(search, half, e)) return e;
  e.sigma_s = std::max({e.sigma_curvature_s, e.sigma_cluster_s, e.sigma_jackknife_s});
  e.rms_residual_deg = cb.inliers ? std::sqrt(cb.inlier_sum / static_cast<double>(cb.inliers)) : 0.0;
  e.residual_correlation = cb.lag1_den > 0 ? std::clamp(cb.lag1_num / cb.lag1_den, 0.0, 0.95) : 0.0;
  e.valid = true;
  return e;
}

}  // namespace

TimeOffsetEstimate estimate_camera_time_offset(const std::vector<ImuSample>& imu, const Eigen::Vector3d& gyro_bias,
                                               const Eigen::Quaterniond& q_I_C,
                                               const std::vector<Detection>& detections,
                                               const TimeOffsetOptions& o) {
  TimeOffsetEstimate e;
  e.reason = invalid_options(o, imu.size());
  if (!e.reason.empty()) return e;
  const GyroRotation gyro(imu, gyro_bias);
  double rate2 = 0.0;
  const std::vector<Window> windows = make_windows(gyro, gyro_bias, q_I_C, detections, o, e, rate2);
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
  OffsetSearch search(gyro, q_I_C, windows, o, e);
  const std::size_t best = search.lowest(search.blocks(), true);
  if (best == 0 || best + 1 == search.size()) return edge_result(search, best, o, e);
  return vertex_result(search, best, o, e);
}

}  // namespace roe::calib
