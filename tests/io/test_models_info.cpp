// BOP models_info.json reader (io/models_info.hpp): the format of the BOP toolkit (ids as string keys,
// 4x4 row-major transforms with translations in mm, continuous axes with offsets in mm), and its errors
// with file, line, column and key path.
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>

#include "roe/core/error.hpp"
#include "roe/io/models_info.hpp"

using namespace roe;
namespace fs = std::filesystem;

namespace {
// The layout of a BOP file: one object without symmetries, one with a discrete 180° turn about z through
// (5 mm, −10 mm), one body of revolution about z.
const char* kInfo = R"({
  "1": {"diameter": 172.063, "min_x": -51.0, "min_y": -51.0, "min_z": -70.0, "size_x": 102.0, "size_y": 102.0, "size_z": 140.0},
  "2": {"diameter": 100.0, "min_x": -50.0, "min_y": -20.0, "min_z": -10.0, "size_x": 100.0, "size_y": 40.0, "size_z": 20.0,
        "symmetries_discrete": [[-1, 0, 0, 10.0, 0, -1, 0, -20.0, 0, 0, 1, 0, 0, 0, 0, 1]]},
  "13": {"diameter": 170.0, "min_x": -80.0, "min_y": -80.0, "min_z": -30.0, "size_x": 160.0, "size_y": 160.0, "size_z": 60.0,
         "symmetries_continuous": [{"axis": [0, 0, 2], "offset": [0, 0, 5.0]}]}
})";

fs::path write(const std::string& name, const std::string& text) {
  const fs::path p = fs::temp_directory_path() / ("roe_test_models_info_" + name + ".json");
  std::ofstream(p) << text;
  return p;
}
}  // namespace

TEST_CASE("models_info.json: discrete transforms and continuous axes, in metres", "[io][models_info]") {
  const fs::path p = write("ok", kInfo);
  const auto m = io::read_models_info(p);
  REQUIRE(m.size() == 3);
  CHECK(m.at(1).empty());
  REQUIRE(m.at(2).discrete.size() == 1);
  const Pose& S = m.at(2).discrete[0];
  CHECK((S.R() - Eigen::Vector3d(-1, -1, 1).asDiagonal().toDenseMatrix()).cwiseAbs().maxCoeff() < 1e-12);
  CHECK((S.p - Eigen::Vector3d(0.010, -0.020, 0.0)).norm() < 1e-15);
  CHECK(!m.at(2).continuous);
  REQUIRE(m.at(13).continuous);
  CHECK(m.at(13).continuous->axis == Eigen::Vector3d(0, 0, 1));
  CHECK((m.at(13).continuous->offset - Eigen::Vector3d(0, 0, 0.005)).norm() < 1e-15);
  // The discrete transform maps the model onto itself: S applied twice is the identity.
  const Pose SS = S * S;
  CHECK(SS.p.norm() < 1e-15);
  fs::remove(p);
}

TEST_CASE("models_info.json: errors name file, line, column and key", "[io][models_info]") {
  struct Case {
    const char* text;
    const char* key;
    int line;
  };
  const Case cases[] = {
      {"{\n \"1\": {\"diameter\": 1, \"symetries_discrete\": []}\n}", "1.symetries_discrete", 2},
      {"{\n \"1\": {\"symmetries_discrete\": [[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0]]}\n}",
       "1.symmetries_discrete[0]", 2},
      {"{\n \"1\": {\n  \"symmetries_discrete\": [[2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]]}\n}",
       "1.symmetries_discrete[0]", 3},
      {"{\n \"1\": {\"symmetries_discrete\": [[-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]]}\n}",
       "1.symmetries_discrete[0]", 2},
      {"{\n \"1\": {\"symmetries_continuous\": [{\"axis\": [0, 0, 0], \"offset\": [0, 0, 0]}]}\n}",
       "1.symmetries_continuous[0].axis", 2},
      {"{\n \"1\": {\"symmetries_continuous\": [{\"axis\": [0, 0, 1]}]}\n}", "1.symmetries_continuous[0].offset", 2},
      {"{\n \"x1\": {}\n}", "x1", 2},
  };
  for (const Case& c : cases) {
    INFO(c.text);
    const fs::path p = write("bad", c.text);
    try {
      io::read_models_info(p);
      FAIL("accepted");
    } catch (const InputError& e) {
      CHECK(e.context().file == p.string());
      CHECK(e.context().key == c.key);
      CHECK(e.context().line == c.line);
      CHECK(e.context().column > 0);
    }
    fs::remove(p);
  }
}

#include "roe/store/dataset.hpp"

TEST_CASE("roe.json objects point at a models_info.json (relative to roe.json's folder)", "[io][models_info]") {
  const fs::path dir = fs::temp_directory_path() / "roe_test_models_info_ds";
  fs::remove_all(dir);
  fs::create_directories(dir / "models");
  std::ofstream(dir / "models" / "models_info.json") << kInfo;
  const auto manifest = [&](const std::string& objects) {
    std::ofstream(dir / "roe.json") << R"({"schema": "roe-dataset/1", "name": "x", "objects": )" << objects << "}";
    return store::read_manifest(dir);
  };
  const auto m = manifest(R"([{"id": 4, "models_info": "models/models_info.json", "models_info_id": 13},
                               {"id": 2, "models_info": "models/models_info.json"}, {"id": 7}])");
  REQUIRE(m.objects.size() == 3);
  REQUIRE(m.objects[0].symmetry.continuous);
  CHECK(m.objects[0].symmetry.continuous->axis == Eigen::Vector3d(0, 0, 1));
  CHECK(m.objects[1].symmetry.discrete.size() == 1);
  CHECK(m.objects[2].symmetry.empty());
  // Errors name roe.json and the object's key.
  for (const auto& [objects, key] :
       std::vector<std::pair<std::string, std::string>>{
           {R"([{"id": 5, "models_info": "models/models_info.json"}])", "objects[0].models_info"},
           {R"([{"id": 2, "models_info": "models/models_info.json", "models_info_id": 99}])", "objects[0].models_info_id"},
           {R"([{"id": 2, "models_info_id": 1}])", "objects[0].models_info_id"}}) {
    INFO(objects);
    try {
      manifest(objects);
      FAIL("accepted");
    } catch (const InputError& e) {
      CHECK(e.context().file == (dir / "roe.json").string());
      CHECK(e.context().key == key);
    }
  }
  // A missing file is an input error naming it.
  CHECK_THROWS_AS(manifest(R"([{"id": 2, "models_info": "nope.json"}])"), InputError);
  fs::remove_all(dir);
}

TEST_CASE("models_info.json writer: what it writes reads back to the same symmetries", "[io][models_info]") {
  // The reader's file above, read, written, read again; plus a tilted axis with an offset and a discrete
  // group of three turns about an offset axis (values the reader's own fixture does not have).
  std::map<int, ObjectSymmetry> in = io::read_models_info(write("rt_src", kInfo));
  ObjectSymmetry box;
  const Eigen::Vector3d o(0.012, -0.02, 0.003);
  for (int k = 1; k <= 3; ++k) {
    const Eigen::Quaterniond q(Eigen::AngleAxisd(k * M_PI / 2, Eigen::Vector3d::UnitY()));
    box.discrete.push_back(Pose(q, o - q * o));
  }
  box.continuous = ContinuousSymmetry{Eigen::Vector3d(0.3, -0.2, 1.0).normalized(), Eigen::Vector3d(0.001, 0.002, -0.03)};
  in[7] = box;
  const fs::path p = fs::temp_directory_path() / "roe_test_models_info_written.json";
  io::write_models_info(p, in);
  const auto back = io::read_models_info(p);
  REQUIRE(back.size() == in.size());
  for (const auto& [id, s] : in) {
    INFO("object " << id);
    const ObjectSymmetry& b = back.at(id);
    REQUIRE(b.discrete.size() == s.discrete.size());
    for (std::size_t i = 0; i < s.discrete.size(); ++i) {
      CHECK((b.discrete[i].R() - s.discrete[i].R()).cwiseAbs().maxCoeff() < 1e-12);
      CHECK((b.discrete[i].p - s.discrete[i].p).norm() < 1e-15);
    }
    REQUIRE(b.continuous.has_value() == s.continuous.has_value());
    if (s.continuous) {
      CHECK((b.continuous->axis - s.continuous->axis).norm() < 1e-15);
      CHECK((b.continuous->offset - s.continuous->offset).norm() < 1e-15);
    }
  }
  fs::remove(p);
  fs::remove(fs::temp_directory_path() / "roe_test_models_info_rt_src.json");
}
