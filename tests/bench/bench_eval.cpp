// Benchmark of roe eval: a 1,000,000-pose pair (ground truth as EuRoC csv in ns, estimate as TUM in
// seconds, 200 Hz, 5000 s), written by the small generator below, evaluated end to end (parsing,
// association, SE(3) Umeyama, APE metrics), with and without writing the output files.
//   bench_eval [N=1000000] [DIR=/tmp/roe_bench_eval] [keep]
// With `keep` the pair is left in DIR (and reused by the next run with the same N), so that whole-process
// timings (`roe eval DIR/est.tum --gt DIR/gt.csv --no-out`) and old/new binaries read the same files.
#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <string>

#include "roe/app/eval.hpp"
#include "roe/io/output.hpp"
#include "roe/io/trajectory_io.hpp"
#include "roe/math/euler.hpp"

using namespace roe;
namespace fs = std::filesystem;

namespace {
double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
/// CPU time of this process (s): on a shared machine the wall time also counts other processes.
double cpu() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }
}  // namespace

int main(int argc, char** argv) {
  const long n = argc > 1 ? std::atol(argv[1]) : 1000000;
  const fs::path dir = argc > 2 ? fs::path(argv[2]) : fs::temp_directory_path() / "roe_bench_eval";
  const bool keep = argc > 3 && std::string(argv[3]) == "keep";
  const fs::path stamp = dir / fmt::format("n{}", n);  // marks a complete pair of this size
  const bool reuse = keep && fs::exists(stamp);
  if (!reuse) {
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  // Generator: a smooth 3D path; the estimate is in another world (yaw 30°, shifted) with small
  // deterministic errors and its own stamps jittered by up to ±1 ms.
  double t0 = now();
  if (!reuse) {
    std::vector<Timestamp> tg(n), te(n);
    std::vector<Pose> pg(n), pe(n);
    const Pose T_E_G(Eigen::Quaterniond(math::from_euler_zyx(Eigen::Vector3d(0, 0, 0.5236))),
                     Eigen::Vector3d(1, 2, 3));
    for (long i = 0; i < n; ++i) {
      const double s = 0.005 * static_cast<double>(i);
      tg[i] = 1'600'000'000'000'000'000LL + 5'000'000LL * i;
      te[i] = tg[i] + ((i * 7919) % 2001 - 1000) * 1000LL;
      pg[i] = Pose(Eigen::Quaterniond(math::from_euler_zyx(
                       Eigen::Vector3d(0.1 * std::sin(s), 0.2 * std::cos(0.3 * s), 0.05 * s))),
                   Eigen::Vector3d(5 * std::cos(0.01 * s), 5 * std::sin(0.013 * s), std::sin(0.02 * s)));
      Pose e = T_E_G * pg[i];
      e.p += Eigen::Vector3d(0.01 * std::sin(1.7 * s), 0.01 * std::cos(2.3 * s), 0.005 * std::sin(0.7 * s));
      pe[i] = e;
    }
    io::write_trajectory(dir / "gt.csv", tg, pg, io::TrajectoryFormat::kEuroc);
    io::write_trajectory(dir / "est.tum", te, pe, io::TrajectoryFormat::kTum);
    io::write_file_atomic(stamp, "");
  }
  const double t_gen = now() - t0;
  std::printf("%s %ld + %ld poses in %.2f s (gt.csv %.0f MB, est.tum %.0f MB)\n",
              reuse ? "reused" : "generated", n, n, t_gen, fs::file_size(dir / "gt.csv") / 1e6, fs::file_size(dir / "est.tum") / 1e6);

  // Stages separately (wall; CPU of the process in brackets: single-threaded stages, so CPU is what an
  // idle core would take).
  t0 = now();
  double c0 = cpu();
  const io::Trajectory gt = io::read_trajectory(dir / "gt.csv");
  const double t_read_gt = now() - t0, c_read_gt = cpu() - c0;
  t0 = now();
  c0 = cpu();
  const io::Trajectory est = io::read_trajectory(dir / "est.tum");
  const double t_read_est = now() - t0, c_read_est = cpu() - c0;
  t0 = now();
  c0 = cpu();
  const eval::Association a = eval::associate(est.t_ns, gt.t_ns);
  const double t_assoc = now() - t0, c_assoc = cpu() - c0;
  std::vector<Pose> e, g;
  e.reserve(a.size());
  g.reserve(a.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    e.push_back(est.poses[a.est_index[k]]);
    g.push_back(gt.poses[a.gt_index[k]]);
  }
  t0 = now();
  c0 = cpu();
  const eval::Alignment al = eval::compute_alignment(eval::AlignType::kSe3, e, g);
  eval::apply_alignment(al, e);
  const double t_align = now() - t0, c_align = cpu() - c0;
  t0 = now();
  c0 = cpu();
  const eval::ApeResult ape = eval::compute_ape(e, g);
  const double t_metrics = now() - t0, c_metrics = cpu() - c0;
  std::printf("read gt %.3f s (%.3f CPU), read est %.3f s (%.3f CPU), associate %.3f s (%.3f CPU, %zu pairs), "
              "align %.3f s (%.3f CPU), metrics %.3f s (%.3f CPU)\n",
              t_read_gt, c_read_gt, t_read_est, c_read_est, t_assoc, c_assoc, a.size(), t_align, c_align,
              t_metrics, c_metrics);
  std::printf("APE rmse %.6f m, rot rmse %.6f deg\n", ape.trans_m.rmse, ape.rot_deg.rmse);

  // End to end through the app function (what `roe eval` runs).
  app::EvalOptions o;
  o.est = (dir / "est.tum").string();
  o.gt = (dir / "gt.csv").string();
  o.no_out = true;
  t0 = now();
  c0 = cpu();
  const auto r = app::run_eval(o);
  const double t_total = now() - t0, c_total = cpu() - c0;
  o.no_out = false;
  o.out = (dir / "out").string();
  t0 = now();
  c0 = cpu();
  app::run_eval(o);
  const double t_total_out = now() - t0, c_total_out = cpu() - c0;
  std::printf(
      "run_eval (parse + associate + align + metrics): %.3f s wall, %.3f s CPU; with all output files: "
      "%.3f s wall, %.3f s CPU; matched %zu\n",
      t_total, c_total, t_total_out, c_total_out, r.report.association.n_matched);
  fs::remove_all(dir / "out");
  if (!keep) fs::remove_all(dir);
  return 0;
}
