#include "roe/io/json.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <set>
#include <string>
#include <tuple>
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

// A cursor over JSON text for json_key_location: finds members and elements without building a tree.
struct JsonCursor {
  std::string_view t;
  std::size_t i = 0;

  bool done() const { return i >= t.size(); }
  void skip_space() {
    while (i < t.size() && std::isspace(static_cast<unsigned char>(t[i]))) ++i;
  }
  // At '"': reads the string (escapes other than \uXXXX decoded), leaves i after the closing quote.
  bool read_string(std::string& out) {
    out.clear();
    if (done() || t[i] != '"') return false;
    for (++i; i < t.size(); ++i) {
      const char c = t[i];
      if (c == '"') {
        ++i;
        return true;
      }
      if (c == '\\' && i + 1 < t.size()) {
        const char e = t[++i];
        out += e == 'n' ? '\n' : e == 't' ? '\t' : e == 'r' ? '\r' : e == 'b' ? '\b' : e == 'f' ? '\f' : e;
        continue;
      }
      out += c;
    }
    return false;
  }
  // Skips one value (any nesting depth, iteratively); leaves i after it.
  bool skip_value() {
    skip_space();
    int depth = 0;
    std::string ignored;
    while (!done()) {
      const char c = t[i];
      if (c == '"') {
        if (!read_string(ignored)) return false;
      } else if (c == '{' || c == '[') {
        ++depth;
        ++i;
      } else if (c == '}' || c == ']') {
        if (depth == 0) return true;  // the end of the enclosing container
        --depth;
        ++i;
      } else if (c == ',' || std::isspace(static_cast<unsigned char>(c))) {
        if (depth == 0) return true;
        ++i;
      } else {
        ++i;
      }
      if (depth == 0 && (c == '"' || c == '}' || c == ']')) return true;
    }
    return depth == 0;
  }
  // At '{': moves to the value of member `key` (its last occurrence when `last`); returns the offset of
  // its key, or npos.
  std::size_t find_member(const std::string& key, bool last) {
    skip_space();
    if (done() || t[i] != '{') return std::string_view::npos;
    ++i;
    std::string k;
    std::size_t found = std::string_view::npos, value = 0;
    while (true) {
      skip_space();
      const std::size_t at = i;
      if (!read_string(k)) break;
      skip_space();
      if (done() || t[i] != ':') break;
      ++i;
      skip_space();
      if (k == key) {
        found = at;
        value = i;
        if (!last) break;
      }
      if (!skip_value()) break;
      skip_space();
      if (done() || t[i] != ',') break;
      ++i;
    }
    if (found != std::string_view::npos) i = value;
    return found;
  }
  // At '[': moves to element `index`; returns its offset, or npos.
  std::size_t find_element(std::size_t index) {
    skip_space();
    if (done() || t[i] != '[') return std::string_view::npos;
    ++i;
    for (std::size_t k = 0;; ++k) {
      skip_space();
      if (done() || t[i] == ']') return std::string_view::npos;
      if (k == index) return i;
      if (!skip_value()) return std::string_view::npos;
      skip_space();
      if (done() || t[i] != ',') return std::string_view::npos;
      ++i;
    }
  }
};

}  // namespace

std::pair<std::int64_t, std::int64_t> json_key_location(std::string_view text, const std::string& key_path,
                                                        bool last_occurrence) {
  if (key_path.empty() || key_path == "<root>") return {0, 0};
  JsonCursor cur{text};
  cur.i = utf8_bom_length(text);
  std::size_t at = std::string_view::npos;
  for (std::size_t p = 0; p < key_path.size();) {
    if (key_path[p] == '[') {
      const std::size_t close = key_path.find(']', p);
      if (close == std::string::npos) return {0, 0};
      std::size_t index = 0;
      for (std::size_t k = p + 1; k < close; ++k) {
        if (!std::isdigit(static_cast<unsigned char>(key_path[k]))) return {0, 0};
        index = index * 10 + static_cast<std::size_t>(key_path[k] - '0');
      }
      at = cur.find_element(index);
      p = close + 1;
    } else {
      if (key_path[p] == '.') ++p;
      const std::size_t start = p, end = key_path.find_first_of(".[", p);
      p = end == std::string::npos ? key_path.size() : end;
      at = cur.find_member(key_path.substr(start, p - start), last_occurrence && p == key_path.size());
    }
    if (at == std::string_view::npos) return {0, 0};
  }
  std::int64_t line = 0, col = 0;
  line_col(std::string(text.substr(0, at)), at, line, col);
  return {line, col};
}

namespace {
json parse_json_unlocated(const std::string& text, const std::string& source) {
  // A key given twice in one object is an error (nlohmann keeps the last one silently, which hides a
  // mistyped config). Tracked with the parser's events: one frame per open object or array, with the
  // keys seen (objects) or the index of the next element (arrays), for the key path of the error.
  struct Frame {
    bool array = false;
    std::string segment;  ///< "name" under an object, "[i]" under an array, "" for the root
    int next = 0;         ///< arrays: index of the next element
    std::set<std::string> keys;
  };
  std::vector<Frame> open;
  std::string last_key;
  const auto path_of = [&](const std::string& key) {
    std::string where;
    for (const auto& f : open) {
      if (f.segment.empty()) continue;
      where += (where.empty() || f.segment[0] == '[' ? "" : ".") + f.segment;
    }
    return where + (where.empty() ? "" : ".") + key;
  };
  const json::parser_callback_t check = [&](int, json::parse_event_t ev, json& parsed) {
    switch (ev) {
      case json::parse_event_t::object_start:
      case json::parse_event_t::array_start: {
        Frame f;
        f.array = ev == json::parse_event_t::array_start;
        if (!open.empty()) f.segment = open.back().array ? "[" + std::to_string(open.back().next++) + "]" : last_key;
        open.push_back(std::move(f));
        last_key.clear();
        break;
      }
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        if (!open.empty()) open.pop_back();
        last_key.clear();
        break;
      case json::parse_event_t::key:
        last_key = parsed.get<std::string>();
        if (!open.empty() && !open.back().keys.insert(last_key).second)
          throw ConfigError("key \"" + last_key + "\" appears twice in the same object",
                            {source, 0, 0, path_of(last_key)});
        break;
      case json::parse_event_t::value:
        if (!open.empty() && open.back().array) ++open.back().next;
        last_key.clear();
        break;
    }
    return true;
  };
  try {
    return json::parse(text, check);
  } catch (const json::out_of_range& e) {
    // A number beyond double's range (1e999): nlohmann names the token but not its position; the
    // first place it appears as a number is where it is.
    std::string msg = e.what();
    const auto a = msg.find('\''), b = msg.rfind('\'');
    std::int64_t line = 0, col = 0;
    if (a != std::string::npos && b > a + 1) {
      const std::string token = msg.substr(a + 1, b - a - 1);
      bool in_string = false;
      for (std::size_t i = 0; i < text.size(); ++i) {
        const char c = text[i];
        if (in_string) {
          if (c == '\\') ++i;  // skip the escaped character
          else if (c == '"') in_string = false;
          continue;
        }
        if (c == '"') {
          in_string = true;
          continue;
        }
        if (text.compare(i, token.size(), token) == 0) {
          const char before = i ? text[i - 1] : ' ';
          if (before == ':' || before == ',' || before == '[' || std::isspace(static_cast<unsigned char>(before))) {
            line_col(text, i, line, col);
            break;
          }
        }
      }
      throw InputError("number out of range: " + token, {source, line, col});
    }
    throw InputError("invalid JSON: " + msg, {source});
  } catch (const json::parse_error& e) {
    std::int64_t line = 0, col = 0;
    line_col(text, e.byte > 0 ? e.byte - 1 : 0, line, col);
    std::string msg = e.what();
    const auto pos = msg.find("parse error");
    throw InputError("invalid JSON: " + (pos == std::string::npos ? msg : msg.substr(pos)),
                     {source, line, col});
  }
}

}  // namespace

std::string json_error_text(const std::exception& e) {
  const std::string m = e.what();
  if (m.rfind("[json.exception.", 0) != 0) return m;
  const auto end = m.find("] ");
  return end == std::string::npos ? m : m.substr(end + 2);
}

json parse_json_text(const std::string& text, const std::string& source) {
  try {
    return parse_json_unlocated(text, source);
  } catch (const ConfigError& e) {  // a key given twice: located at its second occurrence
    ErrorContext c = e.context();
    if (c.line == 0 && !c.key.empty()) std::tie(c.line, c.column) = json_key_location(text, c.key, true);
    throw ConfigError(e.bare_message(), c);
  }
}

std::string dump_json(const json& j, int indent) {
  return j.dump(indent, ' ', false, json::error_handler_t::replace);
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
  if (std::find(read_.begin(), read_.end(), key) != read_.end()) return;
  read_.emplace_back(key);
  tree_->known.emplace_back(path_, key);
}

JsonObject JsonObject::child(const char* key) {
  mark(key);
  auto it = j_->find(key);
  if (!(it == j_->end() || it->is_null()) && !it->is_object())
    throw ConfigError("expected a JSON object", {source_, 0, 0, key_path(key)});
  JsonObject c(it == j_->end() || it->is_null() ? empty_ : *it, source_, key_path(key));
  c.tree_ = tree_;
  c.is_child_ = true;
  return c;
}

const json* JsonObject::raw(const char* key) {
  mark(key);
  auto it = j_->find(key);
  return it == j_->end() ? nullptr : &*it;
}

namespace {
/// Levenshtein distance, capped at 3 (only 1 and 2 are suggested).
int edit_distance(const std::string& a, const std::string& b) {
  if (a.size() > b.size() + 2 || b.size() > a.size() + 2) return 3;
  std::vector<int> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = static_cast<int>(j);
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = static_cast<int>(i);
    for (std::size_t j = 1; j <= b.size(); ++j)
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
    std::swap(prev, cur);
  }
  return std::min(prev[b.size()], 3);
}
}  // namespace

void JsonObject::throw_unknown(const std::string& path, const std::string& key) const {
  const std::string full = path.empty() ? key : path + "." + key;
  std::string hint;
  for (const auto& [p, k] : tree_->known)  // the same key where the reader reads it
    if (k == key && p != path) {
      hint = p.empty() ? fmt::format(" (did you mean the top-level \"{}\"?)", k)
                       : fmt::format(" (did you mean \"{}.{}\"?)", p, k);
      break;
    }
  int best = 3;
  for (const auto& [p, k] : tree_->known)  // a typo of a key of the same object
    if (hint.empty() && p == path && edit_distance(k, key) < best) best = edit_distance(k, key), hint = k;
  if (best < 3) hint = fmt::format(" (did you mean \"{}\"?)", path.empty() ? hint : path + "." + hint);
  throw ConfigError("unknown key" + hint, {source_, 0, 0, full});
}

void JsonObject::finish() const {
  if (!is_child_ && !tree_->pending_key.empty()) throw_unknown(tree_->pending_path, tree_->pending_key);
  for (auto it = j_->begin(); it != j_->end(); ++it) {
    if (std::find(read_.begin(), read_.end(), it.key()) != read_.end()) continue;
    if (!is_child_) throw_unknown(path_, it.key());
    if (tree_->pending_key.empty()) tree_->pending_path = path_, tree_->pending_key = it.key();
    return;
  }
}

}  // namespace roe::io
