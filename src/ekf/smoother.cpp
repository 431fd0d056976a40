#include "roe/ekf/smoother.hpp"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <map>
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

/// RecordingSpill in memory, in pages of kPage bytes (no reallocation of what was written).
class MemorySpill : public RecordingSpill {
 public:
  static constexpr std::size_t kPage = std::size_t{1} << 22;
  std::uint64_t append(const void* data, std::size_t n) override {
    const std::uint64_t at = size_;
    const char* p = static_cast<const char*>(data);
    while (n > 0) {
      if (pages_.empty() || pages_.back().size() == kPage) pages_.emplace_back().reserve(kPage);
      const std::size_t k = std::min(n, kPage - pages_.back().size());
      pages_.back().insert(pages_.back().end(), p, p + k);
      p += k;
      n -= k;
      size_ += k;
    }
    return at;
  }
  void read(std::uint64_t offset, void* data, std::size_t n) const override {
    ROE_CHECK(offset + n <= size_, "recording: a read beyond what was recorded");
    char* p = static_cast<char*>(data);
    while (n > 0) {
      const std::vector<char>& page = pages_[offset / kPage];
      const std::size_t at = offset % kPage, k = std::min(n, kPage - at);
      std::copy(page.begin() + static_cast<std::ptrdiff_t>(at), page.begin() + static_cast<std::ptrdiff_t>(at + k), p);
      p += k;
      n -= k;
      offset += k;
    }
  }

 private:
  std::vector<std::vector<char>> pages_;
  std::uint64_t size_ = 0;
};

// A step in the spill: the stamp's bits, the nominal core state and the transition, 63 doubles. The sizes
// catch a field added to either struct (it would have to be written here too).
static_assert(sizeof(CoreState) == 16 * sizeof(double), "CoreState's fields: see put_step");
static_assert(sizeof(CoreTransition) == 46 * sizeof(double), "CoreTransition's fields: see put_step");
constexpr std::size_t kStepDoubles = 63;

template <class M>
double* put(double* d, const M& m) {
  return std::copy(m.data(), m.data() + m.size(), d);
}
template <class M>
const double* get(const double* d, M& m) {
  std::copy(d, d + m.size(), m.data());
  return d + m.size();
}

void put_step(const RecordedStep& s, double* d) {
  std::memcpy(d++, &s.t_ns, sizeof(double));
  for (const Vec3* v : {&s.x.p_W_I, &s.x.v_W_I}) d = put(d, *v);
  d = put(d, s.x.q_W_I.coeffs());
  for (const Vec3* v : {&s.x.b_g, &s.x.b_a}) d = put(d, *v);
  *d++ = s.F.dt;
  for (const Mat3* m : {&s.F.F_vtheta, &s.F.F_vbg, &s.F.F_vba, &s.F.F_tt, &s.F.F_tbg}) d = put(d, *m);
}

void get_step(const double* d, RecordedStep& s) {
  std::memcpy(&s.t_ns, d++, sizeof(double));
  for (Vec3* v : {&s.x.p_W_I, &s.x.v_W_I}) d = get(d, *v);
  d = get(d, s.x.q_W_I.coeffs());
  for (Vec3* v : {&s.x.b_g, &s.x.b_a}) d = get(d, *v);
  s.F.dt = *d++;
  for (Mat3* m : {&s.F.F_vtheta, &s.F.F_vbg, &s.F.F_vba, &s.F.F_tt, &s.F.F_tbg}) d = get(d, *m);
}

/// A node's matrices as doubles: P (rows, then its entries), Φ and P_cc (a propagation node), B (rows, cols,
/// entries) and the decay (size, entries); sizes are exact as doubles.
std::vector<double> node_matrices(const RecordedNode& nd) {
  std::vector<double> v;
  v.reserve(4 + nd.P.size() + nd.B.size() + nd.decay.size() + (nd.kind == RecordedNode::Kind::kPropagate ? 450 : 0));
  v.push_back(static_cast<double>(nd.P.rows()));
  v.insert(v.end(), nd.P.data(), nd.P.data() + nd.P.size());
  if (nd.kind == RecordedNode::Kind::kPropagate) {
    v.insert(v.end(), nd.Phi.data(), nd.Phi.data() + nd.Phi.size());
    v.insert(v.end(), nd.P_cc.data(), nd.P_cc.data() + nd.P_cc.size());
  }
  v.push_back(static_cast<double>(nd.B.rows()));
  v.push_back(static_cast<double>(nd.B.cols()));
  v.insert(v.end(), nd.B.data(), nd.B.data() + nd.B.size());
  v.push_back(static_cast<double>(nd.decay.size()));
  v.insert(v.end(), nd.decay.data(), nd.decay.data() + nd.decay.size());
  return v;
}

void read_node_matrices(const std::vector<double>& v, RecordedNode& nd) {
  const double* d = v.data();
  const auto n = static_cast<Eigen::Index>(*d++);
  nd.P.resize(n, n);
  d = get(d, nd.P);
  if (nd.kind == RecordedNode::Kind::kPropagate) {
    d = get(d, nd.Phi);
    d = get(d, nd.P_cc);
  }
  const auto br = static_cast<Eigen::Index>(*d++), bc = static_cast<Eigen::Index>(*d++);
  nd.B.resize(br, bc);
  d = get(d, nd.B);
  nd.decay.resize(static_cast<Eigen::Index>(*d++));
  d = get(d, nd.decay);
  ROE_CHECK(d == v.data() + v.size(), "recording: a node's matrices read back with another size");
}

}  // namespace

FilterRecording::FilterRecording(RecordingSpill* spill) {
  if (spill == nullptr) {
    own_ = std::make_unique<MemorySpill>();
    spill = own_.get();
  }
  steps.spill_ = spill;
  nodes.spill_ = spill;
}
FilterRecording::~FilterRecording() = default;
FilterRecording::FilterRecording(FilterRecording&&) noexcept = default;
FilterRecording& FilterRecording::operator=(FilterRecording&&) noexcept = default;

void StepLog::push_back(const RecordedStep& step) {
  times_.push_back(step.t_ns);
  tail_.push_back(step);
  if (tail_.size() < kChunk) return;
  std::vector<double> buf(kChunk * kStepDoubles);
  for (std::size_t i = 0; i < kChunk; ++i) put_step(tail_[i], buf.data() + i * kStepDoubles);
  chunks_.push_back(spill_->append(buf.data(), buf.size() * sizeof(double)));
  tail_.clear();
}

void StepLog::clear() {
  times_.clear();
  tail_.clear();
  chunks_.clear();
}

RecordedStep StepLog::operator[](std::size_t i) const {
  std::vector<RecordedStep> one;
  load(i, i + 1, one);
  return one.front();
}

void StepLog::load(std::size_t first, std::size_t last, std::vector<RecordedStep>& out) const {
  ROE_CHECK(first <= last && last <= size(), "recording: steps beyond those recorded");
  out.resize(last - first);
  std::vector<double> buf;
  for (std::size_t i = first; i < last;) {
    const std::size_t c = i / kChunk;
    if (c == chunks_.size()) {  // the tail in memory
      for (; i < last; ++i) out[i - first] = tail_[i - c * kChunk];
      break;
    }
    const std::size_t end = std::min(last, (c + 1) * kChunk);
    buf.resize((end - i) * kStepDoubles);
    spill_->read(chunks_[c] + (i - c * kChunk) * kStepDoubles * sizeof(double), buf.data(), buf.size() * sizeof(double));
    for (std::size_t k = i; k < end; ++k) get_step(buf.data() + (k - i) * kStepDoubles, out[k - first]);
    i = end;
  }
}

void NodeLog::spill_live() {
  const std::vector<double> m = node_matrices(live_);
  heads_.push_back({live_.kind, live_.append_only, live_.anchor, live_.steps, live_.first_step, std::move(live_.x),
                    spill_->append(m.data(), m.size() * sizeof(double)), m.size()});
}

RecordedNode& NodeLog::emplace_back() {
  if (has_live_) spill_live();
  live_ = RecordedNode();
  has_live_ = true;
  return live_;
}

void NodeLog::clear() {
  heads_.clear();
  live_ = RecordedNode();
  has_live_ = false;
}

RecordedNode NodeLog::operator[](std::size_t j) const {
  ROE_CHECK(j < size(), "recording: a node beyond those recorded");
  if (j == heads_.size()) return live_;
  const Head& h = heads_[j];
  RecordedNode nd;
  nd.kind = h.kind;
  nd.append_only = h.append_only;
  nd.anchor = h.anchor;
  nd.steps = h.steps;
  nd.first_step = h.first_step;
  nd.x = h.x;
  std::vector<double> m(h.doubles);
  spill_->read(h.offset, m.data(), m.size() * sizeof(double));
  read_node_matrices(m, nd);
  return nd;
}

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
  std::size_t first_step = 0;      // the index of the segment's first step
  std::vector<RecordedStep> steps;  // the segment's steps, read back from the recording
  Mat15 Pa_cc;                      // the core block of P_a
  Vec15 delta_a;
  Vec15 lambda_c;
  bool with_M = false;
  Eigen::Matrix<double, 30, 30> M;
  Mat15 Ps_b_cc;
  Vec6 extr_var_b = Vec6::Zero();
  Pose T_I_C;
  Vec6 extr_var = Vec6::Zero();
  /// The segment lies before the anchor's first sight: its states are moved into the new W by `gauge`
  /// (SmootherResult::gauge_shift), known by then (the backward pass has passed the anchor's node).
  bool shift = false;
  Pose gauge;
};

/// The rigid change of frame T_Wnew_Wold of a state smoothed in the old W (smoother.hpp, the anchor's first
/// sight).
void shift_gauge(const Pose& T, CoreState& x) {
  x.p_W_I = T.q * x.p_W_I + T.p;
  x.v_W_I = T.q * x.v_W_I;
  x.q_W_I = (T.q * x.q_W_I).normalized();
}

/// The smoothed mean at every IMU step inside a segment, written to `out` (one per step, σ nan): λ carried
/// backwards from b with the recorded F, then δ forwards from δ_a with the smoothed process noise
/// (smoother.hpp). The process noise Q_i is formed once per distinct dt (add_process_noise, the one
/// definition the filter uses).
void smooth_segment_means(const StepsTask& task, const ImuNoiseParams& noise, std::vector<SmoothedState>& out) {
  const std::size_t m = task.steps.size();
  std::vector<Vec15> lambda(m);
  Eigen::Matrix<double, 1, kCore> l = task.lambda_c.transpose();
  for (std::size_t i = m; i-- > 0;) {
    lambda[i] = l.transpose();
    task.steps[i].F.apply_right(l);  // λ(t_{i−1})ᵀ = λ(t_i)ᵀ F_i
  }
  Vec15 delta = task.delta_a;
  Mat15 Q = Mat15::Zero();
  double q_dt = std::numeric_limits<double>::quiet_NaN();
  for (std::size_t i = 0; i < m; ++i) {
    const RecordedStep& st = task.steps[i];
    if (!(st.F.dt == q_dt)) {
      Q.setZero();
      add_process_noise(noise, st.F.dt, Q);
      q_dt = st.F.dt;
    }
    st.F.apply_left(delta);
    delta.noalias() += Q * lambda[i];
    CoreState x = st.x;
    boxplus_core(x, delta);
    out[i] = mean_state(st.t_ns, x, task.T_I_C);
  }
}

/// The smoothed covariance at the IMU steps of a segment that `want` marks (by step index), after
/// smooth_segment_means: P(t) and Φ(t, a) re-propagated from P_a with the recorded F and the same process
/// noise, then backwards Ψ = Φ(b, t), A_t = [P_cc(t) Ψᵀ, Φ(t, a) P_a,cr] = G_t Tᵀ with G_t = [P_cc(t) Ψᵀ,
/// Φ(t, a)] (15 x 30): P_s(t) = P_cc(t) + G_t M G_tᵀ (fixed-size products only; of P_s(t) only the entries
/// the output holds: the variances and the [δp; δθ] block). Nothing when no step of the segment is marked;
/// without M only the last step can be, and its covariance is P_s,b (equal to P_cc(b) + G_b M G_bᵀ in exact
/// arithmetic: G_b = [P_b⁻,cc, Φ(b, a)], so G_b M G_bᵀ = (P_b⁻ W P_b⁻)_cc = D_cc).
void smooth_segment_covariances(const StepsTask& task, const ImuNoiseParams& noise, const std::vector<char>& want,
                                std::vector<SmoothedState>& out) {
  const std::size_t m = task.steps.size();
  if (!task.with_M) {
    if (want[task.first_step + m - 1])
      set_covariance(out[m - 1], task.Ps_b_cc.diagonal(), pose_block(task.Ps_b_cc), task.extr_var_b);
    return;
  }
  // The first and one past the last step asked for: P(t) is re-propagated up to the last of them only and Ψ
  // carried back to the first only (roe run's output level standard asks for the first step after an image).
  std::size_t lo = m, hi = 0;
  for (std::size_t i = 0; i < m; ++i)
    if (want[task.first_step + i]) {
      lo = std::min(lo, i);
      hi = i + 1;
    }
  if (lo == m) return;
  std::vector<Mat15> Pcc(hi), Phi(hi);
  Mat15 Pc = task.Pa_cc;
  Mat15 Ph = Mat15::Identity();
  for (std::size_t i = 0; i < hi; ++i) {
    const CoreTransition& F = task.steps[i].F;
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
    const RecordedStep& st = task.steps[i];
    if (want[task.first_step + i]) {
      G.leftCols<kCore>().noalias() = Pcc[i] * Psi.transpose();
      G.rightCols<kCore>() = Phi[i];
      GM.noalias() = G * task.M;
      const Vec15 var = Pcc[i].diagonal() + GM.cwiseProduct(G).rowwise().sum();
      Eigen::Matrix<double, 6, 6> pose_cov;
      for (int c = 0; c < 6; ++c)
        for (int r = 0; r < 6; ++r) pose_cov(r, c) = Pcc[i](kPose[r], kPose[c]) + GM.row(kPose[r]).dot(G.row(kPose[c]));
      set_covariance(out[i], var, pose_cov, task.extr_var);
    }
    if (i > lo) st.F.apply_right(Psi);
  }
}

/// The IMU steps of one segment: their means, then the covariances `want` asks for, moved into the new W
/// when the segment lies before the anchor's first sight, handed to `sink`.
void smooth_segment_steps(const StepsTask& task, const ImuNoiseParams& noise, const std::vector<char>& want,
                          std::vector<SmoothedState>& out, SmoothedStates& sink) {
  out.resize(task.steps.size());
  smooth_segment_means(task, noise, out);
  smooth_segment_covariances(task, noise, want, out);
  if (task.shift)
    for (SmoothedState& s : out) shift_gauge(task.gauge, s.x);
  sink.segment(out);
}

/// Runs the segments' IMU steps (StepsTask) while the backward pass goes on: on a second thread when
/// `threaded`, else at once on the caller's. Either way the tasks run one at a time in the order pushed, so
/// the sink receives the segments in that order and the result does not depend on the threading. At most
/// kMaxQueued tasks wait (push() waits for room): memory does not grow with the recording when the steps are
/// slower than the backward pass. finish() waits for the queue to empty and rethrows the first exception a
/// task threw (push() rethrows it early); the destructor stops the worker without waiting for the rest (an
/// exception in the backward pass).
class StepsWorker {
 public:
  static constexpr std::size_t kMaxQueued = 64;

  StepsWorker(const ImuNoiseParams& noise, const std::vector<char>& want, SmoothedStates& sink, bool threaded)
      : noise_(noise), want_(want), sink_(sink) {
    if (threaded) thread_ = std::thread([this] { work(); });
  }
  StepsWorker(const StepsWorker&) = delete;
  StepsWorker& operator=(const StepsWorker&) = delete;
  ~StepsWorker() { stop(true); }

  void push(StepsTask task) {
    if (!thread_.joinable()) {
      smooth_segment_steps(task, noise_, want_, out_, sink_);
      return;
    }
    {
      std::unique_lock<std::mutex> lock(mu_);
      room_.wait(lock, [this] { return queue_.size() < kMaxQueued || abandon_; });
      if (error_) std::rethrow_exception(error_);
      queue_.push_back(std::move(task));
    }
    cv_.notify_one();
  }

  void finish() {
    stop(false);
    if (error_) std::rethrow_exception(error_);
  }

 private:
  /// Runs queued tasks in order until the queue is empty after stop(), or a task has failed.
  void work() {
    for (;;) {
      StepsTask task;
      {
        std::unique_lock<std::mutex> lock(mu_);
        cv_.wait(lock, [this] { return !queue_.empty() || done_; });
        if (queue_.empty() || abandon_) return;
        task = std::move(queue_.front());
        queue_.pop_front();
      }
      room_.notify_one();
      try {
        smooth_segment_steps(task, noise_, want_, out_, sink_);
      } catch (...) {
        {
          std::lock_guard<std::mutex> lock(mu_);
          if (!error_) error_ = std::current_exception();
          abandon_ = true;
        }
        room_.notify_all();
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

  const ImuNoiseParams& noise_;
  const std::vector<char>& want_;
  SmoothedStates& sink_;
  std::vector<SmoothedState> out_;  // one segment's states (reused)
  std::thread thread_;
  std::mutex mu_;
  std::condition_variable cv_, room_;
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
    while (k < times->size() && (*times)[k] < rec.steps.time(i)) ++k;
    if (k < times->size() && (*times)[k] == rec.steps.time(i)) want[i] = 1;
  }
  return want;
}

}  // namespace

/// The nodes the backward pass works on, read back from the recording once each: it goes from the last node to
/// the first and needs node j and the (at most three) nodes before it; drop_after(j) forgets the later ones.
class NodeWindow {
 public:
  explicit NodeWindow(const NodeLog& log) : log_(log) {}
  const RecordedNode& operator[](std::size_t j) {
    auto it = nodes_.find(j);
    if (it == nodes_.end()) it = nodes_.emplace(j, log_[j]).first;
    return it->second;
  }
  void drop_after(std::size_t j) { nodes_.erase(nodes_.upper_bound(j), nodes_.end()); }

 private:
  const NodeLog& log_;
  std::map<std::size_t, RecordedNode> nodes_;  // stable references while held
};

Pose smooth(const FilterRecording& rec, const ImuNoiseParams& noise, SmoothedStates& out,
            const SmootherOptions& options) {
  const unsigned threads = options.threads;
  const std::size_t n_nodes = rec.nodes.size();
  ROE_CHECK(n_nodes > 0 && rec.nodes.kind(0) == RecordedNode::Kind::kInit,
            "smooth: the recording does not start with the filter's initialisation");
  ROE_CHECK(rec.nodes.back().steps == rec.steps.size(), "smooth: the recording was not finished");
  NodeWindow nodes(rec.nodes);
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
  // The anchor's first sight (the earliest anchor node): the states before it move into the new W, by the
  // change of frame found when the backward pass reaches it, before any of theirs is smoothed.
  std::size_t anchor_node = 0;
  for (std::size_t j = n_nodes; j-- > 1;)
    if (rec.nodes.kind(j) == RecordedNode::Kind::kAugment && rec.nodes.anchor(j)) anchor_node = j;

  Pose gauge_shift;
  StateEstimate xs = rec.nodes.back().x;
  MatX Ps = full_P(n_nodes - 1);
  const std::vector<char> want = wanted_steps(rec, options.covariance_at);
  StepsWorker steps(noise, want, out, (threads ? threads : available_cpus()) > 1);

  for (std::size_t j = n_nodes - 1; j >= 1; --j) {
    nodes.drop_after(j);
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
        // The same IMU pose smoothed in the new W (xs) and in the old one (xu): T_Wnew_Wold.
        if (j == anchor_node) gauge_shift = Pose(xs.x.q_W_I, xs.x.p_W_I) * Pose(xu.x.q_W_I, xu.x.p_W_I).inverse();
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
        StepsTask task{nd.first_step,
                       {},
                       a.P.topLeftCorner<kCore, kCore>(),
                       g.delta_a.head<kCore>(),
                       g.lambda_c,
                       g.with_M,
                       g.M,
                       Ps.topLeftCorner<kCore, kCore>(),
                       extrinsics_variance(Ps, nd.x.extr_offset),
                       xa.T_I_C,
                       extrinsics_variance(g.Ps_a, xa.extr_offset),
                       j < anchor_node,
                       gauge_shift};
        rec.steps.load(nd.first_step, nd.steps, task.steps);
        steps.push(std::move(task));
        xs = std::move(xa);
        Ps = std::move(g.Ps_a);
        break;
      }
    }
  }
  steps.finish();
  const Mat15 Pcc = Ps.topLeftCorner<kCore, kCore>();
  std::vector<SmoothedState> first{mean_state(xs.t_ns, xs.x, xs.T_I_C)};
  set_covariance(first[0], Pcc.diagonal(), pose_block(Pcc), extrinsics_variance(Ps, xs.extr_offset));
  if (anchor_node > 0) shift_gauge(gauge_shift, first[0].x);
  out.segment(first);
  return gauge_shift;
}

namespace {

/// Collects the segments into SmootherResult::states, from the back (they arrive from the last to the first).
class CollectStates : public SmoothedStates {
 public:
  explicit CollectStates(std::vector<SmoothedState>& states) : states_(states), end_(states.size()) {}
  void segment(const std::vector<SmoothedState>& states) override {
    ROE_CHECK(states.size() <= end_, "smooth: more smoothed states than recorded steps");
    std::copy(states.begin(), states.end(), states_.begin() + static_cast<std::ptrdiff_t>(end_ - states.size()));
    end_ -= states.size();
  }
  std::size_t left() const { return end_; }

 private:
  std::vector<SmoothedState>& states_;
  std::size_t end_;
};

}  // namespace

SmootherResult smooth(const FilterRecording& rec, const ImuNoiseParams& noise, const SmootherOptions& options) {
  SmootherResult res;
  res.states.resize(rec.steps.size() + 1);
  CollectStates collect(res.states);
  res.gauge_shift = smooth(rec, noise, collect, options);
  ROE_CHECK(collect.left() == 0, "smooth: fewer smoothed states than recorded steps");
  return res;
}

}  // namespace roe::ekf
