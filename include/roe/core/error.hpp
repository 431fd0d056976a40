#pragma once
/// @file
/// The roe error hierarchy. Library code throws these; only src/cli turns them into messages and
/// exit codes (DESIGN §1): InputError → 2, DataError → 1, everything else → 3.

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>

namespace roe {

/// Where in an input an error was found. Empty/zero fields are omitted from the message.
struct ErrorContext {
  std::string file;         ///< path of the file (or a logical source name)
  std::int64_t line = 0;    ///< 1-based line (or row) number, 0 when not applicable
  std::int64_t column = 0;  ///< 1-based column number, 0 when not applicable
  std::string key;          ///< JSON key path or column name, when applicable

  ErrorContext() = default;
  ErrorContext(std::string file_in, std::int64_t line_in = 0, std::int64_t column_in = 0,
               std::string key_in = {})
      : file(std::move(file_in)), line(line_in), column(column_in), key(std::move(key_in)) {}

  /// "file:line:column: " (or the parts that are set), ready to prefix a message.
  std::string prefix() const;
};

/// Base of every error roe throws on purpose.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message, ErrorContext context = {});
  const ErrorContext& context() const noexcept { return context_; }
  /// The message without the location prefix.
  const std::string& bare_message() const noexcept { return bare_; }

 private:
  ErrorContext context_;
  std::string bare_;
};

/// Bad usage or bad input: unreadable file, malformed row, unknown key, inconsistent options.
/// The CLI exits with code 2.
class InputError : public Error {
 public:
  using Error::Error;
};

/// A configuration (JSON) error: unknown key, wrong type, out-of-range value. Exit code 2.
class ConfigError : public InputError {
 public:
  using InputError::InputError;
};

/// The run failed for a reason in the data (e.g. filter divergence, no usable measurement).
/// The CLI exits with code 1.
class DataError : public Error {
 public:
  using Error::Error;
};

/// A numerical failure (non-finite or non-PD covariance, state out of bounds). Exit code 1.
class NumericError : public DataError {
 public:
  using DataError::DataError;
};

/// A broken internal invariant (a bug in roe). Exit code 3.
class InternalError : public Error {
 public:
  using Error::Error;
};

}  // namespace roe

/// Always-on invariant check: throws roe::InternalError naming the source location.
#define ROE_CHECK(cond, msg)                                                                 \
  do {                                                                                       \
    if (!(cond)) {                                                                           \
      throw ::roe::InternalError(std::string("check failed: ") + #cond + ": " + (msg) +      \
                                 " (" + __FILE__ + ":" + std::to_string(__LINE__) + ")"); \
    }                                                                                        \
  } while (0)
