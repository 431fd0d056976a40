#pragma once
/// @file
/// Work spread over the CPUs the process may use, with results that do not depend on the thread
/// count: each index is handled exactly once and writes its own slot; reductions stay with the caller,
/// in index order. Used by calib's time-offset grid, eval's per-pair metrics and `roe run`'s output files
/// (the smoother's second thread is its own: ekf/smoother.cpp's StepsWorker).
///
///   parallel_for(n, available_cpus(), [&](std::size_t i) { out[i] = f(in[i]); });
///   parallel_ranges(n, 16384, available_cpus(), [&](std::size_t b, std::size_t e) { ... });
///   parallel_ranges_ordered(n, 16384, threads, map_range, reduce_in_order);

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <functional>
#include <map>
#include <type_traits>
#include <mutex>
#include <thread>
#include <vector>

namespace roe {

/// The CPUs this process may run on (its affinity mask: what taskset, Slurm or a container grants);
/// at least 1.
unsigned available_cpus();

/// Runs fn(begin, end) over the consecutive ranges [k·grain, min((k + 1)·grain, n)) of [0, n), each
/// exactly once, on up to `threads` threads (the calling thread is one of them; ranges are handed out
/// in order as threads become free). With one thread or one range everything runs on the calling
/// thread. An exception thrown by fn is rethrown here once every thread has stopped (the one of the
/// lowest range when several throw; ranges not yet started are skipped).
template <typename Fn>
void parallel_ranges(std::size_t n, std::size_t grain, unsigned threads, Fn&& fn) {
  grain = std::max<std::size_t>(grain, 1);
  const std::size_t ranges = n / grain + (n % grain != 0);
  threads = static_cast<unsigned>(std::min<std::size_t>(std::max(1u, threads), ranges));
  if (threads <= 1) {
    for (std::size_t b = 0; b < n; b += grain) fn(b, std::min(n, b + grain));
    return;
  }
  std::atomic<std::size_t> next{0};
  std::atomic<bool> failed{false};
  std::mutex m;
  std::exception_ptr error;
  std::size_t error_range = ranges;
  const auto work = [&] {
    for (std::size_t k = next++; k < ranges && !failed; k = next++) {
      try {
        fn(k * grain, std::min(n, (k + 1) * grain));
      } catch (...) {
        const std::lock_guard<std::mutex> lock(m);
        if (k < error_range) error_range = k, error = std::current_exception();
        failed = true;
      }
    }
  };
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

/// parallel_ranges where each range gives a partial result, map(begin, end) → T, and reduce(T&&) takes
/// them in range order, one at a time, on whichever thread finished the range that completes the order:
/// a reduction with the sequential loop's order of operations (so its bits), that never holds more than
/// the results of the ranges in flight.
template <typename Map, typename Reduce>
void parallel_ranges_ordered(std::size_t n, std::size_t grain, unsigned threads, Map&& map, Reduce&& reduce) {
  using T = std::decay_t<std::invoke_result_t<Map&, std::size_t, std::size_t>>;
  grain = std::max<std::size_t>(grain, 1);
  std::mutex m;
  std::map<std::size_t, T> done;  // ranges computed, not yet reduced
  std::size_t next = 0;           // the range to reduce next
  parallel_ranges(n, grain, threads, [&](std::size_t b, std::size_t e) {
    T part = map(b, e);
    const std::lock_guard<std::mutex> lock(m);
    done.emplace(b / grain, std::move(part));
    for (auto it = done.begin(); it != done.end() && it->first == next; it = done.erase(it), ++next)
      reduce(std::move(it->second));
  });
}

/// Runs fn(i) for i in [0, n) on up to `threads` threads, each i exactly once (one index at a time:
/// for work items that are large and uneven).
template <typename Fn>
void parallel_for(std::size_t n, unsigned threads, Fn&& fn) {
  parallel_ranges(n, 1, threads, [&fn](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) fn(i);
  });
}

/// Runs every task once, on up to `threads` threads, in list order as threads free up (put the longest
/// first); waits for all of them, then rethrows the exception of the first task in the list that threw
/// (unlike parallel_ranges, a failure does not skip the tasks not yet started). For independent pieces of
/// one command's work, such as the output files of `roe run`.
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
