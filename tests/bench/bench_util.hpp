#pragma once
/// @file
/// Timing helper shared by the benchmark programs.

#include <algorithm>
#include <chrono>
#include <ctime>

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

/// Best (minimum) CPU time of the calling thread in seconds of `n` calls of `f`: independent of other
/// processes sharing the machine (not of cache effects they cause).
template <typename F>
double best_cpu_of(int n, F&& f) {
  const auto now = [] {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
  };
  double best = 1e30;
  for (int i = 0; i < n; ++i) {
    const double t0 = now();
    f();
    best = std::min(best, now() - t0);
  }
  return best;
}

}  // namespace roe::bench
