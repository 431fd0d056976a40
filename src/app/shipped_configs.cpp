#include "roe/app/shipped_configs.hpp"

#include <fmt/format.h>

#include <system_error>

#include "roe/core/error.hpp"
#include "roe/io/install_paths.hpp"
#include "roe/io/json.hpp"

namespace roe::app {

namespace fs = std::filesystem;

namespace {
// A one-line summary of a config's description: the configs open with a title before ": " ("The paper's
// choices (Jantos et al., ICRA 2023, Sec. III): ..."), else the first 100 characters.
std::string summary_of(const std::string& text) {
  if (const auto colon = text.find(": "); colon != std::string::npos && colon <= 120) return text.substr(0, colon);
  if (text.size() <= 100) return text;
  const auto space = text.rfind(' ', 100);
  return text.substr(0, space == std::string::npos ? 100 : space) + " ...";
}
}  // namespace

std::vector<ShippedConfig> shipped_run_configs() {
  std::vector<ShippedConfig> out;
  for (const std::string& name : io::shipped_run_config_names()) {
    ShippedConfig c{name, io::find_shipped_run_config(name), {}, {}};
    const auto j = io::parse_json_file(c.path);
    if (j.is_object() && j.contains("description") && j["description"].is_string()) {
      c.description = j["description"].get<std::string>();
      c.summary = summary_of(c.description);
    }
    out.push_back(std::move(c));
  }
  return out;
}

fs::path resolve_run_config(const std::string& argument) {
  std::error_code ec;
  if (fs::exists(argument, ec)) return argument;  // a path as given wins over a shipped name
  if (fs::path shipped = io::find_shipped_run_config(argument); !shipped.empty()) return shipped;
  std::string names;
  for (const std::string& n : io::shipped_run_config_names()) names += (names.empty() ? "" : ", ") + n;
  throw InputError(fmt::format("--config: '{}' is neither a file nor a shipped config ({})", argument,
                               names.empty() ? "none found beside this roe" : "shipped: " + names),
                   {});
}

}  // namespace roe::app
