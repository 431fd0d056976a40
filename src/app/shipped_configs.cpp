#include "roe/app/shipped_configs.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <system_error>
#include <utility>

#include "roe/core/error.hpp"
#include "roe/io/input.hpp"
#include "roe/io/install_paths.hpp"
#include "roe/io/json.hpp"

namespace roe::app {
namespace detail {
const std::vector<std::pair<std::string, std::string>>& embedded_run_configs();  // cmake/extra-sweep.cmake
}  // namespace detail

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

fs::path comparable(const fs::path& p) {
  std::error_code ec;
  fs::path r = fs::weakly_canonical(fs::absolute(p, ec), ec);
  return ec ? fs::absolute(p, ec).lexically_normal() : r;
}
}  // namespace

std::vector<std::string> shipped_config_names() {
  std::vector<std::string> names;
  for (const auto& c : detail::embedded_run_configs()) names.push_back(c.first);
  std::sort(names.begin(), names.end());
  return names;
}

const std::string& shipped_config_text(const std::string& name) {
  for (const auto& c : detail::embedded_run_configs())
    if (c.first == name) return c.second;
  throw InputError(fmt::format("unknown shipped config '{}' (shipped: {}; or give a path to a JSON file)", name,
                               fmt::join(shipped_config_names(), ", ")));
}

fs::path shipped_config_path(const std::string& name) {
  if (fs::path installed = io::find_shipped_run_config(name); !installed.empty()) return installed;
  const auto roots = io::shipped_data_roots();
  return roots.empty() ? fs::path("share/roe/configs") / (name + ".json")
                       : (roots.front() / "configs" / (name + ".json")).lexically_normal();
}

std::string shipped_config_at(const fs::path& file) {
  const fs::path f = comparable(file);
  for (const std::string& name : shipped_config_names()) {
    bool at = comparable(shipped_config_path(name)) == f;
    for (const fs::path& root : io::shipped_data_roots()) at = at || comparable(root / "configs" / (name + ".json")) == f;
    if (!at) continue;
    if (io::optional_regular_file(file, "config") && io::read_file(file) != shipped_config_text(name))
      throw ConfigError(fmt::format("this copy of the shipped config '{}' differs from the one compiled into this roe "
                                    "(an edited or stale installation): roe reads the shipped configs from itself, so "
                                    "copy an edited config to another path and pass that path, or reinstall roe",
                                    name),
                        {file.string()});
    return name;
  }
  return {};
}

std::vector<ShippedConfig> shipped_run_configs() {
  std::vector<ShippedConfig> out;
  for (const std::string& name : shipped_config_names()) {
    ShippedConfig c{name, shipped_config_path(name), {}, {}};
    const auto j = io::parse_json_text(shipped_config_text(name), "configs/" + name + ".json");
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
  const auto names = shipped_config_names();
  if (std::find(names.begin(), names.end(), argument) != names.end()) return shipped_config_path(argument);
  throw InputError(fmt::format("--config: '{}' is neither a file nor a shipped config (shipped: {})", argument,
                               fmt::join(names, ", ")),
                   {});
}

}  // namespace roe::app
