// median_rate_hz: the rate roe reports for streams whose rate no header states (mocap exports, RealSense
// motion streams without a configured fps, real IMUs under --from-groundtruth).
#include <catch2/catch.hpp>
#include <utility>
#include <vector>

#include "roe/core/types.hpp"

using namespace roe;

namespace {
// Stamps from a start and a list of intervals [ns].
std::vector<Timestamp> stamps(std::initializer_list<Timestamp> intervals) {
  std::vector<Timestamp> t{1'000'000'000};
  for (Timestamp d : intervals) t.push_back(t.back() + d);
  return t;
}
}  // namespace

TEST_CASE("core: median_rate_hz", "[core]") {
  CHECK(median_rate_hz(std::vector<Timestamp>{}) == 0.0);
  CHECK(median_rate_hz(std::vector<Timestamp>{5}) == 0.0);
  CHECK(median_rate_hz(stamps({5'000'000})) == 200.0);
  // Gaps and dropped samples do not move it; the mean interval would.
  CHECK(median_rate_hz(stamps({5'000'000, 5'000'000, 10'000'000, 5'000'000, 5'000'000, 40'000'000})) == 200.0);
  CHECK(median_rate_hz(stamps({10'000'000, 10'000'000, 5'000'000, 10'000'000, 10'000'000, 5'000'000})) == 100.0);
  // Unordered intervals: the middle one of the sorted five is 4 ms; of an even count, the upper middle.
  CHECK(median_rate_hz(stamps({8'000'000, 2'000'000, 4'000'000, 16'000'000, 3'000'000})) == 250.0);
  CHECK(median_rate_hz(stamps({8'000'000, 2'000'000, 4'000'000, 3'000'000})) == 250.0);
  // Unsorted stamps (a non-positive median interval) give no rate rather than a negative one.
  CHECK(median_rate_hz(stamps({-5'000'000, -5'000'000, 5'000'000})) == 0.0);
  CHECK(median_rate_hz(stamps({0, 0, 5'000'000})) == 0.0);
  // Any samples, with the stamp taken by a function.
  const std::vector<std::pair<Timestamp, double>> v = {{0, 1.0}, {2'500'000, 2.0}, {5'000'000, 3.0}};
  CHECK(median_rate_hz(v, [](const std::pair<Timestamp, double>& x) { return x.first; }) == 400.0);
  std::vector<ImuSample> imu(3);
  imu[1].t_ns = 5'000'000;
  imu[2].t_ns = 10'000'000;
  CHECK(median_rate_hz(imu, [](const ImuSample& s) { return s.t_ns; }) == 200.0);
}
