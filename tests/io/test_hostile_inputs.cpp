// Hostile inputs, by class (issue 28): paths that are not regular files, symlink loops, files cut
// short, integers beyond their type, YAML aliases. Each test names the class it guards.
#include <sys/stat.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <chrono>
#include <filesystem>
#include <string>

#include <fmt/format.h>

#include "roe/io/csv.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/input.hpp"
#include "roe/io/json.hpp"
#include "roe/io/kalibr.hpp"
#include "roe/io/mocap_formats.hpp"
#include "roe/io/poet_results.hpp"
#include "roe/io/ros/ros1_bag.hpp"
#include "roe/io/trajectory_io.hpp"
#include "support/test_util.hpp"

namespace fs = std::filesystem;
using roe::test::expect_input_error;
using Catch::Contains;

namespace {

/// Captures what the process writes to stderr (log::warn) while it lives.
class StderrCapture {
 public:
  explicit StderrCapture(const fs::path& file) : file_(file) {
    std::fflush(stderr);
    saved_ = ::dup(2);
    FILE* f = std::fopen(file.c_str(), "w");
    ::dup2(::fileno(f), 2);
    std::fclose(f);
  }
  std::string text() {
    restore();
    return roe::io::read_file(file_);
  }
  ~StderrCapture() { restore(); }

 private:
  void restore() {
    if (saved_ < 0) return;
    std::fflush(stderr);
    ::dup2(saved_, 2);
    ::close(saved_);
    saved_ = -1;
  }
  fs::path file_;
  int saved_ = -1;
};

// Every path-taking reader, as one list: each must refuse what is not a regular file.
void read_with_every_reader(const fs::path& p) {
  using namespace roe::io;
  CHECK_THROWS_AS(read_file(p), roe::InputError);
  CHECK_THROWS_AS(sha256_file(p), roe::InputError);
  CHECK_THROWS_AS(CsvReader(p), roe::InputError);
  CHECK_THROWS_AS(parse_json_file(p), roe::InputError);
  CHECK_THROWS_AS(read_trajectory(p, TrajectoryFormat::kAuto), roe::InputError);
  CHECK_THROWS_AS(read_motive_csv(p, ""), roe::InputError);
  CHECK_THROWS_AS(read_kalibr_camchain(p), roe::InputError);
  CHECK_THROWS_AS(read_poet_results(p), roe::InputError);
  CHECK_THROWS_AS(ros1::Reader(p), roe::InputError);
}

}  // namespace

TEST_CASE("input class: a FIFO, a device, a folder, a symlink loop are refused by every reader, naming what is there",
          "[io][hostile]") {
  roe::test::TempDir d("roe_hostile");
  const fs::path fifo = d / "fifo.csv";
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);  // no writer: opening it for reading would block
  const fs::path loop = d / "loop.csv";
  fs::create_symlink(loop, loop);
  const fs::path dangling = d / "dangling.csv";
  fs::create_symlink(d / "nothing-here", dangling);
  fs::create_directories(d / "folder.csv");

  const auto t0 = std::chrono::steady_clock::now();
  for (const fs::path& p : {fifo, fs::path("/dev/zero"), d / "folder.csv", loop, dangling}) {
    INFO(p);
    read_with_every_reader(p);
  }
  CHECK(std::chrono::steady_clock::now() - t0 < std::chrono::seconds(5));  // a hang never gets here anyway
  CHECK_THAT(expect_input_error([&] { roe::io::read_file(fifo); }).what(), Contains("FIFO") && Contains("fifo.csv"));
  CHECK_THAT(expect_input_error([&] { roe::io::read_file("/dev/zero"); }).what(), Contains("character device"));
  CHECK_THAT(expect_input_error([&] { roe::io::read_file(loop); }).what(), Contains("symlink loop"));
  CHECK_THAT(expect_input_error([&] { roe::io::read_file(dangling); }).what(), Contains("dangling symlink"));
  CHECK_THAT(expect_input_error([&] { roe::io::read_file(d / "folder.csv"); }).what(), Contains("is a folder"));
  // The non-throwing queries: a loop is an input error, never a std::filesystem exception.
  CHECK_THROWS_AS(roe::io::path_exists(loop), roe::InputError);
  CHECK_THROWS_AS(roe::io::is_folder(loop), roe::InputError);
  CHECK_FALSE(roe::io::path_exists(d / "absent"));
  CHECK_FALSE(roe::io::optional_regular_file(d / "absent"));
  CHECK_THROWS_AS(roe::io::optional_regular_file(fifo), roe::InputError);
}

TEST_CASE("input class: read_file allocates the file's size at open, and read_file_head at most its limit",
          "[io][hostile]") {
  roe::test::TempDir d("roe_hostile");
  const auto p = d.write("a.txt", std::string(1000, 'x'));
  CHECK(roe::io::read_file(p).size() == 1000);
  CHECK(roe::io::read_file_head(p, 10) == std::string(10, 'x'));
  CHECK(roe::io::InputFile(p).size() == 1000);
}

TEST_CASE("input class: a folder or a symlink loop where roe.json or a stream file should be says so",
          "[io][hostile]") {
  roe::test::TempDir d("roe_hostile");
  fs::create_directories(d / "roe.json");
  CHECK_THAT(expect_input_error([&] { roe::store::read_manifest(d.path); }).what(),
             Contains("is a folder") && Contains("roe.json"));
  fs::remove(d / "roe.json");
  fs::create_symlink(d / "roe.json", d / "roe.json");
  CHECK_THAT(expect_input_error([&] { roe::store::read_manifest(d.path); }).what(), Contains("symlink loop"));

  // A dataset whose imu0/data.csv is a folder: not "0 samples".
  roe::test::TempDir e("roe_hostile");
  roe::Dataset ds;
  ds.manifest.name = "x";
  roe::store::write_dataset(ds, e.path, true);
  fs::create_directories(roe::store::imu_csv_path(e.path));
  CHECK_THAT(expect_input_error([&] { roe::store::read_dataset(e.path, {}); }).what(),
             Contains("is a folder") && Contains("imu0"));
  fs::remove(roe::store::imu_csv_path(e.path));
  fs::create_symlink(roe::store::imu_csv_path(e.path), roe::store::imu_csv_path(e.path));
  CHECK_THAT(expect_input_error([&] { roe::store::read_dataset(e.path, {}); }).what(), Contains("symlink loop"));
}

TEST_CASE("truncation class: the last line without its line end is a warning naming file and line, a short one says "
          "the file looks cut",
          "[io][hostile][csv]") {
  roe::test::TempDir d("roe_hostile");
  roe::io::CsvOptions o;
  o.expected_header = {"t", "x", "y"};
  {
    StderrCapture cap(d / "err.txt");
    auto r = roe::io::CsvReader::from_text("t,x,y\n1,2.5,3.25\n2,2.5,3.2", "cut.csv", o);
    REQUIRE(r.next());
    CHECK_FALSE(r.row_unterminated());
    REQUIRE(r.next());
    CHECK(r.row_unterminated());
    CHECK(r.get_double(2) == 3.2);  // a value that may be cut short: read, but warned about
    const std::string err = cap.text();
    CHECK_THAT(err, Contains("warning") && Contains("cut.csv:3") && Contains("no line end"));
  }
  {
    StderrCapture cap(d / "err2.txt");
    auto r = roe::io::CsvReader::from_text("t,x,y\n1,2.5,3.25\n", "whole.csv", o);
    while (r.next()) {
    }
    CHECK(cap.text().empty());
  }
  // Cut inside the second value: the row is short, an error that says why.
  const auto e = expect_input_error([&] {
    auto r = roe::io::CsvReader::from_text("t,x,y\n1,2.5,3.25\n2,2.", "cut.csv", o);
    while (r.next()) {
    }
  });
  CHECK(e.context().line == 3);
  CHECK_THAT(e.what(), Contains("cut short"));
}

TEST_CASE("truncation class: a Vicon file cut inside its last row drops that row with a warning", "[io][hostile]") {
  roe::test::TempDir d("roe_hostile");
  const std::string head =
      "Objects\n100\n,,Global Angle b:b,,,,,\nFrame,Sub Frame,RX,RY,RZ,TX,TY,TZ\n,,deg,deg,deg,mm,mm,mm\n";
  const auto p = d.write("v.csv", head + "1,0,0,0,0,10,20,30\n2,0,0,0,0,10,20,30\n3,0,0,0,0,10,2");
  const auto m = roe::io::read_vicon_csv(p, "");
  CHECK(m.poses.size() == 2);
  REQUIRE(m.warnings.size() == 1);
  CHECK_THAT(m.warnings[0], Contains("v.csv:8") && Contains("dropped"));
}

TEST_CASE("integer class: integers read from JSON are range-checked where they are read", "[io][hostile][json]") {
  const auto j = roe::io::parse_json_text(R"({"w": 1000000000000, "u": -1, "ok": 640})", "c.json");
  roe::io::JsonObject r(j, "c.json");
  int w = 0, ok = 0;
  unsigned u = 0;
  r.get("ok", ok);
  CHECK(ok == 640);
  CHECK_THROWS_WITH(r.get("w", w), Contains("c.json") && Contains("'w'") && Contains("out of range"));
  CHECK_THROWS_WITH(r.get("u", u), Contains("'u'") && Contains("out of range"));
}

TEST_CASE("YAML class: Kalibr files with anchors or aliases are refused at once (no exponential walk)",
          "[io][hostile][kalibr]") {
  // Billion laughs: 10 levels of 9 aliases each, under 1 kB.
  std::string y = "a0: &a0 [x, x, x, x, x, x, x, x, x]\n";
  for (int i = 1; i < 10; ++i) {
    y += "a" + std::to_string(i) + ": &a" + std::to_string(i) + " [";
    for (int k = 0; k < 9; ++k) y += (k ? ", *a" : "*a") + std::to_string(i - 1);
    y += "]\n";
  }
  REQUIRE(y.size() < 1024);
  const auto t0 = std::chrono::steady_clock::now();
  const auto e = expect_input_error([&] { roe::io::parse_kalibr_camchain(y, "laughs.yaml"); });
  CHECK(std::chrono::steady_clock::now() - t0 < std::chrono::seconds(2));
  CHECK(e.context().line == 1);
  CHECK_THAT(e.what(), Contains("anchor"));
  CHECK_THROWS_WITH(roe::io::parse_kalibr_imu("a: &x 1\nb: *x\n", "i.yaml"), Contains("i.yaml:1:") && Contains("anchor"));
  CHECK_THROWS_WITH(roe::io::parse_kalibr_imu("a: 1\nb: *x\n", "i.yaml"), Contains("i.yaml:2:"));  // undefined
}

TEST_CASE("integer class: a Kalibr resolution beyond an int is an input error at its line", "[io][hostile][kalibr]") {
  const std::string cc =
      "cam0:\n  T_cam_imu:\n  - [1.0, 0.0, 0.0, 0.1]\n  - [0.0, 1.0, 0.0, 0.0]\n  - [0.0, 0.0, 1.0, 0.0]\n"
      "  - [0.0, 0.0, 0.0, 1.0]\n  camera_model: pinhole\n  distortion_coeffs: [0, 0, 0, 0]\n"
      "  distortion_model: radtan\n  intrinsics: [600, 600, 320, 240]\n  resolution: [1e12, 480]\n";
  const auto e = expect_input_error([&] { roe::io::parse_kalibr_camchain(cc, "cc.yaml"); });
  CHECK(e.context().line == 11);
  CHECK(e.context().key == "cam0.resolution");
  CHECK_THAT(e.what(), Contains("1 to 100000"));
}

TEST_CASE("location class: semantic errors in roe.json give line and column besides the key path",
          "[io][hostile][json]") {
  const std::string sample = roe::io::read_file(fs::path(ROE_SOURCE_DIR) / "datasets/sample/roe.json");
  struct Case {
    std::string from, to, key, message;
    std::int64_t line, column;
  };
  // Lines and columns of the sample's keys (the "fx" key on line 27, column 5, and so on).
  const Case cases[] = {
      {"\"fx\": 919.806", "\"fx\": 0", "camera.fx", "", 27, 5},
      {"\"fx\": 919.806", "\"fx\": \"919\"", "camera.fx", "expected a number", 27, 5},
      {"\"fx\": 919.806", "\"fx\": 919.806, \"fxx\": 1", "camera.fxx", "unknown key", 27, 20},
      {"\"fx\": 919.806,", "", "camera.fx", "missing required key", 24, 3},  // at its object
      {"\"rate_hz\": 200.0", "\"rate_hz\": -200.0", "imu.rate_hz", "", 18, 5},
      {"\"width\": 640", "\"width\": 1000000000000", "camera.width", "out of range", 25, 5},
      {"0.9999548861306463", "1.9999548861306463", "camera.T_I_C.q", "unit", 35, 7},
  };
  roe::test::TempDir d("roe_hostile");
  for (const Case& c : cases) {
    std::string text = sample;
    REQUIRE(text.find(c.from) != std::string::npos);
    text.replace(text.find(c.from), c.from.size(), c.to);
    d.write("roe.json", text);
    INFO(c.to);
    const auto e = expect_input_error([&] { (void)roe::store::read_manifest(d.path); });
    CHECK(e.context().key == c.key);
    CHECK(e.context().line == c.line);
    CHECK(e.context().column == c.column);
    CHECK_THAT(e.what(), Contains(c.message));
    CHECK_THAT(e.what(), Contains(fmt::format("roe.json:{}:{}", c.line, c.column)));
  }
  // A key given twice is located too (the parser's own check).
  const auto e = expect_input_error(
      [&] { (void)roe::io::parse_json_text("{\n  \"a\": 1,\n  \"a\": 2\n}", "dup.json"); });
  CHECK(e.context().line == 3);
  CHECK(e.context().column == 3);
}

TEST_CASE("location class: json_key_location finds members and elements, any nesting, not inside strings",
          "[io][json]") {
  const std::string t = "{\"a\": {\"s\": \"x.b[1]\\\"}\", \"b\": [10, {\"c\": 1}, [2, 3]]},\n \"d\": null}";
  using roe::io::json_key_location;
  CHECK(json_key_location(t, "a") == std::pair<std::int64_t, std::int64_t>{1, 2});
  CHECK(json_key_location(t, "a.b") == std::pair<std::int64_t, std::int64_t>{1, 26});
  CHECK(json_key_location(t, "a.b[1].c") == std::pair<std::int64_t, std::int64_t>{1, 37});
  CHECK(json_key_location(t, "a.b[2][1]") == std::pair<std::int64_t, std::int64_t>{1, 50});
  CHECK(json_key_location(t, "d") == std::pair<std::int64_t, std::int64_t>{2, 2});
  CHECK(json_key_location(t, "a.x") == std::pair<std::int64_t, std::int64_t>{0, 0});
  CHECK(json_key_location(t, "a.b[7]") == std::pair<std::int64_t, std::int64_t>{0, 0});
  CHECK(json_key_location("\xEF\xBB\xBF{\"k\": 1}", "k") == std::pair<std::int64_t, std::int64_t>{1, 5});
}

TEST_CASE("BOM class: every text reader skips a UTF-8 byte order mark", "[io][hostile]") {
  const std::string bom = "\xEF\xBB\xBF";
  roe::test::TempDir d("roe_hostile");
  CHECK(roe::io::parse_json_text(bom + "{\"a\": 1}", "b.json")["a"] == 1);
  CHECK(roe::io::parse_trajectory(bom + "1 0 0 0 0 0 0 1\n2 0 0 0 0 0 0 1\n", "b.txt").size() == 2);
  auto r = roe::io::CsvReader::from_text(bom + "t,x\n1,2\n", "b.csv");
  CHECK(r.header()[0] == "t");
  const std::string cc =
      "cam0:\n  T_cam_imu:\n  - [1.0, 0.0, 0.0, 0.1]\n  - [0.0, 1.0, 0.0, 0.0]\n  - [0.0, 0.0, 1.0, 0.0]\n"
      "  - [0.0, 0.0, 0.0, 1.0]\n  camera_model: pinhole\n  distortion_coeffs: [0, 0, 0, 0]\n"
      "  distortion_model: radtan\n  intrinsics: [600, 600, 320, 240]\n  resolution: [640, 480]\n";
  CHECK(roe::io::parse_kalibr_camchain(bom + cc, "b.yaml").width == 640);
  CHECK(roe::io::utf8_bom_length(bom + "x") == 3);
  CHECK(roe::io::utf8_bom_length("\xEFx") == 0);  // a lone 0xEF is not a BOM
  const std::string sample = roe::io::read_file(fs::path(ROE_SOURCE_DIR) / "datasets/sample/roe.json");
  d.write("roe.json", bom + sample);
  CHECK(roe::store::read_manifest(d.path).name == "paper-seq4");
}

TEST_CASE("YAML class (fuzz finding): a camera or an IMU that is not a mapping is an input error, not yaml-cpp's "
          "BadSubscript",
          "[io][hostile][kalibr]") {
  // fuzz_kalibr's first finding: a byte change turned cam0's mapping into a scalar, and cam0["camera_model"]
  // threw YAML::BadSubscript through the reader (exit 3 in roe).
  for (const std::string y : {"cam0: 5\n", "cam0: [1, 2]\n", "cam0:\n  \"T_cam_imu:\n  - [1, 0]\n"}) {
    INFO(y);
    const auto e = expect_input_error([&] { roe::io::parse_kalibr_camchain(y, "cc.yaml"); });
    CHECK(e.context().line >= 1);
  }
  // fuzz_kalibr's second finding: yaml-cpp's loop over a file's documents never ends on ",m0:" (4 bytes).
  const auto t0 = std::chrono::steady_clock::now();
  CHECK_THROWS_AS(roe::io::parse_kalibr_camchain(",m0:", "cc.yaml"), roe::InputError);
  CHECK(std::chrono::steady_clock::now() - t0 < std::chrono::seconds(2));
  for (const std::string y : {"imu0: 5\n", "imu0: [1]\n"})
    CHECK_THROWS_WITH(roe::io::parse_kalibr_imu(y, "i.yaml"), Contains("i.yaml:1:"));
}

TEST_CASE("YAML class: a line without ':' or a second document is refused at its line, not ignored", "[io][hostile][kalibr]") {
  // yaml-cpp reads a stray `nan` line under a block mapping as the start of a second document and YAML::Load
  // drops it; PyYAML (Kalibr's reader) refuses the file ("could not find expected ':'", line 12).
  const std::string cc =
      "cam0:\n  T_cam_imu:\n  - [1.0, 0.0, 0.0, 0.1]\n  - [0.0, 1.0, 0.0, 0.0]\n  - [0.0, 0.0, 1.0, 0.0]\n"
      "  - [0.0, 0.0, 0.0, 1.0]\n  camera_model: pinhole\n  distortion_coeffs: [0, 0, 0, 0]\n"
      "  distortion_model: radtan\n  intrinsics: [600, 600, 320, 240]\n  resolution: [640, 480]\n";
  CHECK_NOTHROW(roe::io::parse_kalibr_camchain(cc, "cc.yaml"));
  CHECK_NOTHROW(roe::io::parse_kalibr_camchain(cc + "...\n", "cc.yaml"));  // an explicit document end
  const auto stray = expect_input_error([&] { roe::io::parse_kalibr_camchain(cc + "nan\n", "cc.yaml"); });
  CHECK(stray.context().line == 12);
  CHECK_THAT(stray.what(), Contains("without ':'"));
  const auto second = expect_input_error([&] { roe::io::parse_kalibr_camchain(cc + "---\ncam1: 5\n", "cc.yaml"); });
  CHECK(second.context().line == 12);
  CHECK_THAT(second.what(), Contains("after the first YAML document"));
  CHECK_NOTHROW(roe::io::parse_kalibr_camchain(cc + "cam1:\n", "cc.yaml") /* a key with ':' and no value */ );
  CHECK_THROWS_WITH(roe::io::parse_kalibr_imu("imu0:\n  update_rate: 200\nnan\n", "i.yaml"), Contains("i.yaml:3:"));
}
