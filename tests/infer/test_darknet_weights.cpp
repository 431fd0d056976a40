// The Darknet weights file must have exactly the size the cfg's layers need: OpenCV reads a
// truncated file without complaint (and ignores extra bytes), so roe checks it before loading.
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "roe/core/error.hpp"
#include "roe/infer/bundle.hpp"
#include "roe/infer/model.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"

namespace fs = std::filesystem;
using namespace roe::infer;

namespace {
const fs::path kTiny = fs::path(ROE_SOURCE_DIR) / "tests/models/tiny_poet";

struct TmpDir {
  fs::path path;
  explicit TmpDir(const std::string& name)
      : path(fs::temp_directory_path() / ("roe_darknet_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TmpDir() { fs::remove_all(path); }
};

// A Darknet weights file: version major.minor.revision, "seen", then `n` float32 values.
std::string weights_file(std::int32_t major, std::int32_t minor, std::size_t n) {
  std::string s;
  const std::int32_t head[3] = {major, minor, 5};
  s.append(reinterpret_cast<const char*>(head), sizeof head);
  s.append(major * 10 + minor >= 2 ? 8 : 4, '\0');
  s.append(4 * n, '\0');
  return s;
}

std::string error_of(const fs::path& cfg, const fs::path& weights) {
  try {
    check_darknet_weights(cfg, weights);
  } catch (const roe::InputError& e) {
    return e.what();
  }
  return "";
}

// Layers whose parameters follow each of OpenCV's shape rules. The count was checked against
// OpenCV 4.6's readNetFromDarknet: with the values 1, 2, 3, ... in the file, the largest value in
// the loaded layers' blobs is 27382.
const char* kCfg = R"([net]
width=64
height=32
channels=3

# 0: BN conv, 16 x 3 x 3x3 weights + 4 x 16
[convolutional]
batch_normalize=1
filters=16
size=3
stride=1
pad=1
activation=mish

[maxpool]
size=2
stride=2

# 2: grouped conv, 8 x 16/4 x 3x3 + 8 biases
[convolutional]
filters=8
groups=4
size=3
stride=1
pad=1
activation=leaky

# 3: 8 + 16 channels; 4: x4 channels
[route]
layers=-1,-2

[reorg]
stride=2

# 5: 10 x 96 + 10
[convolutional]
filters=10
size=1
activation=linear

[upsample]
stride=2

[shortcut]
from=-5

# 8: inputs = 10 x 32 x 16 (OpenCV's shape: route keeps the spatial size), BN: 5 x 5120 + 4 x 5
[connected]
batch_normalize=1
output=5
activation=linear
)";
}  // namespace

TEST_CASE("darknet_parameter_count follows OpenCV's Darknet importer", "[darknet]") {
  CHECK(darknet_parameter_count(kCfg) == std::optional<std::uint64_t>(27382));
  // The tiny bundle: 3 x 3 + 3, 3 x 3 x 29² + 3, 8 x 6 + 8 (route 1,4: 3 + 3 channels).
  CHECK(darknet_parameter_count(roe::io::read_file(kTiny / "detector.cfg")) == std::optional<std::uint64_t>(7640));
  // What OpenCV refuses is left to OpenCV's own message.
  CHECK_FALSE(darknet_parameter_count("[net]\nwidth=32\n[deconvolutional]\nfilters=3\nsize=1\n"));
  CHECK_FALSE(darknet_parameter_count("[net]\nwidth=32\n[route]\nlayers=3\n"));
  CHECK_FALSE(darknet_parameter_count("[net]\nwidth=32\n"));
  // A route with groups (YOLOv4-tiny: groups=2 group_id=1) passes on one group's channels:
  // conv 8 x 3 x 3x3 + 8, route 8/2 = 4 channels, conv 4 x 4 x 3x3 + 4 = 224 + 148 (as OpenCV 4.6 loads it).
  const std::string grouped = "[net]\nwidth=32\nheight=32\nchannels=3\n"
                              "[convolutional]\nfilters=8\nsize=3\nstride=1\npad=1\n"
                              "[route]\nlayers=-1\ngroups=2\ngroup_id=1\n"
                              "[convolutional]\nfilters=4\nsize=3\nstride=1\npad=1\n";
  CHECK(darknet_parameter_count(grouped) == std::optional<std::uint64_t>(224 + 148));
  CHECK_FALSE(darknet_parameter_count("[net]\nwidth=32\nchannels=3\n[convolutional]\nfilters=3\nsize=1\n"
                                      "[route]\nlayers=-1\ngroups=2\n"));  // 3 channels in 2 groups
}

TEST_CASE("a Darknet weights file of the wrong size is refused with both sizes", "[darknet]") {
  TmpDir tmp("size");
  const fs::path cfg = tmp.path / "net.cfg", w = tmp.path / "net.weights";
  roe::io::write_file_atomic(cfg, kCfg);
  roe::io::write_file_atomic(w, weights_file(0, 2, 27382));
  CHECK(error_of(cfg, w).empty());
  // Before version 0.2 "seen" is 4 bytes: a 16-byte header.
  roe::io::write_file_atomic(w, weights_file(0, 1, 27382));
  CHECK(error_of(cfg, w).empty());
  roe::io::write_file_atomic(w, weights_file(0, 2, 27381));
  std::string e = error_of(cfg, w);
  CHECK_THAT(e, Catch::Contains(w.string()));
  CHECK_THAT(e, Catch::Contains("has 109544 bytes, but the layers of net.cfg need 109548 (a 20-byte header + 27382 float32 parameters)"));
  CHECK_THAT(e, Catch::Contains("truncated"));
  roe::io::write_file_atomic(w, weights_file(0, 2, 27383));
  e = error_of(cfg, w);
  CHECK_THAT(e, Catch::Contains("has 109552 bytes, but the layers of net.cfg need 109548"));
  CHECK_THAT(e, Catch::Contains("4 byte(s) too many"));
  roe::io::write_file_atomic(w, "abc");
  CHECK_THAT(error_of(cfg, w), Catch::Contains("has 3 bytes, but the layers of net.cfg need 109544"));
}

TEST_CASE("a bundle with truncated detector weights and no detector self-test is refused on load", "[darknet]") {
  TmpDir tmp("bundle");
  const fs::path dir = tmp.path / "bundle";
  fs::copy(kTiny, dir, fs::copy_options::recursive);
  const std::string full = roe::io::read_file(dir / "detector.weights");
  roe::io::write_file_atomic(dir / "detector.weights", full.substr(0, 1000));
  auto manifest = roe::io::parse_json_file(dir / kBundleManifest);
  manifest["detector"].erase("selftest");  // optional: nothing else would notice the damage
  roe::io::write_file_atomic(dir / kBundleManifest, manifest.dump(2));
  try {
    PoetModel model(read_bundle(dir));
    FAIL("accepted truncated detector weights");
  } catch (const roe::InputError& e) {
    CHECK(e.context().file == (dir / "detector.weights").string());
    CHECK_THAT(std::string(e.what()), Catch::Contains("has 1000 bytes, but the layers of detector.cfg need 30580"));
  }
  roe::io::write_file_atomic(dir / "detector.weights", full + full);
  CHECK_THROWS_WITH(PoetModel(read_bundle(dir)), Catch::Contains("30580 byte(s) too many"));
}

#ifdef ROE_HAVE_TORCH
TEST_CASE("external boxes of a class the bundle lacks are an InputError, not a pose-head crash", "[darknet][torch]") {
  PoetModel model(read_bundle(kTiny));
  const std::string img = roe::io::read_file(kTiny / "selftest/detector_input.png");
  BoxDetection b;
  b.x1 = 10, b.y1 = 10, b.x2 = 34, b.y2 = 34, b.score = 0.9;
  for (int cls : {4, 1000000000, 0, -1}) {
    b.class_id = cls;
    const std::vector<BoxDetection> boxes{b};
    CHECK_THROWS_WITH(model.infer(img, &boxes, "frame.png"),
                      Catch::Contains("box class " + std::to_string(cls) + " is not a class of model tiny-poet"));
  }
  b.class_id = 3;
  const std::vector<BoxDetection> ok{b};
  CHECK(model.infer(img, &ok).detections.size() == 1);
}
#endif

TEST_CASE("the [yolo] heads of a cfg: anchors picked by mask, classes, errors naming the cfg", "[darknet]") {
  const std::string net = "[net]\nwidth=64\nheight=64\nchannels=3\n[convolutional]\nfilters=8\nsize=1\nactivation=linear\n";
  // PoET's layout: nine anchors, each head takes three by its mask.
  const auto heads = darknet_yolo_heads(net +
                                            "[yolo]\nmask = 0,1,2\nanchors = 12, 16, 19, 36, 40, 28, 36, 75, 76, 55, 72, "
                                            "146, 142, 110, 192, 243, 459, 401\nclasses=21\nscale_x_y = 1.05\n"
                                            "[convolutional]\nfilters=8\nsize=1\nactivation=linear\n"
                                            "[yolo]\nmask = 6,7,8\nanchors = 12, 16, 19, 36, 40, 28, 36, 75, 76, 55, "
                                            "72, 146, 142, 110, 192, 243, 459, 401\nclasses=21\n",
                                        "y.cfg");
  REQUIRE(heads.size() == 2);
  CHECK(heads[0].classes == 21);
  CHECK(heads[0].anchors == std::vector<std::array<float, 2>>{{12, 16}, {19, 36}, {40, 28}});
  CHECK(heads[1].anchors == std::vector<std::array<float, 2>>{{142, 110}, {192, 243}, {459, 401}});
  // No mask: every anchor.
  CHECK(darknet_yolo_heads(net + "[yolo]\nanchors=1,2,3,4\nclasses=2\n", "y.cfg")[0].anchors.size() == 2);
  CHECK_THROWS_WITH(darknet_yolo_heads(net + "[yolo]\nmask=2\nanchors=1,2,3,4\nclasses=2\n", "y.cfg"),
                    Catch::Contains("y.cfg") && Catch::Contains("mask index 2 has no anchor"));
  CHECK_THROWS_WITH(darknet_yolo_heads(net + "[yolo]\nmask=0\nanchors=1,2,3\nclasses=2\n", "y.cfg"),
                    Catch::Contains("w,h pairs"));
  CHECK_THROWS_WITH(darknet_yolo_heads(net + "[yolo]\nmask=0\nanchors=1,x\nclasses=2\n", "y.cfg"),
                    Catch::Contains("w,h pairs"));
  CHECK_THROWS_WITH(darknet_yolo_heads(net + "[yolo]\nmask=0\nanchors=1,2\n", "y.cfg"),
                    Catch::Contains("classes must be a positive number"));
}
