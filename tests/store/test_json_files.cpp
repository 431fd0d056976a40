// The store's JSON files on the one field walker (src/store/json_fields.hpp): files written by roe at main 8a5e53d
// (before the walker; tests/store/data/main_8a5e53d: roe simulate, roe run with each estimator, roe refine,
// roe import realsense and mocap on the real recordings in ../shared/data) and datasets/sample read and write
// back byte for byte; and each key of run.json, roe.json and meta.json is spelled once per block in src.
#include <catch2/catch.hpp>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "roe/io/json.hpp"
#include "roe/store/dataset.hpp"
#include "roe/store/run_record.hpp"
#include "support/test_util.hpp"

using namespace roe;
using namespace roe::store;
namespace fs = std::filesystem;

namespace {

const std::string kMainEra = std::string(ROE_SOURCE_DIR) + "/tests/store/data/main_8a5e53d/";

/// `written` without the lines of config keys added after the fixtures were written (store::keys_added_later,
/// the last part of each path) that `fixture` does not have: a run.json of 8a5e53d reads them as their
/// defaults, and today's writer adds them; every other byte must be the fixture's.
std::string without_later_keys(std::string written, const std::string& fixture) {
  for (const char* key : {"consider_correlated_errors"}) {
    const std::string quoted = std::string("\"") + key + "\": ";
    if (fixture.find(quoted) != std::string::npos) continue;
    const std::size_t at = written.find(quoted);
    if (at == std::string::npos) continue;
    const std::size_t begin = written.rfind('\n', at) + 1, end = written.find('\n', at);
    written.erase(begin, end - begin + 1);
  }
  return written;
}

std::string text_of(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  REQUIRE(in);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST_CASE("store json: run.json files written by roe at 8a5e53d read and write back byte for byte",
          "[store][json_fields][run_json]") {
  const std::map<std::string, Estimator> files = {{"run_smoother.json", Estimator::kSmoother},
                                                  {"run_filter_minimal.json", Estimator::kFilter},
                                                  {"run_batch.json", Estimator::kBatch},
                                                  {"run_refined.json", Estimator::kSmoother}};
  for (const auto& [name, estimator] : files) {
    CAPTURE(name);
    const std::string text = text_of(kMainEra + name);
    const RunRecord r = read_run_json(kMainEra + name);
    CHECK(without_later_keys(format_run_json(r), text) == text);
    CHECK(r.config.estimator == estimator);
    CHECK(r.refine.has_value() == (name == "run_batch.json" || name == "run_refined.json"));
    CHECK(r.counts.imu_samples > 0);
    CHECK(!r.counts.per_object.empty());
  }
  CHECK(read_run_json(kMainEra + "run_filter_minimal.json").config.output_level == OutputLevel::kMinimal);
  CHECK(read_run_json(kMainEra + "run_refined.json").command == "refine");
}

TEST_CASE("store json: roe.json files written by roe at 8a5e53d, and datasets/sample's, read and write back byte "
          "for byte", "[store][json_fields][manifest]") {
  const test::TempDir tmp("roe_json_files");
  const std::vector<std::string> files = {kMainEra + "roe_simulate.json", kMainEra + "roe_realsense.json",
                                          kMainEra + "roe_mocap.json",
                                          std::string(ROE_SOURCE_DIR) + "/datasets/sample/roe.json"};
  for (const std::string& file : files) {
    CAPTURE(file);
    const std::string text = text_of(file);
    const DatasetManifest m = manifest_from_json(io::parse_json_text(text, file), file);
    write_manifest(m, tmp.path / "roe.json");
    CHECK(text_of(tmp.path / "roe.json") == text);
  }
  const DatasetManifest sim = manifest_from_json(io::parse_json_file(files[0]), files[0]);
  REQUIRE(sim.truth.has_value());
  CHECK(!sim.truth->detection_noise.empty());
  CHECK(sim.camera.has_value());
  const DatasetManifest mocap = manifest_from_json(io::parse_json_file(files[2]), files[2]);
  CHECK(mocap.mocap->body == "Rigid Body 1");
  CHECK(mocap.sources.at(0).options.at("format") == "motive");
}

TEST_CASE("store json: meta.json files written by roe at 8a5e53d read and write back byte for byte, the producer's "
          "own keys kept", "[store][json_fields][meta]") {
  const test::TempDir tmp("roe_json_files");
  for (const std::string& file :
       {kMainEra + "meta_simulate.json", std::string(ROE_SOURCE_DIR) + "/datasets/sample/detections/sim/meta.json"}) {
    CAPTURE(file);
    const std::string text = text_of(file);
    const DetectionSetMeta m = detection_set_meta_from_json(io::parse_json_text(text, file), file);
    CHECK(m.producer.rfind("roe simulate", 0) == 0);
    CHECK(m.details.contains("config"));
    CHECK(!m.details.contains("producer"));
    write_detection_set_meta(tmp.path / "meta.json", m);
    CHECK(text_of(tmp.path / "meta.json") == text);
  }
}

namespace {

/// For each key of `j` (below `path`), the paths of the objects that hold it, arrays as "[]"; the keys of the
/// objects at `data_maps` are data (an object id, a file name), not keys of the mapping, and are skipped.
void key_places(const io::json& j, const std::string& path, const std::set<std::string>& data_maps,
                std::map<std::string, std::set<std::string>>& places) {
  if (j.is_array()) {
    for (const auto& e : j) key_places(e, path + "[]", data_maps, places);
    return;
  }
  if (!j.is_object()) return;
  const bool data = data_maps.count(path) != 0;
  for (const auto& [k, v] : j.items()) {
    if (!data) places[k].insert(path);
    key_places(v, path + "." + (data ? std::string("*") : k), data_maps, places);
  }
}

/// How often "key" (in double quotes) is spelled in the code `text` as a key: comments are not code, and a literal
/// compared with == or != is a value (a closed vocabulary: "run" or "refine"), not a key.
std::size_t spellings(const std::string& text, const std::string& key) {
  const std::string quoted = "\"" + key + "\"";
  std::size_t n = 0;
  for (std::size_t at = text.find(quoted); at != std::string::npos; at = text.find(quoted, at + 1)) {
    std::size_t before = at;
    while (before > 0 && text[before - 1] == ' ') --before;
    const bool compared = before >= 2 && text[before - 1] == '=' && (text[before - 2] == '=' || text[before - 2] == '!');
    n += compared ? 0 : 1;
  }
  return n;
}

/// `text` without its // comments.
std::string code_of(const std::string& text) {
  std::string out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out += line.substr(0, line.find("//")) + "\n";
  return out;
}

RunRecord every_block() {
  RunRecord r = read_run_json(kMainEra + "run_batch.json");
  r.init.gyro_bias_rest_refused = "moving";
  r.relocks.push_back({1.0, 0.5, {0, 0, 0}, {0, 0, 0}, 0.1, 4, 2});
  r.inputs.config = "c.json";
  r.inputs.config_abs = "/c.json";
  r.config.output_level = OutputLevel::kStandard;
  r.config.description = "d";
  return r;
}

}  // namespace

// The done-when of issue 52 ("grep finds each run.json/roe.json key spelled once in src"), as a test: every key
// of run.json, roe.json and meta.json (as today's writers write them, every optional block present) is spelled
// in the store's mapping files (and io's pose and IMU-noise form) at most once per place the files hold it. A
// second hand-written reader or writer of any block spells its keys again and fails here. roe.json's printer
// orders keys by a table of names (key_rank: it orders, never reads or writes), left out of the count, and a
// configuration key may also be the name of a value of an enum setting ("filter").
TEST_CASE("store json: each key of run.json, roe.json and meta.json is spelled once per place in src",
          "[store][json_fields][keys]") {
  std::map<std::string, std::set<std::string>> places;
  key_places(run_record_to_json(every_block()), "run", {"run.counts.detections.per_object", "run.inputs.sha256",
                                                        "run.timing_s"},
             places);
  DatasetManifest m = manifest_from_json(io::parse_json_file(kMainEra + "roe_simulate.json"), "roe.json");
  m.mocap = manifest_from_json(io::parse_json_file(kMainEra + "roe_mocap.json"), "roe.json").mocap;
  m.objects.at(0).models_info = "models_info.json";
  m.objects.at(0).models_info_id = 3;
  m.truth->camera_time_offset_s = 0.01;
  m.truth->imu_noise = m.imu->noise;
  key_places(manifest_to_json(m), "roe", {"roe.sources[].options", "roe.truth.detection_noise"}, places);
  DetectionSetMeta meta;
  meta.roe_version = "v";
  meta.detections = 1;
  meta.score = meta.sigma = "s";
  key_places(detection_set_meta_to_json(meta), "meta", {}, places);
  REQUIRE(places.size() > 150);

  const std::string src = std::string(ROE_SOURCE_DIR) + "/";
  std::string text;
  for (const char* f : {"src/store/run_record.cpp", "src/store/run_config.cpp", "src/store/dataset_json.cpp",
                        "src/io/pose_json.cpp", "include/roe/io/pose_json.hpp"})
    text += code_of(text_of(src + f));
  // roe.json's printer's order table.
  const std::size_t rank = text.find("int key_rank("), rank_end = text.find("\n}\n", rank);
  REQUIRE(rank_end != std::string::npos);
  text.erase(rank, rank_end - rank);
  // A configuration key may also be the name of a setting's value ("filter"), and a key be named once more where
  // a rule across keys reports at it (run_config.cpp's check_filter).
  std::multiset<std::string> also = {"meas_sigma_ray_m"};
  for (const auto& names : {estimators(), output_levels(), output_rates()}) also.insert(names.begin(), names.end());
  for (const auto& [key, where] : places) {
    CAPTURE(key, where.size());
    const std::size_t n = spellings(text, key), allowed = where.size() + also.count(key);
    CHECK(n >= 1);  // spelled in the mapping files, not elsewhere
    CHECK(n <= allowed);
  }
}

// Issue 52 item 5: the string-valued run settings are enums, parsed once where a configuration is read; an
// unknown name is refused at its key path with the allowed names, and each value is written back as its name.
TEST_CASE("store json: the run settings are parsed once into enums and written back by name",
          "[store][json_fields][run_config]") {
  struct Bad {
    const char* text;
    const char* key;
    const char* says;
  };
  for (const Bad& bad : {Bad{R"({"estimator": "smoothr"})", "estimator", "\"filter\", \"smoother\" or \"batch\""},
                         Bad{R"({"output": {"rate": "camera"}})", "output.rate", "\"imu\" or \"images\""},
                         Bad{R"({"output": {"level": 3}})", "output.level", "expected a string"},
                         Bad{R"({"filter": {"estimator": "batch"}})", "filter.estimator",
                             "did you mean the top-level \"estimator\""}}) {
    CAPTURE(bad.text);
    try {
      (void)run_config_from_json(io::json::parse(bad.text), "c.json");
      FAIL("accepted");
    } catch (const ConfigError& e) {
      CHECK(e.context().key == bad.key);
      CHECK_THAT(e.what(), Catch::Contains(bad.says));
    }
  }
  // Every value: its name is read as itself and written back as that name (the enum's order is the names').
  const auto each_name = [](const std::vector<std::string>& names, auto member, const auto& config_of,
                            const auto& written) {
    for (std::size_t i = 0; i < names.size(); ++i) {
      const RunConfig c = run_config_from_json(config_of(names[i]), "c.json");
      CHECK(static_cast<std::size_t>(c.*member) == i);
      CHECK(written(run_config_to_json(c, true)) == names[i]);
    }
  };
  each_name(
      estimators(), &RunConfig::estimator, [](const std::string& n) { return io::json{{"estimator", n}}; },
      [](const io::json& j) { return j.at("estimator"); });
  each_name(
      output_rates(), &RunConfig::output_rate, [](const std::string& n) { return io::json{{"output", {{"rate", n}}}}; },
      [](const io::json& j) { return j.at("output").at("rate"); });
  each_name(
      output_levels(), &RunConfig::output_level,
      [](const std::string& n) { return io::json{{"output", {{"level", n}}}}; },
      [](const io::json& j) { return j.at("output").at("level"); });
  CHECK(to_string(Estimator::kBatch) == "batch");
  CHECK(to_string(OutputRate::kImages) == "images");
  CHECK(to_string(OutputLevel::kMinimal) == "minimal");
  // The key "smoother" of configs before issue 48 still reads, as the estimator it meant.
  CHECK(run_config_from_json(io::json{{"smoother", "none"}}, "c.json").estimator == Estimator::kFilter);
  CHECK(run_config_from_json(io::json{{"smoother", "rts"}}, "c.json").estimator == Estimator::kSmoother);
}
