// The one output rule (issue 51): an output path that exists and is not a regular file (file outputs) or a
// folder (folder outputs) is refused, with and without force, and left as it was. The special files are made
// here, in a private temporary folder: a FIFO, a unix socket and (as root) a character device node with
// /dev/null's numbers, never the machine's own /dev nodes. Every writing command goes through these classes;
// the hostile catalogue (scripts/hostile-catalogue.py, "output-rule/*") runs each command on each kind.
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/un.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <cstring>
#include <string>
#include <vector>

#include "roe/core/error.hpp"
#include "roe/io/output.hpp"
#include "support/test_util.hpp"

namespace fs = std::filesystem;
using namespace roe;

namespace {

/// Makes a special file of `kind` at `p`; false when this process may not (a device node needs root).
bool make_special(const fs::path& p, const std::string& kind) {
  if (kind == "fifo") return ::mkfifo(p.c_str(), 0600) == 0;
  if (kind == "device") return ::mknod(p.c_str(), S_IFCHR | 0600, makedev(1, 3)) == 0;
  if (kind == "socket") {
    const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    if (fd < 0 || p.string().size() >= sizeof a.sun_path) return false;
    std::strcpy(a.sun_path, p.c_str());
    const bool ok = ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
    ::close(fd);  // the socket's file stays
    return ok;
  }
  if (kind == "symlink-to-device") {
    if (!make_special(p.parent_path() / (p.filename().string() + ".node"), "device")) return false;
    fs::create_symlink(p.filename().string() + ".node", p);
    return true;
  }
  return false;
}

struct Ident {
  ino_t ino;
  mode_t mode;
  dev_t rdev;
  bool operator==(const Ident& o) const { return ino == o.ino && mode == o.mode && rdev == o.rdev; }
};
Ident ident(const fs::path& p) {
  struct stat st {};
  REQUIRE(::stat(p.c_str(), &st) == 0);
  return {st.st_ino, st.st_mode, st.st_rdev};
}

/// Nothing but `keep` and its node in `dir`: no temporary left beside the refused output.
std::vector<std::string> others(const fs::path& dir, const fs::path& keep) {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename() != keep.filename() && e.path().filename() != keep.filename().string() + ".node")
      out.push_back(e.path().filename().string());
  return out;
}

}  // namespace

TEST_CASE("output rule: a FIFO, a socket, a device node or a link to one is refused as any output, with and "
          "without force, and left untouched", "[io][output][hostile]") {
  for (const std::string kind : {"fifo", "socket", "device", "symlink-to-device"}) {
    DYNAMIC_SECTION(kind) {
      test::TempDir tmp("roe_output_rule");
      const fs::path p = tmp / "out";
      if (!make_special(p, kind)) {
        WARN("cannot make a " << kind << " here (a device node needs root): skipped");
        continue;
      }
      const Ident before = ident(p);
      for (const bool force : {false, true}) {
        CHECK_THROWS_WITH(io::refuse_special_output(p, io::OutputKind::file, "x"),
                          Catch::Contains("never this") && Catch::Contains("not even with --force"));
        CHECK_THROWS_WITH(io::check_file_output(p, force), Catch::Contains("never this"));
        CHECK_THROWS_AS(io::write_file_atomic(p, "data", force), InputError);
        CHECK_THROWS_AS(io::AtomicFile(p, force), InputError);
        CHECK_THROWS_WITH(io::OutputDir::check(p, force), Catch::Contains("never this"));
        CHECK_THROWS_AS(io::OutputDir(p, force), InputError);
        io::StagedFiles staged;
        CHECK_THROWS_AS(staged.stage(p), InputError);
      }
      CHECK(ident(p) == before);
      if (kind == "symlink-to-device") CHECK(fs::is_symlink(p));  // the link itself, not replaced by a file
      CHECK(others(tmp.path, p).empty());
    }
  }
}

TEST_CASE("output rule: a special file that appears after the start is refused at the rename, nothing replaced",
          "[io][output][hostile]") {
  test::TempDir tmp("roe_output_rule");
  SECTION("AtomicFile") {
    const fs::path p = tmp / "late.txt";
    io::AtomicFile f(p);
    f.append("data");
    REQUIRE(make_special(p, "fifo"));
    const Ident before = ident(p);
    CHECK_THROWS_WITH(f.commit(), Catch::Contains("FIFO"));
    CHECK(ident(p) == before);
    CHECK(others(tmp.path, p).empty());  // the temporary is gone
  }
  SECTION("StagedFiles") {
    const fs::path a = tmp / "a.txt", b = tmp / "b.txt";
    {
      io::StagedFiles staged;
      io::write_file_atomic(staged.stage(a), "A");
      io::write_file_atomic(staged.stage(b), "B");
      REQUIRE(make_special(b, "fifo"));
      CHECK_THROWS_WITH(staged.commit(), Catch::Contains("FIFO"));
    }
    CHECK_FALSE(fs::exists(a));  // the earlier rename is undone
    CHECK(fs::is_fifo(b));
  }
  SECTION("OutputDir") {
    const fs::path p = tmp / "dir";
    io::OutputDir d(p, true);
    io::write_file_atomic(d.file("x.txt"), "x");
    REQUIRE(make_special(p, "fifo"));
    CHECK_THROWS_WITH(d.commit(), Catch::Contains("FIFO"));
    CHECK(fs::is_fifo(p));
  }
}

TEST_CASE("output rule: regular files and folders are still replaced under force, refused without",
          "[io][output]") {
  test::TempDir tmp("roe_output_rule");
  const fs::path f = tmp.write("f.txt", "old");
  CHECK_THROWS_WITH(io::check_file_output(f, false), Catch::Contains("use --force"));
  CHECK_NOTHROW(io::check_file_output(f, true));
  io::write_file_atomic(f, "new", true);
  CHECK(io::read_file(f) == "new");
  // A folder where a file is written, and a file where a folder is: refused whatever force says.
  fs::create_directories(tmp / "d");
  CHECK_THROWS_WITH(io::check_file_output(tmp / "d", true), Catch::Contains("is a folder"));
  CHECK_THROWS_WITH(io::OutputDir::check(f, true), Catch::Contains("is a regular file"));
  // A dangling symlink is not an existing output.
  fs::create_symlink("absent", tmp / "dangling");
  CHECK_NOTHROW(io::check_file_output(tmp / "dangling", false));
}
