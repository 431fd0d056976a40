// Model bundle manifest: strict validation with the failing key named.
#include <catch2/catch.hpp>
#include <filesystem>
#include <functional>

#include "roe/core/error.hpp"
#include "roe/infer/bundle.hpp"
#include "roe/io/json.hpp"

namespace fs = std::filesystem;
using namespace roe::infer;
using nlohmann::json;

namespace {
const fs::path kTiny = fs::path(ROE_SOURCE_DIR) / "tests/models/tiny_poet";

json tiny_manifest() { return roe::io::parse_json_file(kTiny / kBundleManifest); }

// The ConfigError message of a mutated manifest ("" when it is accepted).
std::string error_of(const std::function<void(json&)>& mutate) {
  json j = tiny_manifest();
  mutate(j);
  try {
    bundle_from_json(j, kTiny, "poet_bundle.json");
  } catch (const roe::ConfigError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST_CASE("the committed tiny bundle is valid", "[bundle]") {
  const PoetBundle b = read_bundle(kTiny);
  CHECK(b.model_id == "tiny-poet");
  CHECK(b.image.width == 128);
  CHECK(b.image.height == 96);
  CHECK(b.image.rgb);
  CHECK(b.num_queries == 4);
  CHECK(b.classes.size() == 3);
  CHECK(b.class_name(2) == "green_square");
  CHECK(b.symmetric == std::vector<int>{3});
  CHECK(b.rotation == RotationFormat::k6d);
  CHECK(b.detector == DetectorKind::kDarknet);
  CHECK(b.darknet.feature_layers.size() == 2);
  CHECK(b.darknet.nms.conf_thresh == Approx(0.4));
  CHECK(b.pose.inputs == PoseInputs::kFeatures);
  CHECK(b.selftest.inputs.size() == 4);
  CHECK(b.pose.aleatoric);
  CHECK(b.selftest.outputs.size() == 4);  // t, rotation, logvar_t, logvar_r
  CHECK(fs::exists(b.pose.file));
}

TEST_CASE("bundle validation errors name the key", "[bundle]") {
  auto has = [](const std::string& msg, const std::string& part) {
    INFO(msg);
    return msg.find(part) != std::string::npos;
  };
  CHECK(has(error_of([](json& j) { j["schema"] = "roe-poet-bundle/2"; }), "unsupported bundle schema"));
  CHECK(has(error_of([](json& j) { j["extra"] = 1; }), "extra"));
  CHECK(has(error_of([](json& j) { j["image"]["colour"] = "RGB"; }), "image.colour"));
  CHECK(has(error_of([](json& j) { j.erase("train_intrinsics"); }), "train_intrinsics"));
  CHECK(has(error_of([](json& j) { j["train_intrinsics"]["fx"] = -1; }), "train_intrinsics.fx"));
  CHECK(has(error_of([](json& j) { j["image"]["width"] = 100; }), "divisible by 32"));
  CHECK(has(error_of([](json& j) { j["image"]["std"] = {1, 0, 1}; }), "image.std"));
  CHECK(has(error_of([](json& j) { j["model_id"] = "a/b"; }), "model_id"));
  CHECK(has(error_of([](json& j) { j["num_queries"] = 0; }), "num_queries"));
  CHECK(has(error_of([](json& j) { j["num_queries"] = "4"; }), "num_queries"));
  CHECK(has(error_of([](json& j) { j["classes"][1]["id"] = 1; }), "duplicate class id"));
  CHECK(has(error_of([](json& j) { j["classes"][0]["id"] = 0; }), "1-based"));
  CHECK(has(error_of([](json& j) { j["symmetric"] = {7}; }), "symmetric"));
  CHECK(has(error_of([](json& j) { j["rotation"] = "euler"; }), "rotation"));
  CHECK(has(error_of([](json& j) { j["translation_unit"] = "cm"; }), "translation_unit"));
  CHECK(has(error_of([](json& j) { j["detector"]["kind"] = "yolo"; }), "detector.kind"));
  CHECK(has(error_of([](json& j) { j["detector"]["weights"] = "missing.weights"; }), "file not found"));
  CHECK(has(error_of([](json& j) { j["detector"]["conf_thresh"] = 1.5; }), "detector.conf_thresh"));
  CHECK(has(error_of([](json& j) { j["detector"]["feature_layers"] = json::array(); }), "feature_layers"));
  CHECK(has(error_of([](json& j) { j["detector"] = {{"kind", "external"}}; }), "pose.inputs"));
  CHECK(has(error_of([](json& j) { j["pose"]["file"] = "nope.ts"; }), "pose.file"));
  CHECK(has(error_of([](json& j) { j["pose"]["inputs"] = "boxes"; }), "pose.inputs"));
  CHECK(has(error_of([](json& j) { j.erase("selftest"); }), "selftest"));
  CHECK(has(error_of([](json& j) { j["selftest"]["inputs"].erase(3); }), "needs 4 files"));
  CHECK(has(error_of([](json& j) { j["selftest"]["outputs"].erase(3); }), "needs 4 files (t, rotation, logvar_t"));
  CHECK(has(error_of([](json& j) { j["pose"]["aleatoric"] = false; }), "needs 2 files (t, rotation)"));
  CHECK(has(error_of([](json& j) { j["provenance"] = "x"; }), "provenance"));
  CHECK(error_of([](json& j) { j["provenance"]["poet_commit"] = "227f6a4"; }).empty());
  CHECK(error_of([](json& j) { j["translation_unit"] = "mm"; }).empty());
}

TEST_CASE("a folder without a manifest is an InputError", "[bundle]") {
  CHECK_THROWS_AS(read_bundle(kTiny / "selftest"), roe::InputError);
  CHECK_THROWS_AS(read_bundle(kTiny / "does-not-exist"), roe::InputError);
}
