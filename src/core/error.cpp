#include "roe/core/error.hpp"

namespace roe {

std::string ErrorContext::prefix() const {
  std::string out;
  if (!file.empty()) out += file;
  if (line > 0) {
    out += (out.empty() ? "line " : ":") + std::to_string(line);
    if (column > 0) out += ":" + std::to_string(column);
  }
  if (!key.empty()) out += (out.empty() ? "" : ": ") + std::string("'") + key + "'";
  if (!out.empty()) out += ": ";
  return out;
}

Error::Error(const std::string& message, ErrorContext context)
    : std::runtime_error(context.prefix() + message), context_(std::move(context)), bare_(message) {}

}  // namespace roe
