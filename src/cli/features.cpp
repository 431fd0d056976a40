// What this roe was built with (the optional libraries, cmake/features.cmake) and the one refusal of a
// command whose library is missing.
#include <fmt/format.h>

#include "command.hpp"
#include "roe/features.hpp"
#include "roe/version.hpp"

namespace roe::cli {

std::string version_text() {
  std::string out = fmt::format("roe {}\noptional libraries (docs/install.md, \"Optional libraries\"):", kVersion);
  for (const BuildFeature& f : kBuildFeatures) {
    out += fmt::format("\n  {:<13} {:<4} {}", f.library, f.built ? "yes" : "no", f.commands);
    if (!f.built) out += fmt::format(" (needs {}, -D{}=ON)", f.debian_package, f.cmake_option);
  }
  return out;
}

nlohmann::json features_json() {
  nlohmann::json j = nlohmann::json::object();
  for (const BuildFeature& f : kBuildFeatures) j[f.key] = f.built;
  return j;
}

std::string not_built_message(const BuildFeature& f, const std::string& command) {
  return fmt::format(
      "roe {} needs {}, and this roe was built without it. Install {} (Debian; scripts/install-deps.sh "
      "infer installs every optional library) and rebuild: cmake -S . -B build -D{}=ON && cmake --build build "
      "(docs/install.md, \"Optional libraries\"). `roe --version` lists what this roe has.",
      command, f.library, f.debian_package, f.cmake_option);
}

}  // namespace roe::cli
