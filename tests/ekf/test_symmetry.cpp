// Symmetric objects in the filter (ekf/symmetry.hpp): the nearest equivalent measurement, the
// continuous-symmetry reduction (numeric Jacobian of the reduced residual through the whole pipeline:
// alignment, projection, H), invariance of the residual under the symmetry, and a Monte-Carlo NEES/NIS
// test of one update with the reduced (5) dof (successive updates: test_symmetry_nees.cpp), and numeric
// Jacobians of the split parts (position rows; rotation rows, 2 after the projection).
#include <catch2/catch.hpp>
#include <cmath>
#include <random>

#include "roe/ekf/filter.hpp"
#include "roe/ekf/symmetry.hpp"
#include "roe/math/so3.hpp"
#include "support/jacobian.hpp"
#include "symmetry_support.hpp"

using namespace roe;
using namespace roe::ekf;
using math::exp_quat;
using roe::test::about_z;
using roe::test::continuous;
using roe::test::flip_of;

namespace {

std::mt19937_64 rng(2029);
double U(double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); }

// 180° about x through (0.01, 0, 0.02): a box-like flip with a translation, as BOP writes them.
Pose flip() {
  const Eigen::Quaterniond q = exp_quat(Vec3(M_PI, 0, 0));
  const Vec3 o(0.01, 0.0, 0.02);
  return Pose(q, o - q * o);
}

// A started filter with objects 1 (anchor), 2 and 3 initialised, symmetries set for 2 and 3.
Filter symmetric_filter(ResidualFrame frame, const ObjectSymmetry& s2, const ObjectSymmetry& s3) {
  FilterOptions opt;
  opt.residual_frame = frame;
  opt.init_min_detections = 1;
  opt.anchor_id = 1;
  opt.require_anchor = false;
  Filter f(opt, ImuNoiseParams{1e-3, 1e-4, 1e-2, 1e-3}, Pose(exp_quat(Vec3(0.1, -0.2, 0.05)), Vec3(0.02, 0.01, -0.03)));
  f.initialize(0, Vec3::Zero(), Vec3(0, 0, 9.81), Vec3(0.3, -0.2, 9.8));
  f.propagate(10'000'000, Vec3(0.1, 0.2, -0.1), Vec3(0.2, 0.1, 9.7));
  std::vector<Detection> dets;
  for (int id : {1, 2, 3}) {
    Detection d;
    d.object_id = id;
    d.T_C_O = Pose(exp_quat(Vec3(U(-1, 1), U(-1, 1), U(-1, 1))), Vec3(U(-0.4, 0.4), U(-0.4, 0.4), U(1.2, 2.5)));
    dets.push_back(d);
  }
  f.update(dets);
  Eigen::VectorXd dx(f.dim());
  for (int i = 0; i < f.dim(); ++i) dx(i) = U(-0.05, 0.05);
  f.boxplus(dx);
  f.set_symmetries({{2, s2}, {3, s3}});
  return f;
}

// −∂r/∂δx of measurement_rows(part) by central differences, r re-evaluated (alignment, projection and
// row selection included) at every perturbed state.
Eigen::MatrixXd numeric_H(const Filter& f, int id, const Pose& z, ResidualPart part) {
  return roe::test::numeric_jacobian(f.dim(), [&](const Eigen::VectorXd& dx) -> Eigen::VectorXd {
    Filter g = f;
    g.boxplus(dx);
    Eigen::VectorXd r;
    Eigen::MatrixXd Hg;
    g.measurement_rows(id, z, part, r, Hg);
    return -r;
  });
}

}  // namespace

TEST_CASE("nearest_equivalent undoes a discrete flip and a turn about a continuous axis", "[ekf][symmetry]") {
  const Pose z_hat(exp_quat(Vec3(0.3, -0.5, 0.2)), Vec3(0.1, -0.2, 1.5));
  const Pose noise(exp_quat(Vec3(0.01, -0.02, 0.015)), Vec3(0.003, -0.002, 0.004));
  const Pose z = z_hat * noise;  // the detection the symmetry-free model expects
  ObjectSymmetry d;
  d.discrete = {flip()};
  // The detector reports T_C_O · S, i.e. z' = S⁻¹ z.
  const Pose zf = flip().inverse() * z;
  CHECK(math::pose_difference(nearest_equivalent(z_hat, zf, d), z).norm() < 1e-12);
  CHECK(math::pose_difference(nearest_equivalent(z_hat, z, d), z).norm() < 1e-12);

  ObjectSymmetry c;
  c.continuous = about_z(Vec3(0.01, -0.02, 0.0));
  for (double psi : {0.3, 1.7, -2.9}) {
    const Pose zc = continuous(*c.continuous, psi).inverse() * z;
    const Pose a = nearest_equivalent(z_hat, zc, c);
    // The aligned measurement is the family member nearest ẑ, whichever member was detected.
    CHECK(math::pose_difference(a, nearest_equivalent(z_hat, z, c)).norm() < 1e-9);
    // It is no farther from ẑ in rotation than z itself.
    CHECK(math::log_quat(z_hat.q.conjugate() * a.q).norm() <= math::log_quat(z_hat.q.conjugate() * z.q).norm() + 1e-12);
  }
  // Both together: a flipped and turned detection.
  ObjectSymmetry both = c;
  both.discrete = {flip_of(*c.continuous)};
  const Pose zb = flip_of(*c.continuous).inverse() * (continuous(*c.continuous, 2.2).inverse() * z);
  const Pose ab = nearest_equivalent(z_hat, zb, both);
  CHECK(math::pose_difference(ab, nearest_equivalent(z_hat, z, both)).norm() < 1e-9);
  CHECK(math::log_quat(z_hat.q.conjugate() * ab.q).norm() < 0.05);
}

TEST_CASE("symmetry_reduction removes the symmetry direction, block form when it has no position part",
          "[ekf][symmetry]") {
  const Pose z_hat(exp_quat(Vec3(0.3, -0.5, 0.2)), Vec3(0.1, -0.2, 1.5));
  for (ResidualFrame frame : {ResidualFrame::kCamera, ResidualFrame::kObject}) {
    for (const Vec3& off : {Vec3(0, 0, 0), Vec3(0.02, -0.01, 0.03)}) {
      const ContinuousSymmetry c = about_z(off);
      const Vec6 d = symmetry_direction(frame, z_hat, c);
      bool sep = false;
      const Mat56 A = symmetry_reduction(d, sep);
      CHECK((A * d).norm() < 1e-12 * d.norm());
      CHECK((A * A.transpose() - Eigen::Matrix<double, 5, 5>::Identity()).norm() < 1e-12);
      const bool expect_sep = frame == ResidualFrame::kCamera && off.isZero();
      CHECK(sep == expect_sep);
      if (sep) {
        CHECK(A.topLeftCorner<3, 3>() == Mat3::Identity());
        CHECK(A.topRightCorner<3, 3>().isZero());
        CHECK(A.bottomLeftCorner<2, 3>().isZero());
      }
    }
  }
}

TEST_CASE("the symmetry-reduced residual: numeric Jacobian through alignment and projection, invariance",
          "[ekf][symmetry][jacobian]") {
  ObjectSymmetry cont, cont_off, disc;
  cont.continuous = about_z();
  cont_off.continuous = about_z(Vec3(0.02, -0.01, 0.03));
  cont_off.discrete = {flip_of(*cont_off.continuous)};
  disc.discrete = {flip()};
  for (ResidualFrame frame : {ResidualFrame::kCamera, ResidualFrame::kObject}) {
    for (int variant = 0; variant < 2; ++variant) {
      const ObjectSymmetry& s2 = variant == 0 ? cont : cont_off;
      Filter f = symmetric_filter(frame, s2, disc);
      for (int id : {2, 3}) {
        const ObjectSymmetry& s = id == 2 ? s2 : disc;
        // The detector reports an equivalent pose of the prediction: T_C_O · S, z = S⁻¹ ẑ.
        Pose S = s.discrete.empty() ? Pose() : s.discrete.front();
        if (s.continuous) S = S * continuous(*s.continuous, 1.3);
        const Pose z = S.inverse() * f.predict(id);
        const int m = s.continuous ? 5 : 6;
        INFO("frame " << to_string(frame) << " variant " << variant << " object " << id);
        Eigen::VectorXd r;
        Eigen::MatrixXd H;
        f.measurement_rows(id, z, ResidualPart::kBoth, r, H);
        REQUIRE(r.size() == m);
        CHECK(r.norm() < 1e-9);  // the equivalent measurement is found: zero residual
        // r(x) = A(x) (z*(x) ⊟ ẑ(x)) with z*(x) re-chosen at every x: ∂r/∂δx = −H.
        const Eigen::MatrixXd Hn = numeric_H(f, id, z, ResidualPart::kBoth);
        INFO("analytic\n" << H << "\nnumeric\n" << Hn);
        CHECK((H - Hn).cwiseAbs().maxCoeff() < 1e-6);
        // Invariance: another equivalent detection of the same pose (plus noise) gives the same residual.
        const Pose zn = f.predict(id) * Pose(exp_quat(Vec3(0.02, -0.01, 0.03)), Vec3(0.01, 0.02, -0.01));
        Eigen::VectorXd ra, rb;
        Eigen::MatrixXd Ha;
        f.measurement_rows(id, zn, ResidualPart::kBoth, ra, Ha);
        Pose S2 = s.discrete.empty() ? Pose() : s.discrete.front();
        if (s.continuous) S2 = S2 * continuous(*s.continuous, -2.4);
        f.measurement_rows(id, S2.inverse() * zn, ResidualPart::kBoth, rb, Ha);
        CHECK((ra - rb).norm() < 1e-9);
        CHECK(ra.norm() > 1e-3);
      }
    }
  }
}

TEST_CASE("Monte-Carlo NEES and NIS of updates of a symmetric object with the reduced dof",
          "[ekf][symmetry][nees]") {
  // Truth drawn from the filter's prior, a detection of object 2 from the truth with the filter's own R,
  // reported as a random equivalent pose (random turn about the axis, random flip). Consistent when the
  // posterior NEES averages the state dimension and the NIS averages 5 (the reduced dof).
  ObjectSymmetry s2, none;
  s2.continuous = about_z();
  s2.discrete = {flip_of(*s2.continuous)};
  FilterOptions opt;
  opt.residual_frame = ResidualFrame::kCamera;
  opt.meas_sigma_p_m = 0.01;
  opt.meas_sigma_rot_deg = 2.0;
  Filter f0 = test::two_objects_started(opt, 1.6, 2.0);
  f0.set_symmetries({{2, s2}});
  Detection d2;  // object 2's detection of each trial (its T_C_O set there)
  d2.object_id = 2;
  d2.T_C_O = f0.predict(2).inverse();
  const int n = f0.dim();
  const Eigen::MatrixXd P0 = f0.covariance();
  const Eigen::MatrixXd L = P0.llt().matrixL();
  const Mat6 R_C = f0.measurement_covariance(d2, false);
  const Mat6 L_R = R_C.llt().matrixL();
  std::mt19937_64 g(7);
  std::normal_distribution<double> N01;
  const int trials = 400;
  double nees = 0.0, nis = 0.0, nis_plain = 0.0;
  for (int k = 0; k < trials; ++k) {
    Eigen::VectorXd w(n);
    for (int i = 0; i < n; ++i) w(i) = N01(g);
    Filter truth = f0;
    truth.boxplus(L * w);
    Vec6 v;
    for (int i = 0; i < 6; ++i) v(i) = N01(g);
    const Vec6 nz = L_R * v;
    const Pose T_true = truth.predict(2).inverse();
    Pose T_meas(exp_quat(nz.tail<3>()) * T_true.q, T_true.p + nz.head<3>());
    Pose S = continuous(*s2.continuous, U(-M_PI, M_PI));
    if (k % 2 == 1) S = s2.discrete[0] * S;
    d2.T_C_O = T_meas * S;
    Filter f = f0;
    const FrameResult res = f.update({d2});
    REQUIRE(res.detections[0].status == DetectionStatus::kAccepted);
    nis += res.detections[0].nis;
    const Eigen::VectorXd e = boxminus(truth.snapshot(), f.snapshot());
    nees += e.dot(f.covariance().llt().solve(e));
    // The same detection without the symmetry model: the control that the test can fail.
    Filter p = f0;
    p.set_symmetries({});
    Vec6 r;
    Eigen::MatrixXd H;
    p.measurement_jacobian(2, d2.T_C_O.inverse(), r, H);
    const Eigen::MatrixXd Sp = H * P0 * H.transpose() + R_C;
    const double np = r.dot(Sp.llt().solve(r));
    nis_plain += std::isfinite(np) ? std::min(1e6, np) : 1e6;
  }
  nees /= trials;
  nis /= trials;
  nis_plain /= trials;
  INFO("NEES mean " << nees << " (dim " << n << "), NIS mean " << nis << ", without symmetries " << nis_plain);
  // Means of χ² variables: 3σ bands of the mean (σ = sqrt(2 dof / trials)).
  CHECK(std::abs(nees - n) < 3.0 * std::sqrt(2.0 * n / trials));
  CHECK(std::abs(nis - 5.0) < 3.0 * std::sqrt(2.0 * 5.0 / trials));
  CHECK(nis_plain > 100.0);
}

TEST_CASE("split parts of the residual, plain and symmetry-reduced: numeric Jacobians", "[ekf][symmetry][jacobian]") {
  // The split gate updates with the position rows, the rotation rows (3, or 2 after a continuous
  // symmetry's projection when the reduction is separable) or both; each part's H against central
  // differences of that part's residual. At an equivalent pose of the prediction (zero residual, as the
  // kBoth test above): H is the first-order Jacobian at the estimate, and at a residual r the exact
  // derivative of the quaternion residual differs from it by O(|r|) (about |r|/2 relative).
  ObjectSymmetry cont, none;
  cont.continuous = about_z();
  for (ResidualFrame frame : {ResidualFrame::kCamera, ResidualFrame::kObject}) {
    Filter f = symmetric_filter(frame, cont, none);
    for (int id : {2, 3}) {
      const bool reduced = id == 2;
      const bool separable = !reduced || frame == ResidualFrame::kCamera;  // the offset is 0
      const Pose z = continuous(*cont.continuous, reduced ? 0.9 : 0.0).inverse() * f.predict(id);
      for (ResidualPart part : {ResidualPart::kPosition, ResidualPart::kRotation}) {
        if (!separable) continue;  // the rows mix: the split gate tests them jointly (kBoth, above)
        INFO("frame " << to_string(frame) << " object " << id << " part " << to_string(part));
        Eigen::VectorXd r;
        Eigen::MatrixXd H;
        f.measurement_rows(id, z, part, r, H);
        const int rows = part == ResidualPart::kPosition ? 3 : (reduced ? 2 : 3);
        REQUIRE(r.size() == rows);
        CHECK(r.norm() < 1e-9);
        const Eigen::MatrixXd Hn = numeric_H(f, id, z, part);
        INFO("analytic\n" << H << "\nnumeric\n" << Hn);
        CHECK((H - Hn).cwiseAbs().maxCoeff() < 1e-6);
      }
    }
  }
}
