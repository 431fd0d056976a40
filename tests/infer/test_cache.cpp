// The per-frame detection cache: round trip, torn lines, foreign headers.
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "roe/infer/cache.hpp"
#include "roe/io/output.hpp"

namespace fs = std::filesystem;
using namespace roe::infer;

namespace {
fs::path temp_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("roe_test_cache_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}
CachedFrame frame(const std::string& key, int cls, double z) {
  CachedFrame f;
  f.key = key;
  f.t_ns = 17;
  f.ms = 1.5;
  PoseDetection d;
  d.class_id = cls;
  d.T_C_O = roe::Pose(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY())), Eigen::Vector3d(0.1, -0.2, z));
  d.score = 0.75;
  d.box = {1, 2, 3, 4};
  f.detections.push_back(d);
  PoseDetection e = d;
  e.score = std::numeric_limits<double>::quiet_NaN();
  roe::Vector6d s;
  s << 0.01, 0.02, 0.03, 0.1, 0.2, 0.3;
  e.sigma = s;
  f.detections.push_back(e);
  return f;
}
}  // namespace

TEST_CASE("cache entries survive a reopen exactly", "[cache]") {
  const fs::path d = temp_dir("roundtrip");
  {
    DetectionCache c(d / "a/frames.jsonl", "m", "h1");
    CHECK(c.size() == 0);
    c.append(frame("k1", 1, 0.5));
    c.append(frame("k2", 2, 0.6));
  }
  DetectionCache c(d / "a/frames.jsonl", "m", "h1");
  REQUIRE(c.size() == 2);
  const CachedFrame* f = c.find("k1");
  REQUIRE(f);
  const CachedFrame ref = frame("k1", 1, 0.5);
  REQUIRE(f->detections.size() == 2);
  CHECK(f->detections[0].T_C_O.p == ref.detections[0].T_C_O.p);
  CHECK(f->detections[0].T_C_O.q.coeffs() == ref.detections[0].T_C_O.q.coeffs());
  CHECK(f->detections[0].score == 0.75);
  CHECK(std::isnan(f->detections[1].score));
  REQUIRE(f->detections[1].sigma);
  CHECK((*f->detections[1].sigma)[5] == 0.3);
  CHECK(f->ms == 1.5);
  CHECK_FALSE(c.find("k3"));
  fs::remove_all(d);
}

TEST_CASE("a torn last line (interrupted run) is ignored, later appends still work", "[cache]") {
  const fs::path d = temp_dir("torn");
  const fs::path file = d / "frames.jsonl";
  {
    DetectionCache c(file, "m", "h1");
    c.append(frame("k1", 1, 0.5));
  }
  {
    std::ofstream f(file, std::ios::app);
    f << R"({"key": "k2", "t_ns": 1, "ms": 2, "detec)";  // no newline: torn
  }
  {
    DetectionCache c(file, "m", "h1");
    CHECK(c.size() == 1);
    CHECK(c.ignored_lines() == 1);
    c.append(frame("k3", 3, 0.7));
  }
  DetectionCache c(file, "m", "h1");
  CHECK(c.size() == 2);
  CHECK(c.find("k3"));
  fs::remove_all(d);
}

TEST_CASE("a cache of another model or config starts over", "[cache]") {
  const fs::path d = temp_dir("foreign");
  const fs::path file = d / "frames.jsonl";
  {
    DetectionCache c(file, "m", "h1");
    c.append(frame("k1", 1, 0.5));
  }
  DetectionCache c(file, "m", "h2");
  CHECK(c.size() == 0);
  fs::remove_all(d);
}

TEST_CASE("the cache writes nothing until the first append", "[cache]") {
  const fs::path d = temp_dir("lazy");
  const fs::path file = d / "infer/m/h1/frames.jsonl";
  {
    DetectionCache c(file, "m", "h1");
    CHECK(c.size() == 0);
    CHECK_FALSE(c.find("k1"));
    c.compact();
  }
  CHECK_FALSE(fs::exists(d / "infer"));  // no folder, no file
  {
    DetectionCache c(file, "m", "h1");
    c.append(frame("k1", 1, 0.5));
  }
  // A cache of another configuration is started over only when a frame is appended.
  const std::string before = roe::io::read_file(file);
  { DetectionCache c(file, "m", "h2"); }
  CHECK(roe::io::read_file(file) == before);
  {
    DetectionCache c(file, "m", "h2");
    c.append(frame("k2", 2, 0.6));
  }
  DetectionCache c(file, "m", "h2");
  CHECK(c.size() == 1);
  CHECK(c.find("k2"));
  fs::remove_all(d);
}

TEST_CASE("a recomputed frame replaces its entry: one line per key after compact()", "[cache]") {
  const fs::path d = temp_dir("refresh");
  const fs::path file = d / "frames.jsonl";
  auto lines = [&] {
    std::ifstream f(file);
    std::size_t n = 0;
    for (std::string l; std::getline(f, l);) ++n;
    return n;
  };
  {
    DetectionCache c(file, "m", "h1");
    c.append(frame("k1", 1, 0.5));
    c.append(frame("k2", 2, 0.6));
  }
  CHECK(lines() == 3);
  {
    DetectionCache c(file, "m", "h1");
    CHECK(c.stale_lines() == 0);
    c.append(frame("k1", 1, 0.9));  // recomputed (--no-cache)
    c.append(frame("k1", 1, 0.8));  // the same image again in this run
    CHECK(c.stale_lines() == 2);
    CHECK(c.find("k1")->detections[0].T_C_O.p.z() == 0.8);
    CHECK(lines() == 5);  // appended as it goes: an interrupted run keeps its work
    c.compact();
    CHECK(c.stale_lines() == 0);
    CHECK(lines() == 3);
    c.append(frame("k3", 3, 0.7));  // appending still works after a compaction
  }
  CHECK(lines() == 4);
  {
    DetectionCache c(file, "m", "h1");
    CHECK(c.size() == 3);
    CHECK(c.stale_lines() == 0);
    CHECK(c.find("k1")->detections[0].T_C_O.p.z() == 0.8);
    CHECK(c.find("k2")->detections[0].T_C_O.p.z() == 0.6);
  }
  // Duplicates left by an interrupted run: the last line wins and compact() removes the others.
  {
    std::ofstream f(file, std::ios::app);
    f << roe::infer::frame_to_json(frame("k2", 2, 0.1)).dump() << '\n';
  }
  DetectionCache c(file, "m", "h1");
  CHECK(c.stale_lines() == 1);
  CHECK(c.find("k2")->detections[0].T_C_O.p.z() == 0.1);
  c.compact();
  CHECK(lines() == 4);
  fs::remove_all(d);
}
