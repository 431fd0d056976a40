// roe_image: librealsense distortion models (round trips, closed forms), undistort + crop + resize
// geometry checked with a synthetic blob, and PNG encoding of the ROS encodings.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <random>

#include "support/test_util.hpp"
#include "roe/core/error.hpp"
#include "roe/image/camera_model.hpp"
#include "roe/image/frame_processor.hpp"

namespace fs = std::filesystem;
using namespace roe;
using image::CameraModel;
using image::Distortion;

namespace {
using roe::test::TempDir;

CameraModel model(Distortion d, std::array<double, 5> c, int w = 640, int h = 480) {
  CameraModel m;
  m.width = w;
  m.height = h;
  m.fx = 600;
  m.fy = 605;
  m.cx = 0.5 * w + 3.25;
  m.cy = 0.5 * h - 2.5;
  m.model = d;
  m.coeffs = c;
  return m;
}


}  // namespace

TEST_CASE("distortion names: librealsense, ROS and Kalibr spellings", "[io][image]") {
  CHECK(image::parse_distortion("Brown Conrady") == Distortion::kBrownConrady);
  CHECK(image::parse_distortion("plumb_bob") == Distortion::kBrownConrady);
  CHECK(image::parse_distortion("radtan") == Distortion::kBrownConrady);
  CHECK(image::parse_distortion("Inverse Brown Conrady") == Distortion::kInverseBrownConrady);
  CHECK(image::parse_distortion("Modified Brown Conrady") == Distortion::kModifiedBrownConrady);
  CHECK(image::parse_distortion("Kannala Brandt4") == Distortion::kKannalaBrandt4);
  CHECK(image::parse_distortion("equidistant") == Distortion::kKannalaBrandt4);
  CHECK(image::parse_distortion("Ftheta") == Distortion::kFtheta);
  CHECK(image::parse_distortion("None") == Distortion::kNone);
  CHECK_THROWS_AS(image::parse_distortion("rational_polynomial"), InputError);
  for (auto d : {Distortion::kNone, Distortion::kBrownConrady, Distortion::kModifiedBrownConrady,
                 Distortion::kInverseBrownConrady, Distortion::kKannalaBrandt4, Distortion::kFtheta})
    CHECK(image::parse_distortion(image::distortion_name(d)) == d);
}

TEST_CASE("distortion models: closed forms and distort/undistort round trips", "[io][image]") {
  const std::array<double, 5> bc{0.12, -0.25, 0.001, -0.002, 0.08};
  // Brown–Conrady distorts with the OpenCV polynomial.
  const auto b = model(Distortion::kBrownConrady, bc);
  const Eigen::Vector2d p(0.3, -0.2);
  const double r2 = p.squaredNorm();
  const double f = 1 + bc[0] * r2 + bc[1] * r2 * r2 + bc[4] * r2 * r2 * r2;
  const Eigen::Vector2d expect(p.x() * f + 2 * bc[2] * p.x() * p.y() + bc[3] * (r2 + 2 * p.x() * p.x()),
                               p.y() * f + 2 * bc[3] * p.x() * p.y() + bc[2] * (r2 + 2 * p.y() * p.y()));
  CHECK((b.distort(p) - expect).norm() < 1e-15);
  // Inverse Brown–Conrady: the same polynomial UNdistorts.
  const auto ib = model(Distortion::kInverseBrownConrady, bc);
  CHECK((ib.undistort(p) - expect).norm() < 1e-15);
  // Modified Brown–Conrady (librealsense's rs2_project_point_to_pixel): the radial factor scales x and y
  // first, and the tangential terms use the scaled x, y with the unscaled r².
  const auto mb = model(Distortion::kModifiedBrownConrady, bc);
  const double xm = p.x() * f, ym = p.y() * f;
  const Eigen::Vector2d expect_mb(xm + 2 * bc[2] * xm * ym + bc[3] * (r2 + 2 * xm * xm),
                                  ym + 2 * bc[3] * xm * ym + bc[2] * (r2 + 2 * ym * ym));
  CHECK((mb.distort(p) - expect_mb).norm() < 1e-15);
  CHECK((mb.distort(p) - expect).norm() > 1e-5);  // differs from Brown–Conrady at this point
  // KB4: θ_d = θ(1 + k1θ² + ...), along the ray.
  const auto kb = model(Distortion::kKannalaBrandt4, {0.05, -0.01, 0.002, -0.0004, 0});
  const double th = std::atan(p.norm());
  const double thd = th * (1 + 0.05 * th * th - 0.01 * std::pow(th, 4) + 0.002 * std::pow(th, 6) - 0.0004 * std::pow(th, 8));
  CHECK((kb.distort(p) - p * (thd / p.norm())).norm() < 1e-15);
  // Fisheye field of view (rays 63–72° off the axis, as a T265 sees them): the radial derivative of
  // distort is ~0.1 there, so undistort needs true Newton steps to converge.
  for (const Eigen::Vector2d& u : {Eigen::Vector2d(2.0, 1.5), Eigen::Vector2d(-2.5, 0.5), Eigen::Vector2d(0.3, -2.0)}) {
    INFO("u = " << u.transpose());
    CHECK((kb.undistort(kb.distort(u)) - u).norm() < 1e-9);
  }
  for (const auto& m : {b, ib, kb, model(Distortion::kModifiedBrownConrady, bc), model(Distortion::kFtheta, {0.9, 0, 0, 0, 0}),
                        model(Distortion::kNone, {})}) {
    INFO(image::distortion_name(m.model));
    for (double x = -0.5; x <= 0.5; x += 0.1)
      for (double y = -0.4; y <= 0.4; y += 0.1) {
        const Eigen::Vector2d u(x, y);
        CHECK((m.undistort(m.distort(u)) - u).norm() < 1e-9);
      }
  }
}

TEST_CASE("FrameProcessor: a point lands where the pinhole output camera projects it", "[io][image]") {
  // Render a blob at the distorted projection of a 3D point into the source image; after undistort
  // + crop (+ resize) its centroid must be at the output camera's pinhole projection.
  const std::array<double, 5> bc{0.12, -0.25, 0.001, -0.002, 0.08};
  struct Case {
    Distortion d;
    std::array<double, 5> c;
    int ow, oh;
  };
  for (const Case& k : {Case{Distortion::kBrownConrady, bc, 0, 0}, Case{Distortion::kInverseBrownConrady, bc, 0, 0},
                        Case{Distortion::kKannalaBrandt4, {0.05, -0.01, 0.002, -0.0004, 0}, 320, 240},
                        Case{Distortion::kModifiedBrownConrady, bc, 0, 0}}) {
    INFO(image::distortion_name(k.d));
    const CameraModel src = model(k.d, k.c, 800, 600);
    image::ProcessOptions o;
    o.out_width = k.ow;
    o.out_height = k.oh;
    const image::FrameProcessor proc(src, o);
    const CameraModel& out = proc.output();
    CHECK(out.model == Distortion::kNone);
    for (const Eigen::Vector3d& P : {Eigen::Vector3d(0.1, 0.05, 1.0), Eigen::Vector3d(-0.3, 0.2, 1.0), Eigen::Vector3d(0.25, -0.3, 1.2)}) {
      const Eigen::Vector2d ps = src.project(P);
      std::string img(static_cast<std::size_t>(src.width) * src.height, '\0');
      for (int v = 0; v < src.height; ++v)
        for (int u = 0; u < src.width; ++u) {
          const double e = (Eigen::Vector2d(u, v) - ps).squaredNorm() / (2 * 3.0 * 3.0);
          img[static_cast<std::size_t>(v) * src.width + u] = static_cast<char>(std::lround(250 * std::exp(-e)));
        }
      TempDir t;
      proc.process_to_png({src.width, src.height, "mono8", static_cast<std::size_t>(src.width), img}, t.path / "o.png", "t");
      const auto res = image::read_image(t.path / "o.png");
      REQUIRE(res.width == out.width);
      REQUIRE(res.height == out.height);
      double sw = 0, su = 0, sv = 0;
      for (int v = 0; v < res.height; ++v)
        for (int u = 0; u < res.width; ++u) {
          const double w = res.at(u, v);
          sw += w;
          su += w * u;
          sv += w * v;
        }
      REQUIRE(sw > 0);
      const Eigen::Vector2d expect(out.fx * P.x() / P.z() + out.cx, out.fy * P.y() / P.z() + out.cy);
      CHECK((Eigen::Vector2d(su / sw, sv / sw) - expect).norm() < 0.25);
    }
  }
}

TEST_CASE("FrameProcessor: crop geometry, errors, encodings", "[io][image]") {
  const auto src = model(Distortion::kNone, {}, 1280, 720);
  const image::FrameProcessor p(src, {});
  CHECK(p.crop_x0() == 320);
  CHECK(p.crop_y0() == 120);
  CHECK(p.output().cx == Approx(src.cx - 320));
  CHECK(p.output().fx == src.fx);
  image::ProcessOptions big;
  big.crop_width = 1281;
  CHECK_THROWS_AS(image::FrameProcessor(src, big), InputError);
  TempDir t;
  const std::string px(1280 * 720 * 3, '\7');
  CHECK_THROWS_WITH(p.process_to_png({1280, 720, "bayer_rggb8", 1280, px}, t.path / "x.png", "frame 1"),
                    Catch::Contains("frame 1") && Catch::Contains("unsupported"));
  CHECK_THROWS_WITH(p.process_to_png({640, 480, "rgb8", 1920, px}, t.path / "x.png", "frame 2"),
                    Catch::Contains("frame 2"));
  CHECK_THROWS_AS(p.process_to_png({1280, 720, "rgb8", 3840, px.substr(0, 1000)}, t.path / "x.png", "f"), InputError);
  CHECK_THROWS_AS(p.process_encoded_to_png("not a png", t.path / "x.png", "f"), InputError);
  // Padded rows (step > width x bytes per pixel): the last row needs no padding, one byte less is an error.
  const std::size_t step = 3840 + 64, need = step * 719 + 3840;
  const std::string padded(need, '\7');
  CHECK_NOTHROW(p.process_to_png({1280, 720, "rgb8", step, padded}, t.path / "p.png", "p"));
  CHECK_THROWS_WITH(
      p.process_to_png({1280, 720, "rgb8", step, padded.substr(0, need - 1)}, t.path / "x.png", "q"),
      Catch::Contains("q: image data too short for 1280x720 rgb8"));
  // 16-bit depth survives as 16-bit PNG.
  const std::string d16(1280 * 720 * 2, '\1');
  p.process_to_png({1280, 720, "mono16", 2560, d16}, t.path / "d.png", "d");
  const auto d = image::read_image(t.path / "d.png");
  CHECK(d.depth_bytes == 2);
  CHECK(d.width == 640);
}

TEST_CASE("PNG encoding: librealsense format names (YUYV, Y8, RGB8, ...) convert as their ROS encodings",
          "[io][image]") {
  // The recorder writes rs2_format_to_string names where its ROS table has no entry (YUYV).
  const int w = 6, h = 4;
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> byte(0, 255);
  struct Case {
    const char *rs, *ros;
    int bytes_pp;
  };
  for (const Case& c : {Case{"YUYV", "yuyv", 2}, Case{"UYVY", "uyvy", 2}, Case{"RGB8", "rgb8", 3},
                        Case{"BGR8", "bgr8", 3}, Case{"RGBA8", "rgba8", 4}, Case{"BGRA8", "bgra8", 4},
                        Case{"Y8", "mono8", 1}, Case{"RAW8", "mono8", 1}, Case{"Y16", "mono16", 2},
                        Case{"Z16", "mono16", 2}}) {
    INFO(c.rs);
    CHECK(image::canonical_encoding(c.rs) == c.ros);
    std::string data(static_cast<std::size_t>(w * h * c.bytes_pp), '\0');
    for (auto& b : data) b = static_cast<char>(byte(rng));
    const std::size_t step = static_cast<std::size_t>(w) * c.bytes_pp;
    const std::string a = image::encode_png({w, h, c.rs, step, data}, "rs.bag");
    const std::string b = image::encode_png({w, h, c.ros, step, data}, "ros.bag");
    CHECK(a == b);
  }
  CHECK(image::canonical_encoding("rgb8") == "rgb8");
  CHECK(image::canonical_encoding("MJPEG") == "MJPEG");
  const std::string px(16, '\0');
  CHECK_THROWS_WITH(image::encode_png({2, 2, "MJPEG", 8, px}, "x.bag: /color"),
                    Catch::Contains("x.bag: /color") && Catch::Contains("unsupported image encoding \"MJPEG\""));
}
