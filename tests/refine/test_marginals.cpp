// refine::marginal_covariance (the Schur complement onto the calibration blocks) against Ceres' own
// ceres::Covariance (sparse QR of the whole Jacobian, code nobody here wrote), on a small nonlinear chain
// with a manifold block, a robust loss and a constant block (docs/refine.md §7).
#include <ceres/autodiff_cost_function.h>
#include <ceres/covariance.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/rotation.h>

#include <catch2/catch.hpp>
#include <array>
#include <random>
#include <vector>

#include "roe/core/error.hpp"
#include "roe/refine/marginals.hpp"

namespace {

/// x_{i+1} − x_i − u_i, weighted: the chain between consecutive nodes.
struct Step {
  std::array<double, 3> u;
  template <typename T>
  bool operator()(const T* a, const T* b, T* r) const {
    for (int k = 0; k < 3; ++k) r[k] = T(4.0) * (b[k] - a[k] - T(u[k]));
    return true;
  }
};

/// R(q) x_i + c − z, with c's third component a scale on the first: couples a node to the kept blocks.
struct Seen {
  std::array<double, 3> z;
  template <typename T>
  bool operator()(const T* x, const T* q, const T* c, T* r) const {
    T p[3];
    ceres::QuaternionRotatePoint(q, x, p);
    r[0] = p[0] + c[0] - T(z[0]);
    r[1] = p[1] + c[1] - T(z[1]);
    r[2] = p[2] * (T(1.0) + c[2]) - T(z[2]);
    return true;
  }
};

/// a[0] + a[1]: only the sum observed (rank 1 in a 2-block).
struct Sum {
  template <typename T>
  bool operator()(const T* a, T* r) const {
    r[0] = a[0] + a[1] - T(1.0);
    return true;
  }
};

struct Prior {
  template <typename T>
  bool operator()(const T* x, T* r) const {
    for (int k = 0; k < 3; ++k) r[k] = T(10.0) * x[k];
    return true;
  }
};

struct Chain {
  std::vector<std::array<double, 3>> x;
  std::array<double, 4> q{0.1, 0.2, -0.3, 0.9};  // Ceres' order: w, x, y, z (normalised below)
  std::array<double, 3> c{0.3, -0.2, 0.1};
  std::array<double, 3> held{1.0, 2.0, 3.0};
  ceres::QuaternionManifold manifold;
  ceres::CauchyLoss loss{1.0};
  ceres::Problem problem;

  explicit Chain(int n) : problem(options()) {
    std::mt19937 rng(7);
    std::normal_distribution<double> g(0.0, 1.0);
    const double nq = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (double& v : q) v /= nq;
    x.resize(static_cast<std::size_t>(n));
    for (auto& xi : x) xi = {g(rng), g(rng), g(rng)};
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Prior, 3, 3>(new Prior), nullptr, x[0].data());
    for (int i = 0; i + 1 < n; ++i)
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Step, 3, 3, 3>(new Step{{g(rng), g(rng), g(rng)}}),
                               nullptr, x[i].data(), x[i + 1].data());
    problem.AddParameterBlock(q.data(), 4, &manifold);
    for (int i = 0; i < n; ++i)  // far from a solution: some residuals deep in the loss's outlier range
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Seen, 3, 3, 4, 3>(new Seen{{3 * g(rng), g(rng), g(rng)}}),
                               i % 3 == 0 ? &loss : nullptr, x[i].data(), q.data(), c.data());
    problem.AddParameterBlock(held.data(), 3);
    problem.SetParameterBlockConstant(held.data());
  }
  static ceres::Problem::Options options() {
    ceres::Problem::Options o;
    o.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    o.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    return o;
  }
  std::vector<double*> nodes() {
    std::vector<double*> v;
    for (auto& xi : x) v.push_back(xi.data());
    return v;
  }
};

Eigen::MatrixXd ceres_block(ceres::Covariance& cov, const double* a, int na, const double* b, int nb) {
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> m(na, nb);
  REQUIRE(cov.GetCovarianceBlockInTangentSpace(a, b, m.data()));
  return m;
}

}  // namespace

TEST_CASE("refine/marginals: the Schur complement gives ceres::Covariance's blocks, the robust loss applied") {
  Chain ch(40);
  const auto got = roe::refine::marginal_covariance(ch.problem, ch.nodes(), {ch.q.data(), ch.c.data(), ch.held.data()});
  REQUIRE(got.has_value());
  ceres::Covariance cov{ceres::Covariance::Options()};
  const std::vector<std::pair<const double*, const double*>> pairs{
      {ch.q.data(), ch.q.data()}, {ch.q.data(), ch.c.data()}, {ch.c.data(), ch.c.data()}};
  REQUIRE(cov.Compute(pairs, &ch.problem));
  const Eigen::MatrixXd qq = ceres_block(cov, ch.q.data(), 3, ch.q.data(), 3);
  const Eigen::MatrixXd qc = ceres_block(cov, ch.q.data(), 3, ch.c.data(), 3);
  const Eigen::MatrixXd cc = ceres_block(cov, ch.c.data(), 3, ch.c.data(), 3);
  CHECK(got->block(ch.q.data(), ch.q.data()).rows() == 3);  // the quaternion's tangent space
  CHECK((got->block(ch.q.data(), ch.q.data()) - qq).norm() <= 1e-9 * qq.norm());
  CHECK((got->block(ch.q.data(), ch.c.data()) - qc).norm() <= 1e-9 * qq.norm());
  CHECK((got->block(ch.c.data(), ch.q.data()) - qc.transpose()).norm() <= 1e-9 * qq.norm());
  CHECK((got->block(ch.c.data(), ch.c.data()) - cc).norm() <= 1e-9 * cc.norm());
  // A constant kept block has zero covariance.
  CHECK(got->block(ch.held.data(), ch.held.data()).isZero(0.0));
  CHECK(got->block(ch.q.data(), ch.held.data()).isZero(0.0));
}

TEST_CASE("refine/marginals: a singular information is refused, as ceres::Covariance refuses it") {
  Chain ch(20);
  // A kept block of which only the sum of its two components is observed: its information has rank 1.
  std::array<double, 2> lonely{0.0, 0.0};
  ch.problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Sum, 1, 2>(new Sum), nullptr, lonely.data());
  CHECK_FALSE(roe::refine::marginal_covariance(ch.problem, ch.nodes(), {ch.q.data(), ch.c.data(), lonely.data()}));
  ceres::Covariance cov{ceres::Covariance::Options()};
  CHECK_FALSE(cov.Compute(std::vector<std::pair<const double*, const double*>>{{lonely.data(), lonely.data()}}, &ch.problem));
}

TEST_CASE("refine/marginals: every free block must be eliminated or kept") {
  Chain ch(10);
  CHECK_THROWS_AS(roe::refine::marginal_covariance(ch.problem, ch.nodes(), {ch.q.data()}), roe::InternalError);
}
