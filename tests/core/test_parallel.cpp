// core/parallel.hpp: every index once whatever the thread count, and run_all's error rule (every task
// runs, the first failing task in list order decides the exception), on which `roe run`'s writers rely.
#include <catch2/catch.hpp>

#include <atomic>
#include <stdexcept>
#include <string>
#include <vector>

#include "roe/core/parallel.hpp"

using namespace roe;

TEST_CASE("parallel_for: each index exactly once on 1, 2 and more threads than items", "[core][parallel]") {
  for (unsigned threads : {1u, 2u, 7u}) {
    std::vector<std::atomic<int>> hits(5);
    parallel_for(hits.size(), threads, [&](std::size_t i) { ++hits[i]; });
    for (const auto& h : hits) CHECK(h == 1);
  }
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
