#pragma once
/// @file
/// Helpers shared by the tests: a self-deleting temporary folder and a runner for the roe binary.

#include <sys/wait.h>

#include <array>
#include <catch2/catch.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>

#include "roe/core/error.hpp"

namespace roe::test {

namespace fs = std::filesystem;

/// The bytes of the file `p` (REQUIRE that it opens).
inline std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  REQUIRE(in);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// A fresh folder under the system temp dir, removed with everything in it on destruction.
struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& tag = "roe_test") {
    std::random_device rd;
    path = fs::temp_directory_path() / (tag + "_" + std::to_string(rd()) + std::to_string(rd()));
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  /// Writes `text` to `name` inside the folder and returns its path.
  fs::path write(const std::string& name, const std::string& text) const {
    const fs::path p = path / name;
    fs::create_directories(p.parent_path());
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }
  fs::path operator/(const std::string& name) const { return path / name; }
};

/// Exit code and captured output of one run of the roe executable.
struct RunResult {
  int code;
  std::string out;
};

/// Runs `cmd` through the shell with stderr merged into `out` (a subshell, so `cmd` may be a list).
inline RunResult run_shell(const std::string& cmd) {
  FILE* p = popen(("(" + cmd + ") 2>&1").c_str(), "r");
  REQUIRE(p != nullptr);
  std::string out;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) out.append(buf.data(), n);
  const int status = pclose(p);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

/// Runs `ROE_BINARY args` through the shell; stderr is merged into `out` unless merge_stderr is false
/// (then it is discarded, so `out` is exactly stdout, e.g. for --json).
inline RunResult run_roe(const std::string& args, bool merge_stderr = true) {
  const std::string cmd =
      std::string(ROE_BINARY) + " " + args + (merge_stderr ? " 2>&1" : " 2>/dev/null");
  FILE* p = popen(cmd.c_str(), "r");
  REQUIRE(p != nullptr);
  std::string out;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) out.append(buf.data(), n);
  const int status = pclose(p);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

/// Runs `fn` and returns the roe::InputError it throws (fails the test when it throws nothing).
template <typename Fn>
InputError expect_input_error(Fn&& fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e;
  }
  FAIL("expected roe::InputError");
  throw std::logic_error("unreachable");
}

}  // namespace roe::test
