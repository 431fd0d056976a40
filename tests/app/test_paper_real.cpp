// The paper-real presets (docs/simulator.md §6b): paper-seqN's trajectories and objects with the
// failure modes of real PoET, calibrated so that configs/paper.json lands at the paper's Table I
// level (docs/RESULTS.md §7, scripts/calibrate-paper-real.py). This test guards the calibration on a
// subset: paper-real-seq1 and -seq4, seed 1, must stay above an error no mild preset reaches and
// below divergence.
#include <catch2/catch.hpp>
#include <string>

#include "../ekf/filter_support.hpp"
#include "roe/app/run.hpp"
#include "roe/math/so3.hpp"

using namespace roe;

TEST_CASE("paper-real presets: paper-seqN's scene with the failure modes switched on", "[app][simulate][paper-real]") {
  for (int s = 1; s <= 8; ++s) {
    const std::string real = "paper-real-seq" + std::to_string(s), mild = "paper-seq" + std::to_string(s);
    INFO(real);
    const sim::SimConfig r = app::sim_config_from_preset(real), m = app::sim_config_from_preset(mild);
    CHECK(r.name == real);
    CHECK_FALSE(app::preset_description(real).empty());
    const auto jr = app::sim_config_to_json(r), jm = app::sim_config_to_json(m);
    CHECK(jr.at("trajectory") == jm.at("trajectory"));
    CHECK(jr.at("objects") == jm.at("objects"));
    CHECK(jr.at("imu") == jm.at("imu"));
    CHECK(jr.at("detection") != jm.at("detection"));
    CHECK(r.detection.burst_start_prob > 0.0);  // runs of bad frames (the paper's dead-reckoning phases)
    CHECK(r.detection.flip_view_gain > 0.0);
  }
}

TEST_CASE("paper-real presets give paper-level errors with configs/paper.json, mild presets do not",
          "[app][run][sim][paper-real]") {
  // Worst-axis position RMSE, seed 1 (docs/RESULTS.md §7): paper-seq1/4 give 0.04 / 0.07 m,
  // paper-real-seq1/4 0.18 / 0.14 m (the paper: 0.163 / 0.157 m); the mild presets never exceed
  // 0.11 m (paper-seq6). Above 0.5 m a run is on its way to divergence.
  const app::RunConfig cfg = app::run_config_from_file(std::string(ROE_SOURCE_DIR) + "/configs/paper.json");
  auto worst = [&](const std::string& preset) {
    const Dataset d = test::simulate_preset(preset, 1, 60.0);
    const auto acc = test::accuracy(test::match(app::run_dataset(d, "sim", cfg), d));
    return acc.pos_rmse.maxCoeff();
  };
  for (int s : {1, 4}) {
    const double real = worst("paper-real-seq" + std::to_string(s));
    const double mild = worst("paper-seq" + std::to_string(s));
    INFO("seq" << s << ": paper-real " << real << " m, paper-seq " << mild << " m");
    CHECK(real > 0.12);
    CHECK(real < 0.5);
    CHECK(mild < 0.10);
  }
}

namespace {
// RMS of (error / written σ) over the detections of a simulated run that are not gross errors
// (pooled over the six axes), and the share of gross errors whose written σ is the failure σ.
struct SigmaStats {
  double rms = 0.0;
  double gross_inflated = 0.0;
  std::size_t gross = 0;
};
SigmaStats sigma_stats(const sim::SimRun& run) {
  const auto& dets = run.dataset.detections.at("sim");
  REQUIRE(dets.size() == run.labels.size());
  double acc = 0.0;
  std::size_t n = 0, inflated = 0, gross = 0;
  for (std::size_t i = 0; i < dets.size(); ++i) {
    const auto& d = dets[i];
    const auto& l = run.labels[i];
    REQUIRE(d.sigma);
    if (l.outlier || l.blurred || l.flipped) {
      ++gross;
      inflated += (*d.sigma)(0) >= 0.3 - 1e-12;
      continue;
    }
    Vector6d e;
    e << d.T_C_O.p - l.T_C_O_true.p, math::log_quat(l.T_C_O_true.q.conjugate() * d.T_C_O.q);
    acc += e.cwiseQuotient(*d.sigma).squaredNorm();
    n += 6;
  }
  return {std::sqrt(acc / static_cast<double>(n)), gross ? static_cast<double>(inflated) / gross : 0.0, gross};
}
}  // namespace

TEST_CASE("paper-real-seq4-sigma presets: the written σ relate to the true errors as configured",
          "[app][simulate][paper-real][sigma]") {
  // Errors are Gauss-Markov correlated over τ = 3 s, so 60 s carry only ~10 independent samples per
  // object and axis: ~240 over 4 objects × 6 axes, RMS known to ~5 % (1σ). Bounds of ±25 % (5σ)
  // separate the informative preset (RMS 1) from the overconfident one (RMS 2, scale 0.5).
  const auto informative = sim::simulate_run(app::sim_config_from_preset("paper-real-seq4-sigma"), 1);
  const auto over = sim::simulate_run(app::sim_config_from_preset("paper-real-seq4-overconfident"), 1);
  // Same name, so the same random streams: identical detections, only the written σ differ.
  const auto& di = informative.dataset.detections.at("sim");
  const auto& dov = over.dataset.detections.at("sim");
  REQUIRE(di.size() == dov.size());
  for (std::size_t i = 0; i < di.size(); ++i) REQUIRE(di[i].T_C_O.p == dov[i].T_C_O.p);
  const SigmaStats si = sigma_stats(informative), so = sigma_stats(over);
  INFO("informative: RMS " << si.rms << ", gross " << si.gross << " inflated " << si.gross_inflated
                           << "; overconfident: RMS " << so.rms << ", inflated " << so.gross_inflated);
  CHECK(si.rms == Approx(1.0).epsilon(0.25));
  CHECK(so.rms == Approx(2.0).epsilon(0.25));
  REQUIRE(si.gross > 50);
  CHECK(si.gross_inflated > 0.6);   // outliers and blur report 0.3 m (flips only a large rotation σ)
  CHECK(so.gross_inflated == 0.0);  // overconfident failures: the ordinary, small σ
  // Runs of bad frames are counted: stationary share 0.02 / (0.02 + 1/5) ≈ 9 % of the 1801 frames
  // (runs of 5 frames: ~330 independent units, share known to ~1.5 %).
  const auto& st = informative.stats;
  CHECK(st.bad_frames > 0.02 * st.frames);
  CHECK(st.bad_frames < 0.17 * st.frames);
  CHECK(st.bad_frame_detections > 0);
}
