#pragma once
/// @file
/// The run configs roe ships (configs/*.json: default, paper, euroc-flight). One source: the files are
/// compiled into roe (cmake/extra-sweep.cmake, cmake/embed.cmake), and every reader of a shipped name
/// (`roe run --config paper`, `roe run --list-configs`, a sweep spec's "configs": ["paper"]) reads those
/// bytes, so a roe without its share/ folder (a half-installed or copied binary) still has them. The
/// installed copies (PREFIX/share/roe/configs/, io/install_paths.hpp) are documentation: reading one of
/// them by path when it differs from the compiled bytes is an error, not a second version.

#include <filesystem>
#include <string>
#include <vector>

namespace roe::app {

struct ShippedConfig {
  std::string name;              ///< `paper`
  std::filesystem::path path;    ///< where it is installed: .../configs/paper.json (see shipped_config_path)
  std::string description;       ///< the config's own "description"
  std::string summary;           ///< its title (the text before the first ": "), for listings
};

/// Names of the shipped run configs, sorted.
std::vector<std::string> shipped_config_names();
/// A shipped config's JSON text (the compiled bytes). InputError naming the shipped names when unknown.
const std::string& shipped_config_text(const std::string& name);

/// Every shipped run config, sorted by name.
std::vector<ShippedConfig> shipped_run_configs();

/// The path that stands for a shipped config: its installed copy beside this roe when there is one,
/// else where an installation puts it (`EXE_DIR/../share/roe/configs/NAME.json`). run.json records it.
std::filesystem::path shipped_config_path(const std::string& name);

/// The shipped config that `file` stands for (a path shipped_config_path gives, existing or not), or
/// empty. ConfigError when that file exists with other bytes than the compiled ones.
std::string shipped_config_at(const std::filesystem::path& file);

/// The file a `--config` argument names: an existing path as given, else shipped_config_path of the
/// shipped config of that name. Throws InputError naming the argument and the shipped names when it is neither.
std::filesystem::path resolve_run_config(const std::string& argument);

}  // namespace roe::app
