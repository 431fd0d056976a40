// core/parallel.hpp: every index once, results that do not depend on the thread count, ordered
// reductions, exceptions from the lowest range, the affinity-bound CPU count, and run_all's error rule
// (every task runs, the first failing task in list order decides the exception), on which `roe run`'s
// writers rely.
#include <catch2/catch.hpp>

#include <sched.h>

#include <atomic>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "roe/core/parallel.hpp"

using namespace roe;

TEST_CASE("parallel_ranges: each index exactly once, in ranges of the grain", "[core][parallel]") {
  for (const unsigned threads : {1u, 2u, 5u}) {
    for (const std::size_t n : {std::size_t{0}, std::size_t{1}, std::size_t{999}, std::size_t{1000}, std::size_t{1001}}) {
      CAPTURE(threads, n);
      std::vector<std::atomic<int>> hits(n);
      std::atomic<int> bad_ranges{0};
      parallel_ranges(n, 100, threads, [&](std::size_t b, std::size_t e) {
        if (b % 100 != 0 || e - b > 100 || e > n || e <= b) ++bad_ranges;
        for (std::size_t i = b; i < e; ++i) ++hits[i];
      });
      CHECK(bad_ranges == 0);
      std::size_t once = 0;
      for (const auto& h : hits) once += h == 1;
      CHECK(once == n);
    }
  }
}

TEST_CASE("parallel_ranges_ordered: the reduction sees the ranges in order", "[core][parallel]") {
  for (const unsigned threads : {1u, 2u, 4u}) {
    CAPTURE(threads);
    std::vector<std::size_t> order;
    double sum = 0.0;  // a floating-point sum in index order, whatever thread computed a range
    parallel_ranges_ordered(
        10'000, 7, threads,
        [](std::size_t b, std::size_t e) {
          std::vector<double> v;
          for (std::size_t i = b; i < e; ++i) v.push_back(1.0 / static_cast<double>(i + 1));
          if (b % 3 == 0) std::this_thread::yield();  // uneven finishing order
          return std::make_pair(b, v);
        },
        [&](std::pair<std::size_t, std::vector<double>>&& part) {
          order.push_back(part.first);
          for (double x : part.second) sum += x;
        });
    double ref = 0.0;
    for (std::size_t i = 0; i < 10'000; ++i) ref += 1.0 / static_cast<double>(i + 1);
    CHECK(sum == ref);
    REQUIRE(order.size() == (10'000 + 6) / 7);
    bool in_order = true;
    for (std::size_t k = 0; k < order.size(); ++k) in_order = in_order && order[k] == 7 * k;
    CHECK(in_order);
  }
}

TEST_CASE("parallel_ranges: an exception is rethrown, the lowest failing range's", "[core][parallel]") {
  for (const unsigned threads : {1u, 2u, 4u}) {
    CAPTURE(threads);
    try {
      parallel_ranges(1000, 10, threads, [](std::size_t b, std::size_t) {
        if (b == 300 || b == 700) throw std::runtime_error("range " + std::to_string(b));
      });
      FAIL("no exception");
    } catch (const std::runtime_error& e) {
      CHECK(std::string(e.what()) == "range 300");
    }
  }
}

TEST_CASE("available_cpus: the process's affinity mask", "[core][parallel]") {
  cpu_set_t set;
  CPU_ZERO(&set);
  REQUIRE(sched_getaffinity(0, sizeof set, &set) == 0);
  CHECK(available_cpus() == static_cast<unsigned>(CPU_COUNT(&set)));
  CHECK(available_cpus() >= 1);
}

TEST_CASE("run_all: every task runs, the first failure in list order is rethrown", "[core][parallel]") {
  for (unsigned threads : {1u, 2u, 4u}) {
    std::vector<std::atomic<int>> ran(6);
    std::vector<std::function<void()>> tasks;
    for (int i = 0; i < 6; ++i)
      tasks.push_back([&ran, i] {
        ++ran[i];
        if (i == 2 || i == 4) throw std::runtime_error("task " + std::to_string(i));
      });
    try {
      run_all(tasks, threads);
      FAIL("no exception");
    } catch (const std::runtime_error& e) {
      CHECK(std::string(e.what()) == "task 2");
    }
    for (const auto& r : ran) CHECK(r == 1);
  }
  std::vector<std::function<void()>> none;
  CHECK_NOTHROW(run_all(none, 2));
}
