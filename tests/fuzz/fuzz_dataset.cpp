// libFuzzer target: the dataset's stream files (imu0, cam0, mocap0, ground truth, detections) and
// the mocap exports (Motive, Vicon), which are read from a path: the input is written to a file first.
#include "fuzz_support.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/mocap_formats.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const auto& f = roe::fuzz::input_file(data + 1, size - 1, "data.csv");
  switch (data[0] % 7) {
    case 0: roe::fuzz::expect_clean([&] { (void)roe::store::read_imu_csv(f); }); break;
    case 1: roe::fuzz::expect_clean([&] { (void)roe::store::read_cam_csv(f); }); break;
    case 2: roe::fuzz::expect_clean([&] { (void)roe::store::read_mocap_csv(f); }); break;
    case 3: roe::fuzz::expect_clean([&] { (void)roe::store::read_groundtruth_csv(f); }); break;
    case 4: roe::fuzz::expect_clean([&] { (void)roe::store::read_detections_csv(f); }); break;
    case 5: roe::fuzz::expect_clean([&] { (void)roe::io::read_motive_csv(f, ""); }); break;
    default: roe::fuzz::expect_clean([&] { (void)roe::io::read_vicon_csv(f, ""); }); break;
  }
  return 0;
}
