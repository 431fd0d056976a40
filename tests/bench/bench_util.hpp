#pragma once
/// @file
/// Timing helper shared by the benchmark programs.

#include <algorithm>
#include <chrono>

namespace roe::bench {

/// Best (minimum) wall time in seconds of `n` calls of `f`.
template <typename F>
double best_of(int n, F&& f) {
  double best = 1e30;
  for (int i = 0; i < n; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  return best;
}

}  // namespace roe::bench
