// libFuzzer target: Kalibr camchain-imucam.yaml and imu.yaml.
#include "fuzz_support.hpp"
#include "roe/io/kalibr.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string t = roe::fuzz::text(data, size);
  roe::fuzz::expect_clean([&] { (void)roe::io::parse_kalibr_camchain(t, "camchain.yaml", "cam0"); });
  roe::fuzz::expect_clean([&] { (void)roe::io::parse_kalibr_camchain(t, "camchain.yaml", "cam1"); });
  roe::fuzz::expect_clean([&] { (void)roe::io::parse_kalibr_imu(t, "imu.yaml"); });
  return 0;
}
