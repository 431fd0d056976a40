// `roe infer` then `roe run`: a static rig looking at three rendered squares. The tiny model's poses
// are constant over identical frames, so the filter must accept them and keep the rig still; every
// frame after the first comes from the cache (identical image content).
#include <catch2/catch.hpp>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <unistd.h>

#include "roe/app/infer.hpp"
#include "roe/app/run.hpp"
#include "roe/store/dataset.hpp"

namespace fs = std::filesystem;
using namespace roe;

#ifdef ROE_HAVE_TORCH

TEST_CASE("roe infer then roe run on a small dataset with images", "[infer][run]") {
  const fs::path root = fs::temp_directory_path() / ("roe_infer_run_" + std::to_string(::getpid()));
  fs::remove_all(root);
  fs::create_directories(root);

  Dataset d;
  d.manifest.name = "static-rig";
  ImuInfo imu;
  imu.rate_hz = 200.0;
  imu.noise = {2.4e-4, 1.9e-5, 1.5e-3, 3.0e-3};
  d.manifest.imu = imu;
  CameraInfo cam;
  cam.width = 128;
  cam.height = 96;
  cam.fx = cam.fy = 120.0;
  cam.cx = 64.0;
  cam.cy = 48.0;
  d.manifest.camera = cam;
  d.manifest.objects = {{11, "red_square", false, "", -1, {}}, {12, "green_square", false, "", -1, {}}, {13, "blue_square", true, "", -1, {}}};
  const Timestamp t0 = 2'000'000'000;
  for (int k = 0; k <= 600; ++k) {  // 3 s at 200 Hz, at rest and level: specific force = +g
    ImuSample s;
    s.t_ns = t0 + static_cast<Timestamp>(k) * 5'000'000;
    s.accel = Eigen::Vector3d(0, 0, 9.81);
    d.imu.push_back(s);
  }
  for (int k = 0; k < 29; ++k) {
    const Timestamp t = t0 + 50'000'000 + static_cast<Timestamp>(k) * 100'000'000;
    d.frames.push_back({t, std::to_string(t) + ".png"});
  }
  const fs::path ds = root / "ds";
  store::write_dataset(d, ds, false);
  fs::create_directories(store::cam_image_dir(ds));
  cv::Mat img(96, 128, CV_8UC3, cv::Scalar(128, 128, 128));
  cv::rectangle(img, cv::Rect(18, 18, 24, 24), cv::Scalar(0, 0, 255), cv::FILLED);
  cv::rectangle(img, cv::Rect(78, 48, 24, 24), cv::Scalar(0, 255, 0), cv::FILLED);
  cv::rectangle(img, cv::Rect(40, 60, 24, 24), cv::Scalar(255, 0, 0), cv::FILLED);
  for (const auto& f : d.frames) REQUIRE(cv::imwrite((store::cam_image_dir(ds) / f.filename).string(), img));

  app::InferOptions io_opt;
  io_opt.model_dir = (fs::path(ROE_SOURCE_DIR) / "tests/models/tiny_poet").string();
  const auto inf = app::run_infer(ds, io_opt);
  CHECK(inf.frames_computed == 1);
  CHECK(inf.frames_reused == 28);
  CHECK(inf.detections_written == 29 * 3);

  app::RunOptions ro;
  ro.detections = "tiny-poet";
  const auto res = app::run(ds, root / "run", ro);
  std::size_t used = 0, rejected = 0, total = 0;
  for (const auto& [id, c] : res.output.summary.counts) {
    used += c.accepted + c.initialized;
    rejected += c.rejected_chi2;
    total += c.detections;
  }
  CHECK(total == 29 * 3);
  CHECK(used >= 70);  // all but the few before the filter has its anchor
  CHECK(rejected == 0);
  const auto states = store::read_states_csv(root / "run" / "states.csv");  // the rows went into the file
  REQUIRE_FALSE(states.empty());
  // The rig did not move: the estimate stays at the origin of W.
  CHECK(states.back().x.p_W_I.norm() < 0.05);
  CHECK(fs::exists(root / "run" / "trajectory.csv"));
  fs::remove_all(root);
}

#endif
