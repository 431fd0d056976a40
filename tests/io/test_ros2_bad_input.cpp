// The bad-input catalogue for ROS 2 bags: truncation at many offsets, wrong magic, a chunk whose CRC
// or length lies, a record longer than the file, an unknown compression, CDR string and sequence
// lengths beyond the message, a .db3 that is not a rosbag2 database, a missing split file. Each is an
// InputError or a damage warning naming the byte offset (or table row); nothing crashes or hangs.
#include <catch2/catch.hpp>
#include <sqlite3.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "roe/core/error.hpp"
#include "roe/io/ros/message_bag.hpp"
#include "roe/io/ros/cdr.hpp"
#include "roe/io/ros/compression.hpp"
#include "roe/io/ros/mcap.hpp"
#include "roe/io/mocap_formats.hpp"
#include "roe/io/ros/bag_poses.hpp"
#include "support/test_util.hpp"

namespace fs = std::filesystem;
using namespace roe;
namespace msg = roe::io::ros::msg;
using roe::io::ros::Wire;
namespace mcap = roe::io::mcap;

namespace {

const fs::path kDir = fs::path(ROE_SOURCE_DIR) / "tests/fixtures/ros2";

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

template <class T>
void put(std::string& b, std::size_t at, T v) {
  std::memcpy(b.data() + at, &v, sizeof v);
}

/// Reads every message; returns their count.
std::size_t read_all(mcap::Reader& r) {
  std::size_t n = 0;
  r.for_each([](const mcap::Channel&) { return true; },
             [&](const mcap::MessageView&) {
               ++n;
               return true;
             });
  return n;
}

bool has_warning(const mcap::Reader& r, std::uint64_t offset, const std::string& text) {
  for (const auto& w : r.warnings())
    if (w.damage && w.offset == offset && w.message.find(text) != std::string::npos) return true;
  return false;
}

std::string warnings_of(const mcap::Reader& r) {
  std::string s;
  for (const auto& w : r.warnings()) s += "\n  byte " + std::to_string(w.offset) + ": " + w.message;
  return s;
}

}  // namespace

TEST_CASE("mcap bad input: truncation at many offsets is damage (or wrong magic), never a crash",
          "[io][mcap][ros2][bad]") {
  for (const char* name : {"rs_zstd.mcap", "rs_lz4.mcap"}) {
    const std::string whole = slurp(kDir / name);
    mcap::Reader intact(whole, name);
    REQUIRE_FALSE(intact.damaged());
    const std::size_t all = read_all(intact);
    REQUIRE(all > 100);
    for (std::size_t cut = 0; cut < whole.size(); cut += cut < 64 ? 1 : 211) {
      INFO(name << " cut at " << cut);
      const std::string part = whole.substr(0, cut);
      if (cut < 8) {
        CHECK_THROWS_WITH(mcap::Reader(part, name), Catch::Contains("not an MCAP file") && Catch::Contains(name));
        continue;
      }
      mcap::Reader r(part, name);
      CHECK(r.damaged());
      CHECK_FALSE(r.summary_used());
      CHECK(read_all(r) <= all);  // a cut inside the summary section loses no message
    }
  }
}

TEST_CASE("mcap bad input: wrong magic, lying CRC and lengths, unknown compression", "[io][mcap][ros2][bad]") {
  const std::string whole = slurp(kDir / "rs_zstd.mcap");
  mcap::Reader intact(whole, "ok.mcap");
  REQUIRE(intact.chunks().size() >= 2);
  const std::uint64_t c0 = intact.chunks()[0].offset;
  const std::size_t all = read_all(intact);

  std::string b = whole;
  b[1] = 'X';
  CHECK_THROWS_WITH(mcap::Reader(b, "bad.mcap"), Catch::Contains("bad.mcap") && Catch::Contains("wrong magic at byte 0"));

  // The chunk's uncompressed CRC lies: that chunk is skipped with its offset, the others are read.
  b = whole;
  put<std::uint32_t>(b, c0 + 9 + 24, 0xDEADBEEF);
  {
    mcap::Reader r(b, "crc.mcap");
    const std::size_t n = read_all(r);
    CHECK(n > 0);
    CHECK(n < all);
    CHECK(has_warning(r, c0, "chunk CRC mismatch"));
  }
  // The chunk claims a bigger uncompressed size than its data holds.
  b = whole;
  std::uint64_t usize = 0;
  std::memcpy(&usize, b.data() + c0 + 9 + 16, 8);
  put<std::uint64_t>(b, c0 + 9 + 16, usize + 100);
  {
    mcap::Reader r(b, "usize.mcap");
    CHECK(read_all(r) < all);
    CHECK(has_warning(r, c0, "fails to decompress"));
  }
  // The records length inside the chunk disagrees with the record length.
  b = whole;
  std::uint32_t clen = 0;
  std::memcpy(&clen, b.data() + c0 + 9 + 28, 4);
  const std::size_t rlen_at = c0 + 9 + 28 + 4 + clen;
  std::uint64_t rlen = 0;
  std::memcpy(&rlen, b.data() + rlen_at, 8);
  put<std::uint64_t>(b, rlen_at, rlen + 1);
  {
    mcap::Reader r(b, "rlen.mcap");
    CHECK(read_all(r) < all);
    CHECK(has_warning(r, c0, "disagrees with the record length"));
  }
  // A record longer than the file, found by the scan (summary bypassed).
  b = whole;
  put<std::uint64_t>(b, c0 + 1, std::uint64_t{1} << 40);
  {
    mcap::ReaderOptions o;
    o.force_scan = true;
    mcap::Reader r(b, "long.mcap", o);
    INFO(warnings_of(r));
    CHECK(has_warning(r, c0, "runs past the end of the file"));
    CHECK(read_all(r) == 0);
  }
  // An unknown compression.
  b = whole;
  REQUIRE(b.compare(c0 + 9 + 32, 4, "zstd") == 0);
  b.replace(c0 + 9 + 32, 4, "zstX");
  {
    mcap::Reader r(b, "comp.mcap");
    CHECK(read_all(r) < all);
    CHECK(has_warning(r, c0, "unknown chunk compression \"zstX\""));
  }
  // A damaged summary (CRC set by @mcap/core, one byte flipped): the reader falls back to the scan and
  // still reads every message.
  b = whole;
  std::uint64_t summary_start = 0;
  std::memcpy(&summary_start, b.data() + b.size() - 8 - 20, 8);
  b[summary_start + 20] ^= 0x55;
  {
    mcap::Reader r(b, "summary.mcap");
    CHECK_FALSE(r.summary_used());
    CHECK(read_all(r) == all);
    bool fallback = false;
    for (const auto& w : r.warnings()) fallback = fallback || w.index_fallback;
    CHECK(fallback);
  }
}

TEST_CASE("cdr bad input: string and sequence lengths beyond the message, bad encapsulation", "[io][cdr][ros2][bad]") {
  io::ros::StampedTransform t;
  t.header.stamp_ns = 1'500'000'000'123;
  t.header.frame_id = "odom";
  t.child_frame_id = "base";
  t.transform.t = Eigen::Vector3d(1, 2, 3);
  const std::string ok = io::ros::encode<msg::TFMessage>(Wire::cdr, {t, t});
  const auto back = io::ros::decode<msg::TFMessage>(Wire::cdr, ok, "m");
  REQUIRE(back.size() == 2);
  CHECK(back[1].child_frame_id == "base");
  CHECK(back[1].header.stamp_ns == t.header.stamp_ns);
  std::string b = ok;
  put<std::uint32_t>(b, 4, 1000000);  // transform count
  CHECK_THROWS_WITH(
      io::ros::decode<msg::TFMessage>(Wire::cdr, b, "topic /tf"),
      Catch::Contains("topic /tf") && Catch::Contains("sequence length 1000000 exceeds the message"));
  b = ok;
  put<std::uint32_t>(b, 16, 0x7FFFFFFF);  // frame_id length (after count, sec, nanosec)
  CHECK_THROWS_WITH(io::ros::decode<msg::TFMessage>(Wire::cdr, b, "m"),
                    Catch::Contains("string length 2147483647 exceeds the message"));
  b = ok;
  b[20 + 4] = 'X';  // the NUL of "odom"
  CHECK_THROWS_WITH(io::ros::decode<msg::TFMessage>(Wire::cdr, b, "m"),
                    Catch::Contains("not NUL-terminated"));
  b = ok;
  b[1] = 3;  // PL_CDR_LE: not plain CDR
  CHECK_THROWS_WITH(io::ros::decode<msg::TFMessage>(Wire::cdr, b, "m"), Catch::Contains("not plain CDR"));
  for (std::size_t cut = 0; cut < ok.size() - 3; ++cut)
    CHECK_THROWS_AS(io::ros::decode<msg::TFMessage>(Wire::cdr, ok.substr(0, cut), "m"), InputError);
  CHECK_THROWS_WITH(io::ros::decode<msg::TFMessage>(Wire::cdr, ok + std::string(8, '\0'), "m"),
                    Catch::Contains("trailing bytes"));
  // Big-endian CDR of the same message decodes to the same values.
  std::string be(4, '\0');  // encapsulation 0x00 0x00: CDR big-endian
  auto u32be = [&](std::uint32_t v) {
    while ((be.size() - 4) % 4) be.push_back('\0');
    for (int k = 3; k >= 0; --k) be.push_back(static_cast<char>((v >> (8 * k)) & 0xFF));
  };
  auto f64be = [&](double d) {
    while ((be.size() - 4) % 8) be.push_back('\0');
    std::uint64_t v;
    std::memcpy(&v, &d, 8);
    for (int k = 7; k >= 0; --k) be.push_back(static_cast<char>((v >> (8 * k)) & 0xFF));
  };
  auto strbe = [&](const std::string& s) {
    u32be(static_cast<std::uint32_t>(s.size() + 1));
    be += s;
    be.push_back('\0');
  };
  u32be(1);
  u32be(1500);
  u32be(123);
  strbe("odom");
  strbe("base");
  for (double d : {1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0}) f64be(d);
  const auto bt = io::ros::decode<msg::TFMessage>(Wire::cdr, be, "be");
  REQUIRE(bt.size() == 1);
  CHECK(bt[0].header.stamp_ns == 1'500'000'000'123);
  CHECK(bt[0].transform.t == Eigen::Vector3d(1, 2, 3));
  CHECK(bt[0].transform.q.w() == 1.0);
}

TEST_CASE("rosbag2 bad input: not a rosbag2 database, not a bag, missing split file, bad metadata",
          "[io][rosbag2][ros2][bad]") {
  test::TempDir d;
  const fs::path db = d.path / "other.db3";
  sqlite3* h = nullptr;
  REQUIRE(sqlite3_open(db.c_str(), &h) == SQLITE_OK);
  REQUIRE(sqlite3_exec(h, "CREATE TABLE people(id INTEGER, name TEXT)", nullptr, nullptr, nullptr) == SQLITE_OK);
  sqlite3_close(h);
  CHECK_THROWS_WITH(io::open_bag(db), Catch::Contains("other.db3") && Catch::Contains("not a rosbag2 bag") &&
                                          Catch::Contains("people"));
  CHECK_THROWS_WITH(io::open_bag(d.write("fake.db3", "just text, not a database")),
                    Catch::Contains("fake.db3") && Catch::Contains("not a bag roe reads"));
  // A truncated .db3 (first page only): an error naming the file, never a crash.
  const std::string sq = slurp(kDir / "rs_sqlite/rs_sqlite_0.db3");
  CHECK_THROWS_AS(io::open_bag(d.write("cut.db3", sq.substr(0, 4096))), InputError);

  fs::copy(kDir / "rs_split", d.path / "split");
  fs::remove(d.path / "split/rs_split_0.mcap");
  CHECK_THROWS_WITH(io::open_bag(d.path / "split"), Catch::Contains("rs_split_0.mcap") && Catch::Contains("missing"));
  io::BagOpenOptions o;
  o.allow_missing_files = true;
  const auto salvaged = io::open_bag(d.path / "split", o);
  CHECK(salvaged->damaged());
  CHECK(salvaged->first_damage().find("rs_split_0.mcap") != std::string::npos);

  const std::string meta = slurp(kDir / "rs_split/metadata.yaml");
  fs::create_directories(d.path / "m1");
  d.write("m1/metadata.yaml", meta.substr(0, meta.find("  compression_format")) +
                                  "  compression_format: lzma\n  compression_mode: FILE\n  relative_file_paths:\n    - x.mcap\n");
  CHECK_THROWS_WITH(io::open_bag(d.path / "m1"), Catch::Contains("unknown compression format \"lzma\"") &&
                                                     Catch::Contains("compression_format"));
  d.write("m1/metadata.yaml", "rosbag2_bagfile_information:\n  relative_file_paths:\n    - ../../etc/passwd\n");
  CHECK_THROWS_WITH(io::open_bag(d.path / "m1"), Catch::Contains("not a file inside the bag folder"));
  d.write("m1/metadata.yaml", "rosbag2_bagfile_information: [1, 2\n");
  CHECK_THROWS_WITH(io::open_bag(d.path / "m1"), Catch::Contains("metadata.yaml:"));
  // Shapes yaml-cpp refuses to subscript (fuzz_rosbag2_metadata findings, issue 40): input errors, not exit 3.
  for (const char* text : {"just a scalar\n", "- a\n- b\n",
                           "rosbag2_bagfile_information:\n  relative_file_paths: [x.db3]\n  topics_with_message_count: [1, 2]\n"}) {
    d.write("m1/metadata.yaml", text);
    CHECK_THROWS_AS(io::open_bag(d.path / "m1"), InputError);
  }
}

TEST_CASE("rosbag2: file- and message-level zstd compression of a folder read like the plain one",
          "[io][rosbag2][ros2]") {
  test::TempDir d;
  const auto plain = io::open_bag(kDir / "rs_split");
  std::size_t n_plain = 0;
  std::set<std::string> all;
  for (const auto& t : plain->topics()) all.insert(t.topic);
  std::vector<std::string> payloads;
  plain->for_each(all, [&](const io::BagMessage& m) {
    ++n_plain;
    payloads.emplace_back(m.data);
    return true;
  });
  // FILE mode: each split file compressed as a whole (.mcap.zstd).
  const std::string meta = slurp(kDir / "rs_split/metadata.yaml");
  auto with = [&](const std::string& mode, const std::string& suffix) {
    std::string m = meta;
    m.replace(m.find("compression_format: ''"), 22, "compression_format: zstd");
    m.replace(m.find("compression_mode: ''"), 20, "compression_mode: " + mode);
    for (const char* f : {"rs_split_0.mcap", "rs_split_1.mcap"}) {
      const std::size_t at = m.find(std::string("- ") + f);
      m.replace(at + 2, std::strlen(f), std::string(f) + suffix);
    }
    return m;
  };
  fs::create_directories(d.path / "file");
  d.write("file/metadata.yaml", with("FILE", ".zstd"));
  for (const char* f : {"rs_split_0.mcap", "rs_split_1.mcap"})
    d.write(std::string("file/") + f + ".zstd", io::zstd_compress(slurp(kDir / "rs_split" / f), 3));
  const auto file_bag = io::open_bag(d.path / "file");
  CHECK(file_bag->format() == "rosbag2 folder (mcap, zstd file compression)");
  std::size_t k = 0;
  file_bag->for_each(all, [&](const io::BagMessage& m) {
    CHECK(m.data == payloads.at(k++));
    return true;
  });
  CHECK(k == n_plain);
  // A truncated compressed file is an error naming it.
  const std::string z = slurp(d.path / "file/rs_split_1.mcap.zstd");
  d.write("file/rs_split_1.mcap.zstd", z.substr(0, z.size() / 2));
  CHECK_THROWS_WITH(io::open_bag(d.path / "file"), Catch::Contains("rs_split_1.mcap.zstd") && Catch::Contains("zstd"));
}

TEST_CASE("rosbag2: message-level zstd compression (SQLite) decompresses each message", "[io][rosbag2][ros2]") {
  test::TempDir d;
  fs::create_directories(d.path / "msg");
  fs::copy_file(kDir / "rs_sqlite/rs_sqlite_0.db3", d.path / "msg/rs_sqlite_0.db3");
  std::vector<std::string> plain;
  {
    const auto b = io::open_bag(kDir / "rs_sqlite");
    b->for_each({"/camera/camera/gyro/sample", "/tf_static"}, [&](const io::BagMessage& m) {
      plain.emplace_back(m.data);
      return true;
    });
  }
  sqlite3* h = nullptr;
  REQUIRE(sqlite3_open((d.path / "msg/rs_sqlite_0.db3").c_str(), &h) == SQLITE_OK);
  std::vector<std::pair<std::int64_t, std::string>> rows;
  sqlite3_stmt* s = nullptr;
  sqlite3_prepare_v2(h, "SELECT id, data FROM messages", -1, &s, nullptr);
  while (sqlite3_step(s) == SQLITE_ROW)
    rows.emplace_back(sqlite3_column_int64(s, 0),
                      std::string(static_cast<const char*>(sqlite3_column_blob(s, 1)),
                                  static_cast<std::size_t>(sqlite3_column_bytes(s, 1))));
  sqlite3_finalize(s);
  sqlite3_prepare_v2(h, "UPDATE messages SET data = ? WHERE id = ?", -1, &s, nullptr);
  for (const auto& [id, data] : rows) {
    const std::string z = io::zstd_compress(data, 3);
    sqlite3_bind_blob(s, 1, z.data(), static_cast<int>(z.size()), SQLITE_TRANSIENT);
    sqlite3_bind_int64(s, 2, id);
    REQUIRE(sqlite3_step(s) == SQLITE_DONE);
    sqlite3_reset(s);
  }
  sqlite3_finalize(s);
  sqlite3_close(h);
  std::string meta = slurp(kDir / "rs_sqlite/metadata.yaml");
  meta.replace(meta.find("compression_format: ''"), 22, "compression_format: zstd");
  meta.replace(meta.find("compression_mode: ''"), 20, "compression_mode: MESSAGE");
  d.write("msg/metadata.yaml", meta);
  const auto b = io::open_bag(d.path / "msg");
  std::size_t k = 0;
  b->for_each({"/camera/camera/gyro/sample", "/tf_static"}, [&](const io::BagMessage& m) {
    CHECK(m.data == plain.at(k++));
    return true;
  });
  CHECK(k == plain.size());
  CHECK_FALSE(b->damaged());
}

TEST_CASE("rosbag2: a folder without metadata.yaml and a lone zstd-compressed MCAP are read by content",
          "[io][rosbag2][ros2]") {
  test::TempDir d;
  fs::create_directories(d.path / "nometa");
  for (const char* f : {"rs_split_0.mcap", "rs_split_1.mcap"}) fs::copy_file(kDir / "rs_split" / f, d.path / "nometa" / f);
  const auto plain = io::open_bag(kDir / "rs_split");
  const auto nometa = io::open_bag(d.path / "nometa");
  CHECK(nometa->format() == "rosbag2 folder without metadata.yaml");
  CHECK(nometa->message_count("/camera/camera/imu") == plain->message_count("/camera/camera/imu"));
  CHECK(nometa->message_count("/camera/camera/imu") == 120);
  const fs::path z = d.write("recording.zst", io::zstd_compress(slurp(kDir / "rs_zstd.mcap"), 3));
  CHECK(io::detect_bag_kind(z) == "zstd");
  const auto zb = io::open_bag(z);
  CHECK(zb->message_count("/camera/camera/color/image_raw") == 6);
  std::size_t n = 0;
  zb->for_each({"/camera/camera/imu"}, [&](const io::BagMessage& m) {
    n += io::decode<msg::Imu>(m).header.frame_id == "camera_imu_optical_frame";
    return true;
  });
  CHECK(n == 120);
}

TEST_CASE("a negative ROS 2 header stamp is an input error naming the topic and message", "[io][ros2][hostile]") {
  // The real rosbag2 SQLite /tf bag with its first /tf message's stamp.sec set to -5 (CDR: 4 bytes of
  // encapsulation, the transforms' count, then header.stamp.sec as int32), patched with SQLite itself.
  const fs::path real = fs::path(ROE_SHARED_DATA_DIR) / "rosbag2/tf_example";
  if (!fs::exists(real)) {
    WARN("skipped: " << real << " absent");
    return;
  }
  roe::test::TempDir d("roe_test_ros2_negative_stamp");
  const fs::path bag = d.path / "tf_example";
  fs::copy(real, bag);
  const io::MocapData intact = io::read_bag_poses(bag, "/tf");
  CHECK(intact.poses.size() == 517);  // intact: read
  INFO("frames " << intact.parent_frame << " -> " << intact.body);
  sqlite3* db = nullptr;
  REQUIRE(sqlite3_open((bag / "tf_example.db3").string().c_str(), &db) == SQLITE_OK);
  sqlite3_stmt* q = nullptr;
  REQUIRE(sqlite3_prepare_v2(db, "SELECT id, data FROM messages WHERE topic_id = (SELECT id FROM topics WHERE name = '/tf') "
                                   "ORDER BY timestamp LIMIT 1", -1, &q, nullptr) == SQLITE_OK);
  REQUIRE(sqlite3_step(q) == SQLITE_ROW);
  const sqlite3_int64 id = sqlite3_column_int64(q, 0);
  std::string blob(static_cast<const char*>(sqlite3_column_blob(q, 1)), static_cast<std::size_t>(sqlite3_column_bytes(q, 1)));
  sqlite3_finalize(q);
  REQUIRE(blob.size() > 12);
  const std::int32_t sec = -5;
  std::memcpy(blob.data() + 8, &sec, 4);
  sqlite3_stmt* u = nullptr;
  REQUIRE(sqlite3_prepare_v2(db, "UPDATE messages SET data = ? WHERE id = ?", -1, &u, nullptr) == SQLITE_OK);
  sqlite3_bind_blob(u, 1, blob.data(), static_cast<int>(blob.size()), SQLITE_TRANSIENT);
  sqlite3_bind_int64(u, 2, id);
  REQUIRE(sqlite3_step(u) == SQLITE_DONE);
  sqlite3_finalize(u);
  sqlite3_close(db);
  CHECK_THROWS_WITH(io::read_bag_poses(bag, "/tf"),
                    Catch::Contains("negative header stamp") && Catch::Contains("/tf") &&
                        Catch::Contains("tf_example"));
  // The same through the tf buffer (BAG:/tf:PARENT.CHILD).
  CHECK_THROWS_WITH(io::read_bag_poses(bag, "/tf", intact.body, false, intact.parent_frame),
                    Catch::Contains("negative header stamp") && Catch::Contains("transform ") &&
                        Catch::Contains("tf_example"));
}
