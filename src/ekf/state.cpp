#include "roe/ekf/state.hpp"

#include "roe/core/error.hpp"
#include "roe/math/so3.hpp"

namespace roe::ekf {

using math::exp_quat;
using math::log_quat;
using VecX = Eigen::VectorXd;
using Vec15 = Eigen::Matrix<double, 15, 1>;

void boxplus_core(CoreState& x, const Vec15& dx) {
  x.p_W_I += dx.segment<3>(kP);
  x.v_W_I += dx.segment<3>(kV);
  x.q_W_I = (x.q_W_I * exp_quat(dx.segment<3>(kTheta))).normalized();
  x.b_g += dx.segment<3>(kBg);
  x.b_a += dx.segment<3>(kBa);
}

void boxplus(StateEstimate& s, const Eigen::VectorXd& dx) {
  ROE_CHECK(dx.size() == s.dim, "boxplus: wrong size");
  boxplus_core(s.x, dx.head<kCore>());
  if (s.extr_offset >= 0) {
    s.T_I_C.p += dx.segment<3>(s.extr_offset);
    s.T_I_C.q = (s.T_I_C.q * exp_quat(dx.segment<3>(s.extr_offset + 3))).normalized();
  }
  if (s.td_offset >= 0) s.t_d += dx(s.td_offset);
  for (auto& o : s.objects) {
    if (o.err_offset >= 0) o.err += dx.segment<6>(o.err_offset);
    if (o.dim == 6) {
      o.T_O_W.p += dx.segment<3>(o.offset);
      o.T_O_W.q = (o.T_O_W.q * exp_quat(dx.segment<3>(o.offset + 3))).normalized();
    } else if (o.dim > 0) {  // anchor: the first o.dim components of δθ_O_W
      Vec3 dth = Vec3::Zero();
      dth.head(o.dim) = dx.segment(o.offset, o.dim);
      o.T_O_W.q = (o.T_O_W.q * exp_quat(dth)).normalized();
    }
  }
}

Eigen::VectorXd boxminus(const StateEstimate& a, const StateEstimate& b) {
  ROE_CHECK(a.dim == b.dim && a.extr_offset == b.extr_offset && a.td_offset == b.td_offset &&
                a.objects.size() == b.objects.size(),
            "boxminus: states of different layouts");
  VecX d(b.dim);
  d.segment<3>(kP) = a.x.p_W_I - b.x.p_W_I;
  d.segment<3>(kV) = a.x.v_W_I - b.x.v_W_I;
  d.segment<3>(kTheta) = log_quat(b.x.q_W_I.conjugate() * a.x.q_W_I);
  d.segment<3>(kBg) = a.x.b_g - b.x.b_g;
  d.segment<3>(kBa) = a.x.b_a - b.x.b_a;
  if (b.extr_offset >= 0) {
    d.segment<3>(b.extr_offset) = a.T_I_C.p - b.T_I_C.p;
    d.segment<3>(b.extr_offset + 3) = log_quat(b.T_I_C.q.conjugate() * a.T_I_C.q);
  }
  if (b.td_offset >= 0) d(b.td_offset) = a.t_d - b.t_d;
  for (std::size_t i = 0; i < b.objects.size(); ++i) {
    const auto& oa = a.objects[i];
    const auto& ob = b.objects[i];
    ROE_CHECK(oa.id == ob.id && oa.dim == ob.dim && oa.offset == ob.offset && oa.err_offset == ob.err_offset,
              "boxminus: objects differ");
    if (ob.err_offset >= 0) d.segment<6>(ob.err_offset) = oa.err - ob.err;
    if (ob.dim == 0) continue;
    const Vec3 dth = log_quat(ob.T_O_W.q.conjugate() * oa.T_O_W.q);
    if (ob.dim == 6) {
      d.segment<3>(ob.offset) = oa.T_O_W.p - ob.T_O_W.p;
      d.segment<3>(ob.offset + 3) = dth;
    } else {
      d.segment(ob.offset, ob.dim) = dth.head(ob.dim);
    }
  }
  return d;
}

}  // namespace roe::ekf
