// libFuzzer target: a rosbag2 folder's metadata.yaml (issue 40): the reader alone, then the folder opened
// through it. Its relative_file_paths must never name a file outside the folder; compression keys, counts
// and topic lists of any shape end in InputError.
#include <fstream>

#include "fuzz_support.hpp"
#include "roe/io/ros/message_bag.hpp"
#include "roe/io/ros/rosbag2.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::filesystem::path& file = roe::fuzz::input_file(data, size, "metadata.yaml");
  roe::fuzz::expect_clean([&] {
    const auto m = roe::io::rosbag2::read_metadata(file);
    for (const auto& f : m.relative_file_paths) {
      const std::filesystem::path p(f);
      // The contract the folder reader relies on: a plain relative path without "..".
      if (p.is_absolute() || f.empty()) __builtin_trap();
      for (const auto& part : p)
        if (part == "..") __builtin_trap();
    }
  });
  roe::io::BagOpenOptions o;
  o.allow_missing_files = true;
  roe::fuzz::expect_clean([&] { (void)roe::io::open_bag(file.parent_path(), o); });
  return 0;
}
