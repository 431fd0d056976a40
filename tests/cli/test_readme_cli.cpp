// The README's runnable code blocks, run as written: each fenced block preceded by the line
// `<!-- runnable -->` is executed with bash (`set -euo pipefail`), in order, in one scratch folder
// outside the repository, with only the built `roe` added to PATH. A block that stops working fails
// this test with its README line and output. Only blocks that work on data the repository ships or
// generates are marked (docs/TESTING.md).
#include <sys/wait.h>

#include <array>
#include <catch2/catch.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "support/test_util.hpp"

namespace fs = std::filesystem;

namespace {

struct Block {
  int line = 0;  ///< 1-based README line of the opening fence
  std::string code;
};

/// The blocks marked runnable: `<!-- runnable -->` on the line before a ``` fence (any info string).
std::vector<Block> runnable_blocks(const std::string& text) {
  std::vector<Block> out;
  std::istringstream in(text);
  std::string line;
  int n = 0;
  bool marked = false;
  Block* open = nullptr;
  while (std::getline(in, line)) {
    ++n;
    if (open) {
      if (line.rfind("```", 0) == 0) {
        open = nullptr;
        continue;
      }
      open->code += line + "\n";
      continue;
    }
    if (line.rfind("```", 0) == 0 && marked) {
      out.push_back({n, ""});
      open = &out.back();
    }
    marked = line == "<!-- runnable -->";
  }
  return out;
}

std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

}  // namespace

TEST_CASE("runnable_blocks finds the marked fences only", "[cli][readme]") {
  const auto b = runnable_blocks("x\n```sh\nnot me\n```\n<!-- runnable -->\n```sh\na\nb\n```\n<!-- runnable -->\n\n```\nno\n```\n");
  REQUIRE(b.size() == 1);
  CHECK(b[0].line == 6);
  CHECK(b[0].code == "a\nb\n");
}

TEST_CASE("README: every block marked runnable runs as written from an empty folder", "[cli][readme]") {
  std::ifstream f(std::string(ROE_SOURCE_DIR) + "/README.md");
  REQUIRE(f);
  const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  const auto blocks = runnable_blocks(text);
  REQUIRE(blocks.size() >= 1);  // the main path is marked: an unmarked README would test nothing
  roe::test::TempDir scratch("roe_readme");
  const std::string bin_dir = fs::path(ROE_BINARY).parent_path().string();
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    const fs::path script = scratch.write("block" + std::to_string(i + 1) + ".sh",
                                          "set -euo pipefail\n" + blocks[i].code);
    const std::string cmd = "cd " + shell_quote(scratch.path.string()) + " && PATH=" + shell_quote(bin_dir) +
                            ":/usr/bin:/bin bash " + shell_quote(script.string()) + " 2>&1";
    FILE* p = popen(cmd.c_str(), "r");
    REQUIRE(p != nullptr);
    std::string out;
    std::array<char, 4096> buf;
    std::size_t n;
    while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) out.append(buf.data(), n);
    const int status = pclose(p);
    INFO("README.md line " << blocks[i].line << ":\n" << blocks[i].code << "--- output ---\n" << out);
    CHECK((WIFEXITED(status) && WEXITSTATUS(status) == 0));
  }
}
