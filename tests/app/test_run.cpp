// roe run (app layer): output files, strict config, bad input, and the real-IMU regression.
#include <unistd.h>

#include <algorithm>
#include <catch2/catch.hpp>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>

#include "../ekf/filter_support.hpp"
#include "../support/euroc_snippet.hpp"
#include "roe/app/run.hpp"
#include "roe/core/error.hpp"
#include "roe/eval/associate.hpp"
#include "roe/eval/metrics.hpp"
#include "roe/store/dataset.hpp"
#include "roe/app/calib_check.hpp"
#include "roe/io/json.hpp"

namespace fs = std::filesystem;
using namespace roe;

namespace {

fs::path temp_dir(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("roe_test_run_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(p);
  return p;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A short simulated dataset folder.
fs::path make_dataset(const std::string& name, double duration = 6.0, const std::string& preset = "matched") {
  const fs::path dir = temp_dir(name);
  const Dataset d = test::simulate_preset(preset, 3, duration);
  store::write_dataset(d, dir, true);
  return dir;
}

}  // namespace

TEST_CASE("roe run writes the files of DESIGN §4", "[app][run]") {
  const fs::path ds = make_dataset("files");
  const fs::path out = temp_dir("files_out");
  app::RunOptions opt;
  const auto r = app::run(ds, out, opt);
  for (const char* f :
       {"trajectory.csv", "trajectory.tum", "states.csv", "objects.csv", "reprojection.csv", "run.json"})
    CHECK(fs::exists(out / f));
  // trajectory.csv: header, t with 9 decimals, one row per IMU sample.
  std::ifstream tr(out / "trajectory.csv");
  std::string header, row;
  std::getline(tr, header);
  CHECK(header == "t,tx,ty,tz,qx,qy,qz,qw");
  std::getline(tr, row);
  const auto comma = row.find(',');
  REQUIRE(comma != std::string::npos);
  CHECK(row.find('.') == comma - 10);  // 9 decimals
  std::size_t rows = 1;
  while (std::getline(tr, row)) ++rows;
  const Dataset d = store::read_dataset(ds);
  CHECK(rows == d.imu.size());
  // states.csv: 24 state columns + 21 sigmas, then the time offset and its σ (issue 49).
  std::ifstream st(out / "states.csv");
  std::getline(st, header);
  CHECK(std::count(header.begin(), header.end(), ',') + 1 == 1 + 23 + 21 + 2);
  // objects.csv: the state T_O_W with its σ, then the σ of T_W_O and of T_A_O (0 on the anchor's rows).
  std::ifstream ob(out / "objects.csv");
  std::getline(ob, header);
  CHECK(std::count(header.begin(), header.end(), ',') + 1 == 10 + 6 + 6 + 6);
  CHECK(header.find(",sigma_p_W_O_x,") != std::string::npos);
  CHECK(header.substr(header.size() - 18) == ",sigma_theta_A_O_z");
  std::size_t anchor_rows = 0, other_rows = 0;
  while (std::getline(ob, row)) {
    std::vector<std::string> cols;
    std::stringstream rs(row);
    for (std::string c; std::getline(rs, c, ',');) cols.push_back(c);
    REQUIRE(cols.size() == 28);
    double rel = 0.0;
    for (int i = 22; i < 28; ++i) rel += std::stod(cols[i]);
    if (cols[2] == "1") {
      ++anchor_rows;
      CHECK(rel == 0.0);
    } else {
      ++other_rows;
      CHECK(rel > 0.0);
    }
  }
  CHECK(anchor_rows > 0);
  CHECK(other_rows > 0);
  // reprojection.csv: one row per detection.
  std::ifstream rp(out / "reprojection.csv");
  std::size_t n_rp = 0;
  std::getline(rp, header);
  CHECK(header == "timestamp_ns,object_id,tx,ty,tz,qx,qy,qz,qw,status,nis,used");
  while (std::getline(rp, row)) {
    ++n_rp;
    // used: the split gate (default) uses one part or both of an accepted detection, an initialising one
    // whole, nothing of the others.
    const std::size_t c_used = row.rfind(','), c_nis = row.rfind(',', c_used - 1);
    const std::size_t c_status = row.rfind(',', c_nis - 1);
    const std::string status = row.substr(c_status + 1, c_nis - c_status - 1);
    const std::string used = row.substr(c_used + 1);
    if (status == "accepted")
      CHECK((used == "both" || used == "position" || used == "rotation"));
    else
      CHECK(used == (status == "initialized" ? "both" : "none"));
  }
  CHECK(n_rp == d.detections.at("sim").size());
  // run.json echoes the effective config and counts.
  const auto j = io::parse_json_file(out / "run.json");
  CHECK(j.at("config").at("filter").at("chi2_confidence").get<double>() == 0.95);
  CHECK(j.at("counts").at("imu_samples").get<std::size_t>() == d.imu.size());
  CHECK(j.at("inputs").at("sha256").at("roe.json").get<std::string>().size() == 64);
  CHECK(fs::path(j.at("inputs").at("dataset_abs").get<std::string>()).is_absolute());
  CHECK(fs::equivalent(j.at("inputs").at("dataset_abs").get<std::string>(), ds));
  CHECK(j.at("nis").at("count").get<std::size_t>() > 0);
  CHECK(j.at("nis").at("dof") == 6);
  // The init window and where the gyro bias came from: the default asks for it from rest, the simulated
  // handheld camera moves from the first sample, so the configured 0 is used and run.json says why.
  CHECK(j.at("init").at("gyro_bias_from").get<std::string>() == "config");
  CHECK(j.at("init").at("window_samples").get<int>() > 1);
  CHECK(j.at("init").at("gyro_bias") == io::json::array({0.0, 0.0, 0.0}));
  CHECK_THAT(j.at("init").at("gyro_bias_rest_refused").get<std::string>(), Catch::Contains("the gyro moves"));
  // A second run into the same folder is refused without --force.
  CHECK_THROWS_AS(app::run(ds, out, opt), InputError);
  opt.force = true;
  CHECK_NOTHROW(app::run(ds, out, opt));
  fs::remove_all(ds);
  fs::remove_all(out);
}

TEST_CASE("states rows carry the filter's own sigmas and IMU pose covariance", "[app][run]") {
  const Dataset d = test::simulate_preset("matched", 3, 6.0);
  const app::RunConfig config = test::plain_config();
  const app::RunOutput out = app::run_dataset(d, "", config);
  REQUIRE(out.states.size() == d.imu.size());
  // Before the first update the extrinsics' σ is the configured prior (propagation leaves it alone).
  const double deg = M_PI / 180.0;
  for (int i = 0; i < 3; ++i) {
    CHECK(out.states.front().sigma(15 + i) == Approx(config.filter.extrinsics_sigma_p_m).epsilon(1e-12));
    CHECK(out.states.front().sigma(18 + i) == Approx(config.filter.extrinsics_sigma_rot_deg * deg).epsilon(1e-12));
  }
  // ... and self-calibration shrinks it.
  for (int i = 15; i < 21; ++i) CHECK(out.states.back().sigma(i) < out.states.front().sigma(i));
  // The pose covariance [δp; δθ] holds the σ of δp (error-state 0–2) and δθ (6–8) on its diagonal,
  // is symmetric positive definite, and its p-θ block is filled in (the IMU correlates them).
  double max_cross = 0.0;
  for (const auto& s : out.states) {
    for (int i = 0; i < 3; ++i) {
      CHECK(s.pose_cov(i, i) == Approx(s.sigma(i) * s.sigma(i)).epsilon(1e-12));
      CHECK(s.pose_cov(3 + i, 3 + i) == Approx(s.sigma(6 + i) * s.sigma(6 + i)).epsilon(1e-12));
    }
    CHECK((s.pose_cov - s.pose_cov.transpose()).norm() <= 1e-12 * s.pose_cov.norm());
    CHECK(Eigen::LLT<Eigen::Matrix<double, 6, 6>>(s.pose_cov).info() == Eigen::Success);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        max_cross = std::max(max_cross, std::abs(s.pose_cov(i, 3 + j)) / std::sqrt(s.pose_cov(i, i) * s.pose_cov(3 + j, 3 + j)));
  }
  CHECK(max_cross > 0.1);  // a correlation coefficient
}

TEST_CASE("camera.time_offset_s moves the detections into the IMU clock", "[app][run]") {
  // The same recording with the camera clock 12.5 ms behind the IMU's and the offset declared in
  // roe.json runs exactly like the original.
  const Dataset d = test::simulate_preset("matched", 3, 6.0);
  Dataset late = d;
  const Timestamp shift = 12'500'000;
  for (auto& x : late.detections.at("sim")) x.t_ns -= shift;
  for (auto& f : late.frames) f.t_ns -= shift;
  REQUIRE(late.manifest.camera.has_value());
  late.manifest.camera->time_offset_s = 0.0125;
  const app::RunConfig config = test::plain_config();
  const app::RunOutput a = app::run_dataset(d, "", config), b = app::run_dataset(late, "", config);
  REQUIRE(a.reprojection.size() == b.reprojection.size());
  for (std::size_t k = 0; k < a.reprojection.size(); ++k) CHECK(b.reprojection[k].t_ns == a.reprojection[k].t_ns);
  REQUIRE(a.states.size() == b.states.size());
  CHECK((a.states.back().x.p_W_I - b.states.back().x.p_W_I).norm() < 1e-9);
  // Without the offset the same stamps are 12.5 ms early, and the result differs.
  late.manifest.camera->time_offset_s = 0.0;
  const app::RunOutput c = app::run_dataset(late, "", config);
  CHECK(c.reprojection.front().t_ns == a.reprojection.front().t_ns - shift);
  CHECK((a.states.back().x.p_W_I - c.states.back().x.p_W_I).norm() > 1e-6);
}

TEST_CASE("run.json's detection counts and NIS statistics agree with the reprojection rows", "[app][run]") {
  // PoET-like errors (5 % outliers) give χ² rejections as well as accepted detections; every 7th
  // detection gets a score below min_score, and the IMU stops a second before the camera.
  const fs::path ds = make_dataset("counts", 8.0, "paper-seq1");
  const fs::path out = temp_dir("counts_out");
  const auto rewrite = [](const fs::path& f, const std::function<bool(std::size_t, std::string&)>& keep) {
    std::stringstream in(slurp(f));
    std::ofstream o(f);
    std::size_t i = 0;
    for (std::string l; std::getline(in, l); ++i)
      if (i == 0 || keep(i, l)) o << l << "\n";
  };
  rewrite(ds / "detections" / "sim" / "detections.csv", [](std::size_t i, std::string& l) {
    if (i % 7 == 0) l = l.substr(0, l.rfind(',')) + ",0.25";
    return true;
  });
  std::size_t imu_rows = 0;
  rewrite(ds / "mav0" / "imu0" / "data.csv", [&](std::size_t, std::string&) { return ++imu_rows; });
  rewrite(ds / "mav0" / "imu0" / "data.csv", [&](std::size_t i, std::string&) { return i + 200 <= imu_rows; });
  // The joint gate: every NIS above the χ²₆ gate is a rejection (the split gate keeps parts of some).
  std::ofstream(out.string() + ".json") << R"({"filter": {"min_score": 0.5, "gate_mode": "joint"}})";
  app::RunOptions ro;
  ro.config_file = out.string() + ".json";
  const auto r = app::run(ds, out, ro);
  const io::json report = store::run_record_to_json(r.record);  // run.json's content
  {  // the file reads back through its one reader and writes back byte for byte
    std::ifstream in(out / "run.json");
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    CHECK(store::format_run_json(store::read_run_json(out / "run.json")) == text);
    CHECK(io::json::parse(text) == report);
  }
  const io::json& c = report.at("counts").at("detections");
  const auto rows = store::read_reprojection_csv(out / "reprojection.csv");  // the rows went into the file
  CHECK(c.at("detections").get<std::size_t>() == rows.size());
  const char* statuses[] = {"accepted",         "initialized",    "rejected_chi2", "rejected_no_main",
                            "rejected_score",   "rejected_no_imu", "pending_init"};
  std::size_t all = 0;
  for (const char* st : statuses) {
    std::size_t want = 0;
    for (const auto& x : rows) want += x.status == st ? 1 : 0;
    CHECK(c.at(st).get<std::size_t>() == want);
    std::size_t per = 0;
    for (const auto& kv : c.at("per_object").items()) per += kv.value().at(st).get<std::size_t>();
    CHECK(per == want);
    all += want;
  }
  CHECK(all == rows.size());
  for (const char* st : {"accepted", "rejected_chi2", "rejected_score", "rejected_no_imu"})
    CHECK(c.at(st).get<std::size_t>() > 0);
  // NIS: every gated detection's, against the 95 % χ²₆ gate.
  std::vector<double> nis;
  for (const auto& x : rows)
    if (std::isfinite(x.nis)) nis.push_back(x.nis);
  std::sort(nis.begin(), nis.end());
  const io::json& n = report.at("nis");
  REQUIRE(n.at("count").get<std::size_t>() == nis.size());
  REQUIRE(nis.size() > 20);
  double sum = 0.0;
  std::size_t above = 0;
  for (double x : nis) {
    sum += x;
    above += x > 12.591587 ? 1 : 0;
  }
  CHECK(n.at("gate").get<double>() == Approx(12.591587).epsilon(1e-6));
  CHECK(n.at("mean").get<double>() == Approx(sum / nis.size()).epsilon(1e-12));
  // Quantiles by linear interpolation between the order statistics (numpy's default).
  const auto q = [&](double p) {
    const double h = p * (nis.size() - 1);
    const std::size_t lo = static_cast<std::size_t>(h);
    return nis[lo] + (h - lo) * (nis[std::min(lo + 1, nis.size() - 1)] - nis[lo]);
  };
  CHECK(n.at("median").get<double>() == Approx(q(0.5)).epsilon(1e-12));
  CHECK(n.at("p25").get<double>() == Approx(q(0.25)).epsilon(1e-12));
  CHECK(n.at("p75").get<double>() == Approx(q(0.75)).epsilon(1e-12));
  CHECK(n.at("p95").get<double>() == Approx(q(0.95)).epsilon(1e-12));
  CHECK(n.at("max").get<double>() == nis.back());
  CHECK(n.at("median_ratio").get<double>() == Approx(q(0.5) / 5.348120627).epsilon(1e-8));
  CHECK(n.at("fraction_above_gate").get<double>() == Approx(static_cast<double>(above) / nis.size()).epsilon(1e-12));
  CHECK(above == c.at("rejected_chi2").get<std::size_t>());
  // The text summary names the rarer statuses with their counts when they occur.
  const std::string text = r.to_text();
  CHECK(text.find(fmt::format("rejected χ² {}", c.at("rejected_chi2").get<std::size_t>())) != std::string::npos);
  CHECK(text.find(fmt::format("below min_score {}", c.at("rejected_score").get<std::size_t>())) != std::string::npos);
  CHECK(text.find(fmt::format("outside the IMU stream {}", c.at("rejected_no_imu").get<std::size_t>())) !=
        std::string::npos);
  CHECK((text.find("awaiting initialisation") != std::string::npos) == (c.at("pending_init").get<std::size_t>() > 0));
  fs::remove_all(ds);
  fs::remove_all(out);
  fs::remove(out.string() + ".json");
}

// "smoother": "rts": trajectory.csv/.tum and states.csv hold the smoothed estimate (what roe eval reads),
// the filter's own estimate is kept in the *_filter files, byte for byte what a run without the
// smoother writes, and roe calib-check reads the filter's history, so its verdicts do not change.
TEST_CASE("roe run with the RTS smoother: smoothed outputs, the filter's in *_filter files", "[app][run][smoother]") {
  const fs::path ds = make_dataset("smoother", 12.0);
  const fs::path plain = temp_dir("smoother_plain"), smoothed = temp_dir("smoother_rts");
  const fs::path cfg = temp_dir("smoother_cfg.json");
  {
    std::ofstream(cfg) << R"({"smoother": "none"})";
  }
  app::RunOptions opt;
  const auto r = app::run(ds, smoothed, opt);  // the default is "rts"
  opt.config_file = cfg.string();
  app::run(ds, plain, opt);
  for (const char* f : {"trajectory_filter.csv", "trajectory_filter.tum", "states_filter.csv"}) {
    CHECK(fs::exists(smoothed / f));
    CHECK_FALSE(fs::exists(plain / f));
  }
  CHECK(slurp(smoothed / "trajectory_filter.csv") == slurp(plain / "trajectory.csv"));
  CHECK(slurp(smoothed / "trajectory_filter.tum") == slurp(plain / "trajectory.tum"));
  CHECK(slurp(smoothed / "states_filter.csv") == slurp(plain / "states.csv"));
  CHECK(slurp(smoothed / "trajectory.csv") != slurp(plain / "trajectory.csv"));
  CHECK(slurp(smoothed / "objects.csv") == slurp(plain / "objects.csv"));  // the filter's history
  const auto j = io::parse_json_file(smoothed / "run.json");
  // "estimator" replaced "smoother" (issue 48): the old key is read ("none" = "filter"), the new one written.
  CHECK(j.at("config").at("estimator") == "smoother");
  CHECK(io::parse_json_file(plain / "run.json").at("config").at("estimator") == "filter");
  CHECK_FALSE(j.at("config").contains("smoother"));
  CHECK(j.at("timing_s").at("smoother").get<double>() > 0.0);
  CHECK(j.at("counts").at("trajectory_rows").get<std::size_t>() == r.output.state_rows);
  // calib-check: the same checks with the same numbers on both runs.
  const auto ca = app::calib_check(plain, {}).to_json(), cb = app::calib_check(smoothed, {}).to_json();
  CHECK(ca.at("checks") == cb.at("checks"));
  // A bad value names the key.
  try {
    app::run_config_from_json(io::json::parse(R"({"smoother": "rtss"})"), "cfg.json");
    FAIL("no error");
  } catch (const ConfigError& e) {
    CHECK(std::string(e.what()).find("smoother") != std::string::npos);
  }
  for (const char* bad : {R"({"estimator": "rts"})", R"({"estimator": "filter", "smoother": "rts"})",
                          R"({"estimator": "smoother", "smoother": "none"})"})
    CHECK_THROWS_AS(app::run_config_from_json(io::json::parse(bad), "cfg.json"), ConfigError);
  CHECK(app::run_config_from_json(io::json::parse(R"({"estimator": "batch", "smoother": "rts"})"), "c").estimator == store::Estimator::kBatch);
  CHECK(app::run_config_from_json(io::json::parse(R"({"smoother": "rts"})"), "c").estimator == store::Estimator::kSmoother);
  for (const auto& p : {ds, plain, smoothed, cfg}) fs::remove_all(p);
}

TEST_CASE("run config: strict keys, shipped configs load, defaults round-trip", "[app][run]") {
  const std::string src = ROE_SOURCE_DIR;
  const app::RunConfig def = app::run_config_from_file(src + "/configs/default.json");
  const app::RunConfig paper = app::run_config_from_file(src + "/configs/paper.json");
  // configs/default.json is exactly the built-in defaults.
  auto a = app::run_config_to_json(def), b = app::run_config_to_json(app::RunConfig());
  a.erase("description");
  CHECK(a == b);
  CHECK(paper.filter.anchor_gauge == ekf::AnchorGauge::kPosition);
  CHECK(paper.filter.residual_frame == ekf::ResidualFrame::kObject);
  CHECK(paper.filter.init_min_detections == 3);  // the one departure from the paper (docs/filter.md §6)
  // Round trip.
  const auto j = app::run_config_to_json(paper);
  CHECK(app::run_config_to_json(app::run_config_from_json(j, "echo")) == j);
  // The field table echoes every key it loads, each once: a config that sets every key to a non-default
  // value comes back with those values.
  io::json every = app::run_config_to_json(app::RunConfig());
  every["filter"]["meas_sigma_p_m"] = 0.07;
  every["filter"]["init_gyro_bias"] = {0.01, 0.02, 0.03};
  every["filter"]["anchor_gauge"] = "pose";
  every["filter"]["gate_mode"] = "split";
  every["filter"]["pd_check_every"] = 7;
  every["health"]["max_dead_reckoning_s"] = 4.5;
  every["health"]["min_supported_fraction"] = 0.8;
  const app::RunConfig ev = app::run_config_from_json(every, "every");
  CHECK(ev.filter.meas_sigma_p_m == 0.07);
  CHECK(ev.filter.init_gyro_bias.z() == 0.03);
  CHECK(ev.filter.anchor_gauge == ekf::AnchorGauge::kPose);
  CHECK(ev.filter.gate_mode == ekf::GateMode::kSplit);
  CHECK(ev.filter.pd_check_every == 7);
  CHECK(ev.health.max_dead_reckoning_s == 4.5);
  CHECK(ev.health.min_supported_fraction == 0.8);
  CHECK(app::run_config_to_json(ev) == every);
  CHECK(every.at("filter").size() == 53);  // every FilterOptions field (configs/default.json lists them all)
  CHECK(every.at("health").size() == 4);
  // The health limits are strict too, and their errors name the key path.
  for (const char* bad : {R"({"health": {"min_supported_fraction": 1.5}})", R"({"health": {"max_nis_median_ratio": -1}})",
                          R"({"health": {"support_window_s": -0.5}})", R"({"health": {"max_dead_reckonin_s": 3}})"}) {
    INFO(bad);
    try {
      app::run_config_from_json(io::json::parse(bad), "cfg.json");
      FAIL("accepted");
    } catch (const ConfigError& e) {
      CHECK(e.context().file == "cfg.json");
      CHECK(e.context().key.rfind("health.", 0) == 0);
    }
  }
  // Unknown keys and bad values are ConfigErrors naming the key.
  CHECK_THROWS_AS(app::run_config_from_json(io::json::parse(R"({"filter": {"chi2_confidense": 0.9}})"), "x"),
                  ConfigError);
  CHECK_THROWS_AS(app::run_config_from_json(io::json::parse(R"({"filtr": {}})"), "x"), ConfigError);
  CHECK_THROWS_AS(app::run_config_from_json(io::json::parse(R"({"filter": {"chi2_confidence": 1.5}})"), "x"),
                  ConfigError);
  CHECK_THROWS_AS(app::run_config_from_json(io::json::parse(R"({"filter": {"anchor_gauge": "yaw"}})"), "x"),
                  ConfigError);
  // The ray-aligned σ: a zero σ along the ray, or σ of T_C_O on the paper's T_O_C axes, are refused.
  CHECK_THROWS_AS(app::run_config_from_json(io::json::parse(R"({"filter": {"meas_sigma_ray_m": 0, "meas_sigma_ray_per_depth": 0}})"), "x"),
                  ConfigError);
  CHECK_THROWS_AS(app::run_config_from_json(
                      io::json::parse(R"({"filter": {"residual_frame": "object", "meas_sigma_in_camera": false,
                                                     "meas_sigma_ray_m": 0.05}})"),
                      "x"),
                  ConfigError);
  CHECK_THROWS_AS(app::run_config_from_json(io::json::parse(R"({"filter": {"init_rest_max_gyro_std": 0}})"), "x"),
                  ConfigError);
  CHECK_THROWS_AS(
      app::run_config_from_json(io::json::parse(R"({"filter": {"init_gyro_bias_from_rest": "yes"}})"), "x"),
      ConfigError);
  CHECK(app::run_config_from_file(src + "/configs/euroc-flight.json").filter.init_gyro_bias_from_rest);
  CHECK(app::run_config_from_json(io::json::parse(R"({"filter": {"meas_sigma_ray_m": 0.05}})"), "x")
            .filter.meas_sigma_ray_m == 0.05);
  try {
    app::run_config_from_json(io::json::parse(R"({"filter": {"meas_sigma_p_m": -1}})"), "cfg.json");
    FAIL("no error");
  } catch (const ConfigError& e) {
    CHECK(std::string(e.what()).find("filter.meas_sigma_p_m") != std::string::npos);
    CHECK(std::string(e.what()).find("cfg.json") != std::string::npos);
  }
}

TEST_CASE("bad input gives clear errors", "[app][run]") {
  const fs::path ds = make_dataset("bad", 4.0);
  const fs::path out = temp_dir("bad_out");
  app::RunOptions opt;
  opt.force = true;
  const fs::path det = ds / "detections" / "sim" / "detections.csv";
  const std::string det_text = slurp(det);

  SECTION("no IMU") {
    fs::remove(ds / "mav0" / "imu0" / "data.csv");
    try {
      app::run(ds, out, opt);
      FAIL("no error");
    } catch (const InputError& e) {
      // Over many sequences the message must say which dataset: the file is named with the dataset's path.
      CHECK(e.context().file == (ds / "mav0/imu0/data.csv").string());
      CHECK_THAT(e.what(), Catch::StartsWith((ds / "mav0/imu0/data.csv").string() + ": the dataset has no usable IMU"));
    }
  }
  SECTION("unsorted IMU stamps") {
    const fs::path imu = ds / "mav0" / "imu0" / "data.csv";
    std::string s = slurp(imu);
    // Swap the 3rd and 4th data lines.
    std::vector<std::string> lines;
    std::stringstream ss(s);
    for (std::string l; std::getline(ss, l);) lines.push_back(l);
    std::swap(lines[3], lines[4]);
    std::ofstream o(imu);
    for (const auto& l : lines) o << l << "\n";
    o.close();
    try {
      app::run(ds, out, opt);
      FAIL("no error");
    } catch (const InputError& e) {
      CHECK(std::string(e.what()).find("imu0") != std::string::npos);
      CHECK(e.context().line == 5);
    }
  }
  SECTION("detection of an unknown object id") {
    const auto first_nl = det_text.find('\n');
    const auto second_comma = det_text.find(',', det_text.find(',', first_nl) + 1);
    std::string s = det_text;
    s.replace(det_text.find(',', first_nl) + 1, second_comma - det_text.find(',', first_nl) - 1, "99");
    std::ofstream(det) << s;
    try {
      app::run(ds, out, opt);
      FAIL("no error");
    } catch (const InputError& e) {
      CHECK(std::string(e.what()).find("unknown object id 99") != std::string::npos);
      CHECK(e.context().file == (ds / "detections/sim/detections.csv").string());
      CHECK(e.context().line == 2);
    }
  }
  SECTION("NaN in a detection row") {
    const auto first_nl = det_text.find('\n');
    std::string s = det_text;
    const auto c3 = s.find(',', s.find(',', s.find(',', first_nl) + 1) + 1);  // before ty
    const auto c4 = s.find(',', c3 + 1);
    s.replace(c3 + 1, c4 - c3 - 1, "nan");
    std::ofstream(det) << s;
    CHECK_THROWS_AS(app::run(ds, out, opt), InputError);
  }
  SECTION("the configured anchor is never detected") {
    // Object 2 is declared in roe.json but never detected.
    const fs::path manifest = ds / "roe.json";
    auto j = io::parse_json_file(manifest);
    j["objects"].push_back({{"id", 2}, {"name", "obj_2"}, {"symmetric", false}});
    std::ofstream(manifest) << j.dump(2);
    const fs::path cfg = temp_dir("cfg.json");
    std::ofstream(cfg) << R"({"filter": {"anchor_id": 2}})";
    opt.config_file = cfg.string();
    try {
      app::run(ds, out, opt);
      FAIL("no error");
    } catch (const DataError& e) {
      CHECK(std::string(e.what()).find("anchor object 2 is never detected") != std::string::npos);
      CHECK(e.context().file == (ds / "detections/sim/detections.csv").string());
    }
    // An anchor that is no object of the dataset: the config file is named.
    std::ofstream(cfg) << R"({"filter": {"anchor_id": 7}})";
    try {
      app::run(ds, out, opt);
      FAIL("no error");
    } catch (const ConfigError& e) {
      CHECK(e.context().file == cfg.string());
      CHECK(e.context().key == "filter.anchor_id");
    }
    fs::remove(cfg);
  }
  SECTION("no detections at all") {
    std::ofstream(det) << det_text.substr(0, det_text.find('\n') + 1);  // header only
    try {
      app::run(ds, out, opt);
      FAIL("no error");
    } catch (const DataError& e) {
      CHECK(std::string(e.what()).find("has no detections") != std::string::npos);
      CHECK(e.context().file == (ds / "detections/sim/detections.csv").string());
    }
  }
  CHECK_FALSE(fs::exists(out / "trajectory.csv"));  // nothing half-written
  fs::remove_all(ds);
  fs::remove_all(out);
}

// Real IMU (EuRoC V1_02, ADIS16448) with synthetic detections of 4 objects (docs/RESULTS.md §5).
namespace {

// roe eval's pipeline on state rows of a run of the EuRoC snippet: nearest association within 10 ms,
// SE(3) Umeyama alignment and APE over every matched row of the whole recording. Returns the worst axis
// (m, deg).
std::pair<double, double> euroc_worst_axis(const Dataset& d, const std::vector<app::RecordedState>& states,
                                           std::uint64_t seed, const char* what) {
  std::vector<Timestamp> t_est, t_gt;
  std::vector<Pose> est_all, gt_all;
  for (const auto& st : states) {
    t_est.push_back(st.t_ns);
    est_all.push_back(Pose(st.x.q_W_I, st.x.p_W_I));
  }
  for (const auto& g : d.groundtruth) {
    t_gt.push_back(g.t_ns);
    gt_all.push_back(g.T_W_I);
  }
  const eval::Association a = eval::associate(t_est, t_gt);  // roe eval's defaults
  std::vector<Pose> est, gt;
  for (std::size_t k = 0; k < a.size(); ++k) {
    est.push_back(est_all[a.est_index[k]]);
    gt.push_back(gt_all[a.gt_index[k]]);
  }
  const eval::Alignment al = eval::compute_alignment(eval::AlignType::kSe3, est, gt);
  eval::apply_alignment(al, est);
  const eval::ApeResult ape = eval::compute_ape(est, gt);
  WARN("EuRoC real IMU, " << what << ", seed " << seed << ": " << a.size() << " matched rows (whole run); position RMSE "
                               << ape.pos_rmse_m.transpose() << " m; Euler RMSE " << ape.rpy_rmse_deg.transpose()
                               << " deg");
  // Every ground-truth row inside the IMU span is matched (40 Hz ground truth, 39 s overlap).
  CHECK(a.size() >= 1500);
  return {ape.pos_rmse_m.maxCoeff(), ape.rpy_rmse_deg.maxCoeff()};
}

std::pair<double, double> euroc_worst_axis(const Dataset& d, const app::RunConfig& cfg, std::uint64_t seed) {
  const app::RunOutput r = app::run_dataset(d, "sim", cfg);
  return euroc_worst_axis(d, r.states, seed, cfg.smoothed() ? "smoothed" : "filter");
}

app::RunConfig euroc_flight_config() {
  const app::RunConfig cfg = app::run_config_from_file(std::string(ROE_SOURCE_DIR) + "/configs/euroc-flight.json");
  REQUIRE_FALSE(cfg.filter.require_anchor);
  REQUIRE(cfg.filter.meas_sigma_ray_m > 0.0);
  return cfg;
}

}  // namespace

TEST_CASE("real IMU: EuRoC snippet with 4 objects", "[app][run][euroc]") {
  const fs::path mav0 = fs::path(ROE_SHARED_DATA_DIR) / "euroc_v102_snippet" / "mav0";
  if (!fs::exists(mav0)) {
    WARN("skipped: " << mav0 << " absent");
    return;
  }
  // The acceptance pipeline, in memory: roe simulate --from-groundtruth mav0 --objects 4 --seed S →
  // roe run --config configs/euroc-flight.json → roe eval, seeds 1–5. configs/euroc-flight.json is
  // roe's defaults with require_anchor false (the anchor is in view in ~30 % of the frames), the
  // ADIS16448's in-flight noise densities (docs/simulator.md §9), the ray-aligned, depth-dependent
  // detection σ (docs/filter.md §3) and the gyro bias from the init window at rest (docs/filter.md §4).
  // The config also smooths ("smoother": "rts", docs/filter.md §10). Target ≤ 0.10 m and ≤ 5° per axis
  // on every seed, for the smoothed estimate (what trajectory.csv holds): measured worst axis 0.036,
  // 0.084, 0.061, 0.040, 0.057 m and 1.7, 3.3, 1.0, 2.5, 0.7° (docs/RESULTS.md §5). The filter's own
  // causal estimate (trajectory_filter.csv) does not meet the position target with the simulator's
  // PoET-like errors (0.3 s correlated): 0.108, 0.152, 0.194, 0.111, 0.118 m and 2.7, 2.6, 4.0, 3.7,
  // 1.7°; its bounds below guard it against regressions.
  const app::RunConfig cfg = euroc_flight_config();
  REQUIRE(cfg.estimator == store::Estimator::kSmoother);
  std::vector<double> worst_p, worst_r;
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    app::SimulateOptions so;
    so.from_groundtruth = mav0.string();
    so.objects = 4;
    so.seed = seed;
    const Dataset d = app::simulate_dataset(so).dataset;
    const app::RunOutput r = app::run_dataset(d, "sim", cfg);
    const auto s = euroc_worst_axis(d, r.states, seed, "smoothed");
    CHECK(s.first <= 0.10);  // the issue's target, every seed
    CHECK(s.second <= 5.0);
    const auto f = euroc_worst_axis(d, r.filter_states, seed, "filter");
    worst_p.push_back(f.first);
    worst_r.push_back(f.second);
  }
  std::sort(worst_p.begin(), worst_p.end());
  std::sort(worst_r.begin(), worst_r.end());
  CHECK(worst_r.back() <= 5.0);  // every seed
  CHECK(worst_p[2] <= 0.13);     // median over the seeds (target 0.10: not met by the causal filter)
  CHECK(worst_p.back() <= 0.21);
}

namespace {

using DetectionNoiseConfigEdit = std::function<void(sim::DetectionNoiseConfig&)>;

// The issue's target (≤ 0.10 m per axis, ≤ 5°) on seeds 1–5 of the EuRoC snippet with 4 objects, the
// detection errors set by `errors`, and configs/euroc-flight.json.
void check_target_on_seeds_1_to_5(const DetectionNoiseConfigEdit& errors) {
  const auto snippet = test::load_euroc_snippet();
  if (!snippet) {
    WARN("skipped: ../shared/data/euroc_v102_snippet absent");
    return;
  }
  app::RunConfig cfg = euroc_flight_config();
  cfg.estimator = store::Estimator::kFilter;  // the causal filter: these bound the filter's own estimate
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    sim::FromGroundtruthConfig c;
    c.num_objects = 4;
    errors(c.detection);
    const sim::SimRun s = sim::simulate_from_groundtruth(snippet->imu, snippet->groundtruth, c, seed);
    const auto w = euroc_worst_axis(s.dataset, cfg, seed);
    CHECK(w.first <= 0.10);
    CHECK(w.second <= 5.0);
  }
}

}  // namespace

// The same recording with white Gaussian detection errors of the same σ (no time correlation, outliers,
// symmetric flips or blur): the issue's target holds on every seed (measured 0.043–0.068 m, 1.3–2.0°
// over seeds 1–5), so what separates the row above from it is the detector's error correlation.
TEST_CASE("real IMU: EuRoC snippet, white Gaussian detection errors: <= 0.10 m / 5 deg", "[app][run][euroc]") {
  check_target_on_seeds_1_to_5([](sim::DetectionNoiseConfig& d) {
    d.correlation_time_s = 0.0;
    d.outlier_prob = 0.0;
    d.symmetric_flip_prob = 0.0;
    d.blur_rate_threshold_deg_s = 0.0;
    d.blur_frame_prob = 0.0;
  });
}

// Every PoET-like effect on (σ, 5 % outliers, symmetric flips, blur) but the errors correlated over one
// frame interval (τ = 0.033 s instead of 0.3 s): the target holds on every seed (measured 0.061–0.087 m,
// 1.2–2.3° over seeds 1–5; docs/RESULTS.md §5 has the sweep over τ). A regression in the filter's
// handling of outliers, flips or blur shows here even though the τ = 0.3 s test above has looser bounds.
TEST_CASE("real IMU: EuRoC snippet, PoET-like errors correlated over one frame: <= 0.10 m / 5 deg",
          "[app][run][euroc]") {
  check_target_on_seeds_1_to_5([](sim::DetectionNoiseConfig& d) {
    REQUIRE(d.outlier_prob > 0.0);
    REQUIRE(d.symmetric_flip_prob > 0.0);
    REQUIRE(d.blur_rate_threshold_deg_s > 0.0);
    d.correlation_time_s = 1.0 / 30.0;
  });
}

// init_gyro_bias_from_rest on real data: the ADIS16448 of EuRoC V1_02 stands on the ground for the
// first ~3.5 s with a gyro bias of (−0.002, 0.021, 0.076) rad/s (the ground truth's b_w), 7.6 times
// the default init_sigma_gyro_bias about z. The 0.2 s window's gyro mean recovers it.
TEST_CASE("real IMU: the gyro bias at rest from the init window matches the ground truth's", "[app][run][euroc]") {
  const auto snippet = test::load_euroc_snippet();
  if (!snippet) {
    WARN("skipped: ../shared/data/euroc_v102_snippet absent");
    return;
  }
  sim::FromGroundtruthConfig c;
  c.num_objects = 4;
  const sim::SimRun s = sim::simulate_from_groundtruth(snippet->imu, snippet->groundtruth, c, 1);
  const app::RunOutput r = app::run_dataset(s.dataset, "sim", euroc_flight_config());
  REQUIRE(r.summary.gyro_bias_from_rest);
  const Eigen::Vector3d b_w_truth = snippet->groundtruth.front().b_g;
  INFO("rest estimate " << r.summary.init_gyro_bias.transpose() << ", ground truth " << b_w_truth.transpose());
  CHECK((r.summary.init_gyro_bias - b_w_truth).cwiseAbs().maxCoeff() < 2e-3);
  CHECK(r.summary.init.std_gyro.maxCoeff() < 0.005);  // at rest: the sensor's own noise
  for (const auto& w : r.warnings) CHECK(w.find("init_gyro_bias_from_rest") == std::string::npos);
}

TEST_CASE("detections outside the IMU stream are skipped, counted and named in a warning", "[app][run]") {
  Dataset d = test::simulate_preset("matched", 3, 6.0);
  // The IMU ends a second before the camera does.
  const Timestamp imu_end = d.imu.back().t_ns - kNsPerSecond;
  d.imu.erase(std::remove_if(d.imu.begin(), d.imu.end(), [&](const ImuSample& s) { return s.t_ns > imu_end; }),
              d.imu.end());
  d.groundtruth.erase(std::remove_if(d.groundtruth.begin(), d.groundtruth.end(),
                                     [&](const ImuState& s) { return s.t_ns > imu_end; }),
                      d.groundtruth.end());
  std::size_t late = 0;
  for (const auto& x : d.detections.at("sim")) late += x.t_ns > imu_end ? 1 : 0;
  REQUIRE(late > 10);
  const app::RunOutput r = app::run_dataset(d, "sim", test::plain_config());
  std::size_t skipped = 0;
  for (const auto& kv : r.summary.counts) skipped += kv.second.rejected_no_imu;
  CHECK(skipped == late);
  const std::string want = std::to_string(late) + " detections lie outside the IMU stream and were skipped";
  CHECK(std::count(r.warnings.begin(), r.warnings.end(), want) == 1);
  // None when all lie inside.
  const app::RunOutput inside = app::run_dataset(test::simulate_preset("matched", 3, 6.0), "sim", test::plain_config());
  for (const auto& w : inside.warnings) CHECK(w.find("outside the IMU stream") == std::string::npos);
}

TEST_CASE("init_gyro_bias_from_rest on a recording that starts moving: refused, said in the summary, no warning",
          "[app][run]") {
  // The simulator's handheld presets move from the first sample (orbit and shake).
  const Dataset d = test::simulate_preset("paper-seq4", 1, 3.0);
  app::RunConfig cfg = test::plain_config();
  cfg.filter.init_gyro_bias_from_rest = true;
  cfg.filter.init_gyro_bias = Eigen::Vector3d(1e-3, -1e-3, 2e-3);
  const app::RunOutput r = app::run_dataset(d, "sim", cfg);
  CHECK_FALSE(r.summary.gyro_bias_from_rest);
  CHECK(r.summary.init_gyro_bias == cfg.filter.init_gyro_bias);
  CHECK(r.summary.gyro_bias_rest_refused.find("the gyro moves in the init window") != std::string::npos);
  // The default asks for the bias from rest, and handheld recordings start moving: not worth a warning.
  for (const auto& w : r.warnings) CHECK(w.find("init_gyro_bias_from_rest") == std::string::npos);
}

// With the paper's rule (require_anchor), a recording whose camera often leaves the anchor wastes most of
// its detections: roe run says how many, and names the switch. Not said when the anchor is in almost
// every image, nor when the rule is off.
TEST_CASE("a warning when require_anchor rejects a quarter or more of the detections", "[app][run]") {
  const Dataset d = test::simulate_preset("paper-seq4", 2, 20.0);
  const auto warned = [](const app::RunOutput& r) {
    return std::count_if(r.warnings.begin(), r.warnings.end(), [](const std::string& w) {
      return w.find("because their image lacks the anchor object") != std::string::npos;
    });
  };
  // The share of detections rejected_no_main in images without the anchor (those in images with the
  // anchor before it is initialised are another cause, counted apart).
  const auto rejected_share = [](const app::RunOutput& r, int anchor) {
    std::size_t no_anchor = 0, all = 0;
    std::map<Timestamp, bool> has_anchor;
    for (const auto& p : r.reprojection)
      has_anchor[p.t_ns] |= p.object_id == anchor && (p.outcome.status == ekf::DetectionStatus::kPendingInit ||
                                                      p.outcome.status == ekf::DetectionStatus::kInitialized);
    for (const auto& p : r.reprojection) {
      ++all;
      no_anchor += p.outcome.status == ekf::DetectionStatus::kRejectedNoMain && !has_anchor[p.t_ns];
    }
    return static_cast<double>(no_anchor) / static_cast<double>(all);
  };
  // The anchor roe picks by default (the first seen) against each object in turn.
  std::map<int, double> share;
  for (const auto& o : d.manifest.objects) {
    app::RunConfig cfg = test::plain_config();
    cfg.filter.anchor_id = o.id;
    const app::RunOutput r = app::run_dataset(d, "sim", cfg);
    share[o.id] = rejected_share(r, o.id);
    INFO("anchor " << o.id << ": " << 100.0 * share[o.id] << " % rejected without the anchor");
    CHECK(warned(r) == (share[o.id] >= 0.25 ? 1 : 0));
    if (share[o.id] >= 0.25) {
      cfg.filter.require_anchor = false;
      CHECK(warned(app::run_dataset(d, "sim", cfg)) == 0);
    }
  }
  // Both cases occur in this recording.
  CHECK(std::any_of(share.begin(), share.end(), [](const auto& kv) { return kv.second >= 0.25; }));
  CHECK(std::any_of(share.begin(), share.end(), [](const auto& kv) { return kv.second < 0.25; }));
}

// roe.json's IMU noise: absent = unknown (an error naming the key unless the config sets it), 0 = a
// noise-free IMU (allowed, with a warning); run.json records the values used and where each came from.
TEST_CASE("IMU noise: unknown in roe.json is an error, 0 a warning, the values used are in run.json", "[app][run]") {
  Dataset d = test::simulate_preset("matched", 3, 3.0);
  app::RunConfig cfg = test::plain_config();
  {
    const app::RunOutput r = app::run_dataset(d, "sim", cfg);
    CHECK(r.imu_noise.gyro_noise_density == d.manifest.imu->noise.gyro_noise_density);
    CHECK(r.imu_noise.accel_random_walk == d.manifest.imu->noise.accel_random_walk);
    CHECK(r.imu_noise_from == std::array<std::string, 4>{"dataset", "dataset", "dataset", "dataset"});
    for (const auto& w : r.warnings) CHECK(w.find("IMU noise") == std::string::npos);
  }
  // The config wins where it gives a value; imu_noise_scale applies to both sources.
  cfg.filter.accel_noise_density = 0.05;
  cfg.filter.imu_noise_scale = 2.0;
  {
    const app::RunOutput r = app::run_dataset(d, "sim", cfg);
    CHECK(r.imu_noise.accel_noise_density == 0.1);
    CHECK(r.imu_noise.gyro_noise_density == 2.0 * d.manifest.imu->noise.gyro_noise_density);
    CHECK(r.imu_noise_from == std::array<std::string, 4>{"dataset", "dataset", "config", "dataset"});
  }
  // Unknown in roe.json (as `roe import realsense` leaves it) and not in the config: refused, key named.
  cfg = test::plain_config();
  d.manifest.imu->noise.gyro_random_walk = -1.0;
  try {
    app::run_dataset(d, "sim", cfg);
    FAIL("no error");
  } catch (const ConfigError& e) {
    CHECK_THAT(e.what(), Catch::Contains("imu.gyro_random_walk") && Catch::Contains("filter.gyro_random_walk"));
  }
  cfg.filter.gyro_random_walk = 1e-5;
  CHECK_NOTHROW(app::run_dataset(d, "sim", cfg));
  // 0 is a noise-free IMU: used as given, with a warning.
  d.manifest.imu->noise.gyro_noise_density = 0.0;
  const app::RunOutput z = app::run_dataset(d, "sim", cfg);
  CHECK(z.imu_noise.gyro_noise_density == 0.0);
  CHECK(std::count_if(z.warnings.begin(), z.warnings.end(), [](const std::string& w) {
          return w.find("IMU noise density 0 (gyro 0, accel") == 0 && w.find("from the dataset") != std::string::npos;
        }) == 1);
}

TEST_CASE("run.json records the IMU noise the filter used", "[app][run]") {
  const fs::path ds = make_dataset("noise_json", 3.0);
  const fs::path out = temp_dir("noise_json_out");
  app::RunOptions opt;
  const fs::path cfg = temp_dir("noise_json_cfg.json");
  std::ofstream(cfg) << R"({"filter": {"gyro_noise_density": 0.002, "imu_noise_scale": 1}})";
  opt.config_file = cfg.string();
  app::run(ds, out, opt);
  const auto j = io::parse_json_file(out / "run.json");
  const auto& n = j.at("imu_noise");
  CHECK(n.at("gyro_noise_density") == 0.002);
  CHECK(n.at("from").at("gyro_noise_density") == "config");
  CHECK(n.at("from").at("accel_noise_density") == "dataset");
  const auto m = store::read_manifest(ds);
  CHECK(n.at("accel_noise_density") == m.imu->noise.accel_noise_density);
  fs::remove_all(ds);
  fs::remove_all(out);
  fs::remove(cfg);
}

// A RealSense import declares no objects; `roe import poet` / `roe infer` then write the detector's class
// ids. roe run takes the detections' ids (warning); a dataset that declares objects still refuses others.
TEST_CASE("a dataset that declares no objects runs on the ids of its detections, with a warning", "[app][run]") {
  Dataset d = test::simulate_preset("matched", 3, 3.0);
  const app::RunOutput ref = app::run_dataset(d, "sim", {});
  std::set<int> ids;
  for (const auto& det : d.detections.at("sim")) ids.insert(det.object_id);
  d.manifest.objects.clear();
  const app::RunOutput r = app::run_dataset(d, "sim", {});
  CHECK(r.states.size() == ref.states.size());
  CHECK(r.states.back().x.p_W_I == ref.states.back().x.p_W_I);  // the same run
  CHECK(std::count(r.warnings.begin(), r.warnings.end(),
                   fmt::format("roe.json declares no objects: using the {} object id(s) of "
                               "detections/sim/detections.csv ({})",
                               ids.size(), fmt::join(ids, ", "))) == 1);
  for (const auto& w : ref.warnings) CHECK(w.find("declares no objects") == std::string::npos);
  // Declared objects that miss one of the detected ids: refused.
  d.manifest.objects.push_back({*ids.begin(), "x", false, "", -1, {}});
  CHECK_THROWS_WITH(app::run_dataset(d, "sim", {}), Catch::Contains("detection of unknown object id"));
}

// Why an object was never initialised, and rejections before the anchor's initialisation, are told
// apart from images that lack the anchor.
TEST_CASE("never-initialised objects and rejected_no_main: the warnings name the real cause", "[app][run]") {
  const Dataset d = test::simulate_preset("paper-seq4", 1, 0.01);  // one image, four objects
  const app::RunOutput r = app::run_dataset(d, "sim", test::plain_config());  // the anchor rule
  REQUIRE(r.reprojection.size() == 4);
  const int anchor = r.reprojection.front().object_id;  // the lowest id of the first image
  std::size_t n = 0;
  for (const auto& w : r.warnings) {
    INFO(w);
    CHECK(w.find("lacks the anchor") == std::string::npos);  // the anchor is in the image
    if (w.find("never initialised") == std::string::npos) continue;
    ++n;
    if (w.find(fmt::format("object {} ", anchor)) == 0)
      CHECK_THAT(w, Catch::EndsWith("never initialised: 1 awaited initialisation (3 agreeing consecutive "
                                    "detections needed, init_min_detections)"));
    else
      CHECK_THAT(w, Catch::EndsWith("never initialised: 1 had no initialised anchor in their image"));
  }
  CHECK(n == 4);
  // Over a longer run with the anchor often out of view, the count of rejections before the anchor's
  // initialisation is named beside the main warning.
  const Dataset d2 = test::simulate_preset("paper-seq4", 2, 20.0);
  std::size_t main_warnings = 0;
  for (const auto& o : d2.manifest.objects) {
    app::RunConfig cfg = test::plain_config();
    cfg.filter.anchor_id = o.id;
    const app::RunOutput r2 = app::run_dataset(d2, "sim", cfg);
    for (const auto& w : r2.warnings)
      if (w.find("lacks the anchor") != std::string::npos) {
        INFO(w);
        CHECK_THAT(w, Catch::Contains("more were in images with the anchor, before it was initialised)"));
        ++main_warnings;
      }
  }
  CHECK(main_warnings >= 1);
}

TEST_CASE("an anchor detection below min_score leaves its image without a usable anchor", "[app][run]") {
  Dataset d = test::simulate_preset("paper-seq4", 1, 3.0);
  auto& dets = d.detections.at("sim");
  app::RunConfig cfg = test::plain_config();
  cfg.filter.anchor_id = dets.front().object_id;
  cfg.filter.min_score = 0.5;
  for (auto& det : dets) det.score = det.object_id == cfg.filter.anchor_id ? 0.1 : 0.9;
  const app::RunOutput r = app::run_dataset(d, "sim", cfg);
  std::size_t others = 0;
  for (const auto& det : dets) others += det.object_id != cfg.filter.anchor_id;
  const std::string expect = fmt::format("{} of {} detections", others, dets.size());
  std::size_t n = 0;
  for (const auto& w : r.warnings)
    if (w.find("lacks the anchor") != std::string::npos) {
      INFO(w);
      ++n;
      CHECK(w.rfind(expect, 0) == 0);  // every other detection: its image has no usable anchor
      CHECK(w.find("more were in images with the anchor") == std::string::npos);
    }
  CHECK(n == 1);
}
