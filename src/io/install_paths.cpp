#include "roe/io/install_paths.hpp"

#include <unistd.h>

#include <algorithm>
#include <system_error>

namespace roe::io {

namespace fs = std::filesystem;

fs::path executable_dir() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path{} : exe.parent_path();
}

std::vector<fs::path> shipped_data_roots() {
  const fs::path here = executable_dir();
  if (here.empty()) return {};
  return {here / ".." / "share" / "roe", here / ".."};
}

namespace {
bool is_config_name(const std::string& name) {
  return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-' || c == '_';
  });
}
}  // namespace

fs::path find_shipped_run_config(const std::string& name) {
  if (!is_config_name(name)) return {};
  std::error_code ec;
  for (const fs::path& root : shipped_data_roots()) {
    const fs::path f = root / "configs" / (name + ".json");
    if (fs::is_regular_file(f, ec)) return f.lexically_normal();
  }
  return {};
}

}  // namespace roe::io
