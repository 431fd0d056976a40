// libFuzzer target: PoET's results.json under each rotation form.
#include "fuzz_support.hpp"
#include "roe/io/poet_results.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using F = roe::io::PoetRotationFormat;
  const std::string t = roe::fuzz::text(data, size);
  for (F f : {F::kAuto, F::kMatrix, F::kQuatWxyz})
    roe::fuzz::expect_clean([&] { (void)roe::io::parse_poet_results(t, "results.json", f); });
  return 0;
}
