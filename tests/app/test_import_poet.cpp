// roe import poet: PoET's results.json into a dataset, with its edge cases.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <functional>
#include <unistd.h>

#include "roe/app/import_poet.hpp"
#include "roe/core/error.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/output.hpp"

namespace fs = std::filesystem;
using namespace roe;

namespace {

struct TmpDir {
  fs::path path;
  explicit TmpDir(const std::string& name)
      : path(fs::temp_directory_path() / ("roe_import_poet_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TmpDir() { fs::remove_all(path); }
};

// A dataset with frames (file names given) and objects; no images are needed for the import.
/// roe.json's object entry as these tests give it: id, name, symmetric (no BOP models_info).
struct ObjectEntry {
  int id;
  std::string name;
  bool symmetric;
};

fs::path make_dataset(const fs::path& root, const std::vector<std::pair<Timestamp, std::string>>& frames,
                      const std::vector<ObjectEntry>& objects, bool with_cam = true) {
  Dataset d;
  d.manifest.name = "t";
  for (const auto& e : objects) {
    ObjectInfo o;
    o.id = e.id, o.name = e.name, o.symmetric = e.symmetric;
    d.manifest.objects.push_back(o);
  }
  if (with_cam)
    for (const auto& [t, f] : frames) d.frames.push_back({t, f});
  const fs::path ds = root / "ds";
  store::write_dataset(d, ds, false);
  return ds;
}

fs::path write(const fs::path& root, const std::string& name, const std::string& text) {
  io::write_file_atomic(root / name, text);
  return root / name;
}

const std::string kI = "[[1,0,0],[0,1,0],[0,0,1]]";
std::string det(double z, int cls, const std::string& rot = kI) {
  return "{\"t\": [0.1, 0.2, " + std::to_string(z) + "], \"rot\": " + rot + ", \"box\": [0.5, 0.5, 0.1, 0.1], \"class\": " +
         std::to_string(cls) + "}";
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("ns-named frames: ids are timestamps, classes map by YCB-V name", "[import_poet]") {
  TmpDir tmp("ns");
  const fs::path ds = make_dataset(tmp.path, {{1000, "1000.png"}, {2000, "2000.png"}, {3000, "3000.png"}},
                                   {{5, "006_mustard_bottle", false}, {113, "Bowl", true}});
  const std::string rot90 = "[[0,-1,0],[1,0,0],[0,0,1]]";
  const fs::path res = write(tmp.path, "results.json",
                             "{\"1000\": {\"0\": " + det(0.6, 5, rot90) + ", \"1\": " + det(0.7, 13) + ", \"2\": " + det(0.8, 1) +
                                 "},\n \"2000\": {},\n \"3000\": {\"0\": " + det(0.9, 13) + "}}");
  app::ImportPoetOptions o;
  const auto s = app::import_poet(res, ds, o);
  CHECK(s.images_in_file == 3);
  CHECK(s.images_matched == 3);
  CHECK(s.empty_images == 1);
  CHECK(s.detections_in_file == 4);
  CHECK(s.detections_written == 3);
  CHECK(s.dropped_unmapped_class == 1);  // class 1 (master chef can) is not in roe.json
  CHECK(s.class_map.at(5) == 5);
  CHECK(s.class_map.at(13) == 113);      // "024_bowl" = "Bowl"
  const auto dets = store::read_detections_csv(ds / "detections/poet/detections.csv");
  REQUIRE(dets.size() == 3);
  CHECK(dets[0].t_ns == 1000);
  CHECK(dets[0].object_id == 5);
  CHECK(dets[0].T_C_O.p.z() == Approx(0.6));
  CHECK((dets[0].T_C_O.R() * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm() < 1e-12);
  CHECK(std::isnan(dets[0].score));  // PoET has no score
  CHECK(dets[1].object_id == 113);
  CHECK(dets[2].t_ns == 3000);
  {  // meta.json through its one reader: the typed keys and the importer's own record
    const auto meta = store::read_detection_set_meta(ds, "poet");
    REQUIRE(meta);
    CHECK(meta->producer == "roe import poet");
    CHECK(meta->frames_processed == s.images_matched);
    CHECK_THAT(meta->score, Catch::Contains("no detection score"));
    CHECK(!meta->sigma.empty());
    CHECK(meta->details.at("source").at("format") == "poet results.json");
    CHECK(!meta->details.at("summary").contains("output"));
  }
  const auto m = store::read_manifest(ds);
  REQUIRE(m.sources.size() == 1);
  CHECK(m.sources[0].kind == "poet");
  CHECK(m.sources[0].sha256 == io::sha256_file(res));

  // Re-import needs --force; with it the source record is replaced, not duplicated.
  CHECK(error_of([&] { app::import_poet(res, ds, o); }).find("detections/poet") != std::string::npos);
  o.force = true;
  CHECK_NOTHROW(app::import_poet(res, ds, o));
  CHECK(store::read_manifest(ds).sources.size() == 1);
}

TEST_CASE("other file names: PoET ids and stems match, unknown ids are skipped", "[import_poet]") {
  TmpDir tmp("stem");
  const fs::path ds = make_dataset(tmp.path, {{10, "rgb_000123.png"}, {20, "rgb_000124.png"}, {30, "cam_rgb_17.png"}}, {});
  const fs::path res = write(tmp.path, "results.json",
                             "{\"000123\": {\"0\": " + det(0.5, 2) + "}, \"rgb_000124\": {\"0\": " + det(0.6, 2) +
                                 "}, \"rgb_17\": {\"0\": " + det(0.7, 3) + "}, \"999\": {\"0\": " + det(0.8, 2) + "}}");
  const auto s = app::import_poet(res, ds, {});
  CHECK(s.images_matched == 3);
  CHECK(s.images_unknown == 1);
  CHECK(s.unknown_ids == std::vector<std::string>{"999"});
  const auto dets = store::read_detections_csv(ds / "detections/poet/detections.csv");
  REQUIRE(dets.size() == 3);
  CHECK(dets[0].t_ns == 10);
  CHECK(dets[1].t_ns == 20);
  CHECK(dets[2].t_ns == 30);
  CHECK(dets[2].object_id == 3);  // no objects in roe.json: object id = class id
}

TEST_CASE("colliding ids are errors, not guesses", "[import_poet]") {
  TmpDir tmp("collide");
  const fs::path ds = make_dataset(tmp.path, {{10, "left_1.png"}, {20, "right_1.png"}, {30, "x_2.png"}}, {});
  const fs::path res = write(tmp.path, "a.json", "{\"1\": {\"0\": " + det(0.5, 2) + "}}");
  CHECK(error_of([&] { app::import_poet(res, ds, {}); }).find("matches several frames") != std::string::npos);
  // Two ids of one frame ("2" = PoET id, "x_2" = stem).
  const fs::path res2 = write(tmp.path, "b.json", "{\"2\": {}, \"x_2\": {}}");
  CHECK(error_of([&] { app::import_poet(res2, ds, {}); }).find("denote the same frame") != std::string::npos);
  // Duplicate keys in the file itself.
  const fs::path res3 = write(tmp.path, "c.json", "{\"2\": {}, \"2\": {}}");
  CHECK(error_of([&] { app::import_poet(res3, ds, {}); }).find("duplicate key") != std::string::npos);
  // Nothing matches at all.
  const fs::path res4 = write(tmp.path, "d.json", "{\"77\": {}}");
  CHECK(error_of([&] { app::import_poet(res4, ds, {}); }).find("none of the 1 image ids") != std::string::npos);
}

TEST_CASE("duplicate classes, NaN and quaternion models in one file", "[import_poet]") {
  TmpDir tmp("dup");
  const fs::path ds = make_dataset(tmp.path, {{100, "100.png"}, {200, "200.png"}}, {});
  const fs::path res = write(tmp.path, "results.json",
                             "{\"100\": {\"0\": " + det(0.5, 4) + ", \"1\": " + det(0.9, 4) +
                                 ", \"2\": {\"t\": [NaN, NaN, NaN], \"rot\": [[NaN,NaN,NaN],[NaN,NaN,NaN],[NaN,NaN,NaN]], \"box\": [0,0,0,0], \"class\": 6}},"
                                 " \"200\": {\"0\": {\"t\": [0, 0, 1], \"rot\": [0.7071067811865476, 0, 0.7071067811865476, 0], \"class\": 6}}}");
  const auto s = app::import_poet(res, ds, {});
  CHECK(s.detections_in_file == 4);
  CHECK(s.dropped_duplicate == 1);
  CHECK(s.dropped_non_finite == 1);
  CHECK(s.quaternion_rotations == 1);
  const auto dets = store::read_detections_csv(ds / "detections/poet/detections.csv");
  REQUIRE(dets.size() == 2);
  CHECK(dets[0].T_C_O.p.z() == Approx(0.5));  // the first (highest detector score) is kept
  CHECK(dets[1].object_id == 6);
  // 90° about y: z axis → x axis
  CHECK((dets[1].T_C_O.R() * Eigen::Vector3d::UnitZ() - Eigen::Vector3d::UnitX()).norm() < 1e-12);
}

TEST_CASE("class map file, class names file, and datasets without cam0/data.csv", "[import_poet]") {
  TmpDir tmp("map");
  const fs::path ds = make_dataset(tmp.path, {}, {{1, "drill", false}, {2, "mug", false}}, false);
  const fs::path res = write(tmp.path, "results.json", "{\"5000\": {\"0\": " + det(0.5, 15) + ", \"1\": " + det(0.6, 14) + "}}");
  // By YCB-V name nothing matches "drill"/"mug" exactly... "025_mug" → "mug" does.
  auto s = app::import_poet(res, ds, {});
  CHECK(s.detections_written == 1);
  CHECK(s.class_map.at(14) == 2);
  auto dets = store::read_detections_csv(ds / "detections/poet/detections.csv");
  REQUIRE(dets.size() == 1);
  CHECK(dets[0].t_ns == 5000);  // id taken as a timestamp (no cam0/data.csv)
  // An explicit map.
  app::ImportPoetOptions o;
  o.name = "mapped";
  o.class_map_file = write(tmp.path, "map.json", R"({"15": 1, "14": 2})").string();
  s = app::import_poet(res, ds, o);
  CHECK(s.detections_written == 2);
  // A PoET class-info file renaming class 15.
  o.name = "named";
  o.class_map_file.clear();
  o.classes_file = write(tmp.path, "classes.json", R"({"14": "025_mug", "15": "001_drill"})").string();
  s = app::import_poet(res, ds, o);
  CHECK(s.detections_written == 2);
  CHECK(s.class_map.at(15) == 1);
  // Bad map file and bad options.
  o.name = "bad";
  o.classes_file.clear();
  o.class_map_file = write(tmp.path, "bad.json", R"({"x": 1})").string();
  CHECK_THROWS_AS(app::import_poet(res, ds, o), ConfigError);
  // A map onto an object roe.json does not declare: refused here, not later in roe run.
  o.class_map_file = write(tmp.path, "undeclared.json", R"({"15": 1, "14": 77})").string();
  try {
    app::import_poet(res, ds, o);
    FAIL("no error");
  } catch (const ConfigError& e) {
    CHECK(e.context().file == o.class_map_file);
    CHECK(e.context().key == "14");
    CHECK_THAT(e.what(), Catch::Contains("object id 77") && Catch::Contains("objects: 1, 2"));
  }
  CHECK_FALSE(fs::exists(ds / "detections/bad"));
  o.class_map_file.clear();
  // A file that lists no image at all is no result (an image without detections is one).
  o.name = "empty";
  CHECK_THAT(error_of([&] { app::import_poet(write(tmp.path, "empty.json", "{}"), ds, o); }),
             Catch::Contains("lists no image"));
  CHECK_FALSE(fs::exists(ds / "detections/empty"));
  s = app::import_poet(write(tmp.path, "none.json", "{\"5000\": {}}"), ds, o);
  CHECK(s.detections_written == 0);
  CHECK(s.empty_images == 1);
  o.name = "bad";
  o.rotation = "euler";
  CHECK_THROWS_AS(app::import_poet(res, ds, o), InputError);
  o.rotation = "auto";
  o.name = "../x";
  CHECK_THROWS_AS(app::import_poet(res, ds, o), InputError);
}

TEST_CASE("aleatoric log-variances and covariances become the sigma columns, malformed ones write nothing",
          "[import_poet][uncertainty]") {
  TmpDir tmp("sigma");
  const fs::path fx = fs::path(ROE_SOURCE_DIR) / "tests/fixtures/poet_uncertainty";
  const fs::path ds = make_dataset(tmp.path, {{1000, "1000.png"}, {2000, "2000.png"}, {3000, "3000.png"}},
                                   {{5, "006_mustard_bottle", false}, {13, "024_bowl", true}});
  app::ImportPoetOptions o;
  const auto s = app::import_poet(fx / "good.json", ds, o);
  CHECK(s.detections_written == 4);  // 3000.0 has a NaN pose: dropped
  CHECK(s.dropped_non_finite == 1);
  CHECK(s.sigma_from_log_variances == 2);
  CHECK(s.sigma_from_covariance == 1);
  CHECK(s.max_abs_correlation_dropped > 0.6);
  bool warned_missing = false, warned_corr = false;
  for (const auto& w : s.warnings) {
    warned_missing |= w.find("1 of 4 written detection(s) carry no uncertainty") != std::string::npos;
    warned_corr |= w.find("correlations up to") != std::string::npos;
  }
  CHECK(warned_missing);
  CHECK(warned_corr);
  // Read back from detections.csv (16 columns) and compared with the σ Python computed.
  const auto dets = store::read_detections_csv(ds / "detections/poet/detections.csv");
  const auto ex = nlohmann::json::parse(io::read_file(fx / "expected.json"))["good"];
  REQUIRE(dets.size() == 4);
  const std::pair<const char*, std::size_t> rows[] = {{"1000.0", 0}, {"1000.1", 1}, {"2000.0", 2}};
  for (const auto& [key, i] : rows) {
    INFO(key);
    REQUIRE(dets[i].sigma);
    for (int k = 0; k < 6; ++k) CHECK((*dets[i].sigma)[k] == Approx(ex[key][k].get<double>()).epsilon(1e-12));
  }
  CHECK_FALSE(dets[3].sigma);
  CHECK(s.to_json()["sigma_from_covariance"] == 1);

  // A malformed value: exit-2 error naming file, key and line; no detections folder is left behind.
  const TmpDir tmp2("sigma_bad");
  const fs::path ds2 = make_dataset(tmp2.path, {{1000, "1000.png"}}, {{5, "006_mustard_bottle", false}});
  try {
    (void)app::import_poet(fx / "bad_negative_variance.json", ds2, o);
    FAIL("no error");
  } catch (const InputError& e) {
    CHECK(e.context().key == "1000.0.cov[3][3]");
    CHECK(e.context().line > 1);
  }
  CHECK_FALSE(fs::exists(ds2 / "detections"));
}
