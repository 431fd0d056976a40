// Architecture rules of DESIGN §5 and docs/architecture.md, checked on the sources: the estimator, math and
// the other I/O-free areas include no I/O, JSON, OpenCV or CLI headers; eval does not depend on ekf; the ROS
// wing (io/ros) stands on core, math and io's file primitives, and only app reaches it.
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {
std::vector<std::string> violations(const std::vector<std::string>& areas,
                                    const std::vector<std::string>& forbidden) {
  std::vector<std::string> out;
  const std::regex inc(R"(^\s*#\s*include\s*[<"]([^>"]+)[>"])");
  for (const auto& area : areas) {
    for (const char* root : {"include/roe/", "src/"}) {
      const fs::path dir = fs::path(ROE_SOURCE_DIR) / (std::string(root) + area);
      if (!fs::exists(dir)) continue;
      for (const auto& e : fs::recursive_directory_iterator(dir)) {
        if (!e.is_regular_file()) continue;
        std::ifstream in(e.path());
        std::string line;
        int n = 0;
        while (std::getline(in, line)) {
          ++n;
          std::smatch m;
          if (!std::regex_search(line, m, inc)) continue;
          for (const auto& f : forbidden) {
            if (m[1].str().rfind(f, 0) == 0)
              out.push_back(e.path().string() + ":" + std::to_string(n) + ": " + m[1].str());
          }
        }
      }
    }
  }
  return out;
}
}  // namespace

TEST_CASE("I/O-free areas include no I/O, JSON, OpenCV or CLI headers", "[layering]") {
  // core is included in the header checks but may write its log lines to stderr (log.cpp).
  CHECK(violations({"core"}, {"roe/io/", "roe/infer/", "roe/image/", "roe/app/", "opencv", "nlohmann",
                              "CLI/", "yaml-cpp", "torch"})
            .empty());
  const auto v = violations({"math", "ekf", "sim", "eval", "calib"},
                            {"roe/io/", "roe/infer/", "roe/image/", "roe/app/", "opencv", "nlohmann",
                             "CLI/", "yaml-cpp", "torch", "fstream", "iostream", "cstdio"});
  for (const auto& s : v) UNSCOPED_INFO(s);
  CHECK(v.empty());
}

TEST_CASE("eval does not depend on ekf, math does not depend on higher areas", "[layering]") {
  CHECK(violations({"eval"}, {"roe/ekf/", "roe/sim/"}).empty());
  CHECK(violations({"math"}, {"roe/ekf/", "roe/sim/", "roe/eval/", "roe/calib/"}).empty());
}

TEST_CASE("math is the ground floor: it includes only math and the error types, which include no roe header",
          "[layering]") {
  // One direction between core and math: core/types.hpp uses math's Pose; math uses core's error types
  // alone (core/error.hpp is a leaf). Interpolation of stamped poses (core types) lives in eval.
  std::vector<std::string> v;
  const std::regex inc(R"(^\s*#\s*include\s*[<"](roe/[^>"]+)[>"])");
  for (const char* root : {"include/roe/math", "src/math"}) {
    for (const auto& e : fs::recursive_directory_iterator(fs::path(ROE_SOURCE_DIR) / root)) {
      if (!e.is_regular_file()) continue;
      std::ifstream f(e.path());
      std::string l;
      for (int n = 1; std::getline(f, l); ++n) {
        std::smatch m;
        if (!std::regex_search(l, m, inc)) continue;
        const std::string h = m[1].str();
        if (h.rfind("roe/math/", 0) != 0 && h != "roe/core/error.hpp")
          v.push_back(e.path().string() + ":" + std::to_string(n) + ": " + h);
      }
    }
  }
  for (const auto& x : v) UNSCOPED_INFO(x);
  CHECK(v.empty());
  std::ifstream in(fs::path(ROE_SOURCE_DIR) / "include/roe/core/error.hpp");
  REQUIRE(in);
  const std::regex roe_inc(R"(^\s*#\s*include\s*[<"]roe/)");
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    INFO("include/roe/core/error.hpp:" << n << ": " << line);
    CHECK_FALSE(std::regex_search(line, roe_inc));
  }
}

namespace {
/// Every roe header included by a file of src/ or include/roe/, with the file's path relative to the
/// source root ("src/io/ros/mcap.cpp") and the line.
struct Include {
  std::string file, header;
  int line = 0;
};
std::vector<Include> roe_includes() {
  std::vector<Include> out;
  const std::regex inc(R"(^\s*#\s*include\s*[<"](roe/[^>"]+)[>"])");
  const fs::path root(ROE_SOURCE_DIR);
  for (const char* top : {"src", "include/roe"}) {
    for (const auto& e : fs::recursive_directory_iterator(root / top)) {
      if (!e.is_regular_file()) continue;
      std::ifstream in(e.path());
      std::string line;
      for (int n = 1; std::getline(in, line); ++n) {
        std::smatch m;
        if (std::regex_search(line, m, inc))
          out.push_back({fs::relative(e.path(), root).generic_string(), m[1].str(), n});
      }
    }
  }
  return out;
}
bool starts_with(const std::string& s, const std::string& prefix) { return s.rfind(prefix, 0) == 0; }
bool in_ros_wing(const std::string& file) {
  return starts_with(file, "src/io/ros/") || starts_with(file, "include/roe/io/ros/");
}
}  // namespace

TEST_CASE("the ROS wing (io/ros) stands on core, math and io's file primitives, and only app includes it",
          "[layering]") {
  std::vector<std::string> bad;
  for (const auto& i : roe_includes()) {
    const std::string at = i.file + ":" + std::to_string(i.line) + ": " + i.header;
    const bool ros_header = starts_with(i.header, "roe/io/ros/");
    if (in_ros_wing(i.file)) {
      // Below: core, math, eval's interpolation (tf chains), and of io only what reads and writes files and
      // the motion-capture type the bag poses are returned in. Never the estimator, roe's own files or OpenCV.
      const bool ok = ros_header || starts_with(i.header, "roe/core/") || starts_with(i.header, "roe/math/") ||
                      i.header == "roe/eval/interpolate.hpp" || i.header == "roe/io/input.hpp" ||
                      i.header == "roe/io/output.hpp" || i.header == "roe/io/mocap_formats.hpp";
      if (!ok) bad.push_back(at);
    } else if (ros_header && !starts_with(i.file, "src/app/")) {
      bad.push_back(at);  // the rest of io, the algorithms, image, infer and cli reach bags through app
    }
  }
  for (const auto& s : bad) UNSCOPED_INFO(s);
  CHECK(bad.empty());
  CHECK(violations({"io/ros"}, {"opencv", "torch", "CLI/"}).empty());
}

TEST_CASE("io stays below the estimator and roe's own files: store holds them, above io, ekf and eval",
          "[layering]") {
  // io (text formats, JSON/CSV primitives, OS helpers) includes no estimator room and no store; store (the
  // dataset folder, run files, report.json) stands on io, ekf and eval and includes nothing of app, cli,
  // image or infer (docs/architecture.md "store").
  std::vector<std::string> bad;
  for (const auto& i : roe_includes()) {
    const std::string at = i.file + ":" + std::to_string(i.line) + ": " + i.header;
    const bool in_io = (starts_with(i.file, "src/io/") || starts_with(i.file, "include/roe/io/")) && !in_ros_wing(i.file);
    const bool in_store = starts_with(i.file, "src/store/") || starts_with(i.file, "include/roe/store/");
    if (in_io) {
      for (const char* f : {"roe/ekf/", "roe/sim/", "roe/calib/", "roe/refine/", "roe/store/", "roe/app/"})
        if (starts_with(i.header, f)) bad.push_back(at);
    }
    if (in_store) {
      for (const char* f : {"roe/app/", "roe/cli/", "roe/image/", "roe/infer/", "roe/io/ros/"})
        if (starts_with(i.header, f)) bad.push_back(at);
    }
    // Below store, nothing reaches up into it (only pipeline, app, cli, the tests and benchmarks).
    const bool in_pipeline = starts_with(i.file, "src/pipeline/") || starts_with(i.file, "include/roe/pipeline/");
    if (starts_with(i.header, "roe/store/") && !in_store && !in_pipeline && !starts_with(i.file, "src/app/") &&
        !starts_with(i.file, "include/roe/app/") && !starts_with(i.file, "src/cli/"))
      bad.push_back(at);
  }
  for (const auto& s : bad) UNSCOPED_INFO(s);
  CHECK(bad.empty());
}

TEST_CASE("the run pipeline reads and writes no file, and only app reaches it", "[layering]") {
  // pipeline (roe run's dataset → filter → smoother → rows, docs/architecture.md "pipeline") stands on
  // core, math, ekf and store's types; it includes no I/O, JSON or stream header, nothing of io, app, cli,
  // image or infer, and nothing but app includes it.
  const auto v = violations({"pipeline"}, {"roe/io/", "roe/app/", "roe/cli/", "roe/image/", "roe/infer/",
                                           "nlohmann", "fstream", "iostream", "cstdio", "opencv", "torch"});
  for (const auto& s : v) UNSCOPED_INFO(s);
  CHECK(v.empty());
  std::vector<std::string> bad;
  for (const auto& i : roe_includes())
    if (starts_with(i.header, "roe/pipeline/") && !starts_with(i.file, "src/pipeline/") &&
        !starts_with(i.file, "include/roe/pipeline/") && !starts_with(i.file, "src/app/") &&
        !starts_with(i.file, "include/roe/app/"))
      bad.push_back(i.file + ":" + std::to_string(i.line) + ": " + i.header);
  for (const auto& s : bad) UNSCOPED_INFO(s);
  CHECK(bad.empty());
}

TEST_CASE("JSON is serialised only through io::dump_json (invalid UTF-8 must not throw)", "[layering]") {
  // nlohmann's dump() throws on a string that is not UTF-8 (a path, a body name from a cp1252 file);
  // io::dump_json replaces such bytes. A plain .dump( anywhere else would bring the crash back.
  std::vector<std::string> out;
  const std::regex dump(R"(\.dump\s*\()");
  for (const auto& e : fs::recursive_directory_iterator(fs::path(ROE_SOURCE_DIR) / "src")) {
    if (!e.is_regular_file() || e.path().filename() == "json.cpp") continue;
    std::ifstream in(e.path());
    std::string line;
    for (int n = 1; std::getline(in, line); ++n)
      if (std::regex_search(line, dump)) out.push_back(e.path().string() + ":" + std::to_string(n));
  }
  for (const auto& s : out) UNSCOPED_INFO(s);
  CHECK(out.empty());
}

TEST_CASE("only the image commands' app files reach OpenCV or LibTorch (roe starts without them)", "[layering]") {
  // CMakeLists.txt links src/app/import_realsense*.cpp and src/app/infer*.cpp into the helper executables
  // roe-image and roe-infer; every other app file is in `roe`, which must not map OpenCV or LibTorch.
  std::vector<std::string> out;
  const std::regex inc(R"(^\s*#\s*include\s*[<"](roe/image/|roe/infer/|opencv|torch)[^>"]*[>"])");
  for (const auto& e : fs::directory_iterator(fs::path(ROE_SOURCE_DIR) / "src/app")) {
    const std::string name = e.path().filename().string();
    if (name.rfind("import_realsense", 0) == 0 || name.rfind("infer", 0) == 0) continue;
    std::ifstream in(e.path());
    std::string line;
    for (int n = 1; std::getline(in, line); ++n)
      if (std::regex_search(line, inc)) out.push_back(e.path().string() + ":" + std::to_string(n));
  }
  for (const auto& s : out) UNSCOPED_INFO(s);
  CHECK(out.empty());
}

TEST_CASE("only refine's app files and the refine command reach Ceres (roe starts without it)", "[layering]") {
  // CMakeLists.txt links src/app/refine*.cpp (roe_app_refine) and src/cli/cmd_refine.cpp into the helper
  // roe-refine only (issue 53); every other app and cli file is in `roe`, which must not map Ceres.
  std::vector<std::string> out;
  const std::regex inc(R"(^\s*#\s*include\s*[<"](roe/refine/|roe/app/refine|ceres/|glog/)[^>"]*[>"])");
  for (const char* dir : {"src/app", "src/cli", "include/roe/app"}) {
    for (const auto& e : fs::directory_iterator(fs::path(ROE_SOURCE_DIR) / dir)) {
      const std::string name = e.path().filename().string();
      if (name.rfind("refine", 0) == 0 || name == "cmd_refine.cpp") continue;
      std::ifstream in(e.path());
      std::string line;
      for (int n = 1; std::getline(in, line); ++n)
        if (std::regex_search(line, inc)) out.push_back(e.path().string() + ":" + std::to_string(n));
    }
  }
  for (const auto& s : out) UNSCOPED_INFO(s);
  CHECK(out.empty());
}
