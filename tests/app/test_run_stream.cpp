// roe run with the filter alone and with the smoother (issue 53): the rows go into the files as they are
// produced, none is kept in memory, and the files have the bytes of the in-memory path (the batch's).
#include <catch2/catch.hpp>
#include <filesystem>
#include <map>
#include <set>
#include <string>

#include "../ekf/filter_support.hpp"
#include "roe/app/run.hpp"
#include "roe/core/error.hpp"
#include "roe/io/input.hpp"
#include "roe/io/json.hpp"
#include "roe/io/trajectory_io.hpp"
#include "roe/store/dataset.hpp"
#include "roe/store/run_files.hpp"
#include "support/test_util.hpp"

namespace fs = std::filesystem;
using namespace roe;

namespace {

/// The run folder holds run.json and exactly the files of `all` the config writes, each with its text there;
/// returns how many files it holds.
std::size_t check_run_files(const fs::path& out, const app::RunConfig& config,
                            const std::map<std::string, std::string>& all) {
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
  return files.size();
}

/// paper-seq4 seed 1 for `seconds`, written to `ds` and read back as roe run reads it (no mocap, no ground truth).
Dataset run_input(const fs::path& ds, double seconds) {
  store::write_dataset(test::simulate_preset("paper-seq4", 1, seconds), ds, true);
  store::DatasetParts parts;
  parts.mocap = false;
  parts.groundtruth = false;
  return store::read_dataset(ds, parts);
}

}  // namespace

TEST_CASE("roe run with the filter alone streams its rows: none held, the bytes of the in-memory writers",
          "[app][run][stream]") {
  test::TempDir tmp("roe_test_run_stream");
  const fs::path ds = tmp / "ds";
  const Dataset dataset = run_input(ds, 60.0);  // what roe run reads
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
    app::RunOptions batch;
    batch.estimator = "batch";
    CHECK_FALSE(pipeline::streams_rows(app::effective_run_config(batch)));  // the batch: in memory
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
    CHECK(check_run_files(out, config, all) == (std::string(level) == "full" ? 6u : 3u));
  }
}

TEST_CASE("roe run with the smoother streams its rows: the filter's as it runs, the smoothed through a temporary file",
          "[app][run][stream][smoother]") {
  test::TempDir tmp("roe_test_run_stream_rts");
  const fs::path ds = tmp / "ds";
  const Dataset dataset = run_input(ds, 20.0);
  const auto hidden = [&] {  // temporaries beside the run folders (io::OutputDir's) and inside them
    std::set<std::string> names;
    for (const auto& e : fs::recursive_directory_iterator(tmp.path))
      if (e.path().filename().string().front() == '.') names.insert(e.path().string());
    return names;
  };
  for (const char* level : {"full", "standard", "minimal"}) {
    INFO(level);
    app::RunOptions opt;  // the default estimator: filter + RTS smoother
    opt.output_level = level;
    const fs::path out = tmp / (std::string("run_") + level);
    const app::RunConfig config = app::effective_run_config(opt);
    REQUIRE(config.smoothed());
    REQUIRE(pipeline::streams_rows(config));
    const app::RunResult res = app::run(ds, out, opt);
    CHECK(res.output.smoothed);
    CHECK(res.output.states.empty());
    CHECK(res.output.filter_states.empty());
    CHECK(res.output.reprojection.empty());
    CHECK(hidden().empty());  // the smoothed rows' temporary file is gone

    // The same run in memory (the batch's path), written by the in-memory formatters.
    const app::RunOutput mem = app::run_dataset(dataset, "", config);
    REQUIRE(mem.states.size() > 3000);  // 20 s at the IMU rate
    CHECK(res.output.state_rows == mem.states.size());
    const auto poses = [](const std::vector<store::RecordedState>& rows) {
      return [&rows](std::size_t i) { return StampedPose{rows[i].t_ns, Pose(rows[i].x.q_W_I, rows[i].x.p_W_I)}; };
    };
    std::map<std::string, std::string> all = {
        {"states.csv", store::format_states_csv(mem.states)},
        {"objects.csv", store::format_objects_csv(mem.objects)},
        {"reprojection.csv", store::format_reprojection_csv(mem.reprojection)},
        {"trajectory.csv", io::format_trajectory(mem.states.size(), poses(mem.states), io::TrajectoryFormat::kCsv)},
        {"trajectory.tum", io::format_trajectory(mem.states.size(), poses(mem.states), io::TrajectoryFormat::kTum)}};
    if (store::run_folder_has(config, "states_filter.csv")) {
      REQUIRE(mem.filter_states.size() == mem.states.size());
      const auto& f = mem.filter_states;
      all["states_filter.csv"] = store::format_states_csv(f);
      all["trajectory_filter.csv"] = io::format_trajectory(f.size(), poses(f), io::TrajectoryFormat::kCsv);
      all["trajectory_filter.tum"] = io::format_trajectory(f.size(), poses(f), io::TrajectoryFormat::kTum);
    }
    CHECK(check_run_files(out, config, all) == (std::string(level) == "minimal" ? 3u : 9u));
    // The smoothed estimate is not the filter's (the rows of the two files differ).
    if (store::run_folder_has(config, "states_filter.csv"))
      CHECK(io::read_file(out / "states.csv") != io::read_file(out / "states_filter.csv"));
  }

  // A run that fails after the smoothed rows' temporary file was made leaves nothing behind.
  const fs::path cfg = tmp.write("bad_anchor.json", R"({"filter": {"anchor_id": 99}})");
  app::RunOptions bad;
  bad.config_file = cfg.string();
  CHECK_THROWS_AS(app::run(ds, tmp / "run_bad", bad), ConfigError);
  CHECK_FALSE(fs::exists(tmp / "run_bad"));
  CHECK(hidden().empty());
}
