#include "roe/io/json.hpp"

#include <algorithm>
#include <set>
#include <string>
#include <vector>

#include "roe/io/output.hpp"

namespace roe::io {
namespace {
// Converts a byte offset into 1-based line and column.
void line_col(const std::string& text, std::size_t byte, std::int64_t& line, std::int64_t& col) {
  line = 1;
  col = 1;
  for (std::size_t i = 0; i < byte && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++line;
      col = 1;
    } else {
      ++col;
    }
  }
}
}  // namespace

json parse_json_text(const std::string& text, const std::string& source) {
  // A key given twice in one object is an error (nlohmann keeps the last one silently, which hides a
  // mistyped config). Tracked with the parser's events: one key set per open object.
  std::vector<std::set<std::string>> keys;
  std::vector<std::string> path;  // the key of each open object/array ("" for an array element / root)
  std::string last_key;
  const json::parser_callback_t check = [&](int, json::parse_event_t ev, json& parsed) {
    switch (ev) {
      case json::parse_event_t::object_start:
      case json::parse_event_t::array_start:
        path.push_back(last_key);
        last_key.clear();
        if (ev == json::parse_event_t::object_start) keys.emplace_back();
        break;
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        if (ev == json::parse_event_t::object_end && !keys.empty()) keys.pop_back();
        if (!path.empty()) path.pop_back();
        last_key.clear();
        break;
      case json::parse_event_t::key:
        last_key = parsed.get<std::string>();
        if (!keys.empty() && !keys.back().insert(last_key).second) {
          std::string where;
          for (const auto& p : path)
            if (!p.empty()) where += (where.empty() ? "" : ".") + p;
          where += (where.empty() ? "" : ".") + last_key;
          throw ConfigError("key \"" + last_key + "\" appears twice in the same object", {source, 0, 0, where});
        }
        break;
      case json::parse_event_t::value:
        last_key.clear();
        break;
    }
    return true;
  };
  try {
    return json::parse(text, check);
  } catch (const json::parse_error& e) {
    std::int64_t line = 0, col = 0;
    line_col(text, e.byte > 0 ? e.byte - 1 : 0, line, col);
    std::string msg = e.what();
    const auto pos = msg.find("parse error");
    throw InputError("invalid JSON: " + (pos == std::string::npos ? msg : msg.substr(pos)),
                     {source, line, col});
  }
}

json parse_json_file(const std::filesystem::path& path) {
  return parse_json_text(read_file(path), path.string());
}

JsonObject::JsonObject(const json& j, std::string source, std::string path)
    : j_(&j), source_(std::move(source)), path_(std::move(path)), empty_(json::object()) {
  if (j_->is_null()) j_ = &empty_;
  if (!j_->is_object())
    throw ConfigError("expected a JSON object", {source_, 0, 0, path_.empty() ? "<root>" : path_});
}

bool JsonObject::has(const char* key) const {
  auto it = j_->find(key);
  return it != j_->end() && !it->is_null();
}

void JsonObject::mark(const char* key) {
  if (std::find(read_.begin(), read_.end(), key) == read_.end()) read_.emplace_back(key);
}

JsonObject JsonObject::child(const char* key) {
  mark(key);
  auto it = j_->find(key);
  if (it == j_->end() || it->is_null()) return JsonObject(empty_, source_, key_path(key));
  if (!it->is_object()) throw ConfigError("expected a JSON object", {source_, 0, 0, key_path(key)});
  return JsonObject(*it, source_, key_path(key));
}

const json* JsonObject::raw(const char* key) {
  mark(key);
  auto it = j_->find(key);
  return it == j_->end() ? nullptr : &*it;
}

void JsonObject::finish() const {
  for (auto it = j_->begin(); it != j_->end(); ++it) {
    if (std::find(read_.begin(), read_.end(), it.key()) == read_.end())
      throw ConfigError("unknown key", {source_, 0, 0, key_path(it.key())});
  }
}

}  // namespace roe::io
