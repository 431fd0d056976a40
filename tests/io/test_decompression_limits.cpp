// Bounded decompression and safe names (issue 40): every decompression of a bag (MCAP chunk, ROS 1 chunk,
// rosbag2 file or message) stops at a documented limit; chunks that all overlap in time are not all held at
// once; rows of a rosbag2 database that no topic claims are reported; a rosbag2 folder without
// metadata.yaml is a bag by content; names from user-edited files are checked before they become paths.
#include <sqlite3.h>

#include <catch2/catch.hpp>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "roe/core/error.hpp"
#include "roe/io/ros/message_bag.hpp"
#include "roe/io/ros/compression.hpp"
#include "roe/io/input.hpp"
#include "roe/io/ros/mcap.hpp"
#include "roe/io/output.hpp"
#include "roe/io/poet_results.hpp"
#include "roe/io/ros/ros1_bag.hpp"
#include "roe/io/ros/rosbag2.hpp"
#include "fixtures/bag_writer.hpp"
#include "support/test_util.hpp"

namespace fs = std::filesystem;
using namespace roe;
namespace mcap = roe::io::mcap;

namespace {

std::string u16(std::uint16_t v) { return std::string(reinterpret_cast<const char*>(&v), 2); }
std::string u32(std::uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); }
std::string u64(std::uint64_t v) { return std::string(reinterpret_cast<const char*>(&v), 8); }
std::string str(const std::string& s) { return u32(static_cast<std::uint32_t>(s.size())) + s; }
std::string record(std::uint8_t op, const std::string& body) { return std::string(1, static_cast<char>(op)) + u64(body.size()) + body; }

/// An MCAP file without summary: `n` zstd chunks, all spanning log times 0..1 (so the merge must hold them
/// together), each one message of `payload` zero bytes on channel 1.
std::string overlapping_chunks(int n, std::size_t payload) {
  const std::string magic("\x89MCAP0\r\n", 8);
  std::string f = magic + record(0x01, str("ros2") + str("test"));
  f += record(0x03, u16(1) + str("geometry_msgs/msg/PoseStamped") + str("ros2msg") + u32(0));
  f += record(0x04, u16(1) + u16(1) + str("/big") + str("cdr") + u32(0));
  const std::string msg = record(0x05, u16(1) + u32(0) + u64(1) + u64(1) + std::string(payload, '\0'));
  const std::string z = io::zstd_compress(msg, 1);
  const std::string chunk = record(0x06, u64(0) + u64(1) + u64(msg.size()) + u32(0) + str("zstd") + u64(z.size()) + z);
  for (int i = 0; i < n; ++i) f += chunk;
  return f + record(0x02, u64(0) + u64(0) + u32(0)) + magic;
}

}  // namespace

TEST_CASE("decompression limits: 4x the file within [64 MiB, 256 MiB] per chunk, 16x or 256 MiB per bag file",
          "[io][hostile][limits]") {
  CHECK(io::chunk_decompression_limit(505395) == 64ull << 20);  // nav2_turtlebot.mcap: its 2.9 MB chunk fits
  CHECK(io::chunk_decompression_limit(40ull << 20) == 160ull << 20);
  CHECK(io::chunk_decompression_limit(10ull << 30) == 256ull << 20);
  CHECK(io::file_decompression_limit(20000) == 256ull << 20);
  CHECK(io::file_decompression_limit(1ull << 30) == 16ull << 30);
}

TEST_CASE("mcap: a chunk claiming more than the file's limit is skipped, overlapping chunks are not all held",
          "[io][mcap][hostile][limits]") {
  // One chunk claiming 100 MiB in a file of a few KB (limit 64 MiB): skipped before any allocation.
  const std::string one = overlapping_chunks(1, 1000);
  {
    std::string b = one;
    const std::uint64_t big = 100ull << 20;
    std::memcpy(b.data() + b.find("zstd") - 4 - 4 - 8, &big, 8);  // uncompressed_size precedes crc and the string
    mcap::Reader r(b, "claims.mcap");
    std::size_t n = 0;
    r.for_each([](const mcap::Channel&) { return true; }, [&](const mcap::MessageView&) { return ++n, true; });
    CHECK(n == 0);
    bool said = false;
    for (const auto& w : r.warnings()) said = said || w.message.find("more than the 67108864-byte limit") != std::string::npos;
    CHECK(said);
  }
  // 12 chunks of 8 MiB each, all overlapping, against a limit of 16 MiB: every message arrives, and the reader
  // says that it could not keep them in time order instead of holding 96 MiB.
  mcap::ReaderOptions o;
  o.max_chunk_bytes = 16u << 20;
  mcap::Reader r(overlapping_chunks(12, 8u << 20), "overlap.mcap", o);
  std::size_t n = 0;
  r.for_each([](const mcap::Channel&) { return true; }, [&](const mcap::MessageView& v) {
    n += v.data.size() == (8u << 20);
    return true;
  });
  CHECK(n == 12);
  bool said = false;
  for (const auto& w : r.warnings())
    said = said || (!w.damage && w.message.find("chunks overlapping in time hold more than") != std::string::npos);
  CHECK(said);
}

TEST_CASE("ros1 bag: overlapping LZ4 chunks are not all held, a chunk beyond the limit is skipped",
          "[io][rosbag][hostile][limits]") {
  // 8 chunks of two 1 MiB messages each, at times k and 1000 - k: every chunk spans the others.
  roe::testing::BagWriter w("lz4", 2u << 20);
  const std::string mib(1u << 20, '\0');
  for (int k = 0; k < 8; ++k) {
    w.write("/big", "std_msgs/String", k + 1, mib);
    w.write("/big", "std_msgs/String", 1000 - k, mib);
  }
  const std::string bytes = w.finish();
  io::ros1::ReaderOptions o;
  o.max_chunk_bytes = 4u << 20;
  io::ros1::Reader r(bytes, "overlap.bag", o);
  std::size_t n = 0;
  r.for_each_topic({"/big"}, [&](const io::ros1::MessageView& v) { return n += v.data.size() == mib.size(), true; });
  CHECK(n == 16);
  bool said = false;
  for (const auto& w2 : r.warnings())
    said = said || (!w2.damage && w2.message.find("chunks overlapping in time hold more than") != std::string::npos);
  CHECK(said);
  // A limit below one chunk: each chunk is skipped with the limit named, nothing is allocated for it.
  o.max_chunk_bytes = 1u << 20;
  io::ros1::Reader small(bytes, "small.bag", o);
  n = 0;
  small.for_each_topic({"/big"}, [&](const io::ros1::MessageView&) { return ++n, true; });
  CHECK(n == 0);
  bool limit = false;
  for (const auto& w2 : small.warnings())
    limit = limit || w2.message.find("more than the 1048576-byte limit") != std::string::npos;
  CHECK(limit);
}

TEST_CASE("zstd file decompression stops at its limit with the compressed offset", "[io][hostile][limits]") {
  test::TempDir d;
  const fs::path in = d.write("bomb.db3.zstd", io::zstd_compress(std::string(8u << 20, '\0'), 1));
  CHECK_THROWS_WITH(io::zstd_decompress_file(in, d.path / "out.db3", 1u << 20),
                    Catch::Contains("bomb.db3.zstd") && Catch::Contains("decompresses to more than 1048576 bytes") &&
                        Catch::Contains("compressed byte"));
  io::zstd_decompress_file(in, d.path / "ok.db3", 8u << 20);
  CHECK(fs::file_size(d.path / "ok.db3") == (8u << 20));
}

TEST_CASE("rosbag2: messages whose topic_id no topic has are reported, not dropped in silence",
          "[io][rosbag2][hostile]") {
  test::TempDir d;
  const fs::path db = d.path / "orphans.db3";
  sqlite3* h = nullptr;
  REQUIRE(sqlite3_open(db.c_str(), &h) == SQLITE_OK);
  REQUIRE(sqlite3_exec(h,
                       "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT, type TEXT, serialization_format TEXT);"
                       "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER, timestamp INTEGER, data BLOB);"
                       "INSERT INTO topics VALUES (1, '/a', 'std_msgs/msg/String', 'cdr');"
                       "INSERT INTO messages VALUES (1, 1, 10, x'00'), (2, 7, 11, x'00'), (3, 7, 12, x'00');",
                       nullptr, nullptr, nullptr) == SQLITE_OK);
  sqlite3_close(h);
  const auto bag = io::open_bag(db);
  CHECK(bag->damaged());
  CHECK_THAT(bag->first_damage(), Catch::Contains("2 message(s) have a topic_id that no row of table topics has (7)"));
}

TEST_CASE("bag kinds: a folder of bag files without metadata.yaml is a rosbag2 folder, an empty one is not",
          "[io][rosbag2][hostile]") {
  test::TempDir d;
  fs::create_directories(d.path / "empty");
  CHECK(io::detect_bag_kind(d.path / "empty").empty());
  fs::create_directories(d.path / "bag");
  d.write("bag/x.mcap", overlapping_chunks(1, 100));
  CHECK(io::detect_bag_kind(d.path / "bag") == "rosbag2-folder");
}

TEST_CASE("names from user-edited files: plain names only, paths compared after resolution", "[io][hostile][paths]") {
  for (const char* ok : {"poet", "sim", "a.b", "...", "model-1_2"}) CHECK(io::is_plain_name(ok));
  for (const char* bad : {"", ".", "..", "a/b", "/abs", "../x", "a\nb", "tab\there"}) CHECK_FALSE(io::is_plain_name(bad));
  test::TempDir d;
  fs::create_directories(d.path / "sw" / "jobs");
  CHECK(io::is_within(d.path / "sw" / "jobs" / "x", d.path / "sw" / "jobs"));
  CHECK(io::is_within(d.path / "sw" / "jobs", d.path / "sw" / "jobs"));
  CHECK(io::is_within(d.path / "sw" / "other" / ".." / "jobs" / "y", d.path / "sw" / "jobs"));
  CHECK_FALSE(io::is_within(d.path / "sw" / "jobs2", d.path / "sw" / "jobs"));
  CHECK_FALSE(io::is_within(d.path / "sw", d.path / "sw" / "jobs"));
}

TEST_CASE("poet results: a finite translation beyond a kilometre is an input error at its line and column",
          "[io][poet][hostile]") {
  const std::string text = R"({"1": {"0": {"t": [0.1, 1e308, 0.5], "rot": [[1,0,0],[0,1,0],[0,0,1]], "class": 1}}})";
  CHECK_THROWS_WITH(io::parse_poet_results(text, "r.json"),
                    Catch::Contains("r.json:1:") && Catch::Contains("1e+308 m") && Catch::Contains("1.0.t"));
  // Many images: each is converted as soon as it is parsed (the results equal those of a small file).
  std::string many = "{";
  for (int i = 0; i < 2000; ++i)
    many += (i ? "," : "") + std::string("\"") + std::to_string(i + 1) +
            R"(": {"0": {"t": [0.1, 0.2, 0.5], "rot": [[1,0,0],[0,1,0],[0,0,1]], "class": 2}})";
  const auto r = io::parse_poet_results(many + "}", "many.json");
  REQUIRE(r.images.size() == 2000);
  CHECK(r.images[1999].id == "2000");
  CHECK(r.images[1999].detections.at(0).class_id == 2);
}
