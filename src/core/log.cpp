#include "roe/core/log.hpp"

#include <atomic>
#include <cstdio>

namespace roe::log {
namespace {
std::atomic<int> g_level{static_cast<int>(Level::kWarn)};
}

void set_level(Level l) { g_level = static_cast<int>(l); }
Level level() { return static_cast<Level>(g_level.load()); }

void write(Level l, const std::string& message) {
  const char* tag = l == Level::kWarn ? "warning" : l == Level::kInfo ? "info" : "debug";
  std::fprintf(stderr, "roe: %s: %s\n", tag, message.c_str());
}

}  // namespace roe::log
