#include "roe/sim/random.hpp"

#include <cmath>

#include "roe/math/euler.hpp"

namespace roe::sim {
namespace {
using math::kTwoPi;

// SplitMix64 finaliser: spreads a 64-bit value over all bits (Steele, Lea, Flood 2014).
std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// 64-bit FNV-1a hash of a name.
std::uint64_t fnv1a(std::string_view s) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (unsigned char c : s) {
    h ^= c;
    h *= 0x100000001b3ULL;
  }
  return h;
}
}  // namespace

Rng Rng::stream(std::uint64_t seed, std::string_view name) { return Rng(splitmix64(seed ^ fnv1a(name))); }

double Rng::uniform() {
  // The top 53 bits make a double in [0, 1) with every value equally likely.
  return static_cast<double>(engine_() >> 11) * (1.0 / 9007199254740992.0);
}

std::uint64_t Rng::uniform_int(std::uint64_t n) {
  if (n <= 1) return 0;
  const std::uint64_t max = ~std::uint64_t{0};
  const std::uint64_t limit = max - (max % n);  // reject the incomplete last block
  std::uint64_t x;
  do {
    x = engine_();
  } while (x >= limit);
  return x % n;
}

double Rng::normal() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  // Marsaglia's polar method: two independent N(0, 1) from a point uniform in the unit disc.
  double u, v, s;
  do {
    u = 2.0 * uniform() - 1.0;
    v = 2.0 * uniform() - 1.0;
    s = u * u + v * v;
  } while (s >= 1.0 || s == 0.0);
  const double f = std::sqrt(-2.0 * std::log(s) / s);
  spare_ = v * f;
  has_spare_ = true;
  return u * f;
}

Eigen::Vector3d Rng::unit_vector() {
  Eigen::Vector3d v;
  double n;
  do {
    v = normal3();
    n = v.norm();
  } while (n < 1e-12);
  return v / n;
}

Eigen::Vector3d Rng::in_ball(double r) {
  // Radius with density ∝ ρ² (cube root of a uniform) times a uniform direction.
  const Eigen::Vector3d dir = unit_vector();
  return r * std::cbrt(uniform()) * dir;
}

Eigen::Quaterniond Rng::rotation() {
  const double u1 = uniform(), u2 = uniform(), u3 = uniform();
  const double a = std::sqrt(1.0 - u1), b = std::sqrt(u1);
  // Eigen's constructor order is (w, x, y, z).
  return Eigen::Quaterniond(b * std::cos(kTwoPi * u3), a * std::sin(kTwoPi * u2), a * std::cos(kTwoPi * u2),
                            b * std::sin(kTwoPi * u3));
}

}  // namespace roe::sim
