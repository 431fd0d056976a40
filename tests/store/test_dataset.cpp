#include <unistd.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <random>
#include <string>

#include "support/test_util.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/output.hpp"
#include "roe/math/so3.hpp"

namespace fs = std::filesystem;
using namespace roe;
using roe::io::json;

namespace {
using roe::test::TempDir;

// A fresh, empty temporary folder removed at scope exit.

using roe::test::expect_input_error;

template <typename Fn>
ConfigError expect_config_error(Fn&& fn) {
  try {
    fn();
  } catch (const ConfigError& e) {
    return e;
  }
  FAIL("expected roe::ConfigError");
  throw std::logic_error("unreachable");
}

Pose random_pose(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Pose(math::exp_quat(Eigen::Vector3d(n(rng), n(rng), n(rng))),
              Eigen::Vector3d(n(rng), n(rng), n(rng)));
}

bool same(const Pose& a, const Pose& b) { return a.q.coeffs() == b.q.coeffs() && a.p == b.p; }

// A dataset with every field set to non-trivial values.
Dataset make_dataset() {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  Dataset d;
  auto& m = d.manifest;
  m.name = "round trip, \"quoted\"";
  m.sources.push_back(
      {"simulate", "configs/sim/paper-seq4.json", std::string(64, 'a'), {{"seed", "1"}, {"x", "y"}}});
  m.sources.push_back({"poet", "", "", {}});
  m.imu = ImuInfo{200.0, {1.6968e-4, 1.9393e-5, 2.0e-3, 3.0e-3}};
  CameraInfo c;
  c.width = 640;
  c.height = 480;
  c.fx = 908.1;
  c.fy = 907.7;
  c.cx = 321.3;
  c.cy = 239.9;
  c.distortion_model = "radtan";
  c.distortion = {0.01, -0.02, 1e-4, -2e-4};
  c.T_I_C = random_pose(rng);
  c.time_offset_s = -0.0123;
  m.camera = c;
  m.mocap = MocapInfo{"rig", random_pose(rng), 0.004};
  m.objects = {{1, "002_master_chef_can", false, "", -1, {}}, {13, "024_bowl", true, "", -1, {}}};
  Truth t;
  t.T_I_C = random_pose(rng);
  t.objects = {{1, random_pose(rng)}, {13, random_pose(rng)}};
  t.imu_noise = ImuNoise{1e-4, 2e-5, 3e-3, 4e-4};
  t.detection_noise = {{"sigma_rot_deg", 6.0}, {"outlier_rate", 0.05}, {"correlated", 1.0}};
  m.truth = t;

  Timestamp t0 = 1403715523912140000LL;
  for (int i = 0; i < 50; ++i) {
    ImuSample s;
    s.t_ns = t0 + i * 5'000'000LL;
    s.gyro = Eigen::Vector3d(n(rng), n(rng), n(rng)) * 0.1;
    s.accel = Eigen::Vector3d(n(rng), n(rng), 9.81 + n(rng));
    d.imu.push_back(s);
    ImuState g;
    g.t_ns = s.t_ns;
    g.T_W_I = random_pose(rng);
    g.v_W_I = Eigen::Vector3d(n(rng), n(rng), n(rng));
    g.b_g = Eigen::Vector3d(n(rng), n(rng), n(rng)) * 1e-3;
    g.b_a = Eigen::Vector3d(n(rng), n(rng), n(rng)) * 1e-2;
    d.groundtruth.push_back(g);
  }
  for (int i = 0; i < 10; ++i) {
    const Timestamp ts = t0 + i * 33'333'333LL;
    d.frames.push_back({ts, std::to_string(ts) + ".png"});
    d.mocap.push_back({t0 + i * 8'333'333LL, random_pose(rng)});
    for (int id : {13, 1}) {  // several objects per stamp, not sorted by id
      Detection det;
      det.t_ns = ts;
      det.object_id = id;
      det.T_C_O = random_pose(rng);
      det.score = i % 3 == 0 ? std::nan("") : 0.5 + 0.01 * i;
      d.detections["sim"].push_back(det);
      if (i % 2 == 0) det.sigma = (Vector6d() << 0.01, 0.02, 0.03, 0.1, 0.2, 0.3 + i).finished();
      d.detections["poet"].push_back(det);
    }
  }
  d.detections["empty"];
  return d;
}

void check_equal(const Dataset& a, const Dataset& b) {
  // The manifest compares through its JSON (every field, doubles exactly).
  CHECK(store::manifest_to_json(a.manifest) == store::manifest_to_json(b.manifest));
  CHECK(same(a.manifest.camera->T_I_C, b.manifest.camera->T_I_C));
  CHECK(same(a.manifest.truth->objects[1].T_W_O, b.manifest.truth->objects[1].T_W_O));
  REQUIRE(a.imu.size() == b.imu.size());
  for (std::size_t i = 0; i < a.imu.size(); ++i) {
    CHECK(a.imu[i].t_ns == b.imu[i].t_ns);
    CHECK(a.imu[i].gyro == b.imu[i].gyro);
    CHECK(a.imu[i].accel == b.imu[i].accel);
  }
  REQUIRE(a.groundtruth.size() == b.groundtruth.size());
  for (std::size_t i = 0; i < a.groundtruth.size(); ++i) {
    CHECK(a.groundtruth[i].t_ns == b.groundtruth[i].t_ns);
    CHECK(same(a.groundtruth[i].T_W_I, b.groundtruth[i].T_W_I));
    CHECK(a.groundtruth[i].v_W_I == b.groundtruth[i].v_W_I);
    CHECK(a.groundtruth[i].b_g == b.groundtruth[i].b_g);
    CHECK(a.groundtruth[i].b_a == b.groundtruth[i].b_a);
  }
  REQUIRE(a.frames.size() == b.frames.size());
  for (std::size_t i = 0; i < a.frames.size(); ++i) {
    CHECK(a.frames[i].t_ns == b.frames[i].t_ns);
    CHECK(a.frames[i].filename == b.frames[i].filename);
  }
  REQUIRE(a.mocap.size() == b.mocap.size());
  for (std::size_t i = 0; i < a.mocap.size(); ++i) {
    CHECK(a.mocap[i].t_ns == b.mocap[i].t_ns);
    CHECK(same(a.mocap[i].T, b.mocap[i].T));
  }
  REQUIRE(a.detections.size() == b.detections.size());
  for (const auto& [name, da] : a.detections) {
    CAPTURE(name);
    REQUIRE(b.detections.count(name) == 1);
    const auto& db = b.detections.at(name);
    REQUIRE(da.size() == db.size());
    for (std::size_t i = 0; i < da.size(); ++i) {
      CHECK(da[i].t_ns == db[i].t_ns);
      CHECK(da[i].object_id == db[i].object_id);
      CHECK(same(da[i].T_C_O, db[i].T_C_O));
      CHECK((std::isnan(da[i].score) ? std::isnan(db[i].score) : da[i].score == db[i].score));
      REQUIRE(da[i].sigma.has_value() == db[i].sigma.has_value());
      if (da[i].sigma) CHECK(*da[i].sigma == *db[i].sigma);
    }
  }
}

// Every file of a folder, by relative path → bytes.
std::map<std::string, std::string> folder_bytes(const fs::path& root) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(root))
    if (e.is_regular_file()) out[fs::relative(e.path(), root).string()] = io::read_file(e.path());
  return out;
}

void write_text(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  io::write_file_atomic(p, text);
}

json minimal_manifest() { return json{{"schema", "roe-dataset/1"}, {"name", "x"}}; }

}  // namespace

TEST_CASE("dataset: write then read gives identical structs and writing twice identical bytes", "[dataset]") {
  TempDir tmp("roundtrip");
  const Dataset d = make_dataset();
  store::write_dataset(d, tmp.path / "a", false);
  store::write_dataset(d, tmp.path / "b", false);
  const Dataset back = store::read_dataset(tmp.path / "a");
  check_equal(d, back);
  const auto bytes_a = folder_bytes(tmp.path / "a");
  CHECK(bytes_a == folder_bytes(tmp.path / "b"));
  CHECK(bytes_a.count("roe.json") == 1);
  CHECK(bytes_a.count("mav0/imu0/data.csv") == 1);
  CHECK(bytes_a.count("detections/empty/detections.csv") == 1);
  CHECK(
      bytes_a.at("mav0/imu0/data.csv")
          .rfind(
              "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],"
              "a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n",
              0) == 0);
  CHECK(bytes_a.at("detections/sim/detections.csv")
            .rfind("timestamp_ns,object_id,tx,ty,tz,qx,qy,qz,qw,score\n", 0) == 0);
  CHECK(bytes_a.at("detections/poet/detections.csv").find(",sigma_rz\n") != std::string::npos);

  // Writing what was read gives the same bytes again.
  store::write_dataset(back, tmp.path / "c", false);
  CHECK(folder_bytes(tmp.path / "c") == bytes_a);

  // Parts and named detection sets.
  store::DatasetParts parts;
  parts.imu = false;
  parts.detection_names = {"poet"};
  const Dataset some = store::read_dataset(tmp.path / "a", parts);
  CHECK(some.imu.empty());
  CHECK(some.groundtruth.size() == d.groundtruth.size());
  CHECK(some.detections.size() == 1);
  parts.detection_names = {"nope"};
  auto e = expect_input_error([&] { store::read_dataset(tmp.path / "a", parts); });
  CHECK(std::string(e.what()).find("available: empty, poet, sim") != std::string::npos);

  // An existing dataset is not replaced without force, and is with it.
  e = expect_input_error([&] { store::write_dataset(d, tmp.path / "a", false); });
  CHECK(std::string(e.what()).find("not empty") != std::string::npos);
  Dataset small;
  small.manifest.name = "small";
  store::write_dataset(small, tmp.path / "a", true);
  CHECK(folder_bytes(tmp.path / "a").size() == 1);
  CHECK(store::read_dataset(tmp.path / "a").manifest.name == "small");
}

TEST_CASE("dataset: the committed sample manifest is written back byte for byte", "[dataset][manifest]") {
  // roe.json's layout (key order, two-space indentation at every depth, flat arrays on one line) is
  // part of what users diff between datasets: reading and writing the sample changes no byte.
  const fs::path sample = fs::path(ROE_SOURCE_DIR) / "datasets" / "sample" / "roe.json";
  TempDir tmp("manifest-bytes");
  store::write_manifest(store::read_manifest(sample.parent_path()), tmp.path / "roe.json");
  CHECK(io::read_file(tmp.path / "roe.json") == io::read_file(sample));
}

TEST_CASE("dataset: a folder without roe.json is refused", "[dataset]") {
  TempDir tmp("nomanifest");
  auto e = expect_input_error([&] { store::read_dataset(tmp.path); });
  CHECK(e.context().file == (tmp.path / "roe.json").string());
  e = expect_input_error([&] { store::read_dataset(tmp.path / "missing"); });
  CHECK(std::string(e.what()).find("not found") != std::string::npos);
}

TEST_CASE("dataset: manifest defaults for missing optional keys", "[dataset][manifest]") {
  json j = minimal_manifest();
  j["camera"] = {{"width", 640}, {"height", 480}, {"fx", 600.0}, {"fy", 601.0}, {"cx", 320.0}, {"cy", 240.0}};
  j["mocap"] = json::object();
  j["imu"] = {{"rate_hz", 200}};
  j["objects"] = {{{"id", 5}}};
  j["truth"] = {{"T_I_C", {{"p", {0, 0, 0}}, {"q", {0, 0, 0, 1}}}}};
  const DatasetManifest m = store::manifest_from_json(j, "roe.json");
  CHECK(m.name == "x");
  CHECK(m.sources.empty());
  REQUIRE(m.camera);
  CHECK(m.camera->distortion_model == "none");
  CHECK(m.camera->distortion.empty());
  CHECK(same(m.camera->T_I_C, Pose::identity()));
  CHECK(m.camera->time_offset_s == 0.0);
  REQUIRE(m.mocap);
  CHECK(m.mocap->body.empty());
  CHECK(same(m.mocap->T_B_I, Pose::identity()));
  REQUIRE(m.imu);
  CHECK(m.imu->rate_hz == 200.0);
  CHECK(m.imu->noise.gyro_noise_density < 0.0);  // absent = unknown
  CHECK(m.imu->noise.accel_random_walk < 0.0);
  CHECK_FALSE(m.imu->noise.known());
  // Unknown values are left out when written, 0 (a noise-free IMU) is kept, and both read back.
  {
    DatasetManifest w = m;
    w.imu->noise.accel_noise_density = 0.0;
    const json back = store::manifest_to_json(w);
    CHECK_FALSE(back.at("imu").contains("gyro_noise_density"));
    CHECK(back.at("imu").at("accel_noise_density") == 0.0);
    const DatasetManifest r = store::manifest_from_json(back, "roe.json");
    CHECK(r.imu->noise.gyro_noise_density < 0.0);
    CHECK(r.imu->noise.accel_noise_density == 0.0);
  }
  REQUIRE(m.objects.size() == 1);
  CHECK(m.objects[0].name.empty());
  CHECK_FALSE(m.objects[0].symmetric);
  REQUIRE(m.truth);
  CHECK(m.truth->objects.empty());
  CHECK_FALSE(m.truth->imu_noise);
  const DatasetManifest bare = store::manifest_from_json(minimal_manifest(), "roe.json");
  CHECK_FALSE(bare.camera);
  CHECK_FALSE(bare.imu);
  CHECK_FALSE(bare.mocap);
  CHECK_FALSE(bare.truth);
}

TEST_CASE("dataset: manifest schema errors name the key path", "[dataset][manifest]") {
  struct Case {
    std::string name;
    std::function<void(json&)> edit;
    std::string key;
    std::string what;
  };
  const json pose = {{"p", {0, 0, 0}}, {"q", {0, 0, 0, 1}}};
  const std::vector<Case> cases = {
      {"unknown root key", [](json& j) { j["nmae"] = "typo"; }, "nmae", "unknown key"},
      {"unknown nested key",
       [&](json& j) {
         j["mocap"] = {{"body", "b"}, {"T_B_I", pose}, {"offset", 1}};
       },
       "mocap.offset", "unknown key"},
      {"unknown key in a pose",
       [&](json& j) {
         j["truth"] = {
             {"T_I_C", pose},
             {"objects", {{{"id", 1}, {"T_W_O", {{"p", {0, 0, 0}}, {"q", {0, 0, 0, 1}}, {"r", 1}}}}}}};
       },
       "truth.objects[0].T_W_O.r", "unknown key"},
      {"unknown key in a source option holder",
       [](json& j) {
         j["sources"] = {{{"kind", "sim"}, {"sha", "x"}}};
       },
       "sources[0].sha", "unknown key"},
      {"non-unit quaternion",
       [](json& j) {
         j["camera"] = {{"width", 640},
                        {"height", 480},
                        {"fx", 1.0},
                        {"fy", 1.0},
                        {"cx", 0.0},
                        {"cy", 0.0},
                        {"T_I_C", {{"p", {0, 0, 0}}, {"q", {0, 0, 0, 1.00001}}}}};
       },
       "camera.T_I_C.q", "not unit norm"},
      {"quaternion with three entries",
       [](json& j) {
         j["mocap"] = {{"T_B_I", {{"p", {0, 0, 0}}, {"q", {0, 0, 1}}}}};
       },
       "mocap.T_B_I.q", "array of 4"},
      {"quaternion entry not a number",
       [](json& j) {
         j["mocap"] = {{"T_B_I", {{"p", {0, "0", 0}}, {"q", {0, 0, 0, 1}}}}};
       },
       "mocap.T_B_I.p[1]", "expected a number"},
      {"wrong type int",
       [](json& j) {
         j["camera"] = {{"width", "640"}};
       },
       "camera.width", "expected an integer"},
      {"wrong type object", [](json& j) { j["imu"] = 200; }, "imu", "expected a JSON object"},
      {"wrong type bool",
       [](json& j) {
         j["objects"] = {{{"id", 1}, {"symmetric", 1}}};
       },
       "objects[0].symmetric", "expected true or false"},
      {"array element not an object", [](json& j) { j["objects"] = json::array({1}); }, "objects[0]",
       "expected a JSON object"},
      {"object instead of array",
       [](json& j) {
         j["objects"] = {{"id", 1}};
       },
       "objects", "expected an array"},
      {"source option not a string",
       [](json& j) {
         j["sources"] = {{{"kind", "sim"}, {"options", {{"seed", 1}}}}};
       },
       "sources[0].options.seed", "expected a string"},
      {"missing required",
       [](json& j) {
         j["imu"] = {{"gyro_noise_density", 1e-4}};
       },
       "imu.rate_hz", "missing required key"},
      {"negative noise",
       [](json& j) {
         j["imu"] = {{"rate_hz", 200}, {"accel_random_walk", -1.0}};
       },
       "imu.accel_random_walk", "must be >= 0"},
      {"duplicate object id",
       [](json& j) {
         j["objects"] = {{{"id", 1}}, {{"id", 1}}};
       },
       "objects[1].id", "duplicate object id"},
      {"wrong schema", [](json& j) { j["schema"] = "roe-dataset/2"; }, "schema", "unsupported schema"},
      {"missing schema", [](json& j) { j.erase("schema"); }, "schema", "missing required key"},
      {"truth pose missing", [](json& j) { j["truth"] = json::object(); }, "truth.T_I_C",
       "missing required key"},
      {"detection noise not a number",
       [&](json& j) {
         j["truth"] = {{"T_I_C", pose}, {"detection_noise", {{"tau_s", "0.3"}}}};
       },
       "truth.detection_noise.tau_s", "expected a number"},
  };
  for (const auto& c : cases) {
    CAPTURE(c.name);
    json j = minimal_manifest();
    c.edit(j);
    auto e = expect_config_error([&] { store::manifest_from_json(j, "data/roe.json"); });
    CHECK(e.context().file == "data/roe.json");
    CHECK(e.context().key == c.key);
    CHECK(std::string(e.what()).find(c.what) != std::string::npos);
  }
  // A non-unit quaternion inside the tolerance is accepted and normalised.
  json j = minimal_manifest();
  j["mocap"] = {{"T_B_I", {{"p", {0, 0, 0}}, {"q", {0, 0, 0, 1.0000005}}}}};
  CHECK(std::abs(store::manifest_from_json(j, "roe.json").mocap->T_B_I.q.norm() - 1.0) < 1e-15);
}

TEST_CASE("dataset: manifest file errors carry line and column", "[dataset][manifest]") {
  TempDir tmp("badjson");
  write_text(tmp.path / "roe.json", "{\n  \"schema\": \"roe-dataset/1\",\n  \"name\": x\n}\n");
  auto e = expect_input_error([&] { store::read_manifest(tmp.path); });
  CHECK(e.context().line == 3);
  CHECK(e.context().column == 11);  // the x
  // At the start of a line, and JSON that stops early (reported where it stops).
  write_text(tmp.path / "roe.json", "{\n]\n");
  e = expect_input_error([&] { store::read_manifest(tmp.path); });
  CHECK(e.context().line == 2);
  CHECK(e.context().column == 1);
  write_text(tmp.path / "roe.json", "{\n  \"name\": \"a\",\n");
  e = expect_input_error([&] { store::read_manifest(tmp.path); });
  CHECK(e.context().line == 3);
  CHECK(e.context().column == 1);
}

TEST_CASE("dataset: stream readers reject malformed rows with line and column", "[dataset]") {
  TempDir tmp("streams");
  const std::string imu_h =
      "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],"
      "a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n";
  const fs::path f = tmp.path / "f.csv";

  write_text(f, imu_h + "1,0,0,0,0,0,9.81\n2,0,0,0,0,0,nan\n");
  auto e = expect_input_error([&] { store::read_imu_csv(f); });
  CHECK(e.context().line == 3);
  CHECK(e.context().column == 7);

  write_text(f, imu_h + "2,0,0,0,0,0,9.81\n1,0,0,0,0,0,9.81\n");
  e = expect_input_error([&] { store::read_imu_csv(f); });
  CHECK(e.context().line == 3);
  CHECK(e.context().column == 1);

  // Readings beyond any IMU's range (a corrupt cell): the cell is named, not a filter divergence later.
  write_text(f, imu_h + "1,0,0,0,0,0,9.81\n2,0,1e300,0,0,0,9.81\n");
  e = expect_input_error([&] { store::read_imu_csv(f); });
  CHECK(e.context().line == 3);
  CHECK(e.context().column == 3);
  CHECK(std::string(e.what()).find("beyond any IMU's range") != std::string::npos);
  write_text(f, imu_h + "1,0,0,0,0,0,9810\n");
  e = expect_input_error([&] { store::read_imu_csv(f); });
  CHECK(e.context().column == 7);
  write_text(f, imu_h + "1,-999,0,0,0,0,-4999\n");
  CHECK(store::read_imu_csv(f).size() == 1);

  write_text(f, "#timestamp [ns],w_RS_S_x [rad s^-1]\n1,0\n");
  e = expect_input_error([&] { store::read_imu_csv(f); });
  CHECK(e.context().line == 1);
  CHECK(e.context().column == 3);

  // mocap: quaternion far from unit → error at the first quaternion column.
  write_text(
      f,
      "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z []\n"
      "1,0,0,0,1,0,0,0\n2,0,0,0,0.5,0,0,0\n");
  e = expect_input_error([&] { store::read_mocap_csv(f); });
  CHECK(e.context().line == 3);
  CHECK(e.context().column == 5);
  CHECK(std::string(e.what()).find("not unit norm") != std::string::npos);

  // cam0: duplicate stamp, and a path instead of a file name.
  write_text(f, "#timestamp [ns],filename\n1,1.png\n1,2.png\n");
  e = expect_input_error([&] { store::read_cam_csv(f); });
  CHECK(e.context().line == 3);
  CHECK(e.context().column == 1);
  write_text(f, "#timestamp [ns],filename\n1,../1.png\n");
  e = expect_input_error([&] { store::read_cam_csv(f); });
  CHECK(e.context().column == 2);
  write_text(f, "#timestamp [ns],filename\n1,\n2,2.png\n");
  CHECK(store::read_cam_csv(f).size() == 2);
}

TEST_CASE("dataset: detections.csv rules", "[dataset][detections]") {
  TempDir tmp("det");
  const fs::path f = tmp.path / "detections.csv";
  const std::string h = "timestamp_ns,object_id,tx,ty,tz,qx,qy,qz,qw,score\n";
  const std::string hs =
      "timestamp_ns,object_id,tx,ty,tz,qx,qy,qz,qw,score,sigma_tx,sigma_ty,sigma_tz,sigma_rx,"
      "sigma_ry,sigma_rz\n";

  write_text(f, h + "10,1,0.1,0.2,1.5,0,0,0,1,0.9\n10,2,0,0,1,0,0,0,1,\n20,1,0,0,1,0,0,1,0,0.5\n");
  auto dets = store::read_detections_csv(f);
  REQUIRE(dets.size() == 3);
  CHECK(dets[0].T_C_O.p == Eigen::Vector3d(0.1, 0.2, 1.5));
  CHECK(dets[0].score == 0.9);
  CHECK(std::isnan(dets[1].score));
  CHECK(dets[2].T_C_O.q.z() == 1.0);
  CHECK_FALSE(dets[0].sigma);

  write_text(f, hs + "10,1,0,0,1,0,0,0,1,0.9,0.01,0.01,0.03,0.1,0.1,0.1\n10,2,0,0,1,0,0,0,1,0.8,,,,,,\n");
  dets = store::read_detections_csv(f);
  REQUIRE(dets.size() == 2);
  REQUIRE(dets[0].sigma);
  CHECK((*dets[0].sigma)[2] == 0.03);
  CHECK_FALSE(dets[1].sigma);

  write_text(f, h + "10,1,0,0,1,0,0,0,1,0.9\n10,1,0,0,1,0,0,0,1,0.8\n");
  auto e = expect_input_error([&] { store::read_detections_csv(f); });
  CHECK(e.context().line == 3);
  CHECK(e.context().column == 2);
  CHECK(std::string(e.what()).find("duplicate detection of object 1") != std::string::npos);

  write_text(f, h + "20,1,0,0,1,0,0,0,1,0.9\n10,2,0,0,1,0,0,0,1,0.8\n");
  e = expect_input_error([&] { store::read_detections_csv(f); });
  CHECK(e.context().line == 3);
  CHECK(e.context().column == 1);

  write_text(f, h + "10,1,0,0,1,0,0,0,1,nan\n");
  e = expect_input_error([&] { store::read_detections_csv(f); });
  CHECK(e.context().column == 10);

  write_text(f, "timestamp_ns,object_id,tx,ty,tz,qw,qx,qy,qz,score\n");
  e = expect_input_error([&] { store::read_detections_csv(f); });
  CHECK(e.context().line == 1);
  CHECK(e.context().column == 6);

  write_text(f, "timestamp_ns,object_id,tx,ty,tz,qx,qy,qz,qw,score,sigma_tx\n");
  e = expect_input_error([&] { store::read_detections_csv(f); });
  CHECK(e.context().line == 1);
  CHECK(e.context().column == 11);

  write_text(f, hs + "10,1,0,0,1,0,0,0,1,0.9,0.01,,0.03,0.1,0.1,0.1\n");
  e = expect_input_error([&] { store::read_detections_csv(f); });
  CHECK(e.context().line == 2);
  CHECK(std::string(e.what()).find("all empty or all given") != std::string::npos);

  write_text(f, hs + "10,1,0,0,1,0,0,0,1,0.9,0.01,0.02,0.03,0.1,-0.1,0.1\n");
  e = expect_input_error([&] { store::read_detections_csv(f); });
  CHECK(e.context().column == 15);

  write_text(f, h + "10,-1,0,0,1,0,0,0,1,0.9\n");
  e = expect_input_error([&] { store::read_detections_csv(f); });
  CHECK(e.context().column == 2);
}

TEST_CASE("dataset: writers refuse unsorted streams and invalid manifests", "[dataset]") {
  TempDir tmp("unsorted");
  std::vector<ImuSample> imu(2);
  imu[0].t_ns = 2;
  imu[1].t_ns = 1;
  CHECK_THROWS_AS(store::write_imu_csv(tmp.path / "imu.csv", imu), InternalError);
  std::vector<Detection> dets(2);
  dets[0].t_ns = dets[1].t_ns = 5;  // same stamp, same object
  CHECK_THROWS_AS(store::write_detections_csv(tmp.path / "d.csv", dets), InternalError);
  dets[1].object_id = 3;
  CHECK_NOTHROW(store::write_detections_csv(tmp.path / "d.csv", dets));
  // Every earlier detection of the same stamp is compared, not only the previous one.
  dets.push_back(dets[0]);
  dets.back().object_id = 4;
  CHECK_NOTHROW(store::write_detections_csv(tmp.path / "d.csv", dets));  // objects 0, 3, 4 at t = 5
  dets.back().object_id = 0;
  CHECK_THROWS_AS(store::write_detections_csv(tmp.path / "d.csv", dets), InternalError);  // 0 again, two rows back
  CHECK_FALSE(fs::exists(tmp.path / "imu.csv"));
  DatasetManifest m;
  m.objects = {{3, "a", false, "", -1, {}}, {3, "b", true, "", -1, {}}};
  CHECK_THROWS_AS(store::write_manifest(m, tmp.path / "roe.json"), InternalError);
  m.objects.pop_back();
  m.schema = "other";
  CHECK_THROWS_AS(store::write_manifest(m, tmp.path / "roe.json"), InternalError);
  CHECK_FALSE(fs::exists(tmp.path / "roe.json"));
}

TEST_CASE("dataset: reads the real EuRoC V1_02 snippet (imu0, ground truth)", "[dataset][real]") {
  const fs::path mav0 = fs::path(ROE_SHARED_DATA_DIR) / "euroc_v102_snippet" / "mav0";
  if (!fs::exists(mav0)) {
    WARN("skipped: " << mav0 << " not found");
    return;
  }
  const auto imu = store::read_imu_csv(mav0 / "imu0" / "data.csv");
  REQUIRE(imu.size() == 7999);
  CHECK(imu.front().t_ns == 1403715523912140000LL);
  CHECK(imu.front().gyro.x() == -0.0006981317);
  CHECK(imu.front().accel.z() == -3.1544724167);
  // 200 Hz: the whole snippet spans 7998 intervals of 5 ms, give or take the 10 us stamp truncation.
  CHECK(std::abs(dt_seconds(imu.front().t_ns, imu.back().t_ns) - 39.99) < 0.01);

  const auto gt = store::read_groundtruth_csv(mav0 / "state_groundtruth_estimate0" / "data.csv");
  REQUIRE(gt.size() == 3340);
  CHECK(gt.front().t_ns == 1403715524922140000LL);
  CHECK(gt.front().T_W_I.p == Eigen::Vector3d(0.515292, 1.996597, 0.971028));
  // q w first in the file: 0.161869,0.790012,-0.205215,0.554587 (normalised on reading).
  const Eigen::Vector4d q_file(0.790012, -0.205215, 0.554587, 0.161869);
  CHECK((gt.front().T_W_I.q.coeffs() - q_file.normalized()).norm() < 1e-15);
  CHECK(gt.front().v_W_I.x() == -0.006748);
  CHECK(gt.front().b_g.z() == 0.075806);
  CHECK(gt.front().b_a.x() == -0.013337);
  for (const auto& s : gt) CHECK(std::abs(s.T_W_I.q.norm() - 1.0) < 1e-12);

  // Our own writer reproduces the EuRoC header spelling exactly, and re-reading gives the same states.
  TempDir tmp("euroc");
  store::write_groundtruth_csv(tmp.path / "gt.csv", gt);
  const std::string orig = io::read_file(mav0 / "state_groundtruth_estimate0" / "data.csv");
  const std::string ours = io::read_file(tmp.path / "gt.csv");
  CHECK(orig.substr(0, orig.find('\n')) == ours.substr(0, ours.find('\n')));
  const auto gt2 = store::read_groundtruth_csv(tmp.path / "gt.csv");
  REQUIRE(gt2.size() == gt.size());
  for (std::size_t i = 0; i < gt.size(); i += 97) CHECK(same(gt[i].T_W_I, gt2[i].T_W_I));
}

TEST_CASE("dataset: reads other real EuRoC-layout files (V1_02 full GT, TUM-VI mocap)", "[dataset][real]") {
  const fs::path data = fs::path(ROE_SHARED_DATA_DIR);
  if (!fs::exists(data / "eval" / "V102_groundtruth.csv") || !fs::exists(data / "tumvi")) {
    WARN("skipped: shared data not found");
    return;
  }
  const auto gt = store::read_groundtruth_csv(data / "eval" / "V102_groundtruth.csv");
  CHECK(gt.size() == 16702);
  const auto mocap = store::read_mocap_csv(data / "tumvi" / "dataset-room1_512_16_gt.csv");
  REQUIRE(mocap.size() > 1000);
  CHECK(mocap.front().t_ns == 1520530308189679351LL);
  CHECK(mocap.front().T.p.x() == 0.8417820384);
}

TEST_CASE("output: OutputDir refuses, replaces with force, and leaves nothing behind", "[output]") {
  TempDir tmp("outdir");
  const fs::path target = tmp.path / "out";
  fs::create_directories(target);
  write_text(target / "keep.txt", "old");

  auto e = expect_input_error([&] { io::OutputDir o(target, false); });
  CHECK(e.context().file == target.string());
  CHECK(io::read_file(target / "keep.txt") == "old");

  {  // force, but never committed: the old folder stays, no temporary folder remains.
    io::OutputDir o(target, true);
    write_text(o.file("new.txt"), "new");
    CHECK(fs::exists(o.tmp() / "new.txt"));
  }
  CHECK(io::read_file(target / "keep.txt") == "old");
  CHECK(std::distance(fs::directory_iterator(tmp.path), fs::directory_iterator()) == 1);

  {  // force and commit: replaced.
    io::OutputDir o(target, true);
    write_text(o.file("sub/new.txt"), "new");
    o.commit();
  }
  CHECK_FALSE(fs::exists(target / "keep.txt"));
  CHECK(io::read_file(target / "sub" / "new.txt") == "new");
  CHECK(std::distance(fs::directory_iterator(tmp.path), fs::directory_iterator()) == 1);

  // An exception while writing: nothing appears.
  const fs::path fresh = tmp.path / "fresh";
  try {
    io::OutputDir o(fresh, false);
    write_text(o.file("a.txt"), "a");
    throw std::runtime_error("boom");
  } catch (const std::runtime_error&) {
  }
  CHECK_FALSE(fs::exists(fresh));
  CHECK(std::distance(fs::directory_iterator(tmp.path), fs::directory_iterator()) == 1);

  // An empty existing folder is fine without force; a file in the way is not.
  fs::create_directories(fresh);
  {
    io::OutputDir o(fresh, false);
    write_text(o.file("a.txt"), "a");
    o.commit();
  }
  CHECK(io::read_file(fresh / "a.txt") == "a");
  write_text(tmp.path / "file", "x");
  CHECK_THROWS_AS(io::OutputDir(tmp.path / "file", true), InputError);
}

TEST_CASE("output: OutputDir takes runs/x/ for runs/x, and never replaces an input or the current folder", "[output]") {
  TempDir tmp("outdir2");
  CHECK(io::without_trailing_separator("runs/x/") == fs::path("runs/x"));
  CHECK(io::without_trailing_separator("runs/x//") == fs::path("runs/x"));
  CHECK(io::without_trailing_separator("/") == fs::path("/"));
  CHECK(io::without_trailing_separator("x") == fs::path("x"));
  // A new folder named with a trailing separator (tab completion, "$dir/" in scripts).
  {
    io::OutputDir o((tmp.path / "new").string() + "/", false);
    write_text(o.file("a.txt"), "a");
    o.commit();
  }
  CHECK(io::read_file(tmp.path / "new" / "a.txt") == "a");
  CHECK(std::distance(fs::directory_iterator(tmp.path), fs::directory_iterator()) == 1);
  // ... and an existing one replaced with force.
  {
    io::OutputDir o((tmp.path / "new").string() + "/", true);
    write_text(o.file("b.txt"), "b");
    o.commit();
  }
  CHECK(io::read_file(tmp.path / "new" / "b.txt") == "b");
  CHECK_FALSE(fs::exists(tmp.path / "new" / "a.txt"));
  CHECK(std::distance(fs::directory_iterator(tmp.path), fs::directory_iterator()) == 1);

  // Parent folders created for an output that is never committed are removed again (when empty);
  // existing ones stay.
  {
    io::OutputDir o(tmp.path / "p1" / "p2" / "out", false);
    CHECK(fs::is_directory(tmp.path / "p1" / "p2"));
  }
  CHECK_FALSE(fs::exists(tmp.path / "p1"));
  fs::create_directories(tmp.path / "keep");
  {
    io::OutputDir o(tmp.path / "keep" / "p2" / "out", false);
  }
  CHECK(fs::is_directory(tmp.path / "keep"));
  CHECK_FALSE(fs::exists(tmp.path / "keep" / "p2"));
  fs::remove(tmp.path / "keep");
  {
    io::OutputDir o(tmp.path / "p1" / "out", false);
    write_text(o.file("a.txt"), "a");
    o.commit();
  }
  CHECK(io::read_file(tmp.path / "p1" / "out" / "a.txt") == "a");
  fs::remove_all(tmp.path / "p1");
  // Paths are taken lexically normal: "a/../b/out" never creates "a", and a folder that existed before
  // ("b", empty) is never removed; "x/." is "x".
  fs::create_directories(tmp.path / "b");
  {
    io::OutputDir o(tmp.path / "a" / ".." / "b" / "out", false);
    CHECK(o.final_dir() == tmp.path / "b" / "out");
  }
  CHECK(fs::is_directory(tmp.path / "b"));
  CHECK_FALSE(fs::exists(tmp.path / "a"));
  fs::remove(tmp.path / "b");
  {
    io::OutputDir o(tmp.path / "x" / ".", false);
    write_text(o.file("a.txt"), "a");
    o.commit();
  }
  CHECK(io::read_file(tmp.path / "x" / "a.txt") == "a");
  fs::remove_all(tmp.path / "x");

  // check(): the same refusals, nothing created.
  CHECK_NOTHROW(io::OutputDir::check(tmp.path / "c1" / "c2", false));
  CHECK_FALSE(fs::exists(tmp.path / "c1"));
  write_text(tmp.path / "full" / "f.txt", "f");
  CHECK_THROWS_WITH(io::OutputDir::check(tmp.path / "full", false), Catch::Contains("--force"));
  CHECK_NOTHROW(io::OutputDir::check(tmp.path / "full", true));
  CHECK_THROWS_WITH(io::OutputDir::check(tmp.path / "full", true, {tmp.path / "full" / "f.txt"}),
                    Catch::Contains("input"));
  fs::remove_all(tmp.path / "full");

  // The output is an input, or contains one: refused even with force, nothing touched.
  const fs::path ds = tmp.path / "ds";
  write_text(ds / "mav0" / "imu0" / "data.csv", "imu");
  write_text(tmp.path / "cfg.json", "{}");
  for (const fs::path& out : {ds, fs::path(ds.string() + "/"), tmp.path / "ds" / "mav0" / ".." , tmp.path}) {
    INFO(out);
    auto e = expect_input_error([&] { io::OutputDir o(out, true, {ds / "mav0" / "imu0" / "data.csv"}); });
    CHECK_THAT(e.what(), Catch::Contains("input") && Catch::Contains("data.csv"));
  }
  auto e = expect_input_error([&] { io::OutputDir o(tmp.path / "new", true, {"", tmp.path / "missing", tmp.path / "new"}); });
  CHECK_THAT(e.what(), Catch::Contains("output folder is the input"));
  // Through a symlink to the input.
  fs::create_directory_symlink(ds, tmp.path / "link");
  CHECK_THROWS_AS(io::OutputDir(tmp.path / "link", true, {ds}), InputError);
  // Beside or below an input is fine; missing and empty inputs are ignored.
  CHECK_NOTHROW(io::OutputDir(ds / "run", true, {ds, tmp.path / "cfg.json"}));
  CHECK_NOTHROW(io::OutputDir(tmp.path / "ds2", true, {ds, "", tmp.path / "absent"}));
  CHECK(io::read_file(ds / "mav0" / "imu0" / "data.csv") == "imu");

  // The current folder or an ancestor of it is never an output folder.
  struct Cwd {
    fs::path old = fs::current_path();
    ~Cwd() { fs::current_path(old); }
  } restore;
  fs::create_directories(tmp.path / "work");
  fs::current_path(tmp.path / "work");
  for (const fs::path& out : {fs::path("."), fs::path("./"), fs::path(".."), tmp.path / "work"}) {
    INFO(out);
    auto c = expect_input_error([&] { io::OutputDir o(out, true); });
    CHECK_THAT(c.what(), Catch::Contains("current folder"));
  }
  CHECK_NOTHROW(io::OutputDir("sub", false));
}

TEST_CASE("output: StagedFiles puts files in place only at commit, and cleans up otherwise", "[output]") {
  TempDir tmp("staged");
  const fs::path ds = tmp.path / "ds";
  io::write_file_atomic(ds / "roe.json", "old");
  const auto listing = [](const fs::path& dir) {
    std::vector<std::string> names;
    for (const auto& e : fs::recursive_directory_iterator(dir)) names.push_back(e.path().lexically_relative(dir).string());
    std::sort(names.begin(), names.end());
    return names;
  };
  const auto before = listing(tmp.path);
  {  // an exception after staging: nothing changed, the folders it made are gone
    io::StagedFiles st;
    st.ensure_folder(tmp.path / "new");
    io::write_file_atomic(st.stage(ds / "mav0/mocap0/data.csv"), "poses");
    io::write_file_atomic(st.stage(ds / "roe.json"), "new");
    CHECK(io::read_file(ds / "roe.json") == "old");
    CHECK_FALSE(fs::exists(ds / "mav0/mocap0/data.csv"));
  }
  CHECK(listing(tmp.path) == before);
  {
    io::StagedFiles st;
    io::write_file_atomic(st.stage(ds / "mav0/mocap0/data.csv"), "poses");
    io::write_file_atomic(st.stage(ds / "roe.json"), "new");
    st.commit();
  }
  CHECK(io::read_file(ds / "roe.json") == "new");
  CHECK(io::read_file(ds / "mav0/mocap0/data.csv") == "poses");
  CHECK(listing(ds) == std::vector<std::string>{"mav0", "mav0/mocap0", "mav0/mocap0/data.csv", "roe.json"});
  // A folder that gained other files meanwhile is kept.
  {
    io::StagedFiles st;
    io::write_file_atomic(st.stage(ds / "calib/a.yaml"), "a");
    io::write_file_atomic(ds / "calib/other.txt", "someone else's");
  }
  CHECK(fs::exists(ds / "calib/other.txt"));
  CHECK(listing(ds / "calib") == std::vector<std::string>{"other.txt"});
  // A rename that fails part-way (the last final path is a non-empty folder): the earlier renames are
  // undone, the replaced file is back, the added file gone, and no temporary or backup is left.
  {
    std::vector<std::string> before_fail;
    {
      io::StagedFiles st;
      io::write_file_atomic(st.stage(ds / "mav0/mocap0/data.csv"), "poses 2");
      io::write_file_atomic(st.stage(ds / "mav0/mocap0/extra.csv"), "extra");
      io::write_file_atomic(st.stage(ds / "blocked"), "a file where a folder is");
      // The folder appears after stage() (which refuses one at once: the output rule, issue 51).
      io::write_file_atomic(ds / "blocked/inside.txt", "x");
      for (const auto& n : listing(ds))
        if (n.find(".tmp-") == std::string::npos) before_fail.push_back(n);  // the staged temporaries go
      const auto e = expect_input_error([&] { st.commit(); });
      CHECK_THAT(e.what(), Catch::Contains("nothing was changed"));
      CHECK_THAT(e.what(), Catch::Contains("blocked"));
    }
    CHECK(io::read_file(ds / "mav0/mocap0/data.csv") == "poses");
    CHECK(io::read_file(ds / "roe.json") == "new");
    CHECK(listing(ds) == before_fail);
    fs::remove_all(ds / "blocked");
  }
  // A successful commit over an existing file leaves no backup behind.
  const auto before_ok = listing(ds);
  {
    io::StagedFiles st;
    io::write_file_atomic(st.stage(ds / "roe.json"), "newer");
    st.commit();
  }
  CHECK(io::read_file(ds / "roe.json") == "newer");
  CHECK(listing(ds) == before_ok);
  // The lock needs the folder.
  CHECK_THROWS_AS(io::FolderLock(tmp.path / "missing"), InputError);
  CHECK_NOTHROW(io::FolderLock(ds));
}

TEST_CASE("output: write_file_atomic and sha256", "[output]") {
  TempDir tmp("atomic");
  const fs::path f = tmp.path / "a" / "b.txt";
  io::write_file_atomic(f, "hello");
  CHECK(io::read_file(f) == "hello");
  CHECK_THROWS_AS(io::write_file_atomic(f, "again", false), InputError);
  CHECK(io::read_file(f) == "hello");
  io::write_file_atomic(f, "abc");
  CHECK(std::distance(fs::directory_iterator(f.parent_path()), fs::directory_iterator()) == 1);
  // FIPS 180-2 test vectors.
  CHECK(io::sha256_hex("abc") == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  CHECK(io::sha256_hex("") == "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  CHECK(io::sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq") ==
        "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  CHECK(io::sha256_file(f) == io::sha256_hex("abc"));
  CHECK_THROWS_AS(io::sha256_file(tmp.path / "missing"), InputError);
  CHECK_THROWS_AS(io::read_file(tmp.path / "missing"), InputError);
}

TEST_CASE("json: a key given twice in one object is an error naming its path", "[io][json]") {
  const auto key_of = [](const std::string& text) {
    try {
      io::parse_json_text(text, "c.json");
    } catch (const ConfigError& e) {
      CHECK(e.context().file == "c.json");
      CHECK_THAT(e.what(), Catch::Contains("appears twice"));
      return e.context().key;
    }
    return std::string("<no error>");
  };
  CHECK(key_of(R"({"duration_s": 10, "duration_s": 20})") == "duration_s");
  CHECK(key_of(R"({"filter": {"a": 1, "b": {"c": 2}, "a": 3}})") == "filter.a");
  CHECK(key_of(R"({"objects": {"list": [{"id": 1}, {"id": 2, "id": 3}]}})") == "objects.list[1].id");
  CHECK(key_of(R"({"l": [1, [2, 3], "x", {"a": [{}, {"k": 1, "k": 2}]}]})") == "l[3].a[1].k");
  CHECK(key_of(R"([{"a": 1}, {"a": 1, "a": 2}])") == "[1].a");
  // The same key in different objects, or in sibling array elements, is fine.
  CHECK(key_of(R"({"a": {"x": 1}, "b": {"x": 2}, "l": [{"x": 1}, {"x": 2}], "x": [1, {"x": 3}]})") == "<no error>");
  CHECK(io::parse_json_text(R"({"a": {"x": 1}, "b": [{"x": 2}]})", "c.json")["b"][0]["x"] == 2);
}

TEST_CASE("json: a number beyond double's range is an input error at its line and column", "[io][json]") {
  try {
    io::parse_json_text("{\"a\": 1,\n \"b\": [2, 1e999]}", "c.json");
    FAIL("no error");
  } catch (const InputError& e) {
    CHECK(e.context().file == "c.json");
    CHECK(e.context().line == 2);
    CHECK(e.context().column == 11);
    CHECK_THAT(e.what(), Catch::Contains("number out of range: 1e999"));
  }
  try {  // the same text inside a string earlier does not mislead the position
    io::parse_json_text("{\"s\": \"see 1e999 \\\" 1e999\",\n \"a\":\n 1e999}", "c.json");
    FAIL("no error");
  } catch (const InputError& e) {
    CHECK(e.context().line == 3);
    CHECK(e.context().column == 2);
  }
}

TEST_CASE("json: text that is not UTF-8 is written with U+FFFD, not an exception", "[io][json]") {
  const io::json j = {{"body", std::string("K\xf6rper 1")}};
  CHECK_THROWS(j.dump());  // what nlohmann does by default
  const std::string text = io::dump_json(j);
  CHECK(text == "{\"body\":\"K\xef\xbf\xbdrper 1\"}");
  CHECK(io::parse_json_text(text, "t")["body"] == "K\xef\xbf\xbdrper 1");
  CHECK(io::dump_json(j, 2).find('\n') != std::string::npos);
}

TEST_CASE("detection-set meta.json: one writer for the three producers, a strict reader", "[store][meta]") {
  const roe::test::TempDir tmp("roe_meta");
  const fs::path ds = tmp.path / "ds";
  fs::create_directories(ds / "detections" / "poet");
  // roe import poet's keys: the typed ones and its own record.
  store::DetectionSetMeta m;
  m.producer = "roe import poet";
  m.roe_version = "1.2.3";
  m.frames_processed = 42;
  m.score = "empty";
  m.sigma = "none";
  m.details = {{"source", {{"path", "results.json"}, {"sha256", "ab"}}}, {"summary", {{"images_matched", 42}}}};
  const fs::path file = store::detection_set_meta_path(ds, "poet");
  store::write_detection_set_meta(file, m);
  const auto back = store::read_detection_set_meta(ds, "poet");
  REQUIRE(back);
  CHECK(back->producer == "roe import poet");
  CHECK(back->frames_processed == 42);
  CHECK(!back->detections);
  CHECK(back->details == m.details);
  CHECK(store::detection_set_meta_to_json(*back) == store::detection_set_meta_to_json(m));
  const auto j = io::parse_json_file(file);
  CHECK(j.at("source").at("sha256") == "ab");  // the producer's keys at the top level, as before
  CHECK(j.at("roe_version") == "1.2.3");
  // roe simulate's: no roe_version key, a detection count.
  store::DetectionSetMeta s;
  s.producer = "roe simulate 1.2.3";
  s.frames_processed = 10;
  s.detections = 30;
  s.details = {{"seed", 7}};
  const io::json sj = store::detection_set_meta_to_json(s);
  CHECK(!sj.contains("roe_version"));
  CHECK(store::detection_set_meta_from_json(sj, "x").detections == std::optional<std::size_t>(30));
  // Strict: a missing producer, a mistyped count.
  io::json bad = sj;
  bad.erase("producer");
  CHECK_THROWS_AS(store::detection_set_meta_from_json(bad, "x"), ConfigError);
  bad = sj;
  bad["frames_processed"] = -1;
  std::ofstream(file) << io::dump_json(bad, 2);
  const auto e = roe::test::expect_input_error([&] { store::read_detection_set_meta(ds, "poet"); });
  CHECK(e.context().key == "frames_processed");
  CHECK(e.context().line > 0);
  CHECK(!store::read_detection_set_meta(ds, "none"));  // a set without meta.json
}
