// libFuzzer target: strict JSON (parse_json_text, the key locator) and roe.json (manifest_from_json),
// read as a file so that the located-error path (read_json_file) runs as in roe.
#include "fuzz_support.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/json.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string t = roe::fuzz::text(data, size);
  roe::fuzz::expect_clean([&] {
    const auto j = roe::io::parse_json_text(t, "fuzz.json");
    (void)roe::io::dump_json(j);
  });
  for (const char* path : {"camera.fx", "objects[0].T_W_O.q", "a[1][2].b", "imu.noise"})
    (void)roe::io::json_key_location(t, path);
  const auto& file = roe::fuzz::input_file(data, size, "roe.json");
  roe::fuzz::expect_clean([&] { (void)roe::io::read_json_file(file, roe::store::manifest_from_json); });
  return 0;
}
