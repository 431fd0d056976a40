#include "roe/ekf/covariance.hpp"

#include <Eigen/Cholesky>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "roe/core/error.hpp"

namespace roe::ekf {

// Φᵀ ← Φᵀ Fᵀ for the accumulated core transition Φ = F_k⋯F_1 (kept transposed), using
// the block structure that every product of F's keeps: Φ's columns b_g and b_a are [Φ_pbg; Φ_vbg; Φ_θbg; I; 0]
// and [Φ_pba; Φ_vba; 0; 0; I], its column θ is [Φ_pθ; Φ_vθ; Φ_θθ; 0; 0] (F's rows b_g, b_a are the identity
// and F_θba = 0). So in Φᵀ's rows θ, b_g only the θ columns need products with F (the identity and zero
// blocks give F's own blocks exactly) and the row b_a needs none: 108 multiply-adds instead of the 405 of
// the generic CoreTransition::apply_right_transposed on the 9 rows, with the same operations in the same
// order on every non-trivial entry (the skipped terms are exact zeros, the identity blocks exact copies).
void accumulate_transition(const CoreTransition& F, Mat15& PhiT) {
  const double dt = F.dt;
  // Rows θ and b_g: X_θ = their θ columns, X_bg = [0; I], X_ba = 0.
  Eigen::Matrix<double, 6, 3> dv, dth;
  const Eigen::Matrix<double, 6, 3> X_th = PhiT.block<6, 3>(kTheta, kTheta);
  dv.noalias() = X_th * F.F_vtheta.transpose();
  dv.bottomRows<3>() += F.F_vbg.transpose();
  dth.noalias() = X_th * F.F_tt.transpose();
  dth.bottomRows<3>() += F.F_tbg.transpose();
  PhiT.block<6, 3>(kTheta, kP) += dt * PhiT.block<6, 3>(kTheta, kV) + (0.5 * dt) * dv;
  PhiT.block<6, 3>(kTheta, kV) += dv;
  PhiT.block<6, 3>(kTheta, kTheta) = dth;
  // Row b_a: X_θ = 0, X_bg = 0, X_ba = I, so dv = F_vbaᵀ and its θ columns stay 0.
  PhiT.block<3, 3>(kBa, kP) += dt * PhiT.block<3, 3>(kBa, kV) + (0.5 * dt) * F.F_vba.transpose();
  PhiT.block<3, 3>(kBa, kV) += F.F_vba.transpose();
  // Φ's columns p, v: Φ_pv accumulates dt.
  PhiT.block<3, 3>(kV, kP).diagonal().array() += dt;
}

void CompactJacobian6::append3(int offset, const Mat63& block) {
  ROE_CHECK(nc + 3 <= kMaxCols && offset >= 0, "CompactJacobian6: more than 19 columns or a negative offset");
  for (int j = 0; j < 3; ++j) {
    J.col(nc) = block.col(j);
    idx[nc++] = offset + j;
  }
}

void CompactJacobian6::append1(int offset, const Vec6& column) {
  ROE_CHECK(nc + 1 <= kMaxCols && offset >= 0, "CompactJacobian6: more than 19 columns or a negative offset");
  J.col(nc) = column;
  idx[nc++] = offset;
}

Eigen::MatrixXd CompactJacobian6::dense(int n) const {
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(6, n);
  for (int j = 0; j < nc; ++j) D.col(idx[j]) = J.col(j);
  return D;
}

void FilterCovariance::reset(Eigen::MatrixXd P0) {
  ROE_CHECK(P0.rows() == P0.cols(), "FilterCovariance::reset: P is not square");
  if (consider_)
    Pa_ = P0;
  else
    Pa_.resize(0, 0);
  P_ = std::move(P0);
  cc_pending_ = false;
  PhiT_.setIdentity();
  phi_pending_ = false;
  rec_PhiT_.setIdentity();
}

void FilterCovariance::symmetrise() {
  P_ = (0.5 * (P_ + P_.transpose())).eval();
  if (consider_) Pa_ = (0.5 * (Pa_ + Pa_.transpose())).eval();
}

void FilterCovariance::propagate_dense(const CoreTransition& F, const ImuNoiseParams& noise, double dt) {
  full();
  Eigen::MatrixXd Fn = Eigen::MatrixXd::Identity(dim(), dim());
  Fn.topLeftCorner<kCore, kCore>() = F.dense();
  for (Eigen::MatrixXd* P : {&P_, &Pa_}) {
    if (P == &Pa_ && !consider_) continue;
    *P = (Fn * *P * Fn.transpose()).eval();
    auto Pcc = P->topLeftCorner<kCore, kCore>();
    add_process_noise(noise, dt, Pcc);
  }
  symmetrise();
}

namespace {

void propagate_core_block(const CoreTransition& F, const ImuNoiseParams& noise, double dt, Mat15& C) {
  // P_cc ← F P_cc Fᵀ + Q with every product on columns (contiguous): C = P_cc Fᵀ changes only the
  // columns p, v, θ (F's rows b_g, b_a are the identity), and B = F C = Cᵀ Fᵀ (symmetric) needs only
  // B[0:9, 0:9] = (C[:, 0:9]ᵀ Fᵀ)[:, 0:9]; B[9:15, 0:9] = C[9:15, 0:9], B[9:15, 9:15] = P[9:15, 9:15].
  // Of B[0:9, 0:9] = T Fᵀ (T = C[:, 0:9]ᵀ) only the lower block triangle is formed: its column p on all 9
  // rows, v on rows v, θ, θ on rows θ (so δθ's product, the costliest, on 3 rows instead of 9); the diagonal
  // blocks are symmetrised and the upper blocks mirrored. 675 + 297 multiply-adds instead of 2 x 675.
  F.apply_right_transposed(C);
  const Eigen::Matrix<double, 9, 15> T = C.leftCols<9>().transpose();
  Eigen::Matrix<double, 9, 3> dv;  // (T Fᵀ)[:, v] − T[:, v]
  dv.noalias() = T.middleCols<3>(kTheta) * F.F_vtheta.transpose();
  dv.noalias() += T.middleCols<3>(kBg) * F.F_vbg.transpose();
  dv.noalias() += T.middleCols<3>(kBa) * F.F_vba.transpose();
  Mat3 dth;  // (T Fᵀ)[θ, θ]
  dth.noalias() = T.block<3, 3>(kTheta, kTheta) * F.F_tt.transpose();
  dth.noalias() += T.block<3, 3>(kTheta, kBg) * F.F_tbg.transpose();
  Eigen::Matrix<double, 9, 9> B;
  B.leftCols<3>() = T.middleCols<3>(kP) + (dt * T.middleCols<3>(kV) + (0.5 * dt) * dv);
  B.block<6, 3>(kV, kV) = T.block<6, 3>(kV, kV) + dv.bottomRows<6>();
  B.block<3, 3>(kTheta, kTheta) = dth;
  for (int d = 0; d < 9; d += 3) {
    const Mat3 D = B.block<3, 3>(d, d);
    B.block<3, 3>(d, d) = 0.5 * (D + D.transpose());
  }
  B.block<3, 3>(kP, kV) = B.block<3, 3>(kV, kP).transpose();
  B.block<3, 3>(kP, kTheta) = B.block<3, 3>(kTheta, kP).transpose();
  B.block<3, 3>(kV, kTheta) = B.block<3, 3>(kTheta, kV).transpose();
  // C's rows b_g, b_a (columns 0:9) are B's; its bias block is P's.
  C.topLeftCorner<9, 9>() = B;
  C.block<9, 6>(0, 9) = C.block<6, 9>(9, 0).transpose();
  add_process_noise(noise, dt, C);
}

// P_rc ← P_rc Φᵀ on the contiguous columns of the bottom-left block; Φ's rows b_g, b_a are the identity, so
// only P_rc's columns p, v, θ (and P_cr's rows) change. Column j of the result is a sum of axpys over P_rc's
// columns; Φ's exact zeros are skipped.
void apply_cross_transition(const Mat15& PhiT, Eigen::MatrixXd& P, Eigen::MatrixXd& tmp) {
  const int r = static_cast<int>(P.rows()) - kCore;
  if (r <= 0) return;
  tmp.resize(r, 9);
  for (int j = 0; j < 9; ++j) {
    double* __restrict t = tmp.col(j).data();
    for (int i = 0; i < r; ++i) t[i] = 0.0;
    for (int k = 0; k < kCore; ++k) {
      const double phi = PhiT(k, j);
      if (phi == 0.0) continue;
      const double* __restrict p = &P(kCore, k);
      for (int i = 0; i < r; ++i) t[i] += phi * p[i];
    }
  }
  P.bottomLeftCorner(r, 9) = tmp;
  P.topRightCorner(9, r) = tmp.transpose();
}

}  // namespace

void FilterCovariance::propagate(const CoreTransition& F, const ImuNoiseParams& noise, double dt) {
  // The core block is propagated in the fixed-size Pcc_ (no strided copies per sample); P_'s top-left block
  // takes it back on the next sync_core(). The consider covariance's core block likewise in Pacc_.
  if (!cc_pending_) {
    Pcc_ = P_.topLeftCorner<15, 15>();
    if (consider_) Pacc_ = Pa_.topLeftCorner<15, 15>();
    cc_pending_ = true;
  }
  propagate_core_block(F, noise, dt, Pcc_);
  if (consider_) propagate_core_block(F, noise, dt, Pacc_);
  if (dim() > kCore) {
    // Φᵀ ← Φᵀ Fᵀ (Φ = F_k⋯F_1 is kept transposed so that the products run on columns). Φ's columns p and v
    // (Φᵀ's rows p, v) stay [I; 0; 0; 0; 0] and [Σdt I; I; 0; 0; 0] (F's columns p, v are trivial), so
    // only Φᵀ's rows θ, b_g, b_a need the product (and of those only the θ columns, accumulate_transition)
    // and Φ_pv accumulates dt.
    accumulate_transition(F, PhiT_);
    phi_pending_ = true;
  }
}

void FilterCovariance::sync_core() {
  if (!cc_pending_) return;
  P_.topLeftCorner<15, 15>() = Pcc_;
  if (consider_) Pa_.topLeftCorner<15, 15>() = Pacc_;
  cc_pending_ = false;
}

const Eigen::MatrixXd& FilterCovariance::full() {
  sync_core();
  if (!phi_pending_) return P_;
  apply_cross_transition(PhiT_, P_, tmp_cross_);
  if (consider_) apply_cross_transition(PhiT_, Pa_, tmp_cross_);
  PhiT_.setIdentity();
  phi_pending_ = false;
  return P_;
}

const Eigen::MatrixXd& FilterCovariance::reported_full() {
  full();
  return consider_ ? Pa_ : P_;
}

const Eigen::Block<const Eigen::MatrixXd, kCore, kCore> FilterCovariance::core_block() {
  sync_core();
  return std::as_const(P_).topLeftCorner<kCore, kCore>();
}

void FilterCovariance::inflate_core(int first, double var) {
  sync_core();
  P_.block<3, 3>(first, first).diagonal().array() += var;
  if (consider_) Pa_.block<3, 3>(first, first).diagonal().array() += var;
}

void FilterCovariance::record_step(const CoreTransition& F) { accumulate_transition(F, rec_PhiT_); }

void FilterCovariance::take_segment(Mat15& Phi, Mat15& P_cc) {
  Phi = rec_PhiT_.transpose();
  P_cc = core_block();
  rec_PhiT_.setIdentity();
}

namespace {

// P ← [P, P J_xᵀ; J_x P, J_x P J_xᵀ + Q] with P_xa = P J_xᵀ formed from J_x's compact columns.
void augment_matrix(const CompactJacobian6& Jx, const Mat6& Q, Eigen::MatrixXd& P) {
  const Eigen::Index n = P.rows();
  Eigen::MatrixXd P_xa = Eigen::MatrixXd::Zero(n, 6);
  for (int j = 0; j < Jx.nc; ++j) P_xa.noalias() += P.col(Jx.idx[j]) * Jx.J.col(j).transpose();
  Mat6 P_aa = Q;
  for (int j = 0; j < Jx.nc; ++j) P_aa.noalias() += Jx.J.col(j) * P_xa.row(Jx.idx[j]);
  P_aa = 0.5 * (P_aa + P_aa.transpose()).eval();
  Eigen::MatrixXd P_new(n + 6, n + 6);
  P_new.topLeftCorner(n, n) = P;
  P_new.topRightCorner(n, 6) = P_xa;
  P_new.bottomLeftCorner(6, n) = P_xa.transpose();
  P_new.bottomRightCorner<6, 6>() = P_aa;
  P.swap(P_new);
}

}  // namespace

void FilterCovariance::augment(const CompactJacobian6& Jx, const Mat6& Q) {
  full();
  const int n = dim();
  for (int j = 0; j < Jx.nc; ++j) ROE_CHECK(Jx.idx[j] < n, "FilterCovariance::augment: J_x column outside the state");
  augment_matrix(Jx, Q, P_);
  if (consider_) augment_matrix(Jx, Q, Pa_);
}

void FilterCovariance::decay(const Eigen::VectorXd& b) {
  ROE_CHECK(b.size() == dim(), "FilterCovariance::decay: b's size is not the state's");
  ROE_CHECK((b.head<kCore>().array() == 1.0).all() && (b.array() >= 0.0).all() && (b.array() <= 1.0).all(),
            "FilterCovariance::decay: b must be in [0, 1], 1 on the core");
  // Only the decayed rows/columns change, none of them a core one: the pending core propagation (P_cc and the
  // lazy cross terms) is unaffected, but the cross terms are brought up to date first so that P_ is one matrix.
  full();
  for (Eigen::MatrixXd* P : {&P_, &Pa_}) {
    if (P == &Pa_ && !consider_) continue;
    for (Eigen::Index i = kCore; i < b.size(); ++i) {
      if (b(i) == 1.0) continue;
      P->row(i) *= b(i);
      P->col(i) *= b(i);
      (*P)(i, i) += 1.0 - b(i) * b(i);
    }
  }
}

void FilterCovariance::change_variables(const Eigen::MatrixXd& M) {
  ROE_CHECK(M.cols() == dim(), "FilterCovariance::change_variables: M's columns are not the state's");
  full();
  Eigen::MatrixXd P_new = M * P_ * M.transpose();
  P_.swap(P_new);
  if (consider_) Pa_ = (M * Pa_ * M.transpose()).eval();
  symmetrise();
}

bool FilterCovariance::update(const Eigen::Ref<const Eigen::MatrixXd>& Y, const Eigen::Ref<const Eigen::MatrixXd>& S,
                              const Eigen::Ref<const Eigen::VectorXd>& r, Eigen::VectorXd& dx,
                              const StackedUpdateBuffers& buf, const ConsiderNoise* consider) {
  ROE_CHECK(Y.rows() == dim(), "FilterCovariance::update: P Hᵀ's rows are not the state's");
  ROE_CHECK(!consider_ || consider != nullptr, "FilterCovariance::update: the consider covariance needs H and its noise");
  full();
  if (!stacked_update(P_, Y, S, r, dx, buf)) return false;
  if (!consider_) return true;
  // The nominal gain K = W L⁻¹ from stacked_update's W = Y L⁻ᵀ and S = L Lᵀ (solve K L = W).
  const Eigen::Index m = S.rows();
  Eigen::MatrixXd K = buf.W.leftCols(m);
  buf.L.topLeftCorner(m, m).triangularView<Eigen::Lower>().solveInPlace<Eigen::OnTheRight>(K);
  consider_update(Pa_, K, *consider);
  return true;
}

void consider_update(Eigen::MatrixXd& Pa, const Eigen::Ref<const Eigen::MatrixXd>& K, const ConsiderNoise& noise) {
  const Eigen::MatrixXd& H = noise.H;
  const Eigen::MatrixXd& R = noise.R;
  const Eigen::Index n = Pa.rows(), m = H.rows();
  ROE_CHECK(H.cols() == n && K.rows() == n && K.cols() == m && R.rows() == m && R.cols() == m && noise.d.size() == m,
            "consider_update: K, H, R and d do not match P_a");
  // H's non-zero columns (a detection touches the pose, the calibration and its own object): Y_a = P_a Hᵀ
  // and H Y_a from those only.
  std::vector<Eigen::Index> cols;
  for (Eigen::Index j = 0; j < n; ++j)
    if ((H.col(j).array() != 0.0).any()) cols.push_back(j);
  const Eigen::MatrixXd Hc = H(Eigen::all, cols);
  const Eigen::MatrixXd Ya = Pa(Eigen::all, cols) * Hc.transpose();  // P_a Hᵀ (n x m)
  Eigen::MatrixXd Sa = Hc * Ya(cols, Eigen::all) + R;
  Sa = (0.5 * (Sa + Sa.transpose())).eval();
  // (I − K H) P_a (I − K H)ᵀ + K R Kᵀ = P_a − K Y_aᵀ − Y_a Kᵀ + K S_a Kᵀ = P_a + E Kᵀ + K Eᵀ, E = ½ K S_a − Y_a:
  // a rank-2m product on the lower triangle, mirrored.
  Eigen::MatrixXd E = -Ya;
  E.noalias() += 0.5 * K * Sa;
  const Eigen::MatrixXd Kd = K;  // contiguous for the raw product
  add_abt(Pa.data(), Pa.outerStride(), E.data(), E.outerStride(), Kd.data(), Kd.outerStride(), n, n, m, 1.0, true);
  add_abt(Pa.data(), Pa.outerStride(), Kd.data(), Kd.outerStride(), E.data(), E.outerStride(), n, n, m, 1.0, true);
  Pa.triangularView<Eigen::StrictlyUpper>() = Pa.transpose();
  if (!noise.rows.empty()) {
    const Eigen::MatrixXd DRD_R = noise.d.asDiagonal() * R * noise.d.asDiagonal() - R;
    const Eigen::MatrixXd Ks = K(noise.rows, Eigen::all);
    Eigen::MatrixXd add = Ks * DRD_R * Ks.transpose();
    add = (0.5 * (add + add.transpose())).eval();
    Pa(noise.rows, noise.rows) += add;
  }
}

bool FilterCovariance::update_constant_gain(const Eigen::Ref<const Eigen::MatrixXd>& Y,
                                            const Eigen::Ref<const Eigen::MatrixXd>& S,
                                            const Eigen::Ref<const Eigen::MatrixXd>& R,
                                            const Eigen::Ref<const Eigen::VectorXd>& d,
                                            const Eigen::Ref<const Eigen::VectorXd>& r,
                                            const std::vector<Eigen::Index>& rows, Eigen::VectorXd& dx) {
  ROE_CHECK(Y.rows() == dim(), "FilterCovariance::update_constant_gain: P Hᵀ's rows are not the state's");
  full();
  return stacked_update_constant_gain(P_, Y, S, R, d, r, rows, dx);
}

bool FilterCovariance::update_dense(const Eigen::MatrixXd& H, const Eigen::MatrixXd& R,
                                    const Eigen::Ref<const Eigen::VectorXd>& r, Eigen::VectorXd& dx,
                                    const ConsiderNoise* consider) {
  ROE_CHECK(H.cols() == dim(), "FilterCovariance::update_dense: H's columns are not the state's");
  ROE_CHECK(!consider_ || consider != nullptr, "FilterCovariance::update_dense: the consider covariance needs its noise");
  full();
  const Eigen::MatrixXd S = H * P_ * H.transpose() + R;
  const Eigen::LLT<Eigen::MatrixXd> llt(S);
  if (llt.info() != Eigen::Success) return false;
  const Eigen::MatrixXd K = llt.solve(H * P_).transpose();  // P Hᵀ S⁻¹ (P and S symmetric)
  dx = K * r;
  const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(dim(), dim()) - K * H;
  P_ = IKH * P_ * IKH.transpose() + K * R * K.transpose();
  if (consider_) consider_update(Pa_, K, *consider);
  symmetrise();
  return true;
}

std::optional<std::string> FilterCovariance::check(bool positive_definite) {
  static const char* names[] = {"p_W_I", "v_W_I", "theta_W_I", "b_g", "b_a"};
  sync_core();
  // Every update: one vectorised pass over the diagonal; the loop below only names the first bad entry.
  const auto diag = P_.diagonal().array();
  const bool diag_ok = ((diag > 0.0) && (diag < std::numeric_limits<double>::infinity())).all();
  for (int i = 0; !diag_ok && i < dim(); ++i) {
    const double d = P_(i, i);
    if (!std::isfinite(d) || d <= 0.0) {
      const std::string comp = i < kCore ? std::string(names[i / 3]) + "[" + std::to_string(i % 3) + "]"
                                         : "error-state index " + std::to_string(i);
      return "covariance diagonal of " + comp + (std::isfinite(d) ? " is not positive " : " is not finite ");
    }
  }
  if (consider_ && !((Pa_.diagonal().array() > 0.0) && (Pa_.diagonal().array() < std::numeric_limits<double>::infinity())).all())
    return std::string("the consider covariance's diagonal is not finite and positive");
  if (!positive_definite) return std::nullopt;
  full();
  if (!P_.allFinite()) return std::string("covariance is not finite");
  if (Eigen::LLT<Eigen::MatrixXd>(P_).info() != Eigen::Success)
    return std::string("covariance is not positive definite");
  return std::nullopt;
}

}  // namespace roe::ekf
