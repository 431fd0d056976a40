#pragma once
/// @file
/// Level-filtered logging to stderr. The CLI sets the level (-q, -v); library areas that must stay
/// I/O-free (math, ekf, eval, sim, calib) never log: they return warnings in their results instead.

#include <fmt/format.h>

#include <string>

namespace roe::log {

enum class Level { kQuiet = 0, kWarn = 1, kInfo = 2, kDebug = 3 };

void set_level(Level level);
Level level();
/// Writes "roe: <level>: message" to stderr when the level is enabled.
void write(Level level, const std::string& message);

template <typename... Args>
void warn(fmt::format_string<Args...> f, Args&&... args) {
  if (level() >= Level::kWarn) write(Level::kWarn, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void info(fmt::format_string<Args...> f, Args&&... args) {
  if (level() >= Level::kInfo) write(Level::kInfo, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void debug(fmt::format_string<Args...> f, Args&&... args) {
  if (level() >= Level::kDebug) write(Level::kDebug, fmt::format(f, std::forward<Args>(args)...));
}

}  // namespace roe::log
