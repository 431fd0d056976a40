// The committed tiny PoET bundle through roe: OpenCV Darknet taps and the LibTorch pose head
// reproduce the generator's reference outputs; the detector finds the rendered squares.
#include <catch2/catch.hpp>
#include <filesystem>
#include <set>
#include <unistd.h>

#include "roe/core/error.hpp"
#include "roe/infer/bundle.hpp"
#include "roe/infer/model.hpp"
#include "roe/infer/pose_head.hpp"
#include "roe/infer/tensor.hpp"
#include "roe/io/output.hpp"

namespace fs = std::filesystem;
using namespace roe::infer;

namespace {
const fs::path kTiny = fs::path(ROE_SOURCE_DIR) / "tests/models/tiny_poet";
}

TEST_CASE(".npy reader and writer", "[tensor]") {
  const HostTensor boxes = read_npy(kTiny / "selftest/boxes.npy");
  CHECK(boxes.shape == std::vector<std::int64_t>{4, 4});
  CHECK_FALSE(boxes.is_int);
  CHECK(boxes.f[15] == -1.0f);  // padding row
  const HostTensor cls = read_npy(kTiny / "selftest/classes.npy");
  CHECK(cls.is_int);
  CHECK(cls.i == std::vector<std::int64_t>{1, 2, 3, -1});
  const fs::path tmp = fs::temp_directory_path() / ("roe_npy_" + std::to_string(::getpid()) + ".npy");
  write_npy(tmp, boxes);
  CHECK(max_abs_diff(read_npy(tmp), boxes) == 0.0);
  roe::io::write_file_atomic(tmp, "not numpy");
  CHECK_THROWS_AS(read_npy(tmp), roe::InputError);
  fs::remove(tmp);
}

#ifdef ROE_HAVE_TORCH

TEST_CASE("tiny bundle: self-test within tolerance (pose head 1e-5, Darknet taps 1e-4)", "[model][torch]") {
  PoetModel model(read_bundle(kTiny));
  const SelfTestReport& r = model.selftest_report();
  REQUIRE(r.pose.size() == 2);
  for (const auto& [k, v] : r.pose) {
    INFO(k);
    CHECK(v <= 1e-5);
  }
  REQUIRE(r.detector.size() == 2);
  for (const auto& [k, v] : r.detector) {
    INFO(k);
    CHECK(v <= 1e-4);
  }
}

TEST_CASE("tiny pose head through LibTorch matches the reference outputs", "[model][torch]") {
  const PoetBundle b = read_bundle(kTiny);
  PoseHead head(b.pose.file, "cpu");
  std::vector<HostTensor> in;
  for (const auto& f : b.selftest.inputs) in.push_back(read_npy(f));
  const auto out = head.forward(in);
  REQUIRE(out.size() == 2);
  const HostTensor t_ref = read_npy(b.selftest.outputs[0]);
  const HostTensor r_ref = read_npy(b.selftest.outputs[1]);
  CHECK(out[0].shape == t_ref.shape);
  CHECK(out[1].shape == r_ref.shape);
  CHECK(max_abs_diff(out[0], t_ref) <= 1e-5);
  CHECK(max_abs_diff(out[1], r_ref) <= 1e-5);
}

TEST_CASE("tiny detector finds the rendered squares with PoET's NMS", "[model][torch]") {
  PoetModel model(read_bundle(kTiny));
  const HostTensor blob = model.preprocess(roe::io::read_file(kTiny / "selftest/detector_input.png"));
  const auto [boxes, feats] = model.run_detector(blob);
  // gen_tiny_poet.py renders class 1 at (30, 30), 2 at (90, 60), 3 at (64, 70), 24 px squares.
  REQUIRE(boxes.size() == 3);
  const double cx[4] = {0, 30, 90, 64}, cy[4] = {0, 30, 60, 70};
  std::set<int> classes;
  for (const auto& b : boxes) {
    INFO("class " << b.class_id);
    REQUIRE(b.class_id >= 1);
    REQUIRE(b.class_id <= 3);
    classes.insert(b.class_id);
    CHECK(std::abs((b.x1 + b.x2) / 2 - cx[b.class_id]) <= 2.0);
    CHECK(std::abs((b.y1 + b.y2) / 2 - cy[b.class_id]) <= 2.0);
    CHECK(b.x2 - b.x1 == Approx(24.0));
    CHECK(b.score > 0.4);
  }
  CHECK(classes.size() == 3);
  for (std::size_t k = 1; k < boxes.size(); ++k) CHECK(boxes[k - 1].score >= boxes[k].score);
  REQUIRE(feats.size() == 2);
  CHECK(feats[0].shape == std::vector<std::int64_t>{1, 3, 24, 32});
  CHECK(feats[1].shape == std::vector<std::int64_t>{1, 3, 12, 16});
}

TEST_CASE("a bundle whose reference outputs are not reproduced is refused", "[model][torch]") {
  const fs::path dir = fs::temp_directory_path() / ("roe_bad_bundle_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::copy(kTiny, dir, fs::copy_options::recursive);
  HostTensor t = read_npy(dir / "selftest/t.npy");
  t.f[1] += 1e-3f;
  write_npy(dir / "selftest/t.npy", t);
  try {
    PoetModel model(read_bundle(dir));
    FAIL("accepted a bundle with a wrong self-test output");
  } catch (const roe::InputError& e) {
    CHECK(std::string(e.what()).find("self-test failed: pose-head output t") != std::string::npos);
  }
  ModelOptions no_check;
  no_check.selftest = false;
  CHECK_NOTHROW(PoetModel(read_bundle(dir), no_check));
  fs::remove_all(dir);
}

TEST_CASE("full pipeline on one frame: boxes → queries → poses", "[model][torch]") {
  PoetModel model(read_bundle(kTiny));
  const auto r = model.infer(roe::io::read_file(kTiny / "selftest/detector_input.png"));
  REQUIRE(r.detections.size() == 3);
  for (const auto& d : r.detections) {
    const Eigen::Matrix3d R = d.T_C_O.R();
    CHECK((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-9);
    // The tiny head's pinhole prior: 24 px box at fx = 120 → z ≈ 120 · 0.06 / 24 = 0.3 m.
    CHECK(d.T_C_O.p.z() == Approx(0.3).margin(0.011));
    CHECK(d.score > 0.4);
  }
  CHECK(r.boxes_after_nms == 3);
}

#else

TEST_CASE("without LibTorch the pose head gives a clear error", "[model]") {
  CHECK_FALSE(PoseHead::available());
  try {
    PoseHead h(kTiny / "pose_head.ts");
    FAIL("no error");
  } catch (const roe::InputError& e) {
    CHECK(std::string(e.what()).find("without LibTorch") != std::string::npos);
  }
}

#endif
