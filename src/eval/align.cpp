#include "roe/eval/align.hpp"

#include <fmt/format.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

#include "roe/core/parallel.hpp"

namespace roe::eval {

std::string to_string(AlignType type) {
  switch (type) {
    case AlignType::kSe3:
      return "se3";
    case AlignType::kSim3:
      return "sim3";
    case AlignType::kPosYaw:
      return "posyaw";
    case AlignType::kOrigin:
      return "origin";
    case AlignType::kNone:
      return "none";
  }
  return "none";
}

AlignType parse_align_type(const std::string& name) {
  for (AlignType t :
       {AlignType::kSe3, AlignType::kSim3, AlignType::kPosYaw, AlignType::kOrigin, AlignType::kNone}) {
    if (name == to_string(t)) return t;
  }
  throw InputError(fmt::format("unknown alignment '{}' (expected se3, sim3, posyaw, origin or none)", name),
                   {"", 0, 0, "align"});
}

Pose Alignment::apply(const Pose& T) const {
  // Orientation: R · R_est. Built from the matrix product and re-normalised by Pose's constructor.
  return Pose(Eigen::Matrix3d(R * T.R()), apply(T.p));
}

Eigen::Quaterniond Alignment::q() const { return Eigen::Quaterniond(R).normalized(); }

Pose aligned_pose(const Alignment& a, const Eigen::Quaterniond& qa, const Pose& T) {
  Pose out;
  out.p = a.apply(T.p);
  out.q = (qa * T.q).normalized();
  return out;
}

void apply_alignment(const Alignment& a, std::vector<Pose>& poses) {
  const Eigen::Quaterniond qa = a.q();
  for (Pose& T : poses) T = aligned_pose(a, qa, T);
}

void apply_alignment(const Alignment& a, std::vector<StampedPose>& poses) {
  const Eigen::Quaterniond qa = a.q();
  for (StampedPose& sp : poses) sp.T = aligned_pose(a, qa, sp.T);
}

namespace {

void check_sizes(Eigen::Index n_est, Eigen::Index n_gt) {
  if (n_est != n_gt) {
    throw InputError(
        fmt::format("alignment needs matched pairs: {} estimate vs {} ground-truth positions", n_est, n_gt));
  }
}

}  // namespace

Alignment umeyama_alignment(const Eigen::Ref<const Eigen::Matrix3Xd>& est,
                            const Eigen::Ref<const Eigen::Matrix3Xd>& gt, bool with_scale) {
  check_sizes(est.cols(), gt.cols());
  const Eigen::Index n = est.cols();
  if (n < 3) {
    throw DegenerateAlignmentError(
        fmt::format("{} alignment needs at least 3 non-collinear matched positions, got {}",
                    with_scale ? "Sim(3)" : "SE(3)", n));
  }
  const double inv_n = 1.0 / static_cast<double>(n);
  const Eigen::Vector3d mu_x = est.rowwise().sum() * inv_n;
  const Eigen::Vector3d mu_y = gt.rowwise().sum() * inv_n;
  Eigen::Matrix3d sigma_xy = Eigen::Matrix3d::Zero();
  double sigma2_x = 0.0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3d dx = est.col(i) - mu_x;
    const Eigen::Vector3d dy = gt.col(i) - mu_y;
    sigma_xy.noalias() += dy * dx.transpose();
    sigma2_x += dx.squaredNorm();
  }
  sigma_xy *= inv_n;
  sigma2_x *= inv_n;

  Eigen::JacobiSVD<Eigen::Matrix3d> svd(sigma_xy, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d d = svd.singularValues();  // descending, non-negative
  if (!(d(0) > 0.0) || d(1) <= kRankTolerance * d(0)) {
    throw DegenerateAlignmentError(fmt::format(
        "{} alignment is undetermined: the {} matched positions are {} (singular values of the "
        "cross-covariance {:.3g}, {:.3g}, {:.3g}); the rotation about them cannot be estimated. "
        "Use --align origin, posyaw or none, or more pairs (--n-align)",
        with_scale ? "Sim(3)" : "SE(3)", n, d(0) > 0.0 ? "collinear" : "all identical", d(0), d(1), d(2)));
  }
  const Eigen::Matrix3d& U = svd.matrixU();
  const Eigen::Matrix3d& V = svd.matrixV();
  Eigen::Vector3d S(1.0, 1.0, 1.0);
  // Reflection guard: the best orthogonal matrix may be a reflection; force det(R) = +1.
  if (U.determinant() * V.determinant() < 0.0) S(2) = -1.0;

  Alignment a;
  a.type = with_scale ? AlignType::kSim3 : AlignType::kSe3;
  a.R = U * S.asDiagonal() * V.transpose();
  a.s = with_scale ? d.dot(S) / sigma2_x : 1.0;
  a.t = mu_y - a.s * (a.R * mu_x);
  a.n_used = static_cast<int>(n);
  return a;
}

namespace {

Eigen::Matrix3d rot_z(double yaw) {
  return Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

}  // namespace

Alignment align_pos_yaw(const Eigen::Ref<const Eigen::Matrix3Xd>& est,
                        const Eigen::Ref<const Eigen::Matrix3Xd>& gt) {
  check_sizes(est.cols(), gt.cols());
  const Eigen::Index n = est.cols();
  if (n < 2) {
    throw DegenerateAlignmentError(
        fmt::format("posyaw alignment needs at least 2 matched positions, got {}", n));
  }
  const double inv_n = 1.0 / static_cast<double>(n);
  const Eigen::Vector3d mu_x = est.rowwise().sum() * inv_n;
  const Eigen::Vector3d mu_y = gt.rowwise().sum() * inv_n;
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
  for (Eigen::Index i = 0; i < n; ++i) C.noalias() += (est.col(i) - mu_x) * (gt.col(i) - mu_y).transpose();
  // Σ |y' − Rz x'|² is minimal where tr(Rz C) = cos(ψ)(C00 + C11) + sin(ψ)(C01 − C10) is maximal.
  const double a_cos = C(0, 0) + C(1, 1);
  const double a_sin = C(0, 1) - C(1, 0);
  const double scale = C.cwiseAbs().maxCoeff();
  if (!(std::hypot(a_cos, a_sin) > kRankTolerance * scale) || scale == 0.0) {
    throw DegenerateAlignmentError(fmt::format(
        "posyaw alignment is undetermined: the {} matched positions have no horizontal spread", n));
  }
  Alignment a;
  a.type = AlignType::kPosYaw;
  a.R = rot_z(std::atan2(a_sin, a_cos));
  a.t = mu_y - a.R * mu_x;
  a.n_used = static_cast<int>(n);
  return a;
}

Alignment align_origin(const Pose& est0, const Pose& gt0) {
  Alignment a;
  a.type = AlignType::kOrigin;
  a.R = gt0.R() * est0.R().transpose();
  a.t = gt0.p - a.R * est0.p;
  a.n_used = 1;
  return a;
}

Alignment align_pos_yaw_single(const Pose& est0, const Pose& gt0) {
  const Eigen::Matrix3d M = gt0.R() * est0.R().transpose();
  // tr(Rz(ψ)ᵀ M) = cos(ψ)(M00 + M11) + sin(ψ)(M10 − M01).
  const double a_cos = M(0, 0) + M(1, 1);
  const double a_sin = M(1, 0) - M(0, 1);
  if (!(std::hypot(a_cos, a_sin) > 1e-12)) {
    throw DegenerateAlignmentError(
        "posyaw alignment from one pose is undetermined: the relative rotation is a half-turn about a "
        "horizontal axis");
  }
  Alignment a;
  a.type = AlignType::kPosYaw;
  a.R = rot_z(std::atan2(a_sin, a_cos));
  a.t = gt0.p - a.R * est0.p;
  a.n_used = 1;
  return a;
}

namespace {

/// The matched poses of one side: poses[index[k]], or poses[k] when index is null.
struct Side {
  const std::vector<Pose>& poses;
  const std::vector<std::size_t>* index = nullptr;
  const Pose& operator[](std::size_t k) const { return poses[index ? (*index)[k] : k]; }
  bool in_order(std::size_t n) const {  // the first n pairs are poses 0, 1, ..., n - 1
    if (!index) return true;
    for (std::size_t k = 0; k < n; ++k)
      if ((*index)[k] != k) return false;
    return true;
  }
};

/// The positions of the first n matched poses as a 3×n matrix: a view of the poses themselves when they
/// are in order (no copy: the alignment reads the same numbers), else gathered into `store`.
Eigen::Ref<const Eigen::Matrix3Xd> positions(const Side& side, std::size_t n, Eigen::Matrix3Xd& store,
                                             unsigned threads) {
  static_assert(sizeof(Pose) % sizeof(double) == 0, "a pose is a whole number of doubles");
  const auto cols = static_cast<Eigen::Index>(n);
  if (side.in_order(n))
    return Eigen::Map<const Eigen::Matrix3Xd, 0, Eigen::OuterStride<>>(
        side.poses.front().p.data(), 3, cols, Eigen::OuterStride<>(sizeof(Pose) / sizeof(double)));
  store.resize(3, cols);
  parallel_ranges(n, 65536, threads, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) store.col(static_cast<Eigen::Index>(i)) = side[i].p;
  });
  return store;
}

/// compute_alignment over `size` matched pairs est[k] ↔ gt[k].
Alignment alignment_of(AlignType type, std::size_t size, const Side& est, const Side& gt, int n_align,
                       unsigned threads) {
  if (type == AlignType::kNone) return Alignment{};
  if (size == 0) throw InputError("alignment needs at least one matched pose pair");
  if (type == AlignType::kOrigin) return align_origin(est[0], gt[0]);

  const std::size_t n =
      (n_align <= 0 || static_cast<std::size_t>(n_align) >= size) ? size : static_cast<std::size_t>(n_align);
  if (type == AlignType::kPosYaw && n == 1) return align_pos_yaw_single(est[0], gt[0]);
  if ((type == AlignType::kSe3 || type == AlignType::kSim3) && n_align > 0 && n_align < 3) {
    throw InputError(fmt::format("--n-align {} cannot determine a {} alignment (needs ≥ 3 pairs); use "
                                 "--align origin for a first-pose alignment",
                                 n_align, to_string(type)),
                     {"", 0, 0, "n_align"});
  }
  if (threads == 0) threads = available_cpus();
  Eigen::Matrix3Xd x_store, y_store;
  const Eigen::Ref<const Eigen::Matrix3Xd> x = positions(est, n, x_store, threads);
  const Eigen::Ref<const Eigen::Matrix3Xd> y = positions(gt, n, y_store, threads);
  if (type == AlignType::kPosYaw) return align_pos_yaw(x, y);
  return umeyama_alignment(x, y, type == AlignType::kSim3);
}

}  // namespace

Alignment compute_alignment(AlignType type, const std::vector<Pose>& est, const std::vector<Pose>& gt,
                            int n_align) {
  check_sizes(static_cast<Eigen::Index>(est.size()), static_cast<Eigen::Index>(gt.size()));
  return alignment_of(type, est.size(), Side{est}, Side{gt}, n_align, 1);
}

Alignment compute_alignment(AlignType type, const std::vector<Pose>& est, const std::vector<std::size_t>& est_index,
                            const std::vector<Pose>& gt, const std::vector<std::size_t>& gt_index, int n_align,
                            unsigned threads) {
  check_sizes(static_cast<Eigen::Index>(est_index.size()), static_cast<Eigen::Index>(gt_index.size()));
  return alignment_of(type, est_index.size(), Side{est, &est_index}, Side{gt, &gt_index}, n_align, threads);
}

double alignment_tilt_deg(const Alignment& a) {
  // atan2 of |R e_z × e_z| and R e_z · e_z: exact near 0, where acos of R(2,2) loses half the digits.
  return std::atan2(std::hypot(a.R(0, 2), a.R(1, 2)), a.R(2, 2)) * 180.0 / M_PI;
}

}  // namespace roe::eval
