#include "roe/ekf/smoother.hpp"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "roe/core/error.hpp"
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

/// One output row from a core state, its core covariance and the extrinsics' covariance.
SmoothedState make_state(Timestamp t, const CoreState& x, const Pose& T_I_C, const Mat15& Pcc, const MatX& P,
                         int extr) {
  SmoothedState s;
  s.t_ns = t;
  s.x = x;
  s.T_I_C = T_I_C;
  for (int i = 0; i < kCore; ++i) s.sigma(i) = std::sqrt(std::max(0.0, Pcc(i, i)));
  if (extr >= 0)
    for (int i = 0; i < 6; ++i) s.sigma(kCore + i) = std::sqrt(std::max(0.0, P(extr + i, extr + i)));
  for (int a = 0; a < 2; ++a)
    for (int b = 0; b < 2; ++b)
      s.pose_cov.block<3, 3>(3 * a, 3 * b) = Pcc.block<3, 3>(a == 0 ? kP : kTheta, b == 0 ? kP : kTheta);
  return s;
}

/// What the backward pass needs from one propagation segment a → b (docs in smoother.hpp): with
/// Pp = P_b⁻ and D = P_s,b − P_b⁻, the smoothed δ_a and P_s,a, and, for the IMU steps inside the segment,
/// λ and W = P_b⁻⁻¹ D P_b⁻⁻¹ reduced to the 30 directions the steps see (M = Tᵀ W T, T = diag(I₁₅, P_a,rc)).
struct SegmentGain {
  VecX delta_a;
  MatX Ps_a;
  Eigen::Matrix<double, 30, 1> lambda_T = Eigen::Matrix<double, 30, 1>::Zero();  ///< Tᵀ λ
  Eigen::Matrix<double, 30, 30> M = Eigen::Matrix<double, 30, 30>::Zero();
};

/// The segment's gain C = P_a Φᵀ P_b⁻⁻¹ without forming it. Propagation adds process noise Q to the core
/// block only, so P_a Φᵀ = Φ⁻¹ (P_b⁻ − Q) and C = Φ⁻¹ (I − Q P_b⁻⁻¹), where Q P_b⁻⁻¹ has 15 non-zero rows:
/// δ_a = Φ⁻¹ (δ_b − Q λ), P_s,a = P_a + Φ⁻¹ G D Gᵀ Φ⁻ᵀ with G = I − Q P_b⁻⁻¹, all in O(15 n²) after one
/// Cholesky factor of P_b⁻ (the direct form C D Cᵀ costs several n³ products per segment).
SegmentGain segment_gain(const RecordedNode& nd, const MatX& Pa, const MatX& Ps, const VecX& delta_b) {
  const Eigen::Index n = Pa.rows(), r = n - kCore;
  const MatX Pp = predicted_covariance(nd, Pa);
  const auto llt = factor(Pp, nd.x.t_ns, "predicted");
  MatX T = MatX::Zero(n, 30);
  T.topLeftCorner<kCore, kCore>().setIdentity();
  if (r > 0) T.bottomRightCorner(r, kCore) = Pa.bottomLeftCorner(r, kCore);
  const MatX Z = llt.solve(T);  // P_b⁻⁻¹ T; its first 15 columns are P_b⁻⁻¹'s core columns
  const VecX lambda = llt.solve(delta_b);
  MatX D = Ps - Pp;

  SegmentGain g;
  g.lambda_T = T.transpose() * lambda;
  const MatX DZ = D * Z;
  g.M = Z.transpose() * DZ;
  g.M = 0.5 * (g.M + g.M.transpose()).eval();

  const Mat15 Phi_inv = nd.Phi.inverse();
  const Mat15 Q = nd.P_cc - nd.Phi * Pa.topLeftCorner<kCore, kCore>() * nd.Phi.transpose();
  g.delta_a = delta_b;
  g.delta_a.head<kCore>() = Phi_inv * (delta_b.head<kCore>() - Q * lambda.head<kCore>());
  // G D Gᵀ: E = Q (P_b⁻⁻¹)_c: changes the core rows, then Eᵀ the core columns.
  const MatX E = Q * Z.leftCols<kCore>().transpose();
  D.topRows<kCore>() -= (E * D).eval();
  D.leftCols<kCore>() -= (D * E.transpose()).eval();
  D.topRows<kCore>() = (Phi_inv * D.topRows<kCore>()).eval();
  D.leftCols<kCore>() = (D.leftCols<kCore>() * Phi_inv.transpose()).eval();
  g.Ps_a = symmetric(Pa + D);
  return g;
}

/// The smoothed core state and covariance at every IMU step inside a segment, written to res.states:
/// P(t) and Φ(t, a) re-propagated from P_a with the recorded F and the same process noise, then backwards
/// Ψ = Φ(b, t), A_t = [P_cc(t) Ψᵀ, Φ(t, a) P_a,cr] = G_t Tᵀ with G_t = [P_cc(t) Ψᵀ, Φ(t, a)] (15 x 30):
/// δ_s(t) = G_t Tᵀλ, P_s(t) = P_cc(t) + G_t M G_tᵀ (fixed-size products only).
void smooth_segment_steps(const FilterRecording& rec, const RecordedNode& nd, const MatX& Pa, const SegmentGain& g,
                          const ImuNoiseParams& noise, const StateEstimate& xa, const MatX& Psa,
                          SmootherResult& res) {
  const std::size_t m = nd.steps - nd.first_step;
  std::vector<Mat15> Pcc(m), Phi(m);
  Mat15 Pc = Pa.topLeftCorner<kCore, kCore>();
  Mat15 Ph = Mat15::Identity();
  for (std::size_t i = 0; i < m; ++i) {
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
  Eigen::Matrix<double, kCore, 30> G;
  for (std::size_t i = m; i-- > 0;) {
    const RecordedStep& st = rec.steps[nd.first_step + i];
    G.leftCols<kCore>().noalias() = Pcc[i] * Psi.transpose();
    G.rightCols<kCore>() = Phi[i];
    CoreState x = st.x;
    boxplus_core(x, G * g.lambda_T);
    const Eigen::Matrix<double, kCore, 30> GM = G * g.M;
    Mat15 Psc = Pcc[i];
    Psc.noalias() += GM * G.transpose();
    res.states[nd.first_step + i + 1] = make_state(st.t_ns, x, xa.T_I_C, Psc, Psa, xa.extr_offset);
    st.F.apply_right(Psi);
  }
}

}  // namespace

SmootherResult smooth(const FilterRecording& rec, const ImuNoiseParams& noise) {
  const auto& nodes = rec.nodes;
  ROE_CHECK(!nodes.empty() && nodes.front().kind == RecordedNode::Kind::kInit,
            "smooth: the recording does not start with the filter's initialisation");
  ROE_CHECK(nodes.back().steps == rec.steps.size(), "smooth: the recording was not finished");
  const auto full_P = [&](std::size_t j) -> MatX {
    if (nodes[j].kind != RecordedNode::Kind::kPropagate) return nodes[j].P;
    ROE_CHECK(j > 0 && nodes[j - 1].kind != RecordedNode::Kind::kPropagate,
              "smooth: two propagation nodes in a row");
    return predicted_covariance(nodes[j], nodes[j - 1].P);
  };

  SmootherResult res;
  res.states.resize(rec.steps.size() + 1);
  StateEstimate xs = nodes.back().x;
  MatX Ps = full_P(nodes.size() - 1);
  bool anchor_seen = false;
  std::size_t anchor_steps = 0;

  for (std::size_t j = nodes.size() - 1; j >= 1; --j) {
    const RecordedNode& nd = nodes[j];
    switch (nd.kind) {
      case RecordedNode::Kind::kInit:
        ROE_CHECK(false, "smooth: a second initialisation node");
        break;
      case RecordedNode::Kind::kUpdate:
        // The same variables before and after an update: the smoothed estimate passes unchanged.
        break;
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
          // C = P_u Bᵀ P_y⁻¹, as Cᵀ = P_y⁻¹ (B P_u).
          const auto llt = factor(nd.P, nd.x.t_ns, "augmented");
          const MatX CT = llt.solve(nd.B * Pu);
          du = CT.transpose() * d;
          Psu = Pu + CT.transpose() * (Ps - nd.P) * CT;
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
        const SegmentGain g = segment_gain(nd, a.P, Ps, boxminus(xs, nd.x));
        StateEstimate xa = a.x;
        boxplus(xa, g.delta_a);
        const MatX& Psa = g.Ps_a;
        smooth_segment_steps(rec, nd, a.P, g, noise, xa, Psa, res);
        xs = std::move(xa);
        Ps = Psa;
        break;
      }
    }
  }
  res.states[0] = make_state(xs.t_ns, xs.x, xs.T_I_C, Ps.topLeftCorner<kCore, kCore>(), Ps, xs.extr_offset);

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
