// roe run: a config file (or a shipped config by name) into RunConfig (store/run_config.hpp).
#include "roe/app/run.hpp"
#include "roe/app/shipped_configs.hpp"
#include "roe/io/json.hpp"

namespace roe::app {

RunConfig run_config_from_file(const std::filesystem::path& file) {
  // A shipped config (`--config paper` resolves to its installed path): the bytes compiled into roe, the
  // ones a sweep reads too (app/shipped_configs.hpp), located in errors as the file.
  if (const std::string name = shipped_config_at(file); !name.empty()) {
    const std::string& text = shipped_config_text(name);
    const std::string source = file.string();
    return io::with_json_locations(text, source,
                                   [&] { return run_config_from_json(io::parse_json_text(text, source), source); });
  }
  // Every error with a key path gets the key's line and column in the file (io::read_json_file).
  return io::read_json_file(file, [](const nlohmann::json& j, const std::string& source) {
    return run_config_from_json(j, source);
  });
}

}  // namespace roe::app
