#pragma once
/// @file
/// The run configs roe ships (configs/*.json: default, paper, euroc-flight), found by name wherever roe
/// runs from (io/install_paths.hpp), so `roe run DATASET --config paper` works from any folder.

#include <filesystem>
#include <string>
#include <vector>

namespace roe::app {

struct ShippedConfig {
  std::string name;              ///< `paper`
  std::filesystem::path path;    ///< .../configs/paper.json
  std::string description;       ///< the config's own "description"
  std::string summary;           ///< its title (the text before the first ": "), for listings
};

/// Every shipped run config, sorted by name.
std::vector<ShippedConfig> shipped_run_configs();

/// The file a `--config` argument names: an existing path as given, else the shipped config of that name.
/// Throws InputError naming the argument and the shipped names when it is neither.
std::filesystem::path resolve_run_config(const std::string& argument);

}  // namespace roe::app
