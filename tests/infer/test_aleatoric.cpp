// Aleatoric heads end to end: `roe infer` with the committed tiny bundle (whose pose head has PoET-style
// log-variance heads) writes the sigma columns of detections.csv, and they equal what the generator
// computed in PyTorch for the same image (tests/models/tiny_poet/selftest/expected_detections.csv,
// written by tests/models/gen_tiny_poet.py: sigma = sqrt(exp(s)) from the eager head in float64).
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <unistd.h>

#include "roe/app/infer.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/json.hpp"

namespace fs = std::filesystem;
using namespace roe;

namespace {

const fs::path kTiny = fs::path(ROE_SOURCE_DIR) / "tests/models/tiny_poet";

struct Expected {
  double score = 0;
  Eigen::Vector3d t;
  Eigen::Matrix3d R;
  Vector6d sigma;
};

// class id → the generator's expected detection (first line a comment, second the header).
std::map<int, Expected> read_expected(const fs::path& file) {
  std::ifstream in(file);
  REQUIRE(in);
  std::string line;
  std::getline(in, line);
  REQUIRE(line.rfind("#", 0) == 0);
  std::getline(in, line);
  REQUIRE(line.rfind("class,score,tx,ty,tz,r00", 0) == 0);
  std::map<int, Expected> out;
  while (std::getline(in, line)) {
    std::vector<double> v;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) v.push_back(std::stod(cell));
    REQUIRE(v.size() == 20);
    Expected e;
    e.score = v[1];
    e.t = Eigen::Vector3d(v[2], v[3], v[4]);
    for (int k = 0; k < 9; ++k) e.R(k / 3, k % 3) = v[5 + k];
    for (int k = 0; k < 6; ++k) e.sigma[k] = v[14 + k];
    out[static_cast<int>(v[0])] = e;
  }
  return out;
}

}  // namespace

#ifdef ROE_HAVE_TORCH

TEST_CASE("roe infer writes the aleatoric heads' sigmas as PyTorch computes them", "[infer][aleatoric]") {
  const fs::path root = fs::temp_directory_path() / ("roe_aleatoric_" + std::to_string(::getpid()));
  fs::remove_all(root);
  const fs::path ds = root / "ds";
  Dataset d;  // one frame: the detector self-test image, seen by the training camera (no warp)
  CameraInfo cam;
  cam.width = 128;
  cam.height = 96;
  cam.fx = cam.fy = 120.0;
  cam.cx = 64.0;
  cam.cy = 48.0;
  d.manifest.camera = cam;
  d.frames.push_back({1'000'000'000, "1000000000.png"});
  store::write_dataset(d, ds, false);
  fs::create_directories(store::cam_image_dir(ds));
  fs::copy_file(kTiny / "selftest/detector_input.png", store::cam_image_dir(ds) / "1000000000.png");

  app::InferOptions o;
  o.model_dir = kTiny.string();
  o.threads = 1;
  const auto s = app::run_infer(ds, o);
  CHECK_FALSE(s.warp);
  // The CPU settings are applied and recorded (the optimized head passed the self-test to get here).
  const auto meta = io::parse_json_file(ds / "detections/tiny-poet/meta.json");
  CHECK(meta.at("model").at("cpu_threads") == 1);
  CHECK(meta.at("model").at("pose_head_optimized") == true);
  CHECK(meta.at("options").at("threads") == 1);
  const fs::path csv = ds / "detections/tiny-poet/detections.csv";
  {
    std::ifstream in(csv);
    std::string header;
    std::getline(in, header);
    CHECK(header.find(",sigma_tx,sigma_ty,sigma_tz,sigma_rx,sigma_ry,sigma_rz") != std::string::npos);
  }
  const auto dets = store::read_detections_csv(csv);
  const auto want = read_expected(kTiny / "selftest/expected_detections.csv");
  REQUIRE(want.size() == 3);
  REQUIRE(dets.size() == want.size());
  for (const auto& det : dets) {
    CAPTURE(det.object_id);  // no objects in roe.json: object id = PoET class id
    REQUIRE(want.count(det.object_id) == 1);
    const Expected& e = want.at(det.object_id);
    CHECK(det.score == Approx(e.score).margin(1e-5));
    CHECK((det.T_C_O.p - e.t).cwiseAbs().maxCoeff() < 1e-5);
    CHECK((det.T_C_O.R() - e.R).cwiseAbs().maxCoeff() < 1e-5);
    REQUIRE(det.sigma.has_value());
    for (int k = 0; k < 6; ++k) {
      CAPTURE(k);
      CHECK((*det.sigma)[k] == Approx(e.sigma[k]).epsilon(1e-5));
    }
    // Plausible scales (the generator's offsets): about 1 cm and 3 degrees, all different per axis.
    CHECK(det.sigma->head<3>().maxCoeff() < 0.05);
    CHECK(det.sigma->tail<3>().maxCoeff() < 0.2);
  }
  fs::remove_all(root);
}

#endif
