// PoET results.json per-image limits (issue 51): the file is read one image's entry at a time, so memory is
// bounded by the largest entry; an entry beyond kMaxPoetDetectionsPerImage detections or kMaxPoetValuesPerImage
// JSON values is refused at its line and column, naming the limit (docs/infer.md, "Per-image limits").
#include <catch2/catch.hpp>
#include <string>

#include "roe/core/error.hpp"
#include "roe/io/poet_results.hpp"

using namespace roe;

namespace {
std::string image_of(std::size_t n_detections) {
  const std::string det = R"({"t": [0.1, 0.2, 0.8], "rot": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "box": [0.5, 0.5, 0.1, 0.1], "class": 1})";
  std::string img = "{";
  for (std::size_t k = 0; k < n_detections; ++k) img += (k ? ",\n\"" : "\"") + std::to_string(k) + "\": " + det;
  return img + "}";
}
}  // namespace

TEST_CASE("poet results: one image at the per-image detection limit is read, one more is refused at its line",
          "[io][poet][hostile]") {
  const std::size_t n = io::kMaxPoetDetectionsPerImage;
  const auto ok = io::parse_poet_results("{\"a\": {},\n\"1\": " + image_of(n) + "}", "r.json");
  REQUIRE(ok.images.size() == 2);
  CHECK(ok.images[1].detections.size() == n);
  try {
    (void)io::parse_poet_results("{\"a\": {},\n\"1\": " + image_of(n + 1) + "}", "r.json");
    FAIL("an image beyond the limit was read");
  } catch (const InputError& e) {
    const std::string m = e.what();
    CHECK(m.find("more than 10000 detections in one image") != std::string::npos);
    CHECK(m.find("per-image limit") != std::string::npos);
    CHECK(m.find("r.json:10002:") != std::string::npos);  // the line of the 10 001st detection's key
  }
}

TEST_CASE("poet results: an image's entry of more JSON values than the limit is refused, whatever their shape",
          "[io][poet][hostile]") {
  std::string values = "[0";
  for (std::size_t k = 0; k < io::kMaxPoetValuesPerImage; ++k) values += ",0";
  CHECK_THROWS_WITH(io::parse_poet_results("{\"1\": {\"0\": {\"t\": " + values + "]}}}", "r.json"),
                    Catch::Contains("JSON values in one image's entry") && Catch::Contains("per-image limit"));
  // The count starts again for each image: many images of a few values each are read.
  std::string many = "{";
  for (int k = 0; k < 3000; ++k) many += (k ? ",\"" : "\"") + std::to_string(k) + "\": " + image_of(20);
  CHECK(io::parse_poet_results(many + "}", "r.json").images.size() == 3000);
}
