#pragma once
/// @file
/// The floors of roe (DESIGN §5, docs/architecture.md "The floors"): one table, ground floor first, of each
/// room, the files that make it and what its files may include; and the checker the layering tests run over
/// (file, includes) lists, the real tree's (`scan`) or a copy with a forbidden include added (issue 52).

#include <filesystem>
#include <string>
#include <vector>

namespace roe::test::floors {

struct Room {
  std::string name;  ///< "io/ros"
  /// Where its files are, relative to the source root: a folder ("src/io/ros/"), a name prefix
  /// ("src/app/refine*") or one file ("include/roe/core/error.hpp"). The longest pattern that matches a file
  /// decides its room; a header `roe/X` is the file `include/roe/X`.
  std::vector<std::string> files;
  /// What its files may include besides their own room: rooms listed above it in the table ("ekf"), or
  /// single headers of such a room ("roe/io/input.hpp").
  std::vector<std::string> floors;
  /// The third-party and system headers its files never include, by group of `groups()` ("JSON").
  std::vector<std::string> never;
};

/// The table (tests/core/floors.cpp).
const std::vector<Room>& table();

/// A group of third-party or system headers: each of `headers` is one header ("fstream") or, ending in '/',
/// every header of a folder ("torch/").
struct HeaderGroup {
  std::string name;                  ///< "LibTorch"
  std::vector<std::string> headers;  ///< "torch/", "ATen/", "c10/"
};
const std::vector<HeaderGroup>& groups();

struct Include {
  int line = 0;
  std::string header;   ///< as written: "roe/io/json.hpp", "command.hpp", "vector"
  bool quoted = false;  ///< "…" rather than <…>
};
struct SourceFile {
  std::string path;  ///< relative to the source root, '/'-separated: "src/io/ros/mcap.cpp"
  std::vector<Include> includes;
};

/// Every file under `root`/src and `root`/include/roe (sorted by path) with each of its #include lines.
std::vector<SourceFile> scan(const std::filesystem::path& root);

/// The room of a path relative to the source root; empty when no room's files match it.
std::string room_of(const std::vector<Room>& table, const std::string& path);

/// One line per include that breaks the table, "FILE:LINE: #include \"HEADER\": WHY": a roe header of a
/// room that is not on the file's floors, a roe header of no room, a quoted include of another folder
/// (anything but a file beside the includer), a header of a group the room never includes; and one per file
/// in no room ("FILE: in no room of the floors").
std::vector<std::string> check(const std::vector<Room>& table, const std::vector<SourceFile>& files);

/// What is wrong with the table itself: a repeated room, a floor that names no room, a room or header that
/// is not listed above the room that stands on it (the table must read from the ground up), a group that
/// `groups()` does not define.
std::vector<std::string> check_table(const std::vector<Room>& table);

/// The table and the header groups as docs/architecture.md shows them (two Markdown tables).
std::string markdown(const std::vector<Room>& table);

}  // namespace roe::test::floors
