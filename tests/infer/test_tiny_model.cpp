// The committed tiny PoET bundle through roe: OpenCV Darknet taps and the LibTorch pose head
// reproduce the generator's reference outputs; the detector finds the rendered squares.
#include <catch2/catch.hpp>
#include <filesystem>
#include <limits>
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

TEST_CASE(".npy format versions 2.0 and 3.0 (32-bit header length), float64 and int32 data", "[tensor]") {
  // The files NumPy writes when a header does not fit in 65535 bytes (2.0) or holds UTF-8 (3.0):
  // magic, version, a little-endian uint32 header length, the dict padded to 64 bytes, the data.
  const auto npy = [](char major, const std::string& dict, const std::string& data) {
    std::string h = dict;
    while ((12 + h.size() + 1) % 64 != 0) h += ' ';
    h += '\n';
    std::string out = std::string("\x93NUMPY", 6) + major + '\0';
    for (int k = 0; k < 4; ++k) out += static_cast<char>((h.size() >> (8 * k)) & 0xFF);
    return out + h + data;
  };
  std::string f8, i4;
  for (int k = 0; k < 6; ++k) {
    const double v = 0.25 * k - 0.5;
    f8.append(reinterpret_cast<const char*>(&v), 8);
  }
  for (std::int32_t v : {7, -3, 65536}) i4.append(reinterpret_cast<const char*>(&v), 4);
  const fs::path tmp = fs::temp_directory_path() / ("roe_npy2_" + std::to_string(::getpid()) + ".npy");
  roe::io::write_file_atomic(tmp, npy('\2', "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 3), }", f8));
  const HostTensor a = read_npy(tmp);
  CHECK(a.shape == std::vector<std::int64_t>{2, 3});
  CHECK_FALSE(a.is_int);
  CHECK(a.f == std::vector<float>{-0.5f, -0.25f, 0.0f, 0.25f, 0.5f, 0.75f});
  roe::io::write_file_atomic(tmp, npy('\3', "{'descr': '<i4', 'fortran_order': False, 'shape': (3,), }", i4));
  const HostTensor b = read_npy(tmp);
  CHECK(b.shape == std::vector<std::int64_t>{3});
  CHECK(b.is_int);
  CHECK(b.i == std::vector<std::int64_t>{7, -3, 65536});
  // A header length beyond the file is an error, not a read past the end.
  std::string cut = npy('\2', "{'descr': '<i4', 'fortran_order': False, 'shape': (3,), }", i4);
  cut[8] = '\xFF';
  roe::io::write_file_atomic(tmp, cut);
  CHECK_THROWS_WITH(read_npy(tmp), Catch::Contains("truncated .npy header"));
  roe::io::write_file_atomic(tmp, npy('\2', "{'descr': '<i4', 'fortran_order': False, 'shape': (3,), }", i4.substr(1)));
  CHECK_THROWS_WITH(read_npy(tmp), Catch::Contains("truncated .npy data (11 bytes for 3 elements)"));
  // What roe writes is format 1.0 with the data 64-byte aligned, as NumPy requires.
  write_npy(tmp, HostTensor::ints({2}, {5, -6}));
  const std::string w = roe::io::read_file(tmp);
  REQUIRE(w.size() > 10);
  CHECK(w[6] == '\1');
  const std::size_t header_len = static_cast<unsigned char>(w[8]) | (static_cast<std::size_t>(static_cast<unsigned char>(w[9])) << 8);
  CHECK((10 + header_len) % 64 == 0);
  CHECK(w.size() == 10 + header_len + 16);
  CHECK(read_npy(tmp).i == std::vector<std::int64_t>{5, -6});
  // max_abs_diff on integers is the largest |a - b|.
  CHECK(max_abs_diff(HostTensor::ints({3}, {1, 2, -4}), HostTensor::ints({3}, {1, 5, -5})) == 3.0);
  fs::remove(tmp);
}

TEST_CASE("pose-head queries: normalised cx, cy, w, h and class per box, PoET's -1 padding", "[model]") {
  std::vector<BoxDetection> boxes = {{10, 20, 50, 100, 0.9, 7}, {0, 0, 64, 32, 0.8, 2}};
  auto q = pose_queries(boxes, 3, 64, 128);
  REQUIRE(q.size() == 2);
  CHECK(q[0].shape == std::vector<std::int64_t>{3, 4});
  CHECK(q[0].f == std::vector<float>{30.0f / 64, 60.0f / 128, 40.0f / 64, 80.0f / 128,  // box 0
                                     0.5f, 0.125f, 1.0f, 0.25f,                          // box 1
                                     -1, -1, -1, -1});                                   // padding
  CHECK(q[1].shape == std::vector<std::int64_t>{3});
  CHECK(q[1].i == std::vector<std::int64_t>{7, 2, -1});
  // More boxes than queries: the best Q are kept.
  q = pose_queries(boxes, 1, 64, 128);
  CHECK(q[0].f.size() == 4);
  CHECK(q[1].i == std::vector<std::int64_t>{7});
}

#ifdef ROE_HAVE_TORCH

TEST_CASE("tiny bundle: self-test within tolerance (pose head 1e-5, Darknet taps 1e-4)", "[model][torch]") {
  PoetModel model(read_bundle(kTiny));
  const SelfTestReport& r = model.selftest_report();
  REQUIRE(r.pose.size() == 4);  // t, rotation and the aleatoric heads' log-variances
  for (const auto& [k, v] : r.pose) {
    INFO(k);
    CHECK(v <= 1e-5);
  }
  REQUIRE(r.detector.size() == 3);  // two taps and PoET's detections after NMS
  CHECK(r.detector[2].first == "detections after NMS");
  for (const auto& [k, v] : r.detector) {
    INFO(k);
    CHECK(v <= 1e-4);
  }
}

TEST_CASE("a damaged pose head is called damaged, not a torch version problem", "[model][torch]") {
  const fs::path dir = fs::temp_directory_path() / ("roe_bad_ts_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::copy(kTiny, dir, fs::copy_options::recursive);
  const std::string ts = roe::io::read_file(dir / "pose_head.ts");
  for (const std::string& content : {ts.substr(0, ts.size() / 2), std::string("not a zip file at all")}) {
    roe::io::write_file_atomic(dir / "pose_head.ts", content);
    try {
      PoetModel model(read_bundle(dir));
      FAIL("loaded a damaged pose head");
    } catch (const roe::InputError& e) {
      const std::string what = e.what();
      INFO(what);
      CHECK(what.find("not a readable TorchScript archive") != std::string::npos);
      CHECK(what.find("pose_head.ts") != std::string::npos);
    }
  }
  fs::remove_all(dir);
}

TEST_CASE("a bundle whose detections after NMS are not PoET's is refused", "[model][torch]") {
  const fs::path dir = fs::temp_directory_path() / ("roe_bad_dets_" + std::to_string(::getpid()));
  for (int what = 0; what < 3; ++what) {
    fs::remove_all(dir);
    fs::copy(kTiny, dir, fs::copy_options::recursive);
    HostTensor d = read_npy(dir / "selftest/detections.npy");
    if (what == 0) d.f[2] += 0.5f;  // a box corner half a pixel off
    if (what == 1) d.f[5] = 2.0f;   // another class
    if (what == 2) {                // one detection missing
      d.shape[0] -= 1;
      d.f.resize(d.f.size() - 6);
    }
    write_npy(dir / "selftest/detections.npy", d);
    INFO("case " << what);
    try {
      PoetModel model(read_bundle(dir));
      FAIL("accepted a bundle with wrong reference detections");
    } catch (const roe::InputError& e) {
      CHECK(std::string(e.what()).find("detections after NMS differ from PoET's") != std::string::npos);
    }
  }
  fs::remove_all(dir);
}

TEST_CASE("tiny pose head through LibTorch matches the reference outputs", "[model][torch]") {
  const PoetBundle b = read_bundle(kTiny);
  PoseHead head(b.pose.file, "cpu");
  std::vector<HostTensor> in;
  for (const auto& f : b.selftest.inputs) in.push_back(read_npy(f));
  const auto out = head.forward(in);
  REQUIRE(out.size() == 4);  // t, rotation, logvar_t, logvar_r
  REQUIRE(b.selftest.outputs.size() == 4);
  for (std::size_t k = 0; k < 4; ++k) {
    CAPTURE(k);
    const HostTensor ref = read_npy(b.selftest.outputs[k]);
    CHECK(out[k].shape == ref.shape);
    CHECK(max_abs_diff(out[k], ref) <= 1e-5);
  }
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
    // A 12 px anchor with size logits 0.8814: PoET's (2σ)² doubles it to 24 px (Darknet's exp() rule,
    // OpenCV's Region layer, would give 29 px).
    CHECK(b.x2 - b.x1 == Approx(24.0));
    CHECK(b.y2 - b.y1 == Approx(24.0));
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

TEST_CASE("the warp decision: the training camera (fx, fy to 1e-6, cx, cy to 1e-3 px) is not warped", "[model][torch]") {
  const PoetBundle b = read_bundle(kTiny);
  PoetModel model(b);
  const Intrinsics T = b.train_intrinsics;
  const int w = b.image.width, h = b.image.height;
  model.set_camera(w, h, T);
  CHECK_FALSE(model.warping());
  Intrinsics K = T;
  K.fx *= 1 + 5e-7;
  K.cy += 5e-4;
  model.set_camera(w, h, K);
  CHECK_FALSE(model.warping());  // inside the tolerances
  for (int k = 0; k < 4; ++k) {
    CAPTURE(k);
    K = T;
    if (k == 0) K.fx *= 1 + 1e-4;
    if (k == 1) K.fy *= 1 - 1e-4;
    if (k == 2) K.cx += 0.01;
    if (k == 3) K.cy -= 0.01;
    model.set_camera(w, h, K);
    CHECK(model.warping());
  }
  model.set_camera(w, h, std::nullopt);  // unknown intrinsics at the training size: used as they are
  CHECK_FALSE(model.warping());
  model.set_camera(w + 2, h, T);  // another size: resampled to the training camera
  CHECK(model.warping());
}

TEST_CASE("network input: (pixel x scale - mean) / std per channel", "[model][torch]") {
  PoetBundle b = read_bundle(kTiny);
  const std::string png = roe::io::read_file(kTiny / "selftest/detector_input.png");
  const HostTensor plain = PoetModel(b).preprocess(png);  // the tiny bundle: mean 0, std 1
  const double mean[3] = {0.485, 0.456, 0.406}, sd[3] = {0.229, 0.224, 0.225};  // ImageNet's, as PoET's
  for (int c = 0; c < 3; ++c) {
    b.image.mean[c] = mean[c];
    b.image.std[c] = sd[c];
  }
  ModelOptions opt;
  opt.selftest = false;  // the reference outputs were made with the tiny bundle's normalisation
  const HostTensor norm = PoetModel(b, opt).preprocess(png);
  REQUIRE(norm.shape == plain.shape);
  REQUIRE(plain.shape.size() == 4);
  const std::size_t plane = static_cast<std::size_t>(plain.shape[2] * plain.shape[3]);
  double worst = 0, spread = 0;
  for (std::size_t k = 0; k < plain.f.size(); ++k) {
    const int c = static_cast<int>(k / plane);
    worst = std::max(worst, std::abs(norm.f[k] - (plain.f[k] - mean[c]) / sd[c]));
    spread = std::max(spread, static_cast<double>(std::abs(plain.f[k] - plain.f[0])));
  }
  CHECK(worst < 1e-5);
  CHECK(spread > 0.1);  // the image is not uniform
}

TEST_CASE("pose-head outputs to detections: each query keeps its own translation, sigma, box and class", "[model][torch]") {
  PoetBundle b = read_bundle(kTiny);
  REQUIRE(b.pose.aleatoric);  // the tiny head has variance outputs; crafted ones below
  ModelOptions opt;
  opt.selftest = false;
  const PoetModel model(b, opt);
  const std::size_t Q = static_cast<std::size_t>(b.num_queries);
  REQUIRE(Q == 4);
  std::vector<float> t, r6, lv_t, lv_r;
  for (std::size_t q = 0; q < Q; ++q) {
    const float f = static_cast<float>(q);
    t.insert(t.end(), {0.125f + f, -0.25f - f, 0.5f + 2 * f});
    r6.insert(r6.end(), {1, 0, 0, 0, 1, 0});  // identity in either 6D convention
    lv_t.insert(lv_t.end(), {-8.0f + f, -7.0f + f, -6.0f + f});
    lv_r.insert(lv_r.end(), {-4.0f - f, -3.0f - f, -2.0f - f});
  }
  std::vector<BoxDetection> boxes;
  for (int q = 0; q < 3; ++q) boxes.push_back({10.0 + q, 20.0 + q, 40.0 + q, 60.0 + q, 0.9 - 0.1 * q, 2 + q});
  const auto dets = model.decode_outputs({HostTensor::floats({4, 3}, t), HostTensor::floats({4, 6}, r6),
                                          HostTensor::floats({4, 3}, lv_t), HostTensor::floats({4, 3}, lv_r)},
                                         boxes);
  REQUIRE(dets.size() == 3);  // one per box; the spare query is ignored
  for (std::size_t q = 0; q < 3; ++q) {
    CAPTURE(q);
    const double s = b.translation_scale;
    CHECK(dets[q].T_C_O.p.isApprox(s * Eigen::Vector3d(t[3 * q], t[3 * q + 1], t[3 * q + 2]), 1e-12));
    CHECK(dets[q].T_C_O.R().isApprox(Eigen::Matrix3d::Identity(), 1e-12));
    CHECK(dets[q].class_id == boxes[q].class_id);
    CHECK(dets[q].score == boxes[q].score);
    CHECK(dets[q].box == std::array<double, 4>{boxes[q].x1, boxes[q].y1, boxes[q].x2, boxes[q].y2});
    REQUIRE(dets[q].sigma.has_value());
    for (std::size_t k = 0; k < 3; ++k) {  // sigma = sqrt(exp(log-variance)), translation in metres
      CHECK((*dets[q].sigma)[k] == Approx(s * std::exp(0.5 * lv_t[3 * q + k])).epsilon(1e-12));
      CHECK((*dets[q].sigma)[3 + k] == Approx(std::exp(0.5 * lv_r[3 * q + k])).epsilon(1e-12));
    }
  }
  // A degenerate rotation (query 0: both 6D columns zero) and a non-finite translation (query 2) are
  // dropped and counted; query 1 survives.
  std::vector<float> r6_bad = r6, t_bad = t;
  std::fill(r6_bad.begin(), r6_bad.begin() + 6, 0.0f);
  t_bad[3 * 2 + 1] = std::numeric_limits<float>::quiet_NaN();
  std::size_t dropped = 0;
  const auto kept = model.decode_outputs({HostTensor::floats({4, 3}, t_bad), HostTensor::floats({4, 6}, r6_bad),
                                          HostTensor::floats({4, 3}, lv_t), HostTensor::floats({4, 3}, lv_r)},
                                         boxes, &dropped);
  CHECK(dropped == 2);
  REQUIRE(kept.size() == 1);
  CHECK(kept[0].class_id == boxes[1].class_id);
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
