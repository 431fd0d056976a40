// Tests of roe::eval alignment: Umeyama SE(3)/Sim(3) (exact recovery, reflection guard, degenerate
// input refused), posyaw, origin, and applying an alignment to poses.
#include <catch2/catch.hpp>
#include <random>

#include "roe/eval/align.hpp"
#include "roe/math/euler.hpp"

using namespace roe;
using namespace roe::eval;
using Eigen::Matrix3d;
using Eigen::Matrix3Xd;
using Eigen::Vector3d;

namespace {

Matrix3d random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  return q.normalized().toRotationMatrix();
}

Matrix3Xd random_points(std::mt19937& rng, int n, double spread = 5.0) {
  std::uniform_real_distribution<double> u(-spread, spread);
  Matrix3Xd P(3, n);
  for (int i = 0; i < n; ++i) P.col(i) = Vector3d(u(rng), u(rng), u(rng));
  return P;
}

Matrix3Xd transform(const Matrix3Xd& P, double s, const Matrix3d& R, const Vector3d& t) {
  Matrix3Xd Q(3, P.cols());
  for (int i = 0; i < P.cols(); ++i) Q.col(i) = s * R * P.col(i) + t;
  return Q;
}

}  // namespace

TEST_CASE("umeyama recovers a known Sim(3) exactly", "[eval][align]") {
  std::mt19937 rng(42);
  for (int trial = 0; trial < 20; ++trial) {
    const Matrix3d R = random_rotation(rng);
    const Vector3d t(3.0 * trial - 10.0, 0.5, -2.0);
    const double s = 0.3 + 0.2 * trial;
    const Matrix3Xd x = random_points(rng, 50);
    const Matrix3Xd y = transform(x, s, R, t);
    const Alignment a = umeyama_alignment(x, y, true);
    CHECK(a.type == AlignType::kSim3);
    CHECK(a.n_used == 50);
    CHECK((a.R - R).cwiseAbs().maxCoeff() < 1e-12);
    CHECK(a.R.determinant() == Approx(1.0).margin(1e-12));
    CHECK(std::abs(a.s - s) < 1e-12 * s);
    CHECK((a.t - t).cwiseAbs().maxCoeff() < 1e-11);
    // Applying it maps x onto y.
    for (int i = 0; i < x.cols(); ++i) CHECK((a.apply(Vector3d(x.col(i))) - y.col(i)).norm() < 1e-11);
  }
}

TEST_CASE("umeyama SE(3) ignores scale and recovers R, t", "[eval][align]") {
  std::mt19937 rng(7);
  const Matrix3d R = random_rotation(rng);
  const Vector3d t(1.0, -2.0, 0.25);
  const Matrix3Xd x = random_points(rng, 30);
  const Matrix3Xd y = transform(x, 1.0, R, t);
  const Alignment a = umeyama_alignment(x, y, false);
  CHECK(a.s == 1.0);
  CHECK((a.R - R).cwiseAbs().maxCoeff() < 1e-12);
  CHECK((a.t - t).cwiseAbs().maxCoeff() < 1e-12);

  // With a true scale of 2, SE(3) keeps s = 1 and the same rotation as Sim(3) (the scale does not
  // change R), and its translation is μy − R μx.
  const Matrix3Xd y2 = transform(x, 2.0, R, t);
  const Alignment se3 = umeyama_alignment(x, y2, false);
  const Alignment sim3 = umeyama_alignment(x, y2, true);
  CHECK(se3.s == 1.0);
  CHECK(sim3.s == Approx(2.0).epsilon(1e-12));
  CHECK((se3.R - sim3.R).cwiseAbs().maxCoeff() < 1e-12);
  const Vector3d mu_x = x.rowwise().mean();
  const Vector3d mu_y = y2.rowwise().mean();
  CHECK((se3.t - (mu_y - R * mu_x)).cwiseAbs().maxCoeff() < 1e-11);
}

TEST_CASE("umeyama with noise: residual mean is zero per axis", "[eval][align]") {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.05);
  const Matrix3d R = random_rotation(rng);
  const Matrix3Xd x = random_points(rng, 200);
  Matrix3Xd y = transform(x, 1.3, R, Vector3d(0.1, 0.2, 0.3));
  for (int i = 0; i < y.cols(); ++i) y.col(i) += Vector3d(noise(rng), noise(rng), noise(rng));
  for (bool scale : {false, true}) {
    const Alignment a = umeyama_alignment(x, y, scale);
    Vector3d mean = Vector3d::Zero();
    for (int i = 0; i < x.cols(); ++i) mean += a.apply(Vector3d(x.col(i))) - y.col(i);
    mean /= static_cast<double>(x.cols());
    CHECK(mean.cwiseAbs().maxCoeff() < 1e-12);
    CHECK((a.R - R).norm() < 0.05);
  }
}

TEST_CASE("umeyama reflection guard: always a proper rotation", "[eval][align]") {
  std::mt19937 rng(11);
  SECTION("ground truth is a mirror image of the estimate") {
    const Matrix3Xd x = random_points(rng, 40);
    Matrix3Xd y = x;
    y.row(2) *= -1.0;  // reflection z → −z: the best orthogonal map has det −1
    const Alignment a = umeyama_alignment(x, y, false);
    CHECK(a.R.determinant() == Approx(1.0).margin(1e-12));
    CHECK((a.R * a.R.transpose() - Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-12);
    // Without the guard R would be diag(1,1,-1); with it the best rotation is a different one.
    CHECK((a.R - Vector3d(1, 1, -1).asDiagonal().toDenseMatrix()).norm() > 0.5);
  }
  SECTION("planar points: the free third axis never flips the rotation") {
    // Points in a plane give a zero third singular value, so the SVD's third columns have an
    // arbitrary sign; the guard must still yield exactly the true rotation.
    for (int trial = 0; trial < 20; ++trial) {
      Matrix3Xd x = random_points(rng, 25);
      x.row(2).setZero();
      const Matrix3d R = random_rotation(rng);
      const Matrix3Xd y = transform(x, 1.0, R, Vector3d(1, 2, 3));
      const Alignment a = umeyama_alignment(x, y, true);
      CHECK((a.R - R).cwiseAbs().maxCoeff() < 1e-10);
      CHECK(a.s == Approx(1.0).epsilon(1e-12));
    }
  }
}

TEST_CASE("umeyama refuses degenerate input", "[eval][align]") {
  SECTION("fewer than 3 points") {
    Matrix3Xd x(3, 2);
    x << 0, 1, 0, 0, 0, 1;
    CHECK_THROWS_AS(umeyama_alignment(x, x, false), DegenerateAlignmentError);
  }
  SECTION("all points identical") {
    Matrix3Xd x = Matrix3Xd::Ones(3, 10);
    CHECK_THROWS_AS(umeyama_alignment(x, x, false), DegenerateAlignmentError);
    CHECK_THROWS_AS(umeyama_alignment(x, x, true), DegenerateAlignmentError);
  }
  SECTION("collinear points") {
    Matrix3Xd x(3, 10);
    for (int i = 0; i < 10; ++i) x.col(i) = Vector3d(1, 2, 3) + 0.37 * i * Vector3d(1, -1, 0.5);
    std::mt19937 rng(5);
    const Matrix3Xd y = transform(x, 1.0, random_rotation(rng), Vector3d(4, 5, 6));
    try {
      umeyama_alignment(x, y, false);
      FAIL("collinear input was accepted");
    } catch (const DegenerateAlignmentError& e) {
      CHECK(std::string(e.what()).find("collinear") != std::string::npos);
    }
  }
  SECTION("size mismatch is a usage error") {
    CHECK_THROWS_AS(umeyama_alignment(Matrix3Xd::Random(3, 5), Matrix3Xd::Random(3, 6), false), InputError);
  }
  SECTION("a DegenerateAlignmentError is a DataError (exit code 1)") {
    Matrix3Xd x = Matrix3Xd::Zero(3, 4);
    CHECK_THROWS_AS(umeyama_alignment(x, x, false), DataError);
  }
}

TEST_CASE("posyaw recovers a yaw + translation and ignores roll/pitch", "[eval][align]") {
  std::mt19937 rng(9);
  const Matrix3Xd x = random_points(rng, 30);
  for (double yaw_deg : {-179.0, -90.0, 0.0, 33.0, 135.0, 179.9}) {
    const Matrix3d Rz = math::from_euler_zyx(Vector3d(0, 0, yaw_deg * math::kRadPerDeg));
    const Matrix3Xd y = transform(x, 1.0, Rz, Vector3d(-1, 0.5, 2));
    const Alignment a = align_pos_yaw(x, y);
    CHECK((a.R - Rz).cwiseAbs().maxCoeff() < 1e-12);
    CHECK((a.t - Vector3d(-1, 0.5, 2)).cwiseAbs().maxCoeff() < 1e-12);
    CHECK(a.s == 1.0);
  }
  // Only vertical motion: yaw undetermined.
  Matrix3Xd v(3, 5);
  for (int i = 0; i < 5; ++i) v.col(i) = Vector3d(1, 1, i);
  CHECK_THROWS_AS(align_pos_yaw(v, v), DegenerateAlignmentError);
}

TEST_CASE("single-pose alignments (origin, posyaw)", "[eval][align]") {
  std::mt19937 rng(21);
  const Pose est0(Eigen::Quaterniond(random_rotation(rng)), Vector3d(1, 2, 3));
  const Pose delta(Eigen::Quaterniond(random_rotation(rng)), Vector3d(-4, 0.5, 7));
  const Pose gt0 = delta * est0;
  const Alignment o = align_origin(est0, gt0);
  const Pose moved = o.apply(est0);
  CHECK((moved.p - gt0.p).norm() < 1e-12);
  CHECK(math::angle_between(moved.q, gt0.q) < 1e-12);
  CHECK((o.R - delta.R()).cwiseAbs().maxCoeff() < 1e-12);

  // posyaw from one pose: a pure-yaw offset is recovered exactly.
  const Matrix3d Rz = math::from_euler_zyx(Vector3d(0, 0, 2.5));
  const Pose gt1(Eigen::Quaterniond(Matrix3d(Rz * est0.R())), Rz * est0.p + Vector3d(0.1, 0.2, 0.3));
  const Alignment py = align_pos_yaw_single(est0, gt1);
  CHECK((py.R - Rz).cwiseAbs().maxCoeff() < 1e-12);
  CHECK((py.apply(est0).p - gt1.p).norm() < 1e-12);
}

TEST_CASE("compute_alignment: n_align, types and apply to poses", "[eval][align]") {
  std::mt19937 rng(33);
  const Matrix3d R = random_rotation(rng);
  const Vector3d t(0.5, -0.5, 1.0);
  std::vector<Pose> est, gt;
  for (int i = 0; i < 40; ++i) {
    Pose e(Eigen::Quaterniond(random_rotation(rng)),
           Vector3d(std::cos(0.3 * i), std::sin(0.2 * i), 0.05 * i));
    est.push_back(e);
    gt.push_back(Pose(Eigen::Quaterniond(Matrix3d(R * e.R())), R * e.p + t));
  }
  // Corrupt the tail: with n_align = 10 the head alone fixes the exact transform.
  for (int i = 10; i < 40; ++i) gt[i].p += Vector3d(0.3, 0.0, 0.0) * i;
  const Alignment head = compute_alignment(AlignType::kSe3, est, gt, 10);
  CHECK(head.n_used == 10);
  CHECK((head.R - R).cwiseAbs().maxCoeff() < 1e-12);
  const Alignment all = compute_alignment(AlignType::kSe3, est, gt, -1);
  CHECK(all.n_used == 40);
  CHECK((all.R - R).cwiseAbs().maxCoeff() > 1e-3);

  // Applying to poses rotates orientations by R and never scales them.
  std::vector<Pose> moved(est.begin(), est.begin() + 10);
  apply_alignment(head, moved);
  for (int i = 0; i < 10; ++i) {
    CHECK((moved[i].p - gt[i].p).norm() < 1e-11);
    CHECK(math::angle_between(moved[i].q, gt[i].q) < 1e-11);
    const Pose single = head.apply(est[i]);
    CHECK((single.p - moved[i].p).norm() < 1e-12);
  }
  std::vector<StampedPose> stamped{{5, est[0]}};
  apply_alignment(head, stamped);
  CHECK(stamped[0].t_ns == 5);
  CHECK((stamped[0].T.p - gt[0].p).norm() < 1e-11);

  CHECK(compute_alignment(AlignType::kNone, est, gt).R == Matrix3d::Identity());
  CHECK(compute_alignment(AlignType::kOrigin, est, gt).n_used == 1);
  CHECK(compute_alignment(AlignType::kPosYaw, est, gt, 1).n_used == 1);
  CHECK_THROWS_AS(compute_alignment(AlignType::kSe3, est, gt, 2), InputError);
  CHECK_THROWS_AS(compute_alignment(AlignType::kSim3, est, gt, 1), InputError);
  CHECK_THROWS_AS(compute_alignment(AlignType::kSe3, {}, {}), InputError);
  std::vector<Pose> shorter(gt.begin(), gt.end() - 1);
  CHECK_THROWS_AS(compute_alignment(AlignType::kSe3, est, shorter), InputError);
}

TEST_CASE("alignment names round-trip", "[eval][align]") {
  for (auto t : {AlignType::kSe3, AlignType::kSim3, AlignType::kPosYaw, AlignType::kOrigin, AlignType::kNone})
    CHECK(parse_align_type(to_string(t)) == t);
  CHECK_THROWS_AS(parse_align_type("SE3x"), InputError);
}

// Georeferenced trajectories (UTM: 10⁵–10⁶ m from the origin) spread over a few metres: the centred
// sums keep full precision, so R is recovered to 1e-9 rad and the residuals stay below 1e-6 m. A
// cross-covariance formed from uncentred coordinates on one side loses it (Σ of the centred other side
// is ~n·ε·10⁶, times 10⁶).
TEST_CASE("umeyama and posyaw at UTM-like coordinates keep full precision", "[eval][align]") {
  std::mt19937 rng(11);
  const Vector3d utm(512'345.678, 5'234'567.891, 312.5);
  for (int trial = 0; trial < 5; ++trial) {
    Matrix3Xd est = random_points(rng, 2000, 4.0);
    for (int i = 0; i < est.cols(); ++i) est.col(i) += utm;
    const Matrix3d R_true = math::from_euler_zyx(Vector3d(0.02 * trial, -0.01, 0.3 + trial));
    // gt = R est + t, with t chosen so that gt is also at UTM-like coordinates.
    const Vector3d t_true = utm - R_true * utm + Vector3d(3.0, -2.0, 0.5);
    const Matrix3Xd gt = transform(est, 1.0, R_true, t_true);
    const Alignment a = umeyama_alignment(est, gt, false);
    INFO("trial " << trial);
    CHECK((a.R - R_true).norm() < 1e-9);
    double worst = 0.0;
    for (int i = 0; i < est.cols(); ++i) worst = std::max(worst, (a.R * est.col(i) + a.t - gt.col(i)).norm());
    CHECK(worst < 1e-6);
    // posyaw on a pure yaw + translation.
    const Matrix3d Rz = math::from_euler_zyx(Vector3d(0.0, 0.0, 0.3 + trial));
    const Matrix3Xd gt_yaw = transform(est, 1.0, Rz, utm - Rz * utm + Vector3d(1.0, 2.0, -0.5));
    const Alignment y = align_pos_yaw(est, gt_yaw);
    CHECK((y.R - Rz).norm() < 1e-9);
  }
}
