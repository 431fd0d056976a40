// ROS bag v2.0 reader: round trips through the test-only writer (none/lz4/bz2, indexed and not),
// time ordering across chunks, damaged bags, message decoders, and the real files in ../shared/data.
#include <catch2/catch.hpp>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "fixtures/gen_d435i_bag.hpp"
#include "roe/io/ros/msgs.hpp"
#include "roe/io/ros/ros1_bag.hpp"

namespace fs = std::filesystem;
using namespace roe;
namespace ros1 = roe::io::ros1;
namespace ros = roe::io::ros;
namespace msg = roe::io::ros::msg;
using roe::io::ros::Wire;

namespace {

std::string small_bag(const std::string& compression, bool indexed = true, std::size_t chunk = 4096) {
  testing::BagWriter w(compression, chunk, indexed);
  for (int k = 0; k < 300; ++k) {
    ros::Imu m;
    m.header.stamp_ns = 1'000'000'000LL + k * 5'000'000LL;
    m.header.seq = static_cast<std::uint32_t>(k);
    m.angular_velocity = Eigen::Vector3d(k, -k, 0.5 * k);
    w.write("/imu", "sensor_msgs/Imu", m.header.stamp_ns, ros::encode<msg::Imu>(Wire::ros1, m));
    if (k % 10 == 0) {
      ros::StampedTransform p;
      p.header.stamp_ns = m.header.stamp_ns;
      p.transform.t = Eigen::Vector3d(k * 0.01, 0, 1);
      w.write("/pose", "geometry_msgs/PoseStamped", m.header.stamp_ns,
              ros::encode<msg::PoseStamped>(Wire::ros1, p));
    }
  }
  return w.finish();
}

std::vector<Timestamp> imu_stamps(ros1::Reader& r) {
  std::vector<Timestamp> t;
  r.for_each_topic({"/imu"}, [&](const ros1::MessageView& m) {
    const auto imu = ros::decode<msg::Imu>(Wire::ros1, m.data, "test");
    CHECK(imu.angular_velocity.x() == static_cast<double>(imu.header.seq));
    t.push_back(imu.header.stamp_ns);
    return true;
  });
  return t;
}

std::string shared(const char* rel) { return std::string(ROE_SHARED_DATA_DIR) + "/" + rel; }

// A bag's little-endian uint32 fields, read and overwritten in place (ROS's own uint32 coding).
std::uint32_t get_le32(const std::string& b, std::size_t at) {
  return ros::decode<msg::UInt32>(Wire::ros1, b.substr(at, 4), "test");
}
void put_le32(std::string& b, std::size_t at, std::uint32_t v) {
  b.replace(at, 4, ros::encode<msg::UInt32>(Wire::ros1, v));
}

std::size_t count_messages(ros1::Reader& r) {
  std::size_t n = 0;
  r.for_each_topic({"/imu", "/pose"}, [&](const ros1::MessageView&) {
    ++n;
    return true;
  });
  return n;
}

}  // namespace

TEST_CASE("rosbag: round trip for every compression, indexed and unindexed", "[io][rosbag]") {
  for (const char* comp : {"none", "lz4", "bz2"}) {
    for (bool indexed : {true, false}) {
      INFO(comp << (indexed ? " indexed" : " unindexed"));
      ros1::Reader r(small_bag(comp, indexed), "mem.bag");
      CHECK(r.indexed() == indexed);
      CHECK_FALSE(r.damaged());
      CHECK(r.chunks().size() > 5);
      for (const auto& c : r.chunks()) CHECK(c.compression == comp);
      CHECK(r.topics() == std::vector<std::string>{"/imu", "/pose"});
      CHECK(r.topic_type("/pose") == "geometry_msgs/PoseStamped");
      CHECK(r.message_count("/imu") == 300);
      CHECK(r.message_count("/pose") == 30);
      const auto t = imu_stamps(r);
      REQUIRE(t.size() == 300);
      CHECK(std::is_sorted(t.begin(), t.end()));
      CHECK(t.front() == 1'000'000'000LL);
      std::size_t poses = 0;
      r.for_each_topic({"/pose"}, [&](const ros1::MessageView& m) {
        const auto p = ros::decode<msg::PoseStamped>(Wire::ros1, m.data, "t");
        CHECK(p.transform.t.x() == Approx(poses * 0.1));
        ++poses;
        return true;
      });
      CHECK(poses == 30);
    }
  }
}

TEST_CASE("rosbag: force_scan gives the same content as the index", "[io][rosbag]") {
  const std::string b = small_bag("lz4");
  ros1::ReaderOptions o;
  o.force_scan = true;
  ros1::Reader a(b, "a"), s(b, "s", o);
  CHECK_FALSE(s.indexed());
  CHECK(a.message_count() == 330);
  CHECK(s.message_count() == 330);
  CHECK(imu_stamps(a) == imu_stamps(s));
  // The scan rebuilds each chunk's summary (times from its index records) exactly as the index has it.
  REQUIRE(a.chunks().size() == s.chunks().size());
  for (std::size_t k = 0; k < a.chunks().size(); ++k) {
    CAPTURE(k);
    CHECK(s.chunks()[k].offset == a.chunks()[k].offset);
    CHECK(s.chunks()[k].start_ns == a.chunks()[k].start_ns);
    CHECK(s.chunks()[k].end_ns == a.chunks()[k].end_ns);
    CHECK(s.chunks()[k].counts == a.chunks()[k].counts);
  }
}

TEST_CASE("rosbag: chunks beyond 64 KiB (growing decompression buffers) and progress totals", "[io][rosbag]") {
  for (const char* comp : {"none", "lz4", "bz2"}) {
    INFO(comp);
    ros1::Reader r(small_bag(comp, true, 1u << 20), "big.bag");
    REQUIRE(r.chunks().size() == 1);
    REQUIRE(r.chunks()[0].uncompressed_size > (1u << 16));  // the decompressors start at 64 KiB
    CHECK(r.message_count() == 330);
    std::size_t seen = 0, last_done = 0, last_total = 0, calls = 0;
    r.for_each_topic(
        {"/imu"},
        [&](const ros1::MessageView& m) {
          const auto imu = ros::decode<msg::Imu>(Wire::ros1, m.data, "test");
          CHECK(imu.header.seq == seen);
          CHECK(imu.angular_velocity.z() == 0.5 * seen);
          ++seen;
          return true;
        },
        [&](std::size_t done, std::size_t total) {
          ++calls;
          last_done = done;
          last_total = total;
        });
    CHECK(seen == 300);
    CHECK(calls == 300);
    CHECK(last_done == 300);
    CHECK(last_total == 300);  // the selected topic's messages only
  }
}

TEST_CASE("rosbag: iteration is in record-time order across chunks that overlap", "[io][rosbag]") {
  testing::BagWriter w("none", 200);
  // Written out of order: chunk times overlap.
  const std::vector<Timestamp> ts = {50, 10, 40, 20, 30, 60, 5, 70, 65, 1};
  for (std::size_t i = 0; i < ts.size(); ++i) {
    ros::Imu m;
    m.header.seq = static_cast<std::uint32_t>(i);
    w.write("/a", "sensor_msgs/Imu", ts[i] * 1'000'000, ros::encode<msg::Imu>(Wire::ros1, m));
  }
  ros1::Reader r(w.finish(), "mem");
  std::vector<Timestamp> got;
  r.for_each_topic({"/a"}, [&](const ros1::MessageView& m) {
    got.push_back(m.record_time_ns / 1'000'000);
    return true;
  });
  auto sorted = ts;
  std::sort(sorted.begin(), sorted.end());
  CHECK(got == sorted);
}

TEST_CASE("rosbag: early stop", "[io][rosbag]") {
  ros1::Reader r(small_bag("none"), "mem");
  std::size_t n = 0;
  r.for_each_topic({"/imu"}, [&](const ros1::MessageView&) { return ++n < 7; });
  CHECK(n == 7);
}

TEST_CASE("rosbag: wrong magic and other versions are InputErrors", "[io][rosbag]") {
  CHECK_THROWS_AS(ros1::Reader(std::string("hello world, not a bag at all"), "x"), InputError);
  CHECK_THROWS_WITH(ros1::Reader(std::string("#ROSBAG V1.2\nxxxxxxxxxxxxxxx"), "x"), Catch::Contains("version"));
  CHECK_THROWS_WITH(ros1::Reader(std::string(""), "x"), Catch::Contains("wrong magic"));
}

TEST_CASE("rosbag: a truncated bag yields its intact prefix and warns with the byte offset", "[io][rosbag]") {
  for (const char* comp : {"none", "lz4", "bz2"}) {
    const std::string full = small_bag(comp);
    for (double frac : {0.9, 0.5, 0.2, 0.01}) {
      INFO(comp << " cut at " << frac);
      const std::size_t cut = static_cast<std::size_t>(full.size() * frac);
      ros1::Reader r(full.substr(0, cut), "cut.bag");
      CHECK_FALSE(r.indexed());
      CHECK(r.damaged());
      bool offset_ok = false;
      for (const auto& w : r.warnings()) offset_ok = offset_ok || (w.damage && w.offset > 0 && w.offset <= cut);
      CHECK(offset_ok);
      CHECK(r.first_damage().find("byte ") == 0);
      const auto t = imu_stamps(r);
      // (A cut in the index section at the end loses no message.)
      if (frac <= 0.5) CHECK(t.size() < 300);
      // What was read is exactly a prefix of the full stream.
      for (std::size_t i = 0; i < t.size(); ++i) CHECK(t[i] == 1'000'000'000LL + static_cast<Timestamp>(i) * 5'000'000LL);
      if (frac >= 0.5) CHECK(t.size() > 50);
    }
  }
}

TEST_CASE("rosbag: a corrupt chunk is skipped with a warning, the others are read", "[io][rosbag]") {
  for (const char* comp : {"lz4", "bz2"}) {
    INFO(comp);
    std::string b = small_bag(comp);
    ros1::Reader clean(b, "clean");
    REQUIRE(clean.chunks().size() > 3);
    const auto& c = clean.chunks()[1];
    for (std::size_t i = 8; i < std::min<std::size_t>(c.data_size, 200); ++i) b[c.data_offset + i] ^= 0x5A;
    ros1::Reader r(b, "bad");
    const auto t = imu_stamps(r);
    CHECK(t.size() < 300);
    CHECK(t.size() > 200);
    CHECK(r.damaged());
    bool found = false;
    for (const auto& w : r.warnings())
      found = found || (w.offset == c.offset && w.message.find("decompress") != std::string::npos);
    CHECK(found);
  }
}

TEST_CASE("rosbag: a record whose lengths overrun its chunk ends the chunk there, with the reason", "[io][rosbag]") {
  const std::string clean_bytes = small_bag("none");
  ros1::Reader clean(clean_bytes, "clean");
  REQUIRE(clean.chunks().size() > 3);
  const ros1::ChunkInfo c = clean.chunks()[1];
  REQUIRE(c.compression == "none");
  // The chunk's records: [u32 header length][header][u32 data length][data] ... up to data_size.
  std::vector<std::size_t> records;
  for (std::size_t p = 0; p < c.data_size;) {
    records.push_back(p);
    const std::size_t hlen = get_le32(clean_bytes, c.data_offset + p);
    p += 8 + hlen + get_le32(clean_bytes, c.data_offset + p + 4 + hlen);
  }
  REQUIRE(records.size() > 2);
  const std::size_t last = records.back();  // a message record ending exactly at the chunk's end
  const std::uint32_t hlen = get_le32(clean_bytes, c.data_offset + last);
  const std::uint32_t dlen = get_le32(clean_bytes, c.data_offset + last + 4 + hlen);
  REQUIRE(last + 8 + hlen + dlen == c.data_size);
  const std::size_t all = count_messages(clean);

  const auto check_damage = [&](std::size_t field, std::uint32_t value, const std::string& why) {
    INFO(why);
    std::string b = clean_bytes;
    put_le32(b, c.data_offset + field, value);
    ros1::Reader r(b, "bad.bag");
    CHECK(count_messages(r) == all - 1);  // only the damaged record is lost
    bool found = false;
    for (const auto& w : r.warnings())
      found = found || (w.offset == c.offset &&
                        w.message.find("uncompressed offset " + std::to_string(last) + ": " + why) != std::string::npos);
    CHECK(found);
  };
  // One byte too long, for the data and for the header.
  check_damage(last + 4 + hlen, dlen + 1, "record data runs past the end");
  check_damage(last, static_cast<std::uint32_t>(c.data_size - last - 4 + 1), "record header runs past the end");
  // Lengths that wrap around when added to the offset.
  check_damage(last + 4 + hlen, 0xFFFFFFFFu, "record data runs past the end");
  check_damage(last, 0xFFFFFFF0u, "record header runs past the end");
}

TEST_CASE("rosbag: unknown compression and absurd sizes are skipped, not trusted", "[io][rosbag]") {
  std::string b = small_bag("none");
  ros1::Reader clean(b, "clean");
  const auto& c = clean.chunks()[0];
  // Rewrite the compression field value "none" → "zstd" in the chunk header.
  const std::size_t p = b.find("compression=none", c.offset);
  REQUIRE(p != std::string::npos);
  b.replace(p + 12, 4, "zstd");
  ros1::Reader r(b, "zstd");
  CHECK(imu_stamps(r).size() < 300);
  CHECK(r.first_damage().find("zstd") != std::string::npos);
}

TEST_CASE("ros_msgs: decoders check bounds and trailing bytes", "[io][rosbag]") {
  ros::Imu m;
  m.header.frame_id = "imu";
  const std::string enc = ros::encode<msg::Imu>(Wire::ros1, m);
  CHECK_NOTHROW(ros::decode<msg::Imu>(Wire::ros1, enc, "t"));
  CHECK_THROWS_WITH(ros::decode<msg::Imu>(Wire::ros1, enc.substr(0, enc.size() - 1), "imu.bag: /imu"),
                    Catch::Contains("imu.bag: /imu") && Catch::Contains("too short"));
  CHECK_THROWS_WITH(ros::decode<msg::Imu>(Wire::ros1, enc + "x", "t"), Catch::Contains("trailing"));
  ros::Image im;
  im.width = 4;
  im.height = 2;
  im.step = 12;
  im.encoding = "rgb8";
  const std::string px(23, '\1');  // one byte short of step x height
  im.data = px;
  CHECK_THROWS_AS(ros::decode<msg::Image>(Wire::ros1, ros::encode<msg::Image>(Wire::ros1, im), "t"),
                  InputError);
  // A huge length prefix must not allocate or read out of bounds.
  std::string evil = ros::encode<msg::UInt32>(Wire::ros1, 0) + ros::encode<msg::UInt32>(Wire::ros1, 0) +
                     ros::encode<msg::UInt32>(Wire::ros1, 0) +
                     ros::encode<msg::UInt32>(Wire::ros1, 0xFFFFFFF0u);
  CHECK_THROWS_AS(
      ros::decode<msg::TFMessage>(Wire::ros1, ros::encode<msg::UInt32>(Wire::ros1, 0x7FFFFFFF) + evil, "t"),
      InputError);
  CHECK_THROWS_AS(ros::decode<msg::CameraInfo>(Wire::ros1, evil, "t"), InputError);
  // Values survive a round trip.
  ros::CameraInfo ci;
  ci.width = 640;
  ci.distortion_model = "Inverse Brown Conrady";
  ci.D = {0.1, 0.2, 0.3, 0.4, 0.5};
  ci.K = {1, 0, 2, 0, 3, 4, 0, 0, 1};
  const auto back =
      ros::decode<msg::CameraInfo>(Wire::ros1, ros::encode<msg::CameraInfo>(Wire::ros1, ci), "t");
  CHECK(back.D == ci.D);
  CHECK(back.K == ci.K);
  CHECK(back.distortion_model == ci.distortion_model);
  // float32 fields (realsense_msgs/ImuIntrinsic, std_msgs/Float32), each value in its place.
  ros::ImuIntrinsic ii;
  for (std::size_t k = 0; k < ii.data.size(); ++k) ii.data[k] = 0.5f + static_cast<float>(k);
  for (std::size_t k = 0; k < ii.noise_variances.size(); ++k) ii.noise_variances[k] = -1.25f * (1.0f + k);
  for (std::size_t k = 0; k < ii.bias_variances.size(); ++k) ii.bias_variances[k] = 1e-6f * (3.0f + k);
  const auto iback =
      ros::decode<msg::ImuIntrinsic>(Wire::ros1, ros::encode<msg::ImuIntrinsic>(Wire::ros1, ii), "t");
  CHECK(iback.data == ii.data);
  CHECK(iback.noise_variances == ii.noise_variances);
  CHECK(iback.bias_variances == ii.bias_variances);
  CHECK_THROWS_WITH(
      ros::decode<msg::ImuIntrinsic>(Wire::ros1, ros::encode<msg::ImuIntrinsic>(Wire::ros1, ii) + "x", "t"),
      Catch::Contains("trailing"));
  const float f = -3.75f;
  std::string f_bytes(4, '\0');
  std::memcpy(f_bytes.data(), &f, 4);  // little-endian, as ROS serialises it (and every machine roe runs on)
  CHECK(ros::decode<msg::Float32>(Wire::ros1, f_bytes, "t") == f);
  CHECK_THROWS_AS(ros::decode<msg::Float32>(Wire::ros1, f_bytes.substr(1), "t"), InputError);
}

TEST_CASE("rosbag: the real RealSense recorder bag", "[io][rosbag][shared]") {
  const std::string f = shared("realsense/single_depth_color_640x480.bag");
  if (!fs::exists(f)) {
    WARN("skipped: " << f << " absent");
    return;
  }
  ros1::Reader r(f);
  CHECK(r.indexed());
  CHECK_FALSE(r.damaged());
  CHECK(r.connections().size() == 70);
  REQUIRE(r.chunks().size() == 2);
  CHECK(r.chunks()[0].compression == "lz4");
  CHECK(r.message_count("/device_0/sensor_0/Depth_0/image/data") == 2);
  CHECK(r.message_count("/device_0/sensor_1/Color_0/image/data") == 1);
  int seen = 0;
  r.for_each_topic({"/device_0/sensor_1/Color_0/info/camera_info", "/device_0/sensor_1/Color_0/image/data", "/file_version"},
                   [&](const ros1::MessageView& m) {
                     if (m.connection->topic == "/file_version") {
                       CHECK(ros::decode<msg::UInt32>(Wire::ros1, m.data, "v") ==
                             3);  // file_version 3 (SDK of 2018)
                     } else if (m.connection->type == "sensor_msgs/CameraInfo") {
                       const auto ci = ros::decode<msg::CameraInfo>(Wire::ros1, m.data, "ci");
                       CHECK(ci.K[0] == Approx(613.204).margin(1e-3));
                       CHECK(ci.K[4] == Approx(613.419).margin(1e-3));
                       CHECK(ci.K[2] == Approx(319.939).margin(1e-3));
                       CHECK(ci.K[5] == Approx(239.183).margin(1e-3));
                       CHECK(ci.distortion_model == "Brown Conrady");
                     } else {
                       const auto im = ros::decode<msg::Image>(Wire::ros1, m.data, "im");
                       CHECK(im.encoding == "rgb8");
                       CHECK(im.width == 640);
                       CHECK(im.step == 1920);
                       CHECK(im.data.size() == 921600);
                     }
                     ++seen;
                     return true;
                   });
  CHECK(seen == 3);
}

TEST_CASE("rosbag: the evo example bag (uncompressed, PoseStamped)", "[io][rosbag][shared]") {
  const std::string f = shared("rosbag/evo_ROS_example.bag");
  if (!fs::exists(f)) {
    WARN("skipped: " << f << " absent");
    return;
  }
  ros1::Reader r(f);
  CHECK(r.indexed());
  CHECK(r.message_count("groundtruth") == 12765);
  CHECK(r.message_count("ORB-SLAM") == 8362);
  CHECK(r.message_count("S-PTAM") == 5439);
  for (const auto& c : r.chunks()) CHECK(c.compression == "none");
}

TEST_CASE("ros_msgs: librealsense >= 2.49 images (header.version \"1\") end with 4 bytes of depth_units",
          "[io][rosbag]") {
  // third-party/realsense-file/rosbag/msgs/sensor_msgs/Image.h: when header.version (serialized in the
  // frame_id slot) is "1", a float32 depth_units follows the data, for colour frames too.
  ros::Image im;
  im.header = {7, 1'700'000'000'123'456'789LL, "1"};
  im.width = 2;
  im.height = 1;
  im.step = 6;
  im.encoding = "rgb8";
  const std::string px = "\x01\x02\x03\x04\x05\x06";
  im.data = px;
  im.depth_units = 0.001f;
  const std::string modern = ros::encode<msg::Image>(Wire::ros1, im);
  ros::Image old = im;
  old.header.frame_id = "0";
  const std::string old_bytes = ros::encode<msg::Image>(Wire::ros1, old);
  REQUIRE(modern.size() == old_bytes.size() + 4);
  const auto back = ros::decode<msg::Image>(Wire::ros1, modern, "modern.bag: /image");
  CHECK(back.depth_units == 0.001f);
  CHECK(back.data == px);
  CHECK(back.header.stamp_ns == im.header.stamp_ns);
  CHECK(ros::decode<msg::Image>(Wire::ros1, old_bytes, "t").depth_units == 0.0f);
  // Other trailing bytes are still malformed: 4 bytes after an old-layout image, or more than 4.
  CHECK_THROWS_WITH(ros::decode<msg::Image>(Wire::ros1, old_bytes + std::string(4, '\0'), "old.bag: /image"),
                    Catch::Contains("old.bag: /image") && Catch::Contains("4 unexpected trailing bytes"));
  CHECK_THROWS_WITH(ros::decode<msg::Image>(Wire::ros1, modern + "x", "t"),
                    Catch::Contains("5 unexpected trailing bytes"));
  CHECK_THROWS_WITH(ros::decode<msg::Image>(Wire::ros1, modern + "abcd", "t"),
                    Catch::Contains("8 unexpected trailing bytes"));
  CHECK_THROWS_AS(ros::decode<msg::Image>(Wire::ros1, modern.substr(0, modern.size() - 2), "t"), InputError);
}

TEST_CASE("rosbag: damage() names the most specific problem first, the index fallback after it", "[io][rosbag]") {
  const std::string full = small_bag("none");
  const std::size_t cut = full.size() / 2;
  ros1::Reader r(full.substr(0, cut), "cut.bag");
  const auto d = r.damage();
  REQUIRE(d.size() == 2);
  // The scan's truncated record (where the data ends) before "index position past the end of the file".
  CHECK_FALSE(d[0].index_fallback);
  CHECK(d[0].message.find("truncated record") == 0);
  CHECK(d[0].offset > 13);
  CHECK(d[0].offset <= cut);
  CHECK(d[1].index_fallback);
  CHECK(d[1].message.find("index position") == 0);
  CHECK(d[1].offset == 13);
  CHECK(r.first_damage().find("byte 13: index position") == 0);  // file order is kept there
  // An intact bag has none; an unindexed one only a note, not damage.
  CHECK(ros1::Reader(full, "ok.bag").damage().empty());
  CHECK(ros1::Reader(small_bag("none", false), "unindexed.bag").damage().empty());
}
