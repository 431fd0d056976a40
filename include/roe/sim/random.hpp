#pragma once
/// @file
/// The simulator's random numbers. Everything random in roe::sim is drawn from `Rng`, a seeded
/// std::mt19937_64 (whose output sequence the C++ standard fixes) with the distributions written
/// out here instead of std::uniform_real_distribution / std::normal_distribution, whose algorithms
/// are implementation-defined. So the same seed gives the same numbers with any standard library
/// and compiler (as long as IEEE-754 double arithmetic and libm's sin/cos/log are the same).
///
/// Independent streams: `Rng::stream(seed, "name")` derives a generator from the seed and a name, so
/// adding draws to one part of the simulator (e.g. the IMU) never changes another (e.g. detections).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <random>
#include <string_view>

namespace roe::sim {

class Rng {
 public:
  explicit Rng(std::uint64_t seed) : engine_(seed) {}
  /// A generator for the named stream of `seed` (SplitMix64 of seed ^ FNV-1a(name)).
  static Rng stream(std::uint64_t seed, std::string_view name);

  /// Uniform in [0, 1) with 53 random bits.
  double uniform();
  /// Uniform in [a, b).
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  /// Uniform integer in [0, n) (n > 0), by rejection (no modulo bias).
  std::uint64_t uniform_int(std::uint64_t n);
  /// Standard normal N(0, 1): Marsaglia's polar method (one value per call, the pair's second
  /// value is cached).
  double normal();
  /// N(0, σ²).
  double normal(double sigma) { return sigma * normal(); }
  /// Three independent standard normals.
  Eigen::Vector3d normal3() {
    const double x = normal(), y = normal(), z = normal();
    return {x, y, z};
  }
  /// true with probability p.
  bool bernoulli(double p) { return uniform() < p; }
  /// A uniformly distributed unit vector (normalised Gaussian vector).
  Eigen::Vector3d unit_vector();
  /// A point uniformly distributed in the ball of radius r.
  Eigen::Vector3d in_ball(double r);
  /// A uniformly distributed rotation (Shoemake 1992, "Uniform random rotations").
  Eigen::Quaterniond rotation();

  std::mt19937_64& engine() { return engine_; }

 private:
  std::mt19937_64 engine_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

}  // namespace roe::sim
