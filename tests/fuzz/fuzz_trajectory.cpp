// libFuzzer target: trajectory files (TUM, EuRoC, cnspy CSV, roe csv-ns, and format detection).
#include "fuzz_support.hpp"
#include "roe/io/trajectory_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using F = roe::io::TrajectoryFormat;
  const std::string t = roe::fuzz::text(data, size);
  for (F f : {F::kAuto, F::kTum, F::kEuroc, F::kCsv, F::kCsvNs})
    roe::fuzz::expect_clean([&] { (void)roe::io::parse_trajectory(t, "fuzz.txt", f); });
  return 0;
}
