// The JSON forms of a Pose and of the IMU noise (io/pose_json.hpp): the text written, exact round trips,
// the overlay read of simulator configs, and errors located at the key (and line/column via a file).
#include <catch2/catch.hpp>
#include <random>

#include "roe/core/dataset.hpp"
#include "roe/core/error.hpp"
#include "roe/io/pose_json.hpp"
#include "support/test_util.hpp"

using namespace roe;
using namespace roe::io;

TEST_CASE("pose json: the text, and write then read is bit-identical", "[io][json]") {
  const Pose T(Eigen::Quaterniond(0, 0, 1, 0), Eigen::Vector3d(1.5, -2, 0.25));
  CHECK(dump_json(pose_to_json(T)) == R"({"p":[1.5,-2.0,0.25],"q":[0.0,1.0,0.0,0.0]})");
  std::mt19937 g(3);
  std::normal_distribution<double> n;
  for (int i = 0; i < 200; ++i) {
    const Pose A(Eigen::Quaterniond(n(g), n(g), n(g), n(g)), Eigen::Vector3d(n(g), n(g), n(g)));
    const Pose B = pose_from_json(parse_json_text(dump_json(pose_to_json(A)), "t"), "t", "T");
    CHECK(B.p == A.p);
    CHECK(B.q.coeffs() == A.q.coeffs());
  }
}

TEST_CASE("pose json: overlay on a base pose, and strict errors", "[io][json]") {
  const Pose base(Eigen::Quaterniond(0, 1, 0, 0), Eigen::Vector3d(1, 2, 3));
  const Pose only_p = pose_from_json(json::parse(R"({"p": [4, 5, 6]})"), "c.json", "camera.T_I_C", {1e-6, &base});
  CHECK(only_p.p == Eigen::Vector3d(4, 5, 6));
  CHECK(only_p.q.coeffs() == base.q.coeffs());
  const auto err = [](const std::string& text, const std::string& key) {
    const InputError e = test::expect_input_error(
        [&] { pose_from_json(json::parse(text), "c.json", "camera.T_I_C"); });
    CHECK(e.context().file == "c.json");
    CHECK(e.context().key == key);
    return std::string(e.what());
  };
  CHECK_THAT(err(R"({"q": [0, 0, 0, 1]})", "camera.T_I_C.p"), Catch::Contains("missing"));
  CHECK_THAT(err(R"({"p": [0, 0], "q": [0, 0, 0, 1]})", "camera.T_I_C.p"), Catch::Contains("3 numbers"));
  CHECK_THAT(err(R"({"p": [0, 0, "a"], "q": [0, 0, 0, 1]})", "camera.T_I_C.p[2]"), Catch::Contains("number"));
  CHECK_THAT(err(R"({"p": [0, 0, 0], "q": [0, 0, 0, 1.01]})", "camera.T_I_C.q"), Catch::Contains("unit norm"));
  CHECK_THAT(err(R"({"p": [0, 0, 0], "q": [0, 0, 0, 1], "r": 1})", "camera.T_I_C.r"), Catch::Contains("r"));
  // Through a file: the line and column of the key.
  test::TempDir tmp("roe_pose_json");
  const auto f = tmp.write("c.json", "{\n  \"T\": {\"p\": [0, 0, 0],\n        \"q\": [0, 0, 0, 2]}\n}\n");
  const InputError e = test::expect_input_error([&] {
    read_json_file(f, [](const json& j, const std::string& source) { return pose_from_json(j.at("T"), source, "T"); });
  });
  CHECK(e.context().line == 3);
  CHECK(e.context().column == 9);
}

TEST_CASE("imu noise json: known values written, unknown left out, read strictly", "[io][json]") {
  ImuNoise n;  // every value unknown (-1)
  n.gyro_noise_density = 1.6968e-4;
  n.accel_random_walk = 0.0;
  CHECK(dump_json(imu_noise_to_json(n)) == R"({"accel_random_walk":0.0,"gyro_noise_density":0.00016968})");
  const json j = json::parse(R"({"imu": {"gyro_random_walk": 2e-5, "accel_noise_density": 2e-3}})");
  JsonObject root(j, "roe.json");
  JsonObject o = root.child("imu");
  read_imu_noise(o, n);
  root.finish();
  CHECK(n.gyro_noise_density == 1.6968e-4);
  CHECK(n.gyro_random_walk == 2e-5);
  CHECK(n.accel_noise_density == 2e-3);
  const json bad = json::parse(R"({"accel_random_walk": -1})");
  JsonObject b(bad, "roe.json", "imu");
  const InputError e = test::expect_input_error([&] { read_imu_noise(b, n); });
  CHECK(e.context().key == "imu.accel_random_walk");
}
