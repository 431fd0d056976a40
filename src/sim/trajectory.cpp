#include "roe/sim/trajectory.hpp"

#include <cmath>

#include "roe/core/error.hpp"
#include "roe/math/euler.hpp"

namespace roe::sim {
namespace {
using math::kTwoPi;

// A second-order jet: a scalar function of time with its first and second derivative. Arithmetic
// follows the product/quotient/chain rules, so composite expressions carry exact derivatives.
struct Jet {
  double v = 0.0, d = 0.0, dd = 0.0;
};
Jet operator+(Jet a, Jet b) { return {a.v + b.v, a.d + b.d, a.dd + b.dd}; }
Jet operator-(Jet a, Jet b) { return {a.v - b.v, a.d - b.d, a.dd - b.dd}; }
Jet operator-(Jet a) { return {-a.v, -a.d, -a.dd}; }
Jet operator+(Jet a, double c) { return {a.v + c, a.d, a.dd}; }
Jet operator*(Jet a, Jet b) {
  return {a.v * b.v, a.d * b.v + a.v * b.d, a.dd * b.v + 2.0 * a.d * b.d + a.v * b.dd};
}
// f(g(t)) with f, f', f'' evaluated at g.
Jet chain(Jet g, double f, double f1, double f2) { return {f, f1 * g.d, f2 * g.d * g.d + f1 * g.dd}; }
Jet sin(Jet a) { return chain(a, std::sin(a.v), std::cos(a.v), -std::sin(a.v)); }
Jet cos(Jet a) { return chain(a, std::cos(a.v), -std::sin(a.v), -std::cos(a.v)); }
Jet sqrt(Jet a) {
  const double s = std::sqrt(a.v);
  return chain(a, s, 0.5 / s, -0.25 / (s * a.v));
}
// atan2(y, x): d = (x y' − y x') / (x² + y²); the second derivative by the quotient rule.
Jet atan2(Jet y, Jet x) {
  const double n = x.v * y.d - y.v * x.d;
  const double m = x.v * x.v + y.v * y.v;
  const double n1 = x.v * y.dd - y.v * x.dd;  // (x y' − y x')' = x y'' − y x''
  const double m1 = 2.0 * (x.v * x.d + y.v * y.d);
  return {std::atan2(y.v, x.v), n / m, (n1 * m - n * m1) / (m * m)};
}

Jet signal(const SmoothSignal& s, double t) {
  Jet j{s.offset + s.rate * t, s.rate, 0.0};
  for (const auto& term : s.terms) {
    const double w = kTwoPi * term.frequency_hz;
    const double arg = w * t + term.phase_rad;
    j.v += term.amplitude * std::sin(arg);
    j.d += term.amplitude * w * std::cos(arg);
    j.dd -= term.amplitude * w * w * std::sin(arg);
  }
  return j;
}

Eigen::Matrix3d rot_z(double a) { return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).toRotationMatrix(); }
Eigen::Matrix3d rot_y(double a) { return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitY()).toRotationMatrix(); }
Eigen::Matrix3d rot_x(double a) { return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitX()).toRotationMatrix(); }

// R_L_C: the optical frame C (x right, y down, z forward) in the look frame L (x forward, y left,
// z up). Columns are C's axes in L.
Eigen::Matrix3d R_L_C() {
  Eigen::Matrix3d R;
  R << 0, 0, 1,  //
      -1, 0, 0,  //
      0, -1, 0;
  return R;
}
}  // namespace

Eigen::Vector3d evaluate_signal(const SmoothSignal& s, double t) {
  const Jet j = signal(s, t);
  return {j.v, j.d, j.dd};
}

InspectionTrajectory::InspectionTrajectory(TrajectoryConfig config) : config_(std::move(config)) {}

Kinematics InspectionTrajectory::camera(double t) const {
  const auto& c = config_;
  const Jet az = signal(c.azimuth_rad, t), r = signal(c.radius_m, t), h = signal(c.height_m, t);
  const Jet px = r * cos(az) + signal(c.shake_x_m, t) + c.center.x();
  const Jet py = r * sin(az) + signal(c.shake_y_m, t) + c.center.y();
  const Jet pz = h + signal(c.shake_z_m, t) + c.center.z();
  // Direction to the look-at point.
  const Jet dx = signal(c.target_x_m, t) + c.center.x() - px;
  const Jet dy = signal(c.target_y_m, t) + c.center.y() - py;
  const Jet dz = signal(c.target_z_m, t) + c.center.z() - pz;
  const Jet rho2 = dx * dx + dy * dy;
  if (rho2.v < 1e-8)
    throw NumericError("simulated camera looks straight up or down (look-at point above/below it) at t = " +
                       std::to_string(t) + " s");
  const Jet yaw = atan2(dy, dx);
  const Jet pitch = -atan2(dz, sqrt(rho2));
  const Jet roll = signal(c.roll_rad, t);

  // Body rates of R = Rz(ψ) Ry(θ) Rx(φ) in the rotated frame:
  //   ω = [φ' − ψ' sθ,  θ' cφ + ψ' cθ sφ,  −θ' sφ + ψ' cθ cφ].
  // Their derivatives use jets whose value is the rate and whose derivative is the acceleration.
  const Jet sth = sin(pitch), cth = cos(pitch), sph = sin(roll), cph = cos(roll);
  const Jet dphi{roll.d, roll.dd, 0.0}, dth{pitch.d, pitch.dd, 0.0}, dpsi{yaw.d, yaw.dd, 0.0};
  const Jet wx = dphi - dpsi * sth;
  const Jet wy = dth * cph + dpsi * cth * sph;
  const Jet wz = -(dth * sph) + dpsi * cth * cph;
  const Eigen::Vector3d omega_L(wx.v, wy.v, wz.v);
  const Eigen::Vector3d alpha_L(wx.d, wy.d, wz.d);

  const Eigen::Matrix3d RLC = R_L_C();
  const Eigen::Matrix3d R_M_C = rot_z(yaw.v) * rot_y(pitch.v) * rot_x(roll.v) * RLC;
  Kinematics k;
  k.T_M_X = math::Pose(R_M_C, Eigen::Vector3d(px.v, py.v, pz.v));
  k.v_M = Eigen::Vector3d(px.d, py.d, pz.d);
  k.a_M = Eigen::Vector3d(px.dd, py.dd, pz.dd);
  k.omega_X = RLC.transpose() * omega_L;
  k.alpha_X = RLC.transpose() * alpha_L;
  return k;
}

Kinematics InspectionTrajectory::attached(double t, const math::Pose& T_C_X) const {
  const Kinematics c = camera(t);
  const Eigen::Matrix3d R_M_C = c.T_M_X.R();
  const Eigen::Vector3d w = R_M_C * c.omega_X;
  const Eigen::Vector3d al = R_M_C * c.alpha_X;
  const Eigen::Vector3d r = R_M_C * T_C_X.p;
  Kinematics x;
  x.T_M_X = c.T_M_X * T_C_X;
  x.v_M = c.v_M + w.cross(r);
  x.a_M = c.a_M + al.cross(r) + w.cross(w.cross(r));
  const Eigen::Matrix3d R_X_C = T_C_X.R().transpose();
  x.omega_X = R_X_C * c.omega_X;
  x.alpha_X = R_X_C * c.alpha_X;
  return x;
}

}  // namespace roe::sim
