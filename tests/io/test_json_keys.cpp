// JsonObject's strict key check: an unknown key is an error naming its key path, and says where the
// reader does read that key (another level) or which key of the same object it is one or two edits from.
#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "roe/core/error.hpp"
#include "roe/io/json.hpp"

using namespace roe;

namespace {
/// Reads {"filter": {"gain": ...}, "output": {"rate": ...}, "smoother": ...} as a config reader would.
void read_config(const nlohmann::json& j) {
  io::JsonObject root(j, "cfg.json");
  double gain = 0;
  std::string rate, smoother;
  {
    io::JsonObject f = root.child("filter");
    f.get("gain", gain);
    f.finish();
  }
  {
    io::JsonObject o = root.child("output");
    o.get("rate", rate);
    o.finish();
  }
  root.get("smoother", smoother);
  root.finish();
}

ConfigError error_of(const char* text) {
  try {
    read_config(nlohmann::json::parse(text));
  } catch (const ConfigError& e) {
    return e;
  }
  FAIL("no ConfigError for " << text);
  return ConfigError("");
}
}  // namespace

TEST_CASE("JsonObject: an unknown key that the reader reads at another level says so", "[io][json]") {
  REQUIRE_NOTHROW(read_config(nlohmann::json::parse(R"({"filter": {"gain": 1}, "smoother": "rts"})")));
  ConfigError e = error_of(R"({"filter": {"gain": 1, "smoother": "rts"}})");
  CHECK(e.context().key == "filter.smoother");
  CHECK_THAT(e.bare_message(), Catch::Contains("did you mean the top-level \"smoother\""));
  e = error_of(R"({"rate": "imu"})");
  CHECK(e.context().key == "rate");
  CHECK_THAT(e.bare_message(), Catch::Contains("did you mean \"output.rate\""));
  e = error_of(R"({"filter": {"gian": 1}})");
  CHECK(e.context().key == "filter.gian");
  CHECK_THAT(e.bare_message(), Catch::Contains("did you mean \"filter.gain\""));
  e = error_of(R"({"filter": {"completely_different": 1}})");
  CHECK(e.bare_message() == "unknown key");
  // The first unknown key found is the one reported, even when a later level has one too.
  e = error_of(R"({"filter": {"x": 1}, "y": 2})");
  CHECK(e.context().key == "filter.x");
}
