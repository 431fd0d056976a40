// PoET results.json reader: the file as PoET's inference tool writes it, and its edge cases.
#include <catch2/catch.hpp>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

#include "support/test_util.hpp"
#include "roe/core/error.hpp"
#include "roe/io/poet_results.hpp"
#include "roe/math/so3.hpp"

using roe::InputError;
using namespace roe::io;

namespace {
std::string expect_error(const std::string& text, PoetRotationFormat f = PoetRotationFormat::kAuto) {
  try {
    parse_poet_results(text, "results.json", f);
  } catch (const InputError& e) {
    return e.what();
  }
  FAIL("no error for: " << text);
  return "";
}
}  // namespace

TEST_CASE("results.json as PoET writes it: string indices, 3x3 rot, box, class, empty frame", "[poet_results]") {
  const std::string text = R"({"1662634121000000000": {"0": {"t": [0.05, -0.02, 0.61],
      "rot": [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]], "box": [0.52, 0.44, 0.20, 0.31], "class": 5},
      "1": {"t": [0.1, 0.2, 0.9], "rot": [[1,0,0],[0,1,0],[0,0,1]], "box": [0.1, 0.1, 0.1, 0.1], "class": 13}},
    "1662634121033333333": {}})";
  const auto r = parse_poet_results(text, "results.json");
  REQUIRE(r.images.size() == 2);
  CHECK(r.images[0].id == "1662634121000000000");
  REQUIRE(r.images[0].detections.size() == 2);
  const auto& d = r.images[0].detections[0];
  CHECK(d.index == 0);
  CHECK(d.class_id == 5);
  CHECK(d.t.isApprox(Eigen::Vector3d(0.05, -0.02, 0.61)));
  CHECK(d.R_C_O(1, 2) == Approx(-1.0));  // rows as written
  CHECK(d.R_C_O(2, 1) == Approx(1.0));
  CHECK(d.box[3] == Approx(0.31));
  CHECK(d.finite);
  CHECK_FALSE(d.rot_was_quaternion);
  CHECK(d.line == 1);
  CHECK(r.images[0].detections[1].class_id == 13);
  CHECK(r.images[1].detections.empty());
}

TEST_CASE("bare NaN / Infinity tokens are accepted and flag the detection", "[poet_results]") {
  const std::string text = R"({"NaN_1": {"0": {"t": [NaN, 0.0, Infinity], "rot": [[1,0,0],[0,1,0],[0,0,1]],
      "box": [NaN, 0.5, 0.1, 0.1], "class": 2}, "1": {"t": [0, 0, 1], "rot": [[NaN,0,0],[0,1,0],[0,0,-Infinity]], "class": 3},
      "2": {"t": [0, 0, 1], "rot": [1, 0, 0, 0], "class": 4}}})";
  const auto r = parse_poet_results(text, "results.json");
  REQUIRE(r.images.size() == 1);
  CHECK(r.images[0].id == "NaN_1");  // the token inside a string is just text
  const auto& dets = r.images[0].detections;
  REQUIRE(dets.size() == 3);
  CHECK_FALSE(dets[0].finite);
  CHECK(std::isinf(dets[0].t.z()));
  CHECK(std::isnan(dets[0].box[0]));
  CHECK_FALSE(dets[1].finite);
  CHECK(dets[2].finite);
  // nlohmann itself rejects the token, which is why roe has its own tokenizer.
  CHECK_THROWS(nlohmann::json::parse(R"({"a": NaN})"));
}

TEST_CASE("w-first quaternions (PoET quat models) become rotations", "[poet_results]") {
  const double h = std::sqrt(0.5);
  const std::string text = "{\"a\": {\"0\": {\"t\": [0,0,1], \"rot\": [" + std::to_string(h) + ", 0, 0, " + std::to_string(h) +
                           "], \"class\": 1}}}";
  const auto r = parse_poet_results(text, "results.json");
  const auto& d = r.images[0].detections[0];
  CHECK(d.rot_was_quaternion);
  // 90° about z: x axis → y axis.
  CHECK((d.R_C_O * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm() < 1e-5);
  CHECK(d.R_C_O.determinant() == Approx(1.0));
  // forced formats
  CHECK(expect_error(text, PoetRotationFormat::kMatrix).find("4-vector") != std::string::npos);
  CHECK(expect_error(R"({"a": {"0": {"t": [0,0,1], "rot": [[1,0,0],[0,1,0],[0,0,1]], "class": 1}}})", PoetRotationFormat::kQuatWxyz)
            .find("quat_wxyz") != std::string::npos);
  CHECK(expect_error(R"({"a": {"0": {"t": [0,0,1], "rot": [2, 0, 0, 0], "class": 1}}})").find("unit norm") != std::string::npos);
}

TEST_CASE("float32 rounding of R is removed, non-rotations are errors with line and column", "[poet_results]") {
  const auto r = parse_poet_results(R"({"a": {"0": {"t": [0,0,1], "rot": [[1.0000001,0,0],[0,0.9999999,0],[0,0,1]], "class": 1}}})",
                                    "r.json");
  const auto& R = r.images[0].detections[0].R_C_O;
  CHECK((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-12);
  const std::string e = expect_error("{\"a\": {\"0\": {\"t\": [0,0,1],\n  \"rot\": [[1,0,0],[0,1,0],[0,0,-1]], \"class\": 1}}}");
  CHECK(e.find("results.json:2:10") != std::string::npos);
  CHECK(e.find("not a rotation") != std::string::npos);
  CHECK(expect_error(R"({"a": {"0": {"t": [0,0,1], "rot": [[2,0,0],[0,1,0],[0,0,1]], "class": 1}}})").find("not a rotation") !=
        std::string::npos);
}

TEST_CASE("malformed files are InputErrors naming the place", "[poet_results]") {
  CHECK(expect_error(R"({"a": {"0": {"t": [0,0], "rot": [1,0,0,0], "class": 1}}})").find("\"t\" must be") != std::string::npos);
  CHECK(expect_error(R"({"a": {"x": {"t": [0,0,1], "rot": [1,0,0,0], "class": 1}}})").find("detection keys") != std::string::npos);
  CHECK(expect_error(R"({"a": {"01": {"t": [0,0,1], "rot": [1,0,0,0], "class": 1}}})").find("detection keys") != std::string::npos);
  CHECK(expect_error(R"({"a": {"0": {"t": [0,0,1], "rot": [1,0,0,0], "class": 0}}})").find("1-based") != std::string::npos);
  CHECK(expect_error(R"({"a": {"0": {"t": [0,0,1], "rot": [1,0,0,0], "class": 1.5}}})").find("integer") != std::string::npos);
  CHECK(expect_error(R"({"a": {"0": {"t": [0,0,1], "rot": [1,0,0,0]}}})").find("without \"class\"") != std::string::npos);
  CHECK(expect_error(R"({"a": {"0": {"t": [0,0,1], "rot": [1,0,0,0], "class": 1, "colour": 2}}})").find("unknown key") !=
        std::string::npos);
  CHECK(expect_error(R"({"a": {"0": {"t": [0,0,1], "rot": [1,0,0,0], "class": 1}})").find("expected ','") != std::string::npos);
  CHECK(expect_error(R"([1, 2])").find("object of image ids") != std::string::npos);
  CHECK(expect_error(R"({"a": {"0": {"t": [0,0,1], "rot": [1,0,0,0], "class": 1}}} x)").find("after the JSON") != std::string::npos);
  CHECK(expect_error(R"({"a": {"0": {"t": [0,0,Nope], "rot": [1,0,0,0], "class": 1}}})").find("unexpected character") != std::string::npos);
}

TEST_CASE("colliding image ids (duplicate keys) are reported, not silently overwritten", "[poet_results]") {
  const std::string e = expect_error("{\"17\": {},\n \"17\": {}}");
  CHECK(e.find("duplicate key \"17\"") != std::string::npos);
  CHECK(e.find("results.json:2:2") != std::string::npos);
  CHECK(e.find("two images with the same id") != std::string::npos);
  const std::string e1 = expect_error(
      R"({"a": {"0": {"t": [0,0,1], "rot": [1,0,0,0], "class": 1}, "0": {"t": [0,0,1], "rot": [1,0,0,0], "class": 2}}})");
  CHECK(e1.find("duplicate key \"0\"") != std::string::npos);
  CHECK(e1.find("two detections with the same index") != std::string::npos);
  const std::string e2 = expect_error(R"({"a": {"0": {"t": [0,0,1], "t": [0,0,2], "rot": [1,0,0,0], "class": 1}}})");
  CHECK(e2.find("duplicate key \"t\"") != std::string::npos);
  CHECK(e2.find("results.json:1:28") != std::string::npos);
  CHECK(e2.find("same") == std::string::npos);
}

TEST_CASE("detections are sorted by their index (score rank)", "[poet_results]") {
  const auto r = parse_poet_results(
      R"({"a": {"10": {"t": [0,0,1], "rot": [1,0,0,0], "class": 3}, "2": {"t": [0,0,1], "rot": [1,0,0,0], "class": 2}}})", "r");
  REQUIRE(r.images[0].detections.size() == 2);
  CHECK(r.images[0].detections[0].index == 2);
  CHECK(r.images[0].detections[1].index == 10);
}

TEST_CASE("PoET's image id rule", "[poet_results]") {
  CHECK(poet_image_id("1662634121000000000.png") == "1662634121000000000");
  CHECK(poet_image_id("rgb_000123.png") == "000123");
  CHECK(poet_image_id("cam_rgb_17.png") == "rgb_17");
  CHECK(poet_image_id("some/dir/cam_rgb_17.png") == "rgb_17");
  CHECK(poet_image_id("frame.17.jpg") == "frame.17");
  CHECK(ycbv_class_names().size() == 22);
  CHECK(ycbv_class_names()[5] == "006_mustard_bottle");
  CHECK(ycbv_class_names()[21] == "061_foam_brick");
}

TEST_CASE("the tokenizer: -Infinity, keywords run on into names, backslash-u escapes, nesting depth", "[poet_results]") {
  const auto one = [](const std::string& id, const std::string& t) {
    return R"({")" + id + R"(": {"0": {"t": )" + t + R"(, "rot": [1,0,0,0], "class": 1}}})";
  };
  // The sign of -Infinity is kept.
  const auto r = parse_poet_results(one("a", "[Infinity, -Infinity, 1]"), "results.json");
  CHECK(r.images[0].detections[0].t.x() == std::numeric_limits<double>::infinity());
  CHECK(r.images[0].detections[0].t.y() == -std::numeric_limits<double>::infinity());
  // NaN / Infinity followed by letters, digits or '_' are not the keywords.
  for (const char* t : {"[0, 0, NaNx]", "[0, 0, Infinity2]", "[0, 0, NaN_]"}) {
    INFO(t);
    const std::string e = expect_error(one("a", t));
    CAPTURE(e);
    CHECK(e.find("results.json:1:26") != std::string::npos);
    CHECK(e.find("unexpected character") != std::string::npos);
  }
  // \u escapes in ids: decimal and both cases of hex digits, and a surrogate pair (U+1F600), to UTF-8.
  CHECK(parse_poet_results(one("caf\\u00e9_\\u00C9_\\u0041\\u0030", "[0,0,1]"), "r").images[0].id ==
        "caf\xC3\xA9_\xC3\x89_A0");
  CHECK(parse_poet_results(one("\\ud83d\\ude00\\uD83D\\uDE4F", "[0,0,1]"), "r").images[0].id ==
        "\xF0\x9F\x98\x80\xF0\x9F\x99\x8F");
  CHECK(expect_error(one("\\ud83dx", "[0,0,1]")).find("unpaired UTF-16 surrogate") != std::string::npos);
  CHECK(expect_error(one("\\ud83d\\u0041", "[0,0,1]")).find("invalid UTF-16 surrogate pair") != std::string::npos);
  CHECK(expect_error(one("\\u00g9", "[0,0,1]")).find("invalid \\u escape") != std::string::npos);
  // Nesting: 64 levels are fine (the document is then refused for its content), 65 are not, whether
  // the levels are arrays or objects.
  const auto arrays = [](int n) { return std::string(n, '[') + std::string(n, ']'); };
  std::string objects;
  for (int k = 0; k < 70; ++k) objects += "{\"a\": ";
  objects += "1" + std::string(70, '}');
  CHECK(expect_error(arrays(64)).find("nested too deeply") == std::string::npos);
  CHECK(expect_error(arrays(66)).find("nested too deeply") != std::string::npos);
  CHECK(expect_error(objects).find("nested too deeply") != std::string::npos);
}

TEST_CASE("PoET's image id rule without an extension, and class-name files", "[poet_results]") {
  // Python's name[name.find('_') + 1 : name.rfind('.')] with no '.': the end index is -1, the last
  // character is dropped. roe reproduces it, so ids match what PoET wrote.
  CHECK(poet_image_id("rgb_17") == "1");
  CHECK(poet_image_id("cam_rgb_170") == "rgb_17");
  CHECK(poet_image_id("frame17") == "frame1");  // no '_' and no '.': [0:-1]
  CHECK(poet_image_id("x").empty());
  CHECK(poet_image_id("a.b_c.png") == "c");   // from the first '_' to the last '.'
  CHECK(poet_image_id("x.y_z.png") == "z");
  CHECK(poet_image_id("x_y.z_w") == "y");
  CHECK(poet_image_id("x.y_z").empty());       // the first '_' after the last '.': an empty slice

  // A class-name file {"id": "name"} in any order; ids missing from it get empty names.
  roe::test::TempDir d("poet-classes");
  const auto names = read_poet_class_names(d.write("classes.json", R"({"3": "c", "1": "a", "0": "bg"})"));
  CHECK(names == std::vector<std::string>{"bg", "a", "", "c"});
  CHECK(read_poet_class_names(d.write("one.json", R"({"5": "e"})")).size() == 6);
}

TEST_CASE("a CSV given as results.json says it is a CSV and where a detections.csv goes", "[poet_results]") {
  const std::string e = expect_error("timestamp_ns,object_id,tx,ty,tz,qx,qy,qz,qw\n1,2,0,0,1,0,0,0,1\n");
  CHECK(e.find("looks like a CSV file") != std::string::npos);
  CHECK(e.find("detections/NAME/detections.csv") != std::string::npos);
  CHECK(e.find(":1:1") != std::string::npos);
}
