// Nothing outside --out (issue 40): every call in src/ that removes or renames a path says why that path
// cannot have been steered by a file the user edits (a job id of jobs.jsonl, a name in roe.json, a path
// in metadata.yaml). A call site carries a `path-checked:` comment on its line or on one of the three
// lines above it, naming the check; the files below are exempt as a whole, each for the reason given.
// A new remove/rename without such a note fails this test, so the question is asked at review time.
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

/// Files whose removals and renames touch only paths the process itself made.
const std::map<std::string, std::string>& exempt_files() {
  static const std::map<std::string, std::string> m = {
      {"src/io/output.cpp",
       "the atomic-output machinery: it removes and renames only the temporaries and backups it named itself "
       "(.NAME.tmp-HOST-PID-..., .NAME.old) beside an output the command was given"},
      {"src/app/figures.cpp", "removes the plotting script it wrote into a temporary folder it created"},
  };
  return m;
}

std::vector<std::string> lines_of(const fs::path& f) {
  std::ifstream in(f);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  return lines;
}

}  // namespace

TEST_CASE("path safety: every remove or rename in src names the check of its path", "[io][hostile][paths]") {
  const fs::path root = ROE_SOURCE_DIR;
  // Qualified calls only (fs::remove_all, std::filesystem::rename, ::unlink, std::remove(path)):
  // an unqualified `remove(` is a local lambda or an algorithm, not the file system.
  const std::regex call(R"((fs::|std::filesystem::|std::|::)(remove_all|remove|rename|unlink|unlinkat|rmdir)\s*\()");
  std::vector<std::string> unchecked;
  std::size_t checked = 0;
  for (const auto& e : fs::recursive_directory_iterator(root / "src")) {
    if (!e.is_regular_file() || (e.path().extension() != ".cpp" && e.path().extension() != ".hpp")) continue;
    const std::string rel = fs::relative(e.path(), root).generic_string();
    if (exempt_files().count(rel)) continue;
    const auto lines = lines_of(e.path());
    for (std::size_t i = 0; i < lines.size(); ++i) {
      const std::string code = lines[i].substr(0, lines[i].find("//"));
      std::smatch m;
      if (!std::regex_search(code, m, call)) continue;
      if (m[1] == "std::" && m[2] == "remove" && code.find("std::remove(", 0) != std::string::npos &&
          code.find("erase(") != std::string::npos)
        continue;  // the erase-remove idiom (an algorithm)
      bool noted = false;
      for (std::size_t k = i >= 3 ? i - 3 : 0; k <= i && !noted; ++k)
        noted = lines[k].find("path-checked:") != std::string::npos;
      if (noted)
        ++checked;
      else
        unchecked.push_back(rel + ":" + std::to_string(i + 1) + ": " + lines[i]);
    }
  }
  INFO("remove/rename calls without a `path-checked:` note (say why a user-edited file cannot steer the path, "
       "or check it first):\n" +
       [&] {
         std::string s;
         for (const auto& u : unchecked) s += "  " + u + "\n";
         return s;
       }());
  CHECK(unchecked.empty());
  CHECK(checked >= 4);  // the sweep runner's and the bag reader's calls are found at all
}
