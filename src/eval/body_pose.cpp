// The estimate's body in the ground truth's body: the hand–eye fit of `roe eval --fit-body-pose`
// (eval/body_pose.hpp).
#include "roe/eval/body_pose.hpp"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <sstream>

#include "roe/core/error.hpp"
#include "roe/eval/metrics.hpp"
#include "roe/eval/time_offset.hpp"
#include "roe/math/so3.hpp"

namespace roe::eval {

namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

/// The lever arm's normal equations for the pairs at one alignment: with c_k = s R p_est + t0 − p_gt and
/// the translation eliminated, H t_BI = b with H = Σ (R_k − R̄)ᵀ(R_k − R̄), b = Σ (R_k − R̄)ᵀ(c_k − c̄).
struct LeverArmSystem {
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R_mean = Eigen::Matrix3d::Zero();
};

LeverArmSystem lever_arm_system(const std::vector<Eigen::Vector3d>& c, const std::vector<Eigen::Matrix3d>& R) {
  LeverArmSystem s;
  const auto n = static_cast<double>(c.size());
  Eigen::Vector3d c_mean = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < c.size(); ++k) s.R_mean += R[k] / n, c_mean += c[k] / n;
  for (std::size_t k = 0; k < c.size(); ++k) {
    const Eigen::Matrix3d D = R[k] - s.R_mean;
    s.H += D.transpose() * D;
    s.b += D.transpose() * (c[k] - c_mean);
  }
  return s;
}

std::string axis_text(const Eigen::Vector3d& v) {
  return fmt::format("({:.2f}, {:.2f}, {:.2f})", v.x(), v.y(), v.z());
}

}  // namespace

BodyPoseFit fit_body_pose(const std::vector<Pose>& est, const std::vector<std::size_t>& est_index,
                          const std::vector<Pose>& gt, const std::vector<std::size_t>& gt_index, AlignType type,
                          int n_align) {
  if (type != AlignType::kSe3 && type != AlignType::kSim3 && type != AlignType::kPosYaw)
    throw InputError(fmt::format("--fit-body-pose needs a fitted alignment (se3, sim3 or posyaw), not --align {}",
                                 to_string(type)),
                     {"", 0, 0, "fit-body-pose"});
  const std::size_t n = std::min(est_index.size(), n_align > 0 ? static_cast<std::size_t>(n_align) : est_index.size());
  if (n < 10) throw DataError(fmt::format("--fit-body-pose needs at least 10 matched pairs, got {}", n));
  std::vector<Pose> e(n), g(n);
  std::vector<Eigen::Matrix3d> Rg(n);
  for (std::size_t k = 0; k < n; ++k) e[k] = est[est_index[k]], g[k] = gt[gt_index[k]], Rg[k] = g[k].R();
  BodyPoseFit f;
  f.n_pairs = n;
  // Observability: the spread of the ground truth's rotation (the same for every alignment).
  const LeverArmSystem s0 = lever_arm_system(std::vector<Eigen::Vector3d>(n, Eigen::Vector3d::Zero()), Rg);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(s0.H / static_cast<double>(n));
  const Eigen::Vector3d spread = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt() * kRadToDeg;
  f.rotation_spread_min_deg = spread.minCoeff(), f.rotation_spread_max_deg = spread.maxCoeff();
  const double lambda_min = std::pow(kMinBodyRotationSpreadDeg / kRadToDeg, 2) * static_cast<double>(n);
  Eigen::Matrix3d H_pinv = Eigen::Matrix3d::Zero();
  for (int i = 0; i < 3; ++i)
    if (eig.eigenvalues()[i] * static_cast<double>(n) > lambda_min) {
      H_pinv += eig.eigenvectors().col(i) * eig.eigenvectors().col(i).transpose() / (eig.eigenvalues()[i] * n);
      ++f.lever_arm_rank;
    }
  // Alternate: alignment on the body-corrected ground truth, then the lever arm (min-norm in the
  // unobservable directions), then the rotation.
  Alignment al;
  std::vector<Pose> gI(n);
  for (f.iterations = 1; f.iterations <= 200; ++f.iterations) {
    for (std::size_t k = 0; k < n; ++k) gI[k] = g[k] * f.T_B_I;
    al = compute_alignment(type, e, gI);
    std::vector<Eigen::Vector3d> c(n);
    for (std::size_t k = 0; k < n; ++k) c[k] = al.apply(e[k].p) - g[k].p;
    const Eigen::Vector3d t_new = H_pinv * lever_arm_system(c, Rg).b;
    const double step = (t_new - f.T_B_I.p).norm();
    f.T_B_I.p = t_new;
    const Eigen::Quaterniond qa = al.q();
    f.T_B_I.q = mean_rotation(n, [&](std::size_t k) { return (g[k].q.conjugate() * (qa * e[k].q)).normalized(); });
    if (step < 1e-9) break;
  }
  // σ: residuals at the solution, over the pairs that count as independent.
  std::vector<Eigen::Vector3d> r(n), rr(n);
  double sse = 0.0, sse_r = 0.0;
  const Eigen::Quaterniond qa = al.q();
  for (std::size_t k = 0; k < n; ++k) {
    r[k] = al.apply(e[k].p) - (g[k] * f.T_B_I).p;
    sse += r[k].squaredNorm();
    rr[k] = math::log_quat(((g[k] * f.T_B_I).q.conjugate() * (qa * e[k].q)).normalized());
    sse_r += rr[k].squaredNorm();
  }
  const double nd = static_cast<double>(n);
  const double s2 = sse / std::max(1.0, 3.0 * nd - 7.0 - f.lever_arm_rank);
  const Eigen::Matrix3d cov = s2 * H_pinv / effective_sample_fraction(r);
  f.sigma_p_m = cov.diagonal().cwiseMax(0.0).cwiseSqrt();
  f.sigma_rot_deg = std::sqrt(sse_r / (3.0 * nd) / (nd * effective_sample_fraction(rr))) * kRadToDeg;
  if (f.lever_arm_rank == 3) {
    f.verdict = "observable";
  } else {
    Eigen::Vector3d worst = eig.eigenvectors().col(0);
    f.verdict = fmt::format("{}: the ground truth turns by {:.2f} deg (rms) at most about an axis perpendicular to "
                            "{} (B axes); the lever arm along it is set to 0 (the alignment's translation absorbs "
                            "it), below the {:.1f} deg that make it observable",
                            f.lever_arm_rank == 0 ? "unobservable" : "partly unobservable", f.rotation_spread_min_deg,
                            axis_text(worst), kMinBodyRotationSpreadDeg);
  }
  return f;
}

Pose parse_pose_text(const std::string& text, const std::string& key) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    std::size_t used = 0;
    double x = 0.0;
    try {
      x = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || item.find_first_not_of(" \t", used) != std::string::npos || !std::isfinite(x))
      throw InputError(fmt::format("--{}: '{}' is not a number (expected x,y,z,qx,qy,qz,qw)", key, item),
                       {"", 0, 0, key});
    v.push_back(x);
  }
  if (v.size() != 7)
    throw InputError(fmt::format("--{} needs 7 numbers x,y,z,qx,qy,qz,qw (metres, quaternion x first), got {}", key,
                                 v.size()),
                     {"", 0, 0, key});
  Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
  if (std::abs(q.norm() - 1.0) > 0.05)
    throw InputError(fmt::format("--{}: the quaternion's norm is {:.4f}, not 1", key, q.norm()), {"", 0, 0, key});
  return Pose(q.normalized(), Eigen::Vector3d(v[0], v[1], v[2]));
}

}  // namespace roe::eval
