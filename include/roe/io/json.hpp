#pragma once
/// @file
/// Strict JSON reading for configuration and manifests: parse errors carry line and column, unknown
/// keys are errors (ConfigError naming the file and the key path), types are checked.
///
/// Typical use for an options struct:
///   roe::io::JsonObject r(j, "configs/default.json", "filter");
///   r.get("chi2_confidence", opt.chi2_confidence);   // optional: keeps the inline default
///   r.require("name", opt.name);                      // required
///   auto n = r.child("noise"); n.get(...); n.finish();
///   r.finish();                                       // throws on any key not read

#include <fmt/format.h>

#include <cstdint>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <memory>
#include <string>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

#include "roe/core/error.hpp"
#include "roe/io/input.hpp"

namespace roe::io {

using json = nlohmann::json;

/// Parses a JSON file; roe::InputError with line:column on a syntax error.
json parse_json_file(const std::filesystem::path& path);
/// Parses JSON text; `source` names it in errors.
json parse_json_text(const std::string& text, const std::string& source);

/// The text of an nlohmann::json exception without its "[json.exception.type_error.302] " tag, for a message a
/// user reads ("type must be number, but is null").
std::string json_error_text(const std::exception& e);
/// Where the value at `key_path` ("camera.fx", "objects[2].T_W_O.q") is in the JSON `text`: the 1-based
/// line and column of its key (object members) or of the element itself (array elements); {0, 0}
/// when the path is not in the text. With `last_occurrence`, a key given twice in its object is found at
/// its last occurrence. Linear in the text's size; `text` need not be valid beyond the path.
std::pair<std::int64_t, std::int64_t> json_key_location(std::string_view text, const std::string& key_path,
                                                        bool last_occurrence = false);

/// Gives the errors of a reader their line and column: runs `fn()`, and an roe::InputError (ConfigError
/// included) that names `source` and a key path but no line is thrown again, same type, with the line and
/// column of that key in `text` (json_key_location), or of its nearest ancestor when the key is absent. Every semantic check that throws with the key path
/// (a wrong type, an unknown key, fx = 0, a non-unit quaternion) is located this way, in one place.
template <typename Fn>
decltype(auto) with_json_locations(const std::string& text, const std::string& source, Fn&& fn) {
  const auto located = [&](const InputError& e) {
    ErrorContext c = e.context();
    if (c.file != source || c.line != 0 || c.key.empty()) return c;
    // A key that is not in the text (a missing required key) is located at its nearest ancestor.
    for (std::string path = c.key; !path.empty() && c.line == 0;) {
      std::tie(c.line, c.column) = json_key_location(text, path);
      const std::size_t cut = path.find_last_of(".[");
      path = cut == std::string::npos ? std::string() : path.substr(0, cut);
    }
    return c;
  };
  try {
    return fn();
  } catch (const ConfigError& e) {
    throw ConfigError(e.bare_message(), located(e));
  } catch (const InputError& e) {
    throw InputError(e.bare_message(), located(e));
  }
}

/// Reads a JSON file with `from_json(const json&, const std::string& source)`, errors located as by
/// with_json_locations: the one call a strict config or manifest reader needs.
template <typename FromJson>
auto read_json_file(const std::filesystem::path& path, FromJson&& from_json) {
  const std::string text = read_file(path), source = path.string();
  return with_json_locations(text, source, [&] { return from_json(parse_json_text(text, source), source); });
}

/// Serialises `j` (indent < 0: one line). Strings that are not valid UTF-8 — a path or a name from a
/// file in a legacy encoding — are written with U+FFFD in place of the invalid bytes instead of
/// throwing, so that no output or summary fails on them.
std::string dump_json(const json& j, int indent = -1);

class JsonObject {
 public:
  /// `source` is the file name, `path` the key path of this object ("" for the root).
  JsonObject(const json& j, std::string source, std::string path = "");

  bool has(const char* key) const;
  /// Reads an optional key into `out` (left unchanged when absent). Type errors throw ConfigError.
  template <typename T>
  void get(const char* key, T& out) {
    mark(key);
    auto it = j_->find(key);
    if (it == j_->end() || it->is_null()) return;
    convert(*it, key, out);
  }
  /// Reads a required key; ConfigError when absent.
  template <typename T>
  void require(const char* key, T& out) {
    if (!has(key)) throw ConfigError("missing required key", {source_, 0, 0, key_path(key)});
    get(key, out);
  }
  /// A nested object (ConfigError if the value is not an object). Absent → an empty object.
  JsonObject child(const char* key);
  /// The raw value of a key (marks it as read); nullptr when absent.
  const json* raw(const char* key);
  /// Throws ConfigError naming the first key that was never read, with a suggestion: the same key where
  /// the reader does read it (`filter.smoother` → the top-level `smoother`), or a known key of this
  /// object one or two edits away. An object from child() defers its unknown key to its root's
  /// finish(), when every level's keys are known (so the root's finish() must be called).
  void finish() const;

  const std::string& source() const { return source_; }
  std::string key_path(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }

 private:
  void mark(const char* key);
  template <typename T>
  void convert(const json& v, const char* key, T& out) const {
    try {
      if constexpr (std::is_same_v<T, double> || std::is_same_v<T, float>) {
        if (!v.is_number()) throw ConfigError("expected a number", {source_, 0, 0, key_path(key)});
      } else if constexpr (std::is_same_v<T, bool>) {
        if (!v.is_boolean()) throw ConfigError("expected true or false", {source_, 0, 0, key_path(key)});
      } else if constexpr (std::is_integral_v<T>) {
        if (!v.is_number_integer())
          throw ConfigError("expected an integer", {source_, 0, 0, key_path(key)});
        // Range-checked here, at the read: get<T>() would wrap 10^12 into an int silently.
        const bool fits = v.is_number_unsigned()
                              ? v.get<std::uint64_t>() <= static_cast<std::uint64_t>(std::numeric_limits<T>::max())
                              : v.get<std::int64_t>() >= static_cast<std::int64_t>(std::numeric_limits<T>::min()) &&
                                    (std::is_unsigned_v<T> ||
                                     v.get<std::int64_t>() <= static_cast<std::int64_t>(std::numeric_limits<T>::max()));
        if (!fits)
          throw ConfigError(fmt::format("integer out of range ({} to {})", std::numeric_limits<T>::min(),
                                        std::numeric_limits<T>::max()),
                            {source_, 0, 0, key_path(key)});
      } else if constexpr (std::is_same_v<T, std::string>) {
        if (!v.is_string()) throw ConfigError("expected a string", {source_, 0, 0, key_path(key)});
      }
      out = v.get<T>();
    } catch (const json::exception& e) {
      throw ConfigError(std::string("wrong type: ") + e.what(), {source_, 0, 0, key_path(key)});
    }
  }

  /// What the objects read from one document share: every (object path, key) read so far, and the
  /// first unknown key a child found.
  struct Tree {
    std::vector<std::pair<std::string, std::string>> known;
    std::string pending_path, pending_key;
  };
  [[noreturn]] void throw_unknown(const std::string& path, const std::string& key) const;

  const json* j_;
  std::string source_;
  std::string path_;
  std::vector<std::string> read_;
  json empty_;
  std::shared_ptr<Tree> tree_ = std::make_shared<Tree>();
  bool is_child_ = false;
};

}  // namespace roe::io
