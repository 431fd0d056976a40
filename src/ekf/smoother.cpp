#include "roe/ekf/smoother.hpp"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <condition_variable>
#include <deque>
#include <algorithm>
#include <exception>
#include <limits>
#include <mutex>
#include <thread>

#include "roe/core/error.hpp"
#include "roe/core/parallel.hpp"
#include "roe/ekf/measurement.hpp"
#include "roe/math/so3.hpp"

namespace roe::ekf {

using math::exp_quat;
using math::log_quat;
using MatX = Eigen::MatrixXd;
using VecX = Eigen::VectorXd;
using Vec15 = Eigen::Matrix<double, 15, 1>;

namespace {

/// The predicted covariance of a kPropagate node from the full covariance P_a of the node before it:
/// propagation changes only the core rows/columns (P_cc recorded, P_rc ← P_rc Φᵀ, P_rr unchanged).
MatX predicted_covariance(const RecordedNode& nd, const MatX& Pa) {
  const Eigen::Index n = Pa.rows(), r = n - kCore;
  MatX P(n, n);
  P.topLeftCorner<kCore, kCore>() = nd.P_cc;
  if (r > 0) {
    P.bottomLeftCorner(r, kCore) = Pa.bottomLeftCorner(r, kCore) * nd.Phi.transpose();
    P.topRightCorner(kCore, r) = P.bottomLeftCorner(r, kCore).transpose();
    P.bottomRightCorner(r, r) = Pa.bottomRightCorner(r, r);
  }
  return P;
}

Eigen::LLT<MatX> factor(const MatX& P, Timestamp t, const char* what) {
  Eigen::LLT<MatX> llt(P);
  if (llt.info() != Eigen::Success)
    throw NumericError(fmt::format(
        "smoother failed at t = {:.9f} s: the {} covariance is not positive definite", to_seconds(t), what));
  return llt;
}

MatX symmetric(const MatX& P) { return 0.5 * (P + P.transpose()); }

/// The extrinsics' variances [δp_I_C, δθ_I_C] in a full covariance (0 when they are held fixed).
Vec6 extrinsics_variance(const MatX& P, int extr) {
  return extr >= 0 ? Vec6(P.diagonal().segment<6>(extr)) : Vec6::Zero();
}

/// One output row with its mean; σ and the pose covariance nan until set_covariance.
SmoothedState mean_state(Timestamp t, const CoreState& x, const Pose& T_I_C) {
  SmoothedState s;
  s.t_ns = t;
  s.x = x;
  s.T_I_C = T_I_C;
  s.sigma.setConstant(std::numeric_limits<double>::quiet_NaN());
  s.pose_cov.setConstant(std::numeric_limits<double>::quiet_NaN());
  return s;
}

/// An output row's covariance: the entries of its core covariance that the output holds (the variances and
/// the [δp; δθ] block) and the extrinsics' variances.
void set_covariance(SmoothedState& s, const Vec15& core_var, const Eigen::Matrix<double, 6, 6>& pose_cov,
                    const Vec6& extr_var) {
  for (int i = 0; i < kCore; ++i) s.sigma(i) = std::sqrt(std::max(0.0, core_var(i)));
  for (int i = 0; i < 6; ++i) s.sigma(kCore + i) = std::sqrt(std::max(0.0, extr_var(i)));
  s.pose_cov = pose_cov;
}

/// The [δp; δθ] block of a core covariance.
Eigen::Matrix<double, 6, 6> pose_block(const Mat15& P) {
  Eigen::Matrix<double, 6, 6> C;
  for (int a = 0; a < 2; ++a)
    for (int b = 0; b < 2; ++b) C.block<3, 3>(3 * a, 3 * b) = P.block<3, 3>(a == 0 ? kP : kTheta, b == 0 ? kP : kTheta);
  return C;
}

/// What the backward pass needs from one propagation segment a → b (docs in smoother.hpp): with
/// Pp = P_b⁻ and D = P_s,b − P_b⁻, the smoothed δ_a and P_s,a, and, for the IMU steps inside the segment,
/// the core part of λ = P_b⁻⁻¹ δ_b (the mean) and W = P_b⁻⁻¹ D P_b⁻⁻¹ reduced to the 30 directions the
/// steps' covariance sees (M = Tᵀ W T, T = diag(I₁₅, P_a,rc); only when asked for: `with_M`).
struct SegmentGain {
  VecX delta_a;
  MatX Ps_a;
  Vec15 lambda_c = Vec15::Zero();
  bool with_M = false;
  Eigen::Matrix<double, 30, 30> M = Eigen::Matrix<double, 30, 30>::Zero();
};

/// The segment's gain C = P_a Φᵀ P_b⁻⁻¹ without forming it. Propagation adds process noise Q to the core
/// block only, so P_a Φᵀ = Φ⁻¹ (P_b⁻ − Q) and C = Φ⁻¹ (I − Q P_b⁻⁻¹), where Q P_b⁻⁻¹ has 15 non-zero rows:
/// δ_a = Φ⁻¹ (δ_b − Q λ), P_s,a = P_a + Φ⁻¹ G D Gᵀ Φ⁻ᵀ with G = I − Q P_b⁻⁻¹, all in O(15 n²) after one
/// Cholesky factor of P_b⁻ (the direct form C D Cᵀ costs several n³ products per segment). M (`with_M`: a
/// step strictly inside the segment asks for its covariance) needs the solve on T's 30 columns and
/// Zᵀ (D Z); without it the solve has P_b⁻⁻¹'s 15 core columns only (the same numbers: a triangular solve
/// treats its right-hand sides column by column).
SegmentGain segment_gain(const RecordedNode& nd, const MatX& Pa, const MatX& Ps, const VecX& delta_b, bool with_M) {
  const Eigen::Index n = Pa.rows(), r = n - kCore;
  const MatX Pp = predicted_covariance(nd, Pa);
  const auto llt = factor(Pp, nd.x.t_ns, "predicted");
  MatX T = MatX::Zero(n, with_M ? 30 : kCore);
  T.topLeftCorner<kCore, kCore>().setIdentity();
  if (with_M && r > 0) T.bottomRightCorner(r, kCore) = Pa.bottomLeftCorner(r, kCore);
  const MatX Z = llt.solve(T);  // P_b⁻⁻¹ T; its first 15 columns are P_b⁻⁻¹'s core columns
  const VecX lambda = llt.solve(delta_b);
  MatX D = Ps - Pp;

  SegmentGain g;
  g.lambda_c = lambda.head<kCore>();
  g.with_M = with_M;
  if (with_M) {
    const MatX DZ = D * Z;
    g.M.triangularView<Eigen::Lower>() = Z.transpose() * DZ;
    g.M.triangularView<Eigen::StrictlyUpper>() = g.M.transpose();
  }
  const Mat15 Phi_inv = nd.Phi.inverse();
  const Mat15 Q = nd.P_cc - nd.Phi * Pa.topLeftCorner<kCore, kCore>() * nd.Phi.transpose();
  g.delta_a = delta_b;
  g.delta_a.head<kCore>() = Phi_inv * (delta_b.head<kCore>() - Q * lambda.head<kCore>());
  // Φ⁻¹ G D Gᵀ Φ⁻ᵀ changes only the core rows and columns: with H = Φ⁻¹ ([I 0] − Q (P_b⁻⁻¹)_c·) (15 x n),
  // its core rows are X = H D, its core block X Hᵀ (the rest of D stays).
  MatX H = -Phi_inv * (Q * Z.leftCols<kCore>().transpose());
  H.leftCols<kCore>() += Phi_inv;
  const MatX X = H * D;
  D.topLeftCorner<kCore, kCore>().noalias() = X * H.transpose();
  if (r > 0) {
    D.topRightCorner(kCore, r) = X.rightCols(r);
    D.bottomLeftCorner(r, kCore) = X.rightCols(r).transpose();
  }
  g.Ps_a = symmetric(Pa + D);
  return g;
}

/// What the IMU steps inside one propagation segment a → b need from the backward pass: the segment
/// (its kPropagate node b; a is the node before it), the smoothed δ_a's core part, λ's core part and M of
/// its SegmentGain (`with_M`: some step strictly inside the segment asks for its covariance), and the
/// smoothed state at a's extrinsics (constant inside the segment). Without M, the covariance of the last
/// step (b itself, an update's or an augmentation's time) is the smoothed P_s,b of the backward pass: its
/// core block and extrinsics' variances.
struct StepsTask {
  std::size_t node = 0;
  Vec15 delta_a;
  Vec15 lambda_c;
  bool with_M = false;
  Eigen::Matrix<double, 30, 30> M;
  Mat15 Ps_b_cc;
  Vec6 extr_var_b = Vec6::Zero();
  Pose T_I_C;
  Vec6 extr_var = Vec6::Zero();
};

/// The smoothed mean at every IMU step inside a segment, written to res.states (σ nan): λ carried
/// backwards from b with the recorded F, then δ forwards from δ_a with the smoothed process noise
/// (smoother.hpp). The process noise Q_i is formed once per distinct dt (add_process_noise, the one
/// definition the filter uses).
void smooth_segment_means(const FilterRecording& rec, const StepsTask& task, const ImuNoiseParams& noise,
                          SmootherResult& res) {
  const RecordedNode& nd = rec.nodes[task.node];
  const std::size_t first = nd.first_step, m = nd.steps - first;
  std::vector<Vec15> lambda(m);
  Eigen::Matrix<double, 1, kCore> l = task.lambda_c.transpose();
  for (std::size_t i = m; i-- > 0;) {
    lambda[i] = l.transpose();
    rec.steps[first + i].F.apply_right(l);  // λ(t_{i−1})ᵀ = λ(t_i)ᵀ F_i
  }
  Vec15 delta = task.delta_a;
  Mat15 Q = Mat15::Zero();
  double q_dt = std::numeric_limits<double>::quiet_NaN();
  for (std::size_t i = 0; i < m; ++i) {
    const RecordedStep& st = rec.steps[first + i];
    if (!(st.F.dt == q_dt)) {
      Q.setZero();
      add_process_noise(noise, st.F.dt, Q);
      q_dt = st.F.dt;
    }
    st.F.apply_left(delta);
    delta.noalias() += Q * lambda[i];
    CoreState x = st.x;
    boxplus_core(x, delta);
    res.states[first + i + 1] = mean_state(st.t_ns, x, task.T_I_C);
  }
}

/// The smoothed covariance at the IMU steps of a segment that `want` marks (by step index), after
/// smooth_segment_means: P(t) and Φ(t, a) re-propagated from P_a with the recorded F and the same process
/// noise, then backwards Ψ = Φ(b, t), A_t = [P_cc(t) Ψᵀ, Φ(t, a) P_a,cr] = G_t Tᵀ with G_t = [P_cc(t) Ψᵀ,
/// Φ(t, a)] (15 x 30): P_s(t) = P_cc(t) + G_t M G_tᵀ (fixed-size products only; of P_s(t) only the entries
/// the output holds: the variances and the [δp; δθ] block). Nothing when no step of the segment is marked;
/// without M only the last step can be, and its covariance is P_s,b (equal to P_cc(b) + G_b M G_bᵀ in exact
/// arithmetic: G_b = [P_b⁻,cc, Φ(b, a)], so G_b M G_bᵀ = (P_b⁻ W P_b⁻)_cc = D_cc).
void smooth_segment_covariances(const FilterRecording& rec, const StepsTask& task, const ImuNoiseParams& noise,
                                const std::vector<char>& want, SmootherResult& res) {
  const RecordedNode& nd = rec.nodes[task.node];
  const std::size_t m = nd.steps - nd.first_step;
  if (!task.with_M) {
    if (want[nd.steps - 1])
      set_covariance(res.states[nd.steps], task.Ps_b_cc.diagonal(), pose_block(task.Ps_b_cc), task.extr_var_b);
    return;
  }
  // The first and one past the last step asked for: P(t) is re-propagated up to the last of them only and Ψ
  // carried back to the first only (roe run's output level standard asks for the first step after an image).
  std::size_t lo = m, hi = 0;
  for (std::size_t i = 0; i < m; ++i)
    if (want[nd.first_step + i]) {
      lo = std::min(lo, i);
      hi = i + 1;
    }
  if (lo == m) return;
  std::vector<Mat15> Pcc(hi), Phi(hi);
  Mat15 Pc = rec.nodes[task.node - 1].P.topLeftCorner<kCore, kCore>();
  Mat15 Ph = Mat15::Identity();
  for (std::size_t i = 0; i < hi; ++i) {
    const CoreTransition& F = rec.steps[nd.first_step + i].F;
    F.apply_left(Pc);
    F.apply_right_transposed(Pc);
    add_process_noise(noise, F.dt, Pc);
    Pc = 0.5 * (Pc + Pc.transpose()).eval();
    F.apply_left(Ph);
    Pcc[i] = Pc;
    Phi[i] = Ph;
  }
  Mat15 Psi = Mat15::Identity();  // Φ(b, t_i)
  Eigen::Matrix<double, kCore, 30> G, GM;
  constexpr int kPose[6] = {kP, kP + 1, kP + 2, kTheta, kTheta + 1, kTheta + 2};
  for (std::size_t i = m; i-- > lo;) {
    const RecordedStep& st = rec.steps[nd.first_step + i];
    if (want[nd.first_step + i]) {
      G.leftCols<kCore>().noalias() = Pcc[i] * Psi.transpose();
      G.rightCols<kCore>() = Phi[i];
      GM.noalias() = G * task.M;
      const Vec15 var = Pcc[i].diagonal() + GM.cwiseProduct(G).rowwise().sum();
      Eigen::Matrix<double, 6, 6> pose_cov;
      for (int c = 0; c < 6; ++c)
        for (int r = 0; r < 6; ++r) pose_cov(r, c) = Pcc[i](kPose[r], kPose[c]) + GM.row(kPose[r]).dot(G.row(kPose[c]));
      set_covariance(res.states[nd.first_step + i + 1], var, pose_cov, task.extr_var);
    }
    if (i > lo) st.F.apply_right(Psi);
  }
}

/// The IMU steps of one segment: their means, then the covariances `want` asks for.
void smooth_segment_steps(const FilterRecording& rec, const StepsTask& task, const ImuNoiseParams& noise,
                          const std::vector<char>& want, SmootherResult& res) {
  smooth_segment_means(rec, task, noise, res);
  smooth_segment_covariances(rec, task, noise, want, res);
}

/// Runs the segments' IMU steps (StepsTask) while the backward pass goes on: on a second thread when
/// `threaded`, else at once on the caller's. Each task writes its own range of res.states, so the result
/// does not depend on the threading. finish() runs what is still queued on both threads, waits, and
/// rethrows the first exception a task threw; the destructor stops the worker without waiting for the rest
/// (an exception in the backward pass).
class StepsWorker {
 public:
  StepsWorker(const FilterRecording& rec, const ImuNoiseParams& noise, const std::vector<char>& want,
              SmootherResult& res, bool threaded)
      : rec_(rec), noise_(noise), want_(want), res_(res) {
    if (threaded) thread_ = std::thread([this] { work(true); });
  }
  StepsWorker(const StepsWorker&) = delete;
  StepsWorker& operator=(const StepsWorker&) = delete;
  ~StepsWorker() { stop(true); }

  void push(StepsTask task) {
    if (!thread_.joinable()) {
      smooth_segment_steps(rec_, task, noise_, want_, res_);
      return;
    }
    {
      std::lock_guard<std::mutex> lock(mu_);
      queue_.push_back(std::move(task));
    }
    cv_.notify_one();
  }

  void finish() {
    if (thread_.joinable()) {
      {
        std::lock_guard<std::mutex> lock(mu_);
        done_ = true;
      }
      cv_.notify_one();
      work(false);  // the caller's thread takes its share of the queue
      thread_.join();
    }
    if (error_) std::rethrow_exception(error_);
  }

 private:
  /// Runs queued tasks until the queue is empty after finish() (or at once when not `wait`ing for more),
  /// or a task has failed.
  void work(bool wait) {
    for (;;) {
      StepsTask task;
      {
        std::unique_lock<std::mutex> lock(mu_);
        if (wait) cv_.wait(lock, [this] { return !queue_.empty() || done_; });
        if (queue_.empty() || abandon_) return;
        task = std::move(queue_.front());
        queue_.pop_front();
      }
      try {
        smooth_segment_steps(rec_, task, noise_, want_, res_);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mu_);
        if (!error_) error_ = std::current_exception();
        abandon_ = true;
        return;
      }
    }
  }

  void stop(bool abandon) {
    if (!thread_.joinable()) return;
    {
      std::lock_guard<std::mutex> lock(mu_);
      done_ = true;
      abandon_ = abandon_ || abandon;
    }
    cv_.notify_one();
    thread_.join();
  }

  const FilterRecording& rec_;
  const ImuNoiseParams& noise_;
  const std::vector<char>& want_;
  SmootherResult& res_;
  std::thread thread_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<StepsTask> queue_;
  bool done_ = false, abandon_ = false;
  std::exception_ptr error_;
};

/// P_y = diag(b) P_u diag(b) + diag(1 − b²): the covariance after a decay link (kDecay).
MatX decayed_covariance(const MatX& Pu, const VecX& b) {
  ROE_CHECK(b.size() == Pu.rows(), "smooth: a decay node of another dimension than the node before it");
  MatX Py = b.asDiagonal() * Pu * b.asDiagonal();
  Py.diagonal().array() += 1.0 - b.array().square();
  return Py;
}

/// The RTS step over a linear link y = B u + w (augmentation, decay): C = P_u Bᵀ P_y⁻¹, computed as
/// Cᵀ = P_y⁻¹ (B P_u); δ_u = C δ_y and P_s,u = P_u + C (P_s,y − P_y) Cᵀ.
void linear_link(const MatX& BPu, const MatX& Py, const MatX& Pu, const VecX& dy, const MatX& Psy, Timestamp t_ns,
                 VecX& du, MatX& Psu) {
  const auto llt = factor(Py, t_ns, "linked");
  const MatX CT = llt.solve(BPu);
  du = CT.transpose() * dy;
  Psu = Pu + CT.transpose() * (Psy - Py) * CT;
}

/// want[i]: the covariance after step i is asked for (SmootherOptions::covariance_at; all when nullptr).
std::vector<char> wanted_steps(const FilterRecording& rec, const std::vector<Timestamp>* times) {
  std::vector<char> want(rec.steps.size(), times == nullptr ? 1 : 0);
  if (times == nullptr) return want;
  std::size_t k = 0;
  for (std::size_t i = 0; i < rec.steps.size(); ++i) {
    while (k < times->size() && (*times)[k] < rec.steps[i].t_ns) ++k;
    if (k < times->size() && (*times)[k] == rec.steps[i].t_ns) want[i] = 1;
  }
  return want;
}

}  // namespace

SmootherResult smooth(const FilterRecording& rec, const ImuNoiseParams& noise, const SmootherOptions& options) {
  const unsigned threads = options.threads;
  const auto& nodes = rec.nodes;
  ROE_CHECK(!nodes.empty() && nodes.front().kind == RecordedNode::Kind::kInit,
            "smooth: the recording does not start with the filter's initialisation");
  ROE_CHECK(nodes.back().steps == rec.steps.size(), "smooth: the recording was not finished");
  const auto stored_P = [&](std::size_t j) -> MatX {
    if (nodes[j].kind != RecordedNode::Kind::kPropagate) return nodes[j].P;
    ROE_CHECK(j > 0 && nodes[j - 1].kind != RecordedNode::Kind::kPropagate &&
                  nodes[j - 1].kind != RecordedNode::Kind::kDecay,
              "smooth: a propagation node after a node without a covariance");
    return predicted_covariance(nodes[j], nodes[j - 1].P);
  };
  // A decay node's covariance follows from the node before it (which stores one, or is a propagation node).
  const auto full_P = [&](std::size_t j) -> MatX {
    if (nodes[j].kind != RecordedNode::Kind::kDecay) return stored_P(j);
    ROE_CHECK(j > 0 && nodes[j - 1].kind != RecordedNode::Kind::kDecay, "smooth: two decay nodes in a row");
    return decayed_covariance(stored_P(j - 1), nodes[j].decay);
  };

  SmootherResult res;
  res.states.resize(rec.steps.size() + 1);
  StateEstimate xs = nodes.back().x;
  MatX Ps = full_P(nodes.size() - 1);
  bool anchor_seen = false;
  std::size_t anchor_steps = 0;
  const std::vector<char> want = wanted_steps(rec, options.covariance_at);
  StepsWorker steps(rec, noise, want, res, (threads ? threads : available_cpus()) > 1);

  for (std::size_t j = nodes.size() - 1; j >= 1; --j) {
    const RecordedNode& nd = nodes[j];
    switch (nd.kind) {
      case RecordedNode::Kind::kInit:
        ROE_CHECK(false, "smooth: a second initialisation node");
        break;
      case RecordedNode::Kind::kUpdate:
        // The same variables before and after an update: the smoothed estimate passes unchanged.
        break;
      case RecordedNode::Kind::kDecay: {
        const MatX Pu = full_P(j - 1);
        const MatX BPu = nd.decay.asDiagonal() * Pu;
        VecX du;
        MatX Psu;
        linear_link(BPu, decayed_covariance(Pu, nd.decay), Pu, boxminus(xs, nd.x), Ps, nd.x.t_ns, du, Psu);
        StateEstimate xu = nodes[j - 1].x;
        boxplus(xu, du);
        xs = std::move(xu);
        Ps = symmetric(Psu);
        break;
      }
      case RecordedNode::Kind::kAugment: {
        const VecX d = boxminus(xs, nd.x);
        const MatX Pu = full_P(j - 1);
        const Eigen::Index n = Pu.rows();
        VecX du;
        MatX Psu;
        if (nd.append_only) {
          du = d.head(n);
          Psu = Ps.topLeftCorner(n, n);
        } else {
          linear_link(nd.B * Pu, nd.P, Pu, d, Ps, nd.x.t_ns, du, Psu);
        }
        StateEstimate xu = nodes[j - 1].x;
        boxplus(xu, du);
        if (nd.anchor) {
          // The same IMU pose smoothed in the new W (xs) and in the old one (xu): T_Wnew_Wold.
          res.gauge_shift = Pose(xs.x.q_W_I, xs.x.p_W_I) * Pose(xu.x.q_W_I, xu.x.p_W_I).inverse();
          anchor_seen = true;
          anchor_steps = nd.steps;
        }
        xs = std::move(xu);
        Ps = symmetric(Psu);
        break;
      }
      case RecordedNode::Kind::kPropagate: {
        const RecordedNode& a = nodes[j - 1];
        ROE_CHECK(a.kind != RecordedNode::Kind::kPropagate, "smooth: two propagation nodes in a row");
        // M only when a step strictly inside the segment asks for its covariance (the last one can take P_s,b).
        const bool inner = std::find(want.begin() + nd.first_step, want.begin() + nd.steps - 1, 1) !=
                           want.begin() + nd.steps - 1;
        SegmentGain g = segment_gain(nd, a.P, Ps, boxminus(xs, nd.x), inner);
        StateEstimate xa = a.x;
        boxplus(xa, g.delta_a);
        steps.push({j, g.delta_a.head<kCore>(), g.lambda_c, g.with_M, g.M, Ps.topLeftCorner<kCore, kCore>(),
                    extrinsics_variance(Ps, nd.x.extr_offset), xa.T_I_C, extrinsics_variance(g.Ps_a, xa.extr_offset)});
        xs = std::move(xa);
        Ps = std::move(g.Ps_a);
        break;
      }
    }
  }
  steps.finish();
  const Mat15 Pcc = Ps.topLeftCorner<kCore, kCore>();
  res.states[0] = mean_state(xs.t_ns, xs.x, xs.T_I_C);
  set_covariance(res.states[0], Pcc.diagonal(), pose_block(Pcc), extrinsics_variance(Ps, xs.extr_offset));

  // The states before the anchor's first sight into the new W (a rigid change of frame).
  if (anchor_seen) {
    const Pose& T = res.gauge_shift;
    for (std::size_t k = 0; k <= anchor_steps && k < res.states.size(); ++k) {
      CoreState& x = res.states[k].x;
      x.p_W_I = T.q * x.p_W_I + T.p;
      x.v_W_I = T.q * x.v_W_I;
      x.q_W_I = (T.q * x.q_W_I).normalized();
    }
  }
  return res;
}

}  // namespace roe::ekf
