// PoET's rotation outputs → proper rotations, and PoET's detector post-processing rules.
#include <catch2/catch.hpp>
#include <cmath>
#include <random>
#include <vector>

#include "roe/infer/nms.hpp"
#include "roe/infer/rotation.hpp"
#include "roe/math/so3.hpp"

using namespace roe::infer;

namespace {
bool is_rotation(const Eigen::Matrix3d& R) {
  return (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-12 && std::abs(R.determinant() - 1.0) < 1e-12;
}
}  // namespace

TEST_CASE("6D → R: Gram-Schmidt of the first two columns", "[rotation]") {
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int k = 0; k < 50; ++k) {
    const Eigen::Matrix3d R0 = roe::math::exp_so3(Eigen::Vector3d(n(rng), n(rng), n(rng)));
    // Scaled and skewed columns (what a network outputs): a ∝ x, b = y + α x.
    const double alpha = n(rng), sa = 0.5 + std::abs(n(rng)), sb = 0.5 + std::abs(n(rng));
    const Eigen::Vector3d a = sa * R0.col(0);
    const Eigen::Vector3d b = sb * (R0.col(1) + alpha * R0.col(0));
    const double r[6] = {a.x(), a.y(), a.z(), b.x(), b.y(), b.z()};
    const auto R = rotation_from_6d(r);
    REQUIRE(R);
    CHECK(is_rotation(*R));
    CHECK((*R - R0).norm() < 1e-12);
  }
  // arbitrary values still give a proper rotation
  for (int k = 0; k < 50; ++k) {
    double r[6];
    for (double& v : r) v = n(rng);
    const auto R = rotation_from_6d(r);
    REQUIRE(R);
    CHECK(is_rotation(*R));
    CHECK(R->col(0).dot(Eigen::Vector3d(r[0], r[1], r[2]).normalized()) == Approx(1.0));
  }
  const double zero[6] = {0, 0, 0, 0, 1, 0};
  CHECK_FALSE(rotation_from_6d(zero));
  const double parallel[6] = {1, 0, 0, 2, 0, 0};
  CHECK_FALSE(rotation_from_6d(parallel));
  const double nan[6] = {NAN, 0, 0, 0, 1, 0};
  CHECK_FALSE(rotation_from_6d(nan));
}

TEST_CASE("quaternion (w first) and matrix outputs → R", "[rotation]") {
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  const double wxyz[4] = {2 * q.w(), 2 * q.x(), 2 * q.y(), 2 * q.z()};  // not normalised
  const auto R = rotation_from_output(RotationFormat::kQuatWxyz, wxyz);
  REQUIRE(R);
  CHECK(is_rotation(*R));
  CHECK((*R - q.toRotationMatrix()).norm() < 1e-12);
  const double zero[4] = {0, 0, 0, 0};
  CHECK_FALSE(rotation_from_quat_wxyz(zero));
  Eigen::Matrix3d M = q.toRotationMatrix();
  M(0, 1) += 1e-4;
  double m[9];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m[3 * r + c] = M(r, c);
  const auto R2 = rotation_from_output(RotationFormat::kMatrix, m);
  REQUIRE(R2);
  CHECK(is_rotation(*R2));
  CHECK((*R2 - q.toRotationMatrix()).norm() < 1e-3);
  CHECK(parse_rotation_format("6d") == RotationFormat::k6d);
  CHECK_FALSE(parse_rotation_format("euler"));
  CHECK(rotation_size(RotationFormat::kMatrix) == 9);
}

TEST_CASE("YOLO head decoding follows PoET's detector (Scaled-YOLOv4), not Darknet's exp() rule", "[nms]") {
  // One anchor (10 x 10 px), one class, a 1 x 1 grid at stride 8: tx, ty, tw, th = 1, 0.5, 1, −0.5,
  // objectness logit 0, class logit −1.
  YoloHead head;
  head.anchors = {{10.0f, 10.0f}};
  head.classes = 1;
  const float raw[6] = {1.0f, 0.5f, 1.0f, -0.5f, 0.0f, -1.0f};
  const auto rows = decode_yolo_head(raw, head, 1, 1, 8.0f);
  REQUIRE(rows.size() == 6);
  const auto sig = [](double v) { return 1.0 / (1.0 + std::exp(-v)); };
  CHECK(rows[0] == Approx((2 * sig(1.0) - 0.5) * 8));   // 7.697 (Darknet: 5.85 + ... with exp rule)
  CHECK(rows[1] == Approx((2 * sig(0.5) - 0.5) * 8));   // 5.959
  CHECK(rows[2] == Approx(std::pow(2 * sig(1.0), 2) * 10));   // 21.38 (Darknet: e·10 = 27.18)
  CHECK(rows[3] == Approx(std::pow(2 * sig(-0.5), 2) * 10));  // 5.70
  CHECK(rows[4] == Approx(0.5));
  CHECK(rows[5] == Approx(0.5 * sig(-1.0)));  // 0.134: kept with a low threshold (OpenCV zeroes ≤ 0.2)
  NmsOptions low;
  low.conf_thresh = 0.1;
  const auto c = yolo_candidates(rows.data(), 1, 6, 1, 1, low);
  REQUIRE(c.size() == 1);
  CHECK(c[0].x1 == Approx(rows[0] - rows[2] / 2));
  CHECK(c[0].score == Approx(0.5 * sig(-1.0)));

  // Two anchors on a 2 x 3 grid: rows in PyTorch's order (anchor, row, column), each cell offset by
  // its column and row, each anchor with its own size.
  YoloHead two;
  two.anchors = {{4.0f, 6.0f}, {20.0f, 10.0f}};
  two.classes = 2;
  const int ny = 2, nx = 3, no = 7;
  std::vector<float> in(2 * no * ny * nx, 0.0f);  // all logits 0: σ = 0.5
  const auto r2 = decode_yolo_head(in.data(), two, ny, nx, 16.0f);
  REQUIRE(r2.size() == static_cast<std::size_t>(2 * ny * nx * no));
  for (int a = 0; a < 2; ++a)
    for (int y = 0; y < ny; ++y)
      for (int x = 0; x < nx; ++x) {
        const float* row = r2.data() + ((a * ny + y) * nx + x) * no;
        INFO(a << " " << y << " " << x);
        CHECK(row[0] == Approx((0.5 + x) * 16));
        CHECK(row[1] == Approx((0.5 + y) * 16));
        CHECK(row[2] == Approx(two.anchors[a][0]));
        CHECK(row[3] == Approx(two.anchors[a][1]));
        CHECK(row[5] == Approx(0.25));
        CHECK(row[6] == Approx(0.25));
      }
  // A channel-major input: the value of channel c at (y, x) is read from c·ny·nx + y·nx + x.
  in[0 * ny * nx + 1 * nx + 2] = 2.0f;  // tx of anchor 0 at row 1, column 2
  const auto r3 = decode_yolo_head(in.data(), two, ny, nx, 16.0f);
  CHECK(r3[(1 * nx + 2) * no] == Approx((2 * sig(2.0) - 0.5 + 2) * 16));
  CHECK(r3[0] == Approx(0.5 * 16));
  CHECK(decode_yolo_head(in.data(), YoloHead{}, ny, nx, 16.0f).empty());
}

TEST_CASE("YOLO rows → candidates: objectness gate, multi-label, pixels", "[nms]") {
  NmsOptions o;  // PoET defaults: conf 0.4, iou 0.5, multi-label, class-aware, +1
  // cx, cy, w, h, obj, cls0, cls1, cls2 (class scores already × objectness, as OpenCV writes them)
  const float rows[] = {
      0.5f, 0.5f, 0.25f, 0.5f, 0.9f, 0.85f, 0.45f, 0.1f,  // two labels pass
      0.2f, 0.2f, 0.1f,  0.1f, 0.4f, 0.4f,  0.0f,  0.0f,  // objectness not > 0.4
      0.7f, 0.7f, 0.1f,  0.1f, 0.5f, 0.3f,  0.39f, 0.0f,  // no class > 0.4
  };
  const auto c = yolo_candidates(rows, 3, 8, 200, 100, o);
  REQUIRE(c.size() == 2);
  CHECK(c[0].class_id == 0);
  CHECK(c[0].score == Approx(0.85));
  CHECK(c[1].class_id == 1);
  CHECK(c[0].x1 == Approx(75.0));
  CHECK(c[0].x2 == Approx(125.0));
  CHECK(c[0].y1 == Approx(25.0));
  CHECK(c[0].y2 == Approx(75.0));
  o.multi_label = false;
  const auto c1 = yolo_candidates(rows, 3, 8, 200, 100, o);
  REQUIRE(c1.size() == 1);
  CHECK(c1[0].class_id == 0);
  // Single label: the best class wherever it is, with its own score.
  const float late[] = {0.5f, 0.5f, 0.25f, 0.5f, 0.9f, 0.2f, 0.3f, 0.6f};
  const auto c2 = yolo_candidates(late, 1, 8, 200, 100, o);
  REQUIRE(c2.size() == 1);
  CHECK(c2[0].class_id == 2);
  CHECK(c2[0].score == Approx(0.6));
}

TEST_CASE("class-aware NMS on crafted boxes", "[nms]") {
  auto box = [](double x1, double y1, double x2, double y2, double s, int c) {
    BoxDetection b;
    b.x1 = x1, b.y1 = y1, b.x2 = x2, b.y2 = y2, b.score = s, b.class_id = c;
    return b;
  };
  // A: 0..10, B: shifted by 3 → IoU = 70/130 = 0.538 > 0.5 → suppressed; C shifted by 4 → 60/140 = 0.43 kept.
  CHECK(box_iou(box(0, 0, 10, 10, 1, 0), box(3, 0, 13, 10, 1, 0)) == Approx(70.0 / 130.0));
  NmsOptions o;
  std::vector<BoxDetection> in = {box(3, 0, 13, 10, 0.8, 0), box(0, 0, 10, 10, 0.9, 0), box(4, 0, 14, 10, 0.7, 0),
                                  box(0, 0, 10, 10, 0.6, 1),  // same box, other class: kept (class-aware)
                                  box(100, 100, 110, 110, 0.95, 2)};
  auto kept = nms(in, o);
  REQUIRE(kept.size() == 4);
  CHECK(kept[0].score == Approx(0.95));  // sorted by score
  CHECK(kept[0].class_id == 3);          // +1 offset
  CHECK(kept[1].score == Approx(0.9));
  CHECK(kept[2].score == Approx(0.7));   // IoU 0.43 with the 0.9 box
  CHECK(kept[3].class_id == 2);
  // IoU exactly at the threshold is kept (suppression needs IoU > thresh).
  o.iou_thresh = 70.0 / 130.0;
  kept = nms(in, o);
  REQUIRE(kept.size() == 4);
  CHECK(kept[2].score == Approx(0.8));  // now kept; it suppresses the 0.7 box (IoU 90/110)
  // Agnostic NMS suppresses across classes.
  o.iou_thresh = 0.5;
  o.class_aware = false;
  CHECK(nms(in, o).size() == 3);
  // max_detections cuts after sorting.
  o.class_aware = true;
  o.max_detections = 2;
  kept = nms(in, o);
  REQUIRE(kept.size() == 2);
  CHECK(kept[1].score == Approx(0.9));
  // Equal scores keep the candidate order.
  o.max_detections = 10;
  kept = nms({box(0, 0, 1, 1, 0.5, 0), box(5, 5, 6, 6, 0.5, 1)}, o);
  CHECK(kept[0].class_id == 1);
  CHECK(kept[1].class_id == 2);
}
