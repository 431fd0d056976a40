// A harness of fuzz_replay's own test (CTest fuzz/replay-driver, tests/fuzz/check_replay.sh), not a libFuzzer
// target (its name does not match tests/fuzz/fuzz_*.cpp): each input names the finding it stands for, so
// the test can check that the driver reports every kind of finding, naming the input, and fails.
#include <cstdlib>
#include <new>
#include <stdexcept>
#include <vector>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string t = roe::fuzz::text(data, size);
  roe::fuzz::expect_clean([&] {
    if (t == "input-error") throw roe::InputError("a reader's ordinary refusal");  // clean
    if (t == "runtime-error") throw std::runtime_error("not a reader's error type");
    if (t == "trap") __builtin_trap();
    if (t == "abort") std::abort();
    if (t == "hang") {
      for (volatile bool forever = true; forever;) {
      }
    }
    if (t == "allocate") {
      std::vector<char> big(std::size_t{8} << 30);  // 8 GB: beyond --memory-mb
      big[big.size() - 1] = 1;
    }
  });
  return 0;
}
