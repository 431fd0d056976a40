// roe infer end to end on synthetic frames rendered for the committed tiny bundle: detections are
// written, a second run reuses every frame from the cache, subsampling and the virtual-camera warp.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <map>
#include <set>
#include <unistd.h>

#include "roe/app/infer.hpp"
#include "roe/core/error.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"

namespace fs = std::filesystem;
using namespace roe;

namespace {

const fs::path kTiny = fs::path(ROE_SOURCE_DIR) / "tests/models/tiny_poet";

struct TmpDir {
  fs::path path;
  explicit TmpDir(const std::string& name)
      : path(fs::temp_directory_path() / ("roe_infer_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TmpDir() { fs::remove_all(path); }
};

struct Square {
  int cls;         // 1 red, 2 green, 3 blue (the tiny detector's classes)
  double cx, cy;   // centre in pixels of a 128x96 image
};

// Frames of `scale` x (128x96) with squares of 24·scale px; camera = the training camera scaled.
fs::path make_dataset(const fs::path& root, const std::vector<std::vector<Square>>& frames, int scale = 1) {
  Dataset d;
  d.manifest.name = "synthetic";
  CameraInfo cam;
  cam.width = 128 * scale;
  cam.height = 96 * scale;
  cam.fx = cam.fy = 120.0 * scale;
  cam.cx = 64.0 * scale;
  cam.cy = 48.0 * scale;
  d.manifest.camera = cam;
  d.manifest.objects = {{11, "red_square", false, "", -1, {}}, {12, "green_square", false, "", -1, {}}, {13, "blue_square", true, "", -1, {}}};
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const Timestamp t = 1'000'000'000 + static_cast<Timestamp>(k) * 100'000'000;
    d.frames.push_back({t, std::to_string(t) + ".png"});
  }
  const fs::path ds = root / "ds";
  store::write_dataset(d, ds, false);
  fs::create_directories(store::cam_image_dir(ds));
  for (std::size_t k = 0; k < frames.size(); ++k) {
    cv::Mat img(96 * scale, 128 * scale, CV_8UC3, cv::Scalar(128, 128, 128));
    for (const auto& s : frames[k]) {
      const cv::Scalar bgr = s.cls == 1 ? cv::Scalar(0, 0, 255) : s.cls == 2 ? cv::Scalar(0, 255, 0) : cv::Scalar(255, 0, 0);
      const int side = 24 * scale;
      const int x0 = static_cast<int>(std::lround(s.cx * scale - side / 2.0));
      const int y0 = static_cast<int>(std::lround(s.cy * scale - side / 2.0));
      cv::rectangle(img, cv::Rect(x0, y0, side, side), bgr, cv::FILLED);
    }
    REQUIRE(cv::imwrite((store::cam_image_dir(ds) / d.frames[k].filename).string(), img));
  }
  return ds;
}

const std::vector<std::vector<Square>> kFrames = {
    {{1, 30, 30}, {2, 90, 60}},
    {{1, 34, 33}, {2, 86, 58}, {3, 60, 70}},
    {{3, 40, 50}},
    {},
    {{2, 70, 40}, {3, 100, 70}},
};

}  // namespace

#ifdef ROE_HAVE_TORCH

TEST_CASE("roe infer writes detections, and a second run reuses the cache", "[infer]") {
  TmpDir tmp("e2e");
  const fs::path ds = make_dataset(tmp.path, kFrames);
  app::InferOptions o;
  o.model_dir = kTiny.string();
  std::vector<std::pair<std::size_t, std::size_t>> progress;
  const auto s = app::run_infer(ds, o, [&](std::size_t done, std::size_t total) { progress.emplace_back(done, total); });
  CHECK(s.model_id == "tiny-poet");
  CHECK(s.frames_selected == 5);
  CHECK(s.frames_computed == 5);
  CHECK(s.frames_reused == 0);
  CHECK_FALSE(s.warp);
  CHECK(s.detections_written == 8);
  REQUIRE(progress.size() == 6);
  CHECK(progress.back() == std::make_pair<std::size_t, std::size_t>(5, 5));

  const auto dets = store::read_detections_csv(ds / "detections/tiny-poet/detections.csv");
  REQUIRE(dets.size() == 8);
  // Per frame: the right objects (class → object id by name), plausible poses, a detector score.
  std::map<Timestamp, std::set<int>> objects;
  for (const auto& d : dets) {
    objects[d.t_ns].insert(d.object_id);
    CHECK(d.score > 0.4);
    CHECK(d.score <= 1.0);
    CHECK(d.T_C_O.p.z() == Approx(0.3).margin(0.011));
  }
  CHECK(objects[1'000'000'000] == std::set<int>{11, 12});
  CHECK(objects[1'100'000'000] == std::set<int>{11, 12, 13});
  CHECK(objects[1'200'000'000] == std::set<int>{13});
  CHECK(objects.count(1'300'000'000) == 0);  // an empty frame has no row
  CHECK(objects[1'400'000'000] == std::set<int>{12, 13});
  // x from the pinhole prior: the red square of frame 0 is left of the optical centre.
  CHECK(dets[0].object_id == 11);
  CHECK(dets[0].T_C_O.p.x() == Approx((30 - 64) / 120.0 * 0.3).margin(0.02));

  const auto meta = io::parse_json_file(ds / "detections/tiny-poet/meta.json");
  CHECK(meta.at("model").at("model_id") == "tiny-poet");
  CHECK(meta.at("config_hash") == s.config_hash);
  CHECK(meta.at("per_frame").size() == 5);
  CHECK(meta.at("per_frame")[0].at("ms").get<double>() > 0.0);
  // The summary's mean inference time is the mean over the frames computed in this run.
  double sum_ms = 0.0;
  for (const auto& f : meta.at("per_frame")) sum_ms += f.at("ms").get<double>();
  CHECK(s.mean_ms_computed == Approx(sum_ms / 5.0).epsilon(1e-9));
  CHECK(meta.at("selftest").at("pose_max_abs_diff").at("t").get<double>() <= 1e-5);

  // Second run: everything from the cache, identical output; it needs --force to replace the set.
  CHECK_THROWS_AS(app::run_infer(ds, o), InputError);
  o.force = true;
  const auto s2 = app::run_infer(ds, o);
  CHECK(s2.frames_reused == 5);
  CHECK(s2.frames_computed == 0);
  CHECK(s2.mean_ms_computed == 0.0);  // nothing computed
  CHECK(s2.config_hash == s.config_hash);
  const auto dets2 = store::read_detections_csv(ds / "detections/tiny-poet/detections.csv");
  REQUIRE(dets2.size() == dets.size());
  for (std::size_t k = 0; k < dets.size(); ++k) {
    CHECK(dets2[k].t_ns == dets[k].t_ns);
    CHECK(dets2[k].T_C_O.p == dets[k].T_C_O.p);
    CHECK(dets2[k].T_C_O.q.coeffs() == dets[k].T_C_O.q.coeffs());
    CHECK(dets2[k].score == dets[k].score);
  }
  const auto meta2 = io::parse_json_file(ds / "detections/tiny-poet/meta.json");
  CHECK(meta2.at("per_frame")[0].at("cached") == true);

  // A changed image is recomputed, the others are reused.
  fs::copy_file(store::cam_image_dir(ds) / "1000000000.png", store::cam_image_dir(ds) / "1300000000.png",
                fs::copy_options::overwrite_existing);
  const auto s3 = app::run_infer(ds, o);
  CHECK(s3.frames_reused == 5);  // frame 3 now has frame 0's content, already in the cache
  CHECK(s3.detections_written == 10);
  o.use_cache = false;
  const auto s4 = app::run_infer(ds, o);
  CHECK(s4.frames_computed == 5);
}

TEST_CASE("roe infer: --frames, --every, --name", "[infer]") {
  TmpDir tmp("sel");
  const fs::path ds = make_dataset(tmp.path, kFrames);
  app::InferOptions o;
  o.model_dir = kTiny.string();
  o.frames = "1:5";
  o.every = 2;
  o.name = "sub";
  const auto s = app::run_infer(ds, o);
  CHECK(s.frames_selected == 2);  // frames 1 and 3
  CHECK(s.detections_written == 3);
  const auto dets = store::read_detections_csv(ds / "detections/sub/detections.csv");
  for (const auto& d : dets) CHECK(d.t_ns == 1'100'000'000);
  CHECK(app::parse_frame_range("2", 5) == std::make_pair<std::size_t, std::size_t>(2, 3));
  CHECK(app::parse_frame_range(":2", 5) == std::make_pair<std::size_t, std::size_t>(0, 2));
  CHECK(app::parse_frame_range("3:", 5) == std::make_pair<std::size_t, std::size_t>(3, 5));
  CHECK(app::parse_frame_range("3:99", 5) == std::make_pair<std::size_t, std::size_t>(3, 5));
  CHECK_THROWS_AS(app::parse_frame_range("4:2", 5), InputError);
  CHECK_THROWS_AS(app::parse_frame_range("a:b", 5), InputError);
  CHECK_THROWS_AS(app::parse_frame_range("7:", 5), InputError);
}

TEST_CASE("roe infer warps another camera to the training intrinsics", "[infer]") {
  TmpDir tmp("warp");
  // The same scenes at twice the resolution and focal length: H = diag(0.5, 0.5, 1).
  const fs::path ds = make_dataset(tmp.path, kFrames, 2);
  app::InferOptions o;
  o.model_dir = kTiny.string();
  const auto s = app::run_infer(ds, o);
  CHECK(s.warp);
  CHECK(s.detections_written == 8);
  const auto dets = store::read_detections_csv(ds / "detections/tiny-poet/detections.csv");
  REQUIRE(dets.size() == 8);
  for (const auto& d : dets) CHECK(d.T_C_O.p.z() == Approx(0.3).margin(0.011));
  // Without the warp the 256x192 images do not fit the model.
  o.warp = "off";
  o.force = true;
  CHECK_THROWS_AS(app::run_infer(ds, o), InputError);
}

TEST_CASE("roe infer with external boxes (PoET's ground-truth box mode)", "[infer]") {
  TmpDir tmp("boxes");
  const fs::path ds = make_dataset(tmp.path, kFrames);
  // Frame 0: both squares, one without a score; frame 2: the blue one; frame 1: none listed.
  io::write_file_atomic(tmp.path / "boxes.csv",
                        "timestamp_ns,class,x1,y1,x2,y2,score\n"
                        "1000000000,1,18,18,42,42,0.9\n"
                        "1000000000,2,78,48,102,72,\n"
                        "1200000000,3,28,38,52,62,0.6\n");
  app::InferOptions o;
  o.model_dir = kTiny.string();
  o.boxes_file = (tmp.path / "boxes.csv").string();
  const auto s = app::run_infer(ds, o);
  CHECK(s.frames_computed == 5);
  CHECK(s.detections_written == 3);
  const auto dets = store::read_detections_csv(ds / "detections/tiny-poet/detections.csv");
  REQUIRE(dets.size() == 3);
  CHECK(dets[0].t_ns == 1'000'000'000);
  CHECK(dets[0].object_id == 11);
  CHECK(dets[0].score == Approx(0.9));
  CHECK(std::isnan(dets[1].score));
  CHECK(dets[2].t_ns == 1'200'000'000);
  CHECK(dets[2].object_id == 13);
  // External boxes are part of the cache key: other boxes, same images → recomputed.
  io::write_file_atomic(tmp.path / "boxes.csv", "timestamp_ns,class,x1,y1,x2,y2,score\n1000000000,1,18,18,42,42,0.8\n");
  o.force = true;
  const auto s2 = app::run_infer(ds, o);
  CHECK(s2.frames_reused == 3);   // frames 1, 3, 4 had no boxes before and have none now
  CHECK(s2.frames_computed == 2);  // frame 0 (other score) and frame 2 (its box is gone)
  io::write_file_atomic(tmp.path / "boxes.csv", "timestamp_ns,class,x1,y1,x2,y2,score\n1000000000,0,18,18,42,42,0.8\n");
  CHECK_THROWS_AS(app::run_infer(ds, o), InputError);

  // A box without a score ranks after every scored one and leaves them in score order: of two boxes
  // of class 1 (0.5, then 0.9) around an unscored one, the 0.9 box is object 11's detection (one per
  // object, the highest score).
  io::write_file_atomic(tmp.path / "boxes.csv",
                        "timestamp_ns,class,x1,y1,x2,y2,score\n"
                        "1000000000,1,18,18,42,42,0.5\n"
                        "1000000000,2,78,48,102,72,\n"
                        "1000000000,1,19,19,43,43,0.9\n");
  app::run_infer(ds, o);
  std::map<int, double> score;
  for (const auto& d : store::read_detections_csv(ds / "detections/tiny-poet/detections.csv"))
    if (d.t_ns == 1'000'000'000) score[d.object_id] = d.score;
  REQUIRE(score.size() == 2);
  CHECK(score.at(11) == Approx(0.9));
  CHECK(std::isnan(score.at(12)));
}

// The message of the InputError `f` throws ("" when it throws none; other exceptions escape).
template <typename F>
std::string input_error_of(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

std::size_t count_lines(const fs::path& file) {
  std::ifstream f(file);
  std::size_t n = 0;
  for (std::string l; std::getline(f, l);) ++n;
  return n;
}

TEST_CASE("roe infer: non-finite poses are dropped, counted and warned about, also when reused", "[infer]") {
  TmpDir tmp("invalid");
  const fs::path ds = make_dataset(tmp.path, kFrames);
  // A copy of the tiny bundle whose input scale overflows float32: the features, and so every pose
  // the head returns, are non-finite. External boxes bypass the detector, which would find nothing.
  const fs::path bundle = tmp.path / "bundle";
  fs::copy(kTiny, bundle, fs::copy_options::recursive);
  auto meta = io::parse_json_file(bundle / "poet_bundle.json");
  meta["image"]["scale"] = 1e300;
  meta["detector"].erase("selftest");  // it would (rightly) refuse the bundle
  io::write_file_atomic(bundle / "poet_bundle.json", meta.dump(2));
  io::write_file_atomic(tmp.path / "boxes.csv", "timestamp_ns,class,x1,y1,x2,y2,score\n"
                                                "1000000000,1,18,18,42,42,0.9\n"
                                                "1000000000,2,78,48,102,72,0.8\n"
                                                "1200000000,3,28,38,52,62,0.6\n");
  app::InferOptions o;
  o.model_dir = bundle.string();
  o.boxes_file = (tmp.path / "boxes.csv").string();
  const auto s = app::run_infer(ds, o);
  CHECK(s.frames_computed == 5);
  CHECK(s.dropped_invalid == 3);
  CHECK(s.detections_written == 0);
  auto warned = [](const app::InferSummary& x) {
    for (const auto& w : x.warnings)
      if (w.find("3 pose(s) the model returned with a degenerate rotation") != std::string::npos) return true;
    return false;
  };
  CHECK(warned(s));
  CHECK(s.to_json()["dropped_invalid_pose"] == 3);
  // The second run takes every frame from the cache and still reports what the model returned.
  o.force = true;
  const auto s2 = app::run_infer(ds, o);
  CHECK(s2.frames_reused == 5);
  CHECK(s2.dropped_invalid == 3);
  CHECK(warned(s2));
}

TEST_CASE("roe infer: a box class the bundle does not have names file, row and column", "[infer]") {
  TmpDir tmp("boxclass");
  const fs::path ds = make_dataset(tmp.path, kFrames);
  app::InferOptions o;
  o.model_dir = kTiny.string();
  o.boxes_file = (tmp.path / "boxes.csv").string();
  // The tiny bundle has classes 1..3; a larger id used to reach the pose head (TorchScript index error).
  for (const std::string cls : {"1000000000", "4"}) {
    io::write_file_atomic(tmp.path / "boxes.csv", "timestamp_ns,class,x1,y1,x2,y2,score\n"
                                                  "1000000000,1,18,18,42,42,0.9\n"
                                                  "1200000000," + cls + ",28,38,52,62,1\n");
    const std::string e = input_error_of([&] { app::run_infer(ds, o); });
    INFO(e);
    CHECK(e.find("boxes.csv:3:2:") != std::string::npos);
    CHECK(e.find("class " + cls + " is not a class of model tiny-poet (its classes: 1..3)") != std::string::npos);
  }
  CHECK_FALSE(fs::exists(ds / "cache"));
  CHECK_FALSE(fs::exists(ds / "detections" / "tiny-poet"));
}

TEST_CASE("roe infer: boxes whose timestamps match no frame are an error, some unmatched a warning", "[infer]") {
  TmpDir tmp("boxstamps");
  const fs::path ds = make_dataset(tmp.path, kFrames);
  app::InferOptions o;
  o.model_dir = kTiny.string();
  o.boxes_file = (tmp.path / "boxes.csv").string();
  const std::string header = "timestamp_ns,class,x1,y1,x2,y2,score\n";
  // Stamps in µs instead of ns: nothing matches.
  io::write_file_atomic(tmp.path / "boxes.csv", header + "1000000,1,18,18,42,42,0.9\n1200000,3,28,38,52,62,0.6\n");
  std::string e = input_error_of([&] { app::run_infer(ds, o); });
  CHECK(e.find("none of the 2 timestamp(s) of the boxes matches a frame of the dataset") != std::string::npos);
  CHECK(e.find("the boxes span 1000000..1200000 ns, the frames 1000000000..1400000000 ns") != std::string::npos);
  io::write_file_atomic(tmp.path / "boxes.csv", header);
  CHECK(input_error_of([&] { app::run_infer(ds, o); }).find("the boxes file has no rows") != std::string::npos);
  // Matching frames outside the selection only.
  io::write_file_atomic(tmp.path / "boxes.csv", header + "1200000000,3,28,38,52,62,0.6\n");
  o.frames = "0:2";
  e = input_error_of([&] { app::run_infer(ds, o); });
  CHECK(e.find("matches a selected frame (1 match frames outside --frames/--every)") != std::string::npos);
  CHECK_FALSE(fs::exists(ds / "cache"));
  // Some rows match: the others are counted in a warning.
  o.frames = "";
  io::write_file_atomic(tmp.path / "boxes.csv", header + "1200000000,3,28,38,52,62,0.6\n1250000000,3,28,38,52,62,0.6\n"
                                                         "1250000000,1,18,18,42,42,0.9\n");
  const auto s = app::run_infer(ds, o);
  CHECK(s.detections_written == 1);
  REQUIRE(s.warnings.size() == 1);
  CHECK(s.warnings[0].find("2 box(es) at 1 timestamp(s) of " + o.boxes_file + " match no frame of the dataset") !=
        std::string::npos);
}

TEST_CASE("roe infer on frames without images writes nothing", "[infer]") {
  TmpDir tmp("noimg");
  const fs::path ds = make_dataset(tmp.path, kFrames);
  fs::remove_all(store::cam_image_dir(ds));  // like a dataset from roe simulate: frames listed, no images
  app::InferOptions o;
  o.model_dir = kTiny.string();
  const std::string e = input_error_of([&] { app::run_infer(ds, o); });
  CHECK(e.find("5 of the 5 selected frame(s) have no image") != std::string::npos);
  CHECK(e.find("1000000000.png is missing") != std::string::npos);
  CHECK_FALSE(fs::exists(ds / "cache"));
  CHECK_FALSE(fs::exists(ds / "detections"));
  // An existing detection set is refused (without --force) before anything else is looked at.
  io::write_file_atomic(ds / "detections" / "tiny-poet" / "detections.csv", "x\n");
  CHECK(input_error_of([&] { app::run_infer(ds, o); }).find("--force") != std::string::npos);
  CHECK(io::read_file(ds / "detections" / "tiny-poet" / "detections.csv") == "x\n");
}

TEST_CASE("roe infer --no-cache refreshes the cache without duplicate lines", "[infer]") {
  TmpDir tmp("nocache");
  const fs::path ds = make_dataset(tmp.path, kFrames);
  app::InferOptions o;
  o.model_dir = kTiny.string();
  const auto s = app::run_infer(ds, o);
  REQUIRE(fs::exists(s.cache_file));
  CHECK(count_lines(s.cache_file) == 6);  // header + 5 frames
  o.force = true;
  o.use_cache = false;
  for (int k = 0; k < 2; ++k) {
    const auto r = app::run_infer(ds, o);
    CHECK(r.frames_computed == 5);
    CHECK(count_lines(s.cache_file) == 6);  // the recomputed frames replaced their lines
  }
  o.use_cache = true;
  const auto r = app::run_infer(ds, o);
  CHECK(r.frames_reused == 5);
  CHECK(r.detections_written == s.detections_written);
}

TEST_CASE("roe infer input errors", "[infer]") {
  TmpDir tmp("err");
  const fs::path ds = make_dataset(tmp.path, kFrames);
  app::InferOptions o;
  o.model_dir = (tmp.path / "nope").string();
  CHECK_THROWS_AS(app::run_infer(ds, o), InputError);
  o.model_dir = kTiny.string();
  o.every = 0;
  CHECK_THROWS_AS(app::run_infer(ds, o), InputError);
  o.every = 1;
  fs::remove(store::cam_image_dir(ds) / "1200000000.png");
  CHECK_THROWS_AS(app::run_infer(ds, o), InputError);
}

#else

TEST_CASE("roe infer without LibTorch says so", "[infer]") {
  TmpDir tmp("notorch");
  const fs::path ds = make_dataset(tmp.path, kFrames);
  app::InferOptions o;
  o.model_dir = kTiny.string();
  try {
    app::run_infer(ds, o);
    FAIL("no error");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).find("without LibTorch") != std::string::npos);
  }
}

#endif
