#include "roe/ekf/smoother.hpp"

#include <fmt/format.h>

#include <Eigen/Cholesky>

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
        const MatX& Pa = a.P;
        const Eigen::Index n = Pa.rows(), r = n - kCore;
        const MatX Pp = predicted_covariance(nd, Pa);
        const auto llt = factor(Pp, nd.x.t_ns, "predicted");
        const VecX lambda = llt.solve(boxminus(xs, nd.x));  // P_b⁻⁻¹ δ_b
        const MatX D = Ps - Pp;
        const MatX W = symmetric(llt.solve(llt.solve(D).transpose()));  // P_b⁻⁻¹ D P_b⁻⁻¹
        // C = P_a Φᵀ P_b⁻⁻¹ (Φ acts on the core columns only), as Cᵀ = P_b⁻⁻¹ (Φ P_a).
        MatX PaPhiT = Pa;
        PaPhiT.leftCols<kCore>() = Pa.leftCols<kCore>() * nd.Phi.transpose();
        const MatX CT = llt.solve(PaPhiT.transpose());
        StateEstimate xa = a.x;
        boxplus(xa, PaPhiT * lambda);
        const MatX Psa = symmetric(Pa + CT.transpose() * D * CT);

        // The IMU steps of the segment: P(t) re-propagated from P_a, then, backwards, Φ(b, t) and the
        // smoothed core state and covariance at every step.
        const std::size_t m = nd.steps - nd.first_step;
        std::vector<Mat15> Pcc(m);
        std::vector<MatX> Pcr(m);
        Mat15 Pc = Pa.topLeftCorner<kCore, kCore>();
        MatX Pr = Pa.topRightCorner(kCore, r);
        for (std::size_t i = 0; i < m; ++i) {
          const CoreTransition& F = rec.steps[nd.first_step + i].F;
          const Mat15 Fd = F.dense();
          Pc = Fd * Pc * Fd.transpose();
          add_process_noise(noise, F.dt, Pc);
          Pc = 0.5 * (Pc + Pc.transpose()).eval();
          Pr = Fd * Pr;
          Pcc[i] = Pc;
          Pcr[i] = Pr;
        }
        Mat15 Psi = Mat15::Identity();  // Φ(b, t_i)
        MatX A(kCore, n);
        for (std::size_t i = m; i-- > 0;) {
          const RecordedStep& st = rec.steps[nd.first_step + i];
          A.leftCols<kCore>() = Pcc[i] * Psi.transpose();
          if (r > 0) A.rightCols(r) = Pcr[i];
          CoreState x = st.x;
          boxplus_core(x, A * lambda);
          const Mat15 Psc = Pcc[i] + A * W * A.transpose();
          res.states[nd.first_step + i + 1] = make_state(st.t_ns, x, xa.T_I_C, Psc, Psa, xa.extr_offset);
          Psi = Psi * st.F.dense();
        }
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
