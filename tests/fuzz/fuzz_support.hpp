#pragma once
/// @file
/// Shared by the libFuzzer targets tests/fuzz/fuzz_*.cpp (docs/TESTING.md, "Fuzzing"). Contract of every
/// target: for ANY input bytes the reader returns or throws roe::InputError (or DataError); anything
/// else — another exception, a crash, a sanitizer report, a hang, an allocation beyond libFuzzer's
/// -rss_limit_mb — is a finding.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>

#include "roe/core/error.hpp"
#include "roe/core/log.hpp"

namespace roe::fuzz {

/// Warnings (a CSV's last line without its line end, ...) are not findings: kept off stderr, where they
/// would cost more than the parse.
inline const bool quiet_logs = [] {
  roe::log::set_level(roe::log::Level::kQuiet);
  return true;
}();

/// The input as a string.
inline std::string text(const std::uint8_t* data, std::size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

/// Runs fn; the errors a reader may throw on bad input are swallowed, everything else propagates
/// (and libFuzzer reports it as a crash: "uncaught exception").
template <typename Fn>
void expect_clean(Fn&& fn) {
  try {
    fn();
  } catch (const roe::InputError&) {
  } catch (const roe::DataError&) {
  }
}

/// The folder of input_file(), removed with everything in it when the process exits normally (a replay
/// under CTest, a libFuzzer run that ends; a crash leaves it for the finding's analysis).
struct InputFolder {
  std::filesystem::path path;
  InputFolder() {
    std::error_code ec;
    const std::filesystem::path base =
        std::filesystem::is_directory("/dev/shm", ec) ? "/dev/shm" : std::filesystem::temp_directory_path();
    path = base / ("roe-fuzz-" + std::to_string(::getpid()));
    std::filesystem::create_directories(path);
  }
  ~InputFolder() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
};

/// A file holding the input, for the readers that take a path (one per process, in /dev/shm when
/// there is one: a regular file on tmpfs).
inline const std::filesystem::path& input_file(const std::uint8_t* data, std::size_t size, const char* name) {
  static const InputFolder dir;
  static std::filesystem::path file;
  file = dir.path / name;
  std::FILE* f = std::fopen(file.c_str(), "wb");
  if (f) {
    if (size) std::fwrite(data, 1, size, f);
    std::fclose(f);
  }
  return file;
}

}  // namespace roe::fuzz
