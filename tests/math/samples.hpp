#pragma once
// Rotation-vector sample set shared by the math property tests: the identity, tiny angles around
// the Taylor-branch threshold, angles near and exactly at π about several axes, and ~200 random
// rotations (fixed seed, so failures reproduce).

#include <Eigen/Core>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "roe/math/euler.hpp"

namespace roe::test {

struct RotSample {
  std::string label;
  Eigen::Vector3d phi;
};

inline std::vector<Eigen::Vector3d> sample_axes() {
  return {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ(),
          Eigen::Vector3d(1, 1, 1).normalized(), Eigen::Vector3d(-0.3, 0.8, -0.52).normalized()};
}

inline std::vector<RotSample> rotation_samples(int n_random = 200) {
  std::vector<RotSample> out;
  out.push_back({"identity", Eigen::Vector3d::Zero()});
  int k = 0;
  for (const auto& axis : sample_axes()) {
    const std::string a = "axis" + std::to_string(k++);
    out.push_back({a + " 1e-8", 1e-8 * axis});
    out.push_back({a + " 0.9e-6", 0.9e-6 * axis});  // just below the Taylor threshold
    out.push_back({a + " 1.1e-6", 1.1e-6 * axis});  // just above
    out.push_back({a + " 1e-3", 1e-3 * axis});
    out.push_back({a + " pi/2", 0.5 * math::kPi * axis});
    out.push_back({a + " pi-1e-6", (math::kPi - 1e-6) * axis});
    out.push_back({a + " pi", math::kPi * axis});
  }
  std::mt19937 rng(12345);
  std::normal_distribution<double> n(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, math::kPi);
  for (int i = 0; i < n_random; ++i) {
    const Eigen::Vector3d axis = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
    out.push_back({"random " + std::to_string(i), u(rng) * axis});
  }
  return out;
}

// Random unit vector / rotation helpers.
inline Eigen::Vector3d random_vector(std::mt19937& rng, double sigma = 1.0) {
  std::normal_distribution<double> n(0.0, sigma);
  return Eigen::Vector3d(n(rng), n(rng), n(rng));
}

}  // namespace roe::test
