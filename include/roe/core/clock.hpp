#pragma once
/// @file
/// Wall time of a command's stages (run.json's timing_s, the report's and sweep's timings): one monotonic
/// clock and one way to read an elapsed time.

#include <chrono>

namespace roe {

using SteadyClock = std::chrono::steady_clock;

/// Seconds elapsed since `t0` on the monotonic clock.
inline double seconds_since(SteadyClock::time_point t0) {
  return std::chrono::duration<double>(SteadyClock::now() - t0).count();
}

}  // namespace roe
