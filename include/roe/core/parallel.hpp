#pragma once
/// @file
/// The CPUs a process may use, and a parallel loop whose outcome does not depend on the thread count.
/// Used where one command's work splits into independent parts (calib-check's time-offset grid, the
/// smoother's per-step outputs, the files of `roe run`). Library code decides the split; the thread count comes from the
/// process's affinity mask, so taskset, Slurm's cgroups and containers are respected.

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <functional>
#include <thread>
#include <vector>

namespace roe {

/// The CPUs this process may run on (its affinity mask: what taskset, Slurm or a container grants); 1 when
/// the mask cannot be read.
unsigned available_cpus();

/// Runs fn(i) for i in [0, n) on up to `threads` threads (the calling thread is one of them); each i
/// exactly once, results by index, so the outcome does not depend on the thread count. fn must not throw.
template <typename Fn>
void parallel_for(std::size_t n, unsigned threads, Fn&& fn) {
  threads = static_cast<unsigned>(std::min<std::size_t>(std::max(1u, threads), n));
  if (threads <= 1) {
    for (std::size_t i = 0; i < n; ++i) fn(i);
    return;
  }
  std::atomic<std::size_t> next{0};
  const auto work = [&] {
    for (std::size_t i = next++; i < n; i = next++) fn(i);
  };
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
}

/// Runs every task once, on up to `threads` threads, in list order as threads free up (put the longest
/// first); waits for all of them, then rethrows the exception of the first task in the list that threw.
/// For independent pieces of one command's work, such as the output files of `roe run`.
inline void run_all(const std::vector<std::function<void()>>& tasks, unsigned threads) {
  std::vector<std::exception_ptr> errors(tasks.size());
  parallel_for(tasks.size(), threads, [&](std::size_t i) {
    try {
      tasks[i]();
    } catch (...) {
      errors[i] = std::current_exception();
    }
  });
  for (const auto& e : errors)
    if (e) std::rethrow_exception(e);
}

}  // namespace roe
