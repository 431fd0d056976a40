// evo's command line in `roe eval` (src/cli/evo_syntax.cpp, docs/eval.md "evo's command line"): each evo form
// gives the same report as roe's own spelling of the call, on the real files in ../shared/data; refused
// forms and options name the roe spelling.
#include "support/test_util.hpp"

#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "roe/io/input.hpp"
#include "roe/io/output.hpp"
#include "roe/io/zip.hpp"

namespace fs = std::filesystem;

namespace {

const fs::path kData = fs::path(ROE_SHARED_DATA_DIR);

nlohmann::json report(const std::string& args) {
  const auto r = roe::test::run_roe("--json eval " + args + " --no-out", false);
  INFO("roe --json eval " << args << "\n" << r.out);
  REQUIRE(r.code == 0);
  return nlohmann::json::parse(r.out);
}

/// The figures that must not depend on how the call was spelled.
void check_same(const nlohmann::json& a, const nlohmann::json& b) {
  CHECK(a["ape_trans_m"]["rmse"].get<double>() == b["ape_trans_m"]["rmse"].get<double>());
  CHECK(a["ape_rot_deg"]["rmse"].get<double>() == b["ape_rot_deg"]["rmse"].get<double>());
  CHECK(a["association"] == b["association"]);
  CHECK(a["alignment"]["type"] == b["alignment"]["type"]);
  CHECK(a["rpe"] == b["rpe"]);
}

roe::test::RunResult fails(const std::string& args) {
  const auto r = roe::test::run_roe("eval " + args, true);
  INFO("roe eval " << args << "\n" << r.out);
  CHECK(r.code == 2);
  return r;
}

}  // namespace

TEST_CASE("evo's file forms: tum, euroc and --ref give roe's own call's report", "[cli][eval][evo]") {
  const fs::path gt = kData / "eval/freiburg1_xyz-groundtruth.txt", est = kData / "eval/freiburg1_xyz-rgbdslam.txt";
  if (!fs::exists(gt)) {
    WARN("skipped: " << gt << " absent");
    return;
  }
  const auto roe_call = report(est.string() + " --gt " + gt.string() + " --align se3 --est-format tum --gt-format tum");
  check_same(report("tum " + gt.string() + " " + est.string() + " -a"), roe_call);
  check_same(report("tum " + est.string() + " --ref " + gt.string() + " -a"), roe_call);
  check_same(report(est.string() + " --ref " + gt.string() + " -a"), roe_call);
  // -r: the relations roe's report holds are accepted and change nothing.
  check_same(report("tum " + gt.string() + " " + est.string() + " -a -r trans_part"), roe_call);
  check_same(report("tum " + gt.string() + " " + est.string() + " -a --pose_relation angle_deg"), roe_call);
  // evo_ape euroc: EuRoC ground truth, TUM estimate; RPE with evo's option names.
  const fs::path vgt = kData / "eval/V102_groundtruth.csv", vest = kData / "eval/V102.txt";
  const auto evo_rpe = report("euroc " + vgt.string() + " " + vest.string() +
                              " -as --delta 1 --delta_unit m --all_pairs --pairs_from_reference");
  const auto roe_rpe = report(vest.string() + " --gt " + vgt.string() + " --gt-format euroc --est-format tum " +
                              "--align sim3 --rpe-delta 1 --rpe-unit m --rpe-all-pairs --rpe-pairs-from gt");
  check_same(evo_rpe, roe_rpe);
  CHECK(evo_rpe["rpe"][0]["all_pairs"] == true);
}

TEST_CASE("evo's bag forms: bag2 and bag BAG REF_TOPIC EST_TOPIC", "[cli][eval][evo]") {
  const fs::path mcap = kData / "rosbag2/nav2_turtlebot.mcap", bag = kData / "rosbag/evo_ROS_example.bag";
  if (!fs::exists(mcap)) {
    WARN("skipped: " << mcap << " absent");
    return;
  }
  check_same(report("bag2 " + mcap.string() + " /amcl_pose /odom -a"),
             report(mcap.string() + ":/odom --gt " + mcap.string() + ":/amcl_pose --align se3"));
  check_same(report("bag " + bag.string() + " groundtruth ORB-SLAM -a"),
             report(bag.string() + ":ORB-SLAM --gt " + bag.string() + ":groundtruth --align se3"));
  check_same(report("bag " + bag.string() + " S-PTAM --ref groundtruth -as"),
             report(bag.string() + ":S-PTAM --gt " + bag.string() + ":groundtruth --align sim3"));
}

TEST_CASE("evo's forms that roe cannot take are answered with roe's spelling", "[cli][eval][evo]") {
  // Two plain words: the ground truth goes after --gt (evo's order would need its format word).
  auto r = fails("ref.txt est.txt");
  CHECK_THAT(r.out, Catch::Contains("roe eval est.txt --gt ref.txt"));
  CHECK_THAT(r.out, Catch::Contains("roe eval tum|kitti|euroc ref.txt est.txt"));
  // Several estimates (evo_traj style).
  CHECK_THAT(fails("tum ref.txt a.txt b.txt").out, Catch::Contains("one estimate at a time"));
  CHECK_THAT(fails("bag2 x.mcap /gt").out, Catch::Contains("roe eval bag2 BAG REF_TOPIC EST_TOPIC"));
  // The reference twice, a format contradicting evo's form.
  CHECK_THAT(fails("tum ref.txt est.txt --gt other.txt").out, Catch::Contains("named twice"));
  CHECK_THAT(fails("tum ref.txt est.txt --est-format kitti").out, Catch::Contains("--est-format kitti"));
  // Pose relations roe does not compute, and evo options it has no use for.
  CHECK_THAT(fails("tum ref.txt est.txt -r full").out, Catch::Contains("ape_rot_deg"));
  CHECK_THAT(fails("tum ref.txt est.txt -r rot_part").out, Catch::Contains("angle_deg"));
  CHECK_THAT(fails("tum ref.txt est.txt -r angle_rad").out, Catch::Contains("degrees"));
  CHECK_THAT(fails("tum ref.txt est.txt -r sideways").out, Catch::Contains("point_distance"));
  CHECK_THAT(fails("tum ref.txt est.txt --save_plot p.pdf").out, Catch::Contains("--plot"));
  CHECK_THAT(fails("tum ref.txt est.txt --project_to_plane xy").out, Catch::Contains("--plot-mode"));
  CHECK_THAT(fails("tum ref.txt est.txt --silent").out, Catch::Contains("-q"));
  // evo's --plot_mode is roe's --plot-mode (an option of the figures: it needs -p/--plot).
  CHECK_THAT(fails("tum ref.txt est.txt --plot_mode xz").out, Catch::Contains("needs --plot"));
  // A run folder named like a format word is still a run folder when it stands alone.
  CHECK_THAT(fails("tum").out, Catch::Contains("tum"));
}

TEST_CASE("arguments roe did not expect are listed in the order they were typed", "[cli][eval][evo]") {
  const auto r = fails("est.txt --first 1 --second 2 --third");
  CHECK_THAT(r.out, Catch::Contains("not expected: --first --second --third"));
}

TEST_CASE("evo result files: --save_results writes one, --summary reads it beside roe's reports", "[cli][eval][evo]") {
  const fs::path gt = kData / "eval/freiburg1_xyz-groundtruth.txt", est = kData / "eval/freiburg1_xyz-rgbdslam.txt";
  if (!fs::exists(gt) || roe::test::run_shell("/usr/bin/python3 -c 'import numpy'").code != 0) {
    WARN("skipped: ../shared/data or /usr/bin/python3 with numpy absent");
    return;
  }
  roe::test::TempDir tmp("roe_test_evo_save");
  const fs::path zip = tmp.path / "ape.zip";
  const auto rep = report("tum " + gt.string() + " " + est.string() + " -a --save_results " + zip.string());
  REQUIRE(fs::exists(zip));
  CHECK(rep["evo_results"] == zip.string());
  // Read as evo's load_res_file reads it: Python's zipfile and NumPy.
  const std::string fixture = std::string(ROE_SOURCE_DIR) + "/tests/fixtures/evo/evo_result_fixture.py";
  const auto py = roe::test::run_shell("/usr/bin/python3 " + fixture + " read " + zip.string() + " 2>/dev/null");
  REQUIRE(py.code == 0);
  const auto j = nlohmann::json::parse(py.out);
  const std::vector<std::string> arrays = {"error_array", "seconds_from_start", "timestamps", "distances_from_start",
                                           "distances", "alignment_transformation_sim3"};
  for (std::size_t k = 0; k < arrays.size(); ++k) CHECK(j["names"][2 + k] == arrays[k] + ".npy");
  // Absolute inputs: the members are named after the files (a ZIP member name is relative, APPNOTE 4.4.17),
  // info.json keeps the paths as given (issue 51).
  CHECK(j["names"][8] == gt.filename().string() + ".tum");
  CHECK(j["names"][9] == est.filename().string() + ".tum");
  CHECK(j["info"]["ref_name"] == gt.string());
  CHECK(j["info"]["est_name"] == est.string());
  CHECK(j["info"]["title"] == "APE w.r.t. translation part (m)\n(with SE(3) Umeyama alignment)");
  CHECK(j["info"]["label"] == "APE (m)");
  CHECK(j["stats"]["rmse"].get<double>() == rep["ape_trans_m"]["rmse"].get<double>());
  CHECK(j["stats"]["max"].get<double>() == rep["ape_trans_m"]["max"].get<double>());
  const std::size_t n = rep["association"]["n_matched"].get<std::size_t>();
  CHECK(j["arrays"]["error_array"].size() == n);
  CHECK(j["shapes"]["alignment_transformation_sim3"] == nlohmann::json({4, 4}));
  double rms = 0.0;
  for (const auto& e : j["arrays"]["error_array"]) rms += e.get<double>() * e.get<double>() / static_cast<double>(n);
  CHECK(std::sqrt(rms) == Approx(rep["ape_trans_m"]["rmse"].get<double>()).epsilon(1e-12));
  // Not replaced without --force; --force replaces it.
  CHECK(fails("tum " + gt.string() + " " + est.string() + " --no-out --save_results " + zip.string()).code == 2);
  CHECK(roe::test::run_roe("eval tum " + gt.string() + " " + est.string() + " --no-out --force --save_results " +
                           zip.string()).code == 0);

  // --summary: evo's zip (written by Python as evo writes it) and roe's zip beside a roe report.
  const auto fx = roe::test::run_shell("/usr/bin/python3 " + fixture + " write " + (tmp.path / "fx").string());
  REQUIRE(fx.code == 0);
  const auto expected = nlohmann::json::parse(roe::io::read_file(tmp.path / "fx/expected.json"));
  const fs::path report_dir = tmp.path / "roe_eval";
  REQUIRE(roe::test::run_roe("eval tum " + gt.string() + " " + est.string() + " -a --out " + report_dir.string()).code == 0);
  const auto s = roe::test::run_roe("--json eval --summary " + (tmp.path / "fx/stored.zip").string() + " " +
                                        zip.string() + " " + (report_dir / "report.json").string(),
                                    false);
  INFO(s.out);
  REQUIRE(s.code == 0);
  const auto sum = nlohmann::json::parse(s.out);
  CHECK(sum["runs"][0]["ate_rmse_m"].get<double>() == expected["stats"]["rmse"].get<double>());  // unchanged
  CHECK(sum["runs"][0]["rmse_x_m"].is_null());
  CHECK(sum["runs"][0]["n_objects"].is_null());
  CHECK(sum["runs"][0]["alignment"] == "se3");
  CHECK(sum["runs"][1]["ate_rmse_m"].get<double>() == rep["ape_trans_m"]["rmse"].get<double>());
  CHECK(sum["runs"][1]["label"] == "freiburg1_xyz-rgbdslam");
  CHECK(sum["runs"][2]["ate_rmse_m"].get<double>() == rep["ape_trans_m"]["rmse"].get<double>());
  // Three estimators (evo's est.txt, roe's zip and roe's report): no mean across them.
  CHECK(sum["mean"].is_null());
  CHECK_THAT(sum["warnings"].dump(), Catch::Contains("no mean across different estimators"));
  // An evo result of another metric is refused naming what --summary reads.
  const fs::path full_zip = tmp.path / "full.zip";
  roe::io::write_file_atomic(
      full_zip, roe::io::write_zip({{"info.json", R"J({"title": "APE w.r.t. full transformation (unit-less)"})J"},
                                    {"stats.json", R"({"rmse": 0.5})"}}));
  CHECK_THAT(fails("--summary " + full_zip.string()).out, Catch::Contains("ate_rmse_m"));
}

TEST_CASE("bag topics are labelled BAGSTEM:TOPIC, a bag folder without a topic says it is a bag", "[cli][eval][evo]") {
  const fs::path mcap = kData / "rosbag2/nav2_turtlebot.mcap", bag = kData / "rosbag/evo_ROS_example.bag";
  if (!fs::exists(mcap)) {
    WARN("skipped: " << mcap << " absent");
    return;
  }
  CHECK(report("bag " + bag.string() + " groundtruth ORB-SLAM -a")["info"]["label"] == "evo_ROS_example:ORB-SLAM");
  CHECK(report("bag " + bag.string() + " groundtruth S-PTAM -a")["info"]["label"] == "evo_ROS_example:S-PTAM");
  CHECK(report("bag2 " + mcap.string() + " /amcl_pose /odom -a")["info"]["label"] == "nav2_turtlebot:odom");
  CHECK(report(bag.string() + ":ORB-SLAM --gt " + bag.string() + ":groundtruth --label mine")["info"]["label"] ==
        "mine");
  const auto r = fails((kData / "rosbag2/tf_example").string() + " --gt " + mcap.string() + ":/amcl_pose");
  CHECK_THAT(r.out, Catch::Contains("this is a ROS bag"));
  CHECK_THAT(r.out, Catch::Contains("BAG:/tf:PARENT.CHILD"));
}
