// roe run with the filter alone (issue 53): the rows go into the files as the filter produces them, none is
// kept in memory, and the files have the bytes of the in-memory path (the smoother's and the batch's).
#include <catch2/catch.hpp>
#include <filesystem>
#include <map>
#include <set>
#include <string>

#include "../ekf/filter_support.hpp"
#include "roe/app/run.hpp"
#include "roe/io/input.hpp"
#include "roe/io/json.hpp"
#include "roe/io/trajectory_io.hpp"
#include "roe/store/dataset.hpp"
#include "roe/store/run_files.hpp"
#include "support/test_util.hpp"

namespace fs = std::filesystem;
using namespace roe;

TEST_CASE("roe run with the filter alone streams its rows: none held, the bytes of the in-memory writers",
          "[app][run][stream]") {
  test::TempDir tmp("roe_test_run_stream");
  const fs::path ds = tmp / "ds";
  store::write_dataset(test::simulate_preset("paper-seq4", 1, 60.0), ds, true);
  store::DatasetParts parts;
  parts.mocap = false;
  parts.groundtruth = false;
  const Dataset dataset = store::read_dataset(ds, parts);  // what roe run reads
  for (const char* level : {"full", "minimal"}) {
    INFO(level);
    app::RunOptions opt;
    opt.estimator = "filter";
    opt.output_level = level;
    const fs::path out = tmp / (std::string("run_") + level);
    const app::RunResult res = app::run(ds, out, opt);
    // The streaming path was taken: no row is held, only their counts.
    CHECK(res.output.states.empty());
    CHECK(res.output.objects.empty());
    CHECK(res.output.reprojection.empty());

    // The same run in memory (the path the smoother and the batch take), written by the in-memory formatters.
    const app::RunConfig config = app::effective_run_config(opt);
    CHECK_FALSE(pipeline::streams_rows(app::effective_run_config(app::RunOptions{})));  // the smoother: in memory
    const app::RunOutput mem = app::run_dataset(dataset, "", config);
    REQUIRE(mem.states.size() > 10000);  // 60 s at the IMU rate
    REQUIRE_FALSE(mem.reprojection.empty());
    CHECK(res.output.state_rows == mem.states.size());
    CHECK(res.output.images_with_detections == mem.images_with_detections);
    const io::json counts = io::parse_json_file(out / "run.json").at("counts");
    CHECK(counts.at("trajectory_rows").get<std::size_t>() == mem.states.size());
    std::set<Timestamp> images;
    for (const auto& r : mem.reprojection) images.insert(r.t_ns);
    CHECK(counts.at("images_with_detections").get<std::size_t>() == images.size());

    const auto pose_at = [&](std::size_t i) {
      return StampedPose{mem.states[i].t_ns, Pose(mem.states[i].x.q_W_I, mem.states[i].x.p_W_I)};
    };
    const std::map<std::string, std::string> all = {
        {"states.csv", store::format_states_csv(mem.states)},
        {"objects.csv", store::format_objects_csv(mem.objects)},
        {"reprojection.csv", store::format_reprojection_csv(mem.reprojection)},
        {"trajectory.csv", io::format_trajectory(mem.states.size(), pose_at, io::TrajectoryFormat::kCsv)},
        {"trajectory.tum", io::format_trajectory(mem.states.size(), pose_at, io::TrajectoryFormat::kTum)}};
    std::set<std::string> want = {"run.json"}, files;
    for (const auto& [file, text] : all) {
      if (!store::run_folder_has(config, file)) continue;
      want.insert(file);
      INFO(file);
      const bool same = io::read_file(out / file) == text;
      CHECK(same);
    }
    for (const auto& e : fs::directory_iterator(out)) files.insert(e.path().filename().string());
    CHECK(files == want);
    CHECK(want.size() == (std::string(level) == "full" ? 6u : 3u));
  }
}
