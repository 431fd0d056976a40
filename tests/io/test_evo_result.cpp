// evo result zips and .npy arrays against an independent writer and reader: Python's zipfile and NumPy,
// called as evo's save_res_file / load_res_file call them (tests/fixtures/evo/evo_result_fixture.py).
#include "support/test_util.hpp"

#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "roe/core/error.hpp"
#include "roe/io/evo_result.hpp"
#include "roe/io/input.hpp"
#include "roe/io/npy.hpp"
#include "roe/io/output.hpp"
#include "roe/io/zip.hpp"

namespace fs = std::filesystem;
using roe::io::EvoResult;

namespace {

const std::string kFixture = std::string(ROE_SOURCE_DIR) + "/tests/fixtures/evo/evo_result_fixture.py";

bool have_numpy() { return roe::test::run_shell("/usr/bin/python3 -c 'import numpy'").code == 0; }

nlohmann::json fixture(const fs::path& dir) {
  const auto r = roe::test::run_shell("/usr/bin/python3 " + kFixture + " write " + dir.string());
  INFO(r.out);
  REQUIRE(r.code == 0);
  return nlohmann::json::parse(roe::io::read_file(dir / "expected.json"));
}

std::vector<double> values(const roe::io::NpyArray& a) {
  std::vector<double> v;
  for (std::size_t k = 0; k < a.numel(); ++k) v.push_back(a.as_double(k));
  return v;
}

void check_as_expected(const EvoResult& r, const nlohmann::json& ex) {
  CHECK(r.info == ex["info"]);
  CHECK(r.stats == ex["stats"]);
  for (const auto& [name, v] : ex["arrays"].items()) {
    INFO("array " << name);
    const roe::io::NpyArray* a = r.array(name);
    REQUIRE(a != nullptr);
    CHECK(values(*a) == v.get<std::vector<double>>());
    CHECK(a->shape == ex["shapes"][name].get<std::vector<std::int64_t>>());
  }
}

}  // namespace

TEST_CASE("evo result zips written by Python's zipfile and NumPy read with the same values", "[io][evo]") {
  if (!have_numpy()) {
    WARN("skipped: /usr/bin/python3 with numpy is absent");
    return;
  }
  roe::test::TempDir tmp("roe_test_evo_result");
  const auto ex = fixture(tmp.path);
  for (const char* name : {"stored.zip", "deflated.zip"}) {
    INFO(name);
    const EvoResult r = roe::io::read_evo_result(tmp.path / name);
    check_as_expected(r, ex);
    REQUIRE(r.trajectories.size() == 1);
    CHECK(r.trajectories[0].first == "gt.txt.tum");
  }
  // evo before 1.13 wrote the arrays as .npz members: read as the same arrays.
  const EvoResult old = roe::io::read_evo_result(tmp.path / "old.zip");
  REQUIRE(old.array("error_array") != nullptr);
  CHECK(values(*old.array("error_array")) == ex["arrays"]["error_array"].get<std::vector<double>>());
  // Every dtype NumPy writes that roe reads, exactly.
  for (const auto& [name, v] : ex["npy"].items()) {
    INFO("npy " << name);
    const fs::path f = tmp.path / "npy" / (name + ".npy");
    const auto a = roe::io::parse_npy(roe::io::read_file(f), f.string());
    CHECK(values(a) == v.get<std::vector<double>>());
    CHECK(a.shape == ex["npy_shapes"][name].get<std::vector<std::int64_t>>());
  }
}

TEST_CASE("evo result zips written by roe read in Python with evo's member names and arrays", "[io][evo]") {
  if (!have_numpy()) {
    WARN("skipped: /usr/bin/python3 with numpy is absent");
    return;
  }
  roe::test::TempDir tmp("roe_test_evo_result_w");
  const auto ex = fixture(tmp.path);
  EvoResult r = roe::io::read_evo_result(tmp.path / "deflated.zip");
  const fs::path out = tmp.path / "roe.zip";
  roe::io::write_evo_result(out, r);
  const auto py = roe::test::run_shell("/usr/bin/python3 " + kFixture + " read " + out.string() + " 2>/dev/null");
  INFO(py.out);
  REQUIRE(py.code == 0);
  const auto j = nlohmann::json::parse(py.out);
  CHECK(j["names"] == nlohmann::json({"info.json", "stats.json", "error_array.npy", "timestamps.npy",
                                      "seconds_from_start.npy", "alignment_transformation_sim3.npy", "gt.txt.tum"}));
  CHECK(j["methods"] == nlohmann::json({0}));  // stored, as evo writes
  CHECK(j["info"] == ex["info"]);
  CHECK(j["stats"] == ex["stats"]);
  CHECK(j["arrays"] == ex["arrays"]);
  CHECK(j["shapes"] == ex["shapes"]);
  // And back: the same result, byte for byte the same archive when written again.
  const EvoResult again = roe::io::read_evo_result(out);
  check_as_expected(again, ex);
  roe::io::write_evo_result(tmp.path / "again.zip", again);
  CHECK(roe::io::read_file(tmp.path / "again.zip") == roe::io::read_file(out));
}

TEST_CASE("damaged zips and non-results are input errors naming the file and offset", "[io][evo][hostile]") {
  roe::test::TempDir tmp("roe_test_evo_result_bad");
  const std::string good = roe::io::write_zip({{"info.json", "{}"}, {"stats.json", "{\"rmse\": 1.5}"}});
  const auto refused = [&](const std::string& bytes, const std::string& what) {
    const fs::path f = tmp.path / "bad.zip";
    roe::io::write_file_atomic(f, bytes);
    try {
      roe::io::read_evo_result(f);
      FAIL("no error for: " << what);
    } catch (const roe::InputError& e) {
      INFO(e.what());
      CHECK_THAT(std::string(e.what()), Catch::Contains("bad.zip"));
      CHECK_THAT(std::string(e.what()), Catch::Contains(what));
    }
  };
  {
    const fs::path f = tmp.path / "good.zip";
    roe::io::write_file_atomic(f, good);
    CHECK(roe::io::read_evo_result(f).stats["rmse"] == 1.5);
    CHECK(roe::io::looks_like_zip(f));
  }
  refused("", "shorter than");
  refused("not a zip at all, just some text that is long enough", "no end of central directory");
  std::string crc = good;
  crc[30 + 9] = 'X';  // inside info.json's data ("{}" stored after its 30-byte header and 9-byte name)
  refused(crc, "CRC-32");
  for (std::size_t cut : {good.size() - 1, good.size() / 2, std::size_t{10}}) refused(good.substr(0, cut), "offset");
  refused(roe::io::write_zip({{"info.json", "{}"}}), "no stats.json");
  refused(roe::io::write_zip({{"info.json", "[]"}, {"stats.json", "{}"}}), "not a JSON object");
  refused(roe::io::write_zip({{"info.json", "{}"}, {"stats.json", "{\"rmse\": \"x\"}"}}), "rmse");
  refused(roe::io::write_zip({{"info.json", "{}"}, {"stats.json", "{}"}, {"a.npy", "nope"}}), "a.npy");
  // A .npy whose shape overflows, or whose data is short, never allocates what it claims.
  std::string npy = roe::io::encode_npy(roe::io::NpyArray::float64({2}, {1.0, 2.0}));
  CHECK_THROWS_AS(roe::io::parse_npy(npy.substr(0, npy.size() - 1), "x.npy"), roe::InputError);
  std::string huge = npy;
  const auto at = huge.find("(2,)");
  huge.replace(at, 4, "(4611686018427387904, 4)");
  CHECK_THROWS_AS(roe::io::parse_npy(huge, "x.npy"), roe::InputError);
}
