// rosbag2 SQLite storage and metadata.yaml (include/roe/io/ros/rosbag2.hpp).
#include "roe/io/ros/rosbag2.hpp"

#include <sqlite3.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <map>

#include <fmt/format.h>

#include "roe/core/error.hpp"

namespace roe::io::rosbag2 {

struct SqliteReader::Db {
  sqlite3* h = nullptr;
  ~Db() {
    if (h) sqlite3_close(h);
  }
};

namespace {

struct Stmt {
  sqlite3_stmt* s = nullptr;
  ~Stmt() {
    if (s) sqlite3_finalize(s);
  }
};

/// A path as an SQLite URI path ('%', '?' and '#' escaped).
std::string uri_path(const fs::path& p) {
  std::string out;
  for (char c : fs::absolute(p).string()) {
    if (c == '%') out += "%25";
    else if (c == '?') out += "%3f";
    else if (c == '#') out += "%23";
    else out += c;
  }
  return out;
}

std::string column_text(sqlite3_stmt* s, int i) {
  const unsigned char* t = sqlite3_column_text(s, i);
  return t ? std::string(reinterpret_cast<const char*>(t), static_cast<std::size_t>(sqlite3_column_bytes(s, i)))
           : std::string();
}

}  // namespace

SqliteReader::SqliteReader(const fs::path& file) : db_(std::make_unique<Db>()), name_(file.string()) {
  const std::string uri = "file:" + uri_path(file) + "?immutable=1";
  if (sqlite3_open_v2(uri.c_str(), &db_->h, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI, nullptr) != SQLITE_OK)
    throw InputError(std::string("cannot open the SQLite database: ") + sqlite3_errmsg(db_->h), {name_});
  const auto query = [&](const std::string& sql, const std::function<void(sqlite3_stmt*)>& row, const char* table) {
    Stmt st;
    if (sqlite3_prepare_v2(db_->h, sql.c_str(), -1, &st.s, nullptr) != SQLITE_OK)
      throw InputError(fmt::format("not a readable rosbag2 database (table {}: {})", table, sqlite3_errmsg(db_->h)),
                       {name_});
    int rc;
    while ((rc = sqlite3_step(st.s)) == SQLITE_ROW) row(st.s);
    if (rc != SQLITE_DONE)
      throw InputError(fmt::format("not a readable rosbag2 database (table {}: {})", table, sqlite3_errmsg(db_->h)),
                       {name_});
  };
  std::set<std::string> tables;
  query("SELECT name FROM sqlite_master WHERE type='table'", [&](sqlite3_stmt* s) { tables.insert(column_text(s, 0)); },
        "sqlite_master");
  if (!tables.count("topics") || !tables.count("messages")) {
    std::string list;
    for (const auto& t : tables) list += (list.empty() ? "" : ", ") + t;
    throw InputError("an SQLite database but not a rosbag2 bag: it has no topics and messages tables (tables: " +
                         (list.empty() ? std::string("none") : list) + ")",
                     {name_});
  }
  const auto columns = [&](const char* table) {
    std::set<std::string> c;
    query(std::string("PRAGMA table_info(") + table + ")", [&](sqlite3_stmt* s) { c.insert(column_text(s, 1)); },
          table);
    return c;
  };
  const auto tc = columns("topics"), mc = columns("messages");
  for (const char* k : {"id", "name", "type", "serialization_format"})
    if (!tc.count(k))
      throw InputError(std::string("not a rosbag2 database: table topics has no column ") + k, {name_, 0, 0, "topics"});
  for (const char* k : {"id", "topic_id", "timestamp", "data"})
    if (!mc.count(k))
      throw InputError(std::string("not a rosbag2 database: table messages has no column ") + k,
                       {name_, 0, 0, "messages"});
  if (tables.count("schema"))
    query("SELECT MAX(schema_version) FROM schema", [&](sqlite3_stmt* s) { schema_version_ = sqlite3_column_int(s, 0); },
          "schema");
  std::map<std::int64_t, std::size_t> index;
  query("SELECT id, name, type, serialization_format FROM topics ORDER BY id",
        [&](sqlite3_stmt* s) {
          SqliteTopic t;
          t.id = sqlite3_column_int64(s, 0);
          t.name = column_text(s, 1);
          t.type = column_text(s, 2);
          t.serialization_format = column_text(s, 3);
          index[t.id] = topics_.size();
          topics_.push_back(std::move(t));
        },
        "topics");
  std::uint64_t orphans = 0;
  std::set<std::int64_t> orphan_ids;
  query("SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id",
        [&](sqlite3_stmt* s) {
          const auto it = index.find(sqlite3_column_int64(s, 0));
          const auto n = static_cast<std::uint64_t>(sqlite3_column_int64(s, 1));
          if (it != index.end()) {
            topics_[it->second].count = n;
          } else {
            orphans += n;
            orphan_ids.insert(sqlite3_column_int64(s, 0));
          }
        },
        "messages");
  // Rows no topic claims cannot be decoded (no type): said, not dropped in silence.
  if (orphans > 0)
    warnings_.push_back({0, fmt::format("{} message(s) have a topic_id that no row of table topics has ({}{}): they "
                                        "are skipped",
                                        orphans, *orphan_ids.begin(), orphan_ids.size() > 1 ? ", ..." : "")});
}

SqliteReader::~SqliteReader() = default;

void SqliteReader::for_each(const std::set<std::int64_t>& topic_ids,
                            const std::function<bool(std::int64_t, Timestamp, std::string_view, std::int64_t)>& fn) {
  if (topic_ids.empty()) return;
  std::string in;
  for (auto id : topic_ids) in += (in.empty() ? "" : ",") + std::to_string(id);
  const std::string sql =
      "SELECT id, topic_id, timestamp, data FROM messages WHERE topic_id IN (" + in + ") ORDER BY timestamp, id";
  Stmt st;
  if (sqlite3_prepare_v2(db_->h, sql.c_str(), -1, &st.s, nullptr) != SQLITE_OK) {
    warnings_.push_back({0, std::string("table messages unreadable: ") + sqlite3_errmsg(db_->h)});
    return;
  }
  std::int64_t last = 0;
  int rc;
  while ((rc = sqlite3_step(st.s)) == SQLITE_ROW) {
    last = sqlite3_column_int64(st.s, 0);
    const void* blob = sqlite3_column_blob(st.s, 3);
    const auto n = static_cast<std::size_t>(sqlite3_column_bytes(st.s, 3));
    const std::string_view data(blob ? static_cast<const char*>(blob) : "", blob ? n : 0);
    if (!fn(sqlite3_column_int64(st.s, 1), sqlite3_column_int64(st.s, 2), data, last)) return;
  }
  if (rc != SQLITE_DONE)
    warnings_.push_back({last, std::string("table messages unreadable after this row: ") + sqlite3_errmsg(db_->h) +
                                   "; the rest of the table is skipped"});
}

namespace {
Metadata parse_metadata(const YAML::Node& root, const std::string& name);
}  // namespace

Metadata read_metadata(const fs::path& file) {
  const std::string name = file.string();
  YAML::Node root;
  try {
    root = YAML::LoadFile(name);
  } catch (const YAML::ParserException& e) {
    throw InputError(std::string("malformed YAML: ") + e.msg, {name, e.mark.line + 1, e.mark.column + 1});
  } catch (const YAML::Exception& e) {
    throw InputError(std::string("cannot read: ") + e.what(), {name});
  }
  if (!root.IsMap()) throw InputError("not a rosbag2 metadata.yaml (not a map with rosbag2_bagfile_information)", {name});
  try {
    return parse_metadata(root, name);
  } catch (const YAML::Exception& e) {  // a shape the checks did not foresee (a list where a map belongs)
    throw InputError(std::string("not a rosbag2 metadata.yaml: ") + e.msg, {name, e.mark.line + 1, e.mark.column + 1});
  }
}

namespace {

Metadata parse_metadata(const YAML::Node& root, const std::string& name) {
  const YAML::Node info = root["rosbag2_bagfile_information"];
  if (!info || !info.IsMap())
    throw InputError("not a rosbag2 metadata.yaml (no rosbag2_bagfile_information map)", {name});
  Metadata m;
  const auto key = [&](const YAML::Node& n, const std::string& path) -> YAML::Node {
    if (!n) throw InputError("missing key", {name, 0, 0, path});
    return n;
  };
  const auto scalar = [&](const YAML::Node& n, const std::string& path, auto fallback) {
    using T = decltype(fallback);
    if (!n) return fallback;
    try {
      return n.as<T>();
    } catch (const YAML::Exception&) {
      throw InputError("wrong type", {name, n.Mark().line + 1, n.Mark().column + 1, path});
    }
  };
  const std::string base = "rosbag2_bagfile_information.";
  m.version = scalar(info["version"], base + "version", 0);
  m.storage_identifier = scalar(info["storage_identifier"], base + "storage_identifier", std::string());
  m.compression_format = scalar(info["compression_format"], base + "compression_format", std::string());
  m.compression_mode = scalar(info["compression_mode"], base + "compression_mode", std::string());
  m.message_count = scalar(info["message_count"], base + "message_count", std::uint64_t{0});
  const YAML::Node files = key(info["relative_file_paths"], base + "relative_file_paths");
  if (!files.IsSequence() || files.size() == 0)
    throw InputError("must be a non-empty list of files", {name, 0, 0, base + "relative_file_paths"});
  for (std::size_t i = 0; i < files.size(); ++i) {
    const std::string path = base + "relative_file_paths[" + std::to_string(i) + "]";
    const std::string f = scalar(files[i], path, std::string());
    const fs::path p(f);
    if (f.empty() || p.is_absolute() || std::any_of(p.begin(), p.end(), [](const fs::path& c) { return c == ".."; }))
      throw InputError("\"" + f + "\" is not a file inside the bag folder", {name, 0, 0, path});
    m.relative_file_paths.push_back(f);
  }
  if (const YAML::Node topics = info["topics_with_message_count"]; topics && topics.IsSequence()) {
    for (std::size_t i = 0; i < topics.size(); ++i) {
      const std::string path = base + "topics_with_message_count[" + std::to_string(i) + "]";
      const YAML::Node tm = key(topics[i]["topic_metadata"], path + ".topic_metadata");
      Metadata::Topic t;
      t.name = scalar(tm["name"], path + ".topic_metadata.name", std::string());
      t.type = scalar(tm["type"], path + ".topic_metadata.type", std::string());
      t.serialization_format = scalar(tm["serialization_format"], path + ".topic_metadata.serialization_format",
                                      std::string());
      t.count = scalar(topics[i]["message_count"], path + ".message_count", std::uint64_t{0});
      m.topics.push_back(std::move(t));
    }
  }
  if (m.compression_format != "" && m.compression_format != "zstd")
    throw InputError("unknown compression format \"" + m.compression_format + "\" (roe reads \"\" and zstd)",
                     {name, 0, 0, base + "compression_format"});
  std::string mode = m.compression_mode;
  std::transform(mode.begin(), mode.end(), mode.begin(), [](unsigned char c) { return std::toupper(c); });
  if (mode != "" && mode != "NONE" && mode != "FILE" && mode != "MESSAGE")
    throw InputError("unknown compression mode \"" + m.compression_mode + "\" (\"\", FILE or MESSAGE)",
                     {name, 0, 0, base + "compression_mode"});
  m.compression_mode = mode == "NONE" ? "" : mode;
  if (m.compression_format.empty() != m.compression_mode.empty())
    throw InputError("compression_format \"" + m.compression_format + "\" and compression_mode \"" +
                         m.compression_mode + "\" contradict each other (both empty, or zstd with FILE or MESSAGE)",
                     {name, 0, 0, base + "compression_mode"});
  return m;
}

}  // namespace

}  // namespace roe::io::rosbag2
