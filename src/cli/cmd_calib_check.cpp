// roe calib-check RUN_DIR [--dataset DATASET | --no-dataset] [--strict] [thresholds]
#include <memory>

#include "command.hpp"
#include "roe/app/calib_check.hpp"

namespace roe::cli {
namespace {

struct CalibCheckArgs {
  std::string run_dir;
  app::CalibCheckOptions opt;
};

RunFn setup_calib_check(CLI::App& sub) {
  auto a = std::make_shared<CalibCheckArgs>();
  auto& t = a->opt.thresholds;
  sub.add_option("RUN_DIR", a->run_dir, "Run folder written by roe run (run.json, states.csv, objects.csv)")
      ->required();
  auto* ds = sub.add_option("--dataset", a->opt.dataset,
                            "Dataset for the truth and time-offset checks (default: the one named in run.json, "
                            "when it is still there)");
  sub.add_flag("--no-dataset", a->opt.no_dataset, "Only the checks that need the run folder alone")->excludes(ds);
  sub.add_flag("--strict", a->opt.strict, "Inconclusive checks fail too (exit 1); skipped ones (not applicable) do not");
  const auto pos = number_in("positive");
  sub.add_option("--max-sigma-p", t.max_sigma_p_m, "extrinsics.sigma: largest axis σ of p_I_C [m]")
      ->capture_default_str()
      ->check(pos)->group("Thresholds");
  sub.add_option("--max-sigma-rot", t.max_sigma_rot_deg, "extrinsics.sigma: largest axis σ of θ_I_C [deg]")
      ->capture_default_str()
      ->check(pos)->group("Thresholds");
  sub.add_option("--settle-fraction", t.settle_fraction,
                 "extrinsics.settled: the last fraction of the run examined (0, 1]")
      ->capture_default_str()
      ->check(number_in("fraction"))->group("Thresholds");
  sub.add_option("--settle-min", t.settle_min_s, "extrinsics.settled: … but at least this long [s]")
      ->capture_default_str()
      ->check(pos)->group("Thresholds");
  sub.add_option("--max-drift-p", t.max_drift_p_m, "extrinsics.settled: largest distance from the final p_I_C [m]")
      ->capture_default_str()
      ->check(pos)->group("Thresholds");
  sub.add_option("--max-drift-rot", t.max_drift_rot_deg,
                 "extrinsics.settled: largest angle from the final q_I_C [deg]")
      ->capture_default_str()
      ->check(pos)->group("Thresholds");
  sub.add_option("--confidence", t.confidence,
                 "the σ tests (extrinsics.prior, extrinsics.settled, truth.*) and the time offset's verdict")
      ->capture_default_str()
      ->check(number_in("confidence"))->group("Thresholds");
  sub.add_option("--max-object-sigma-p", t.max_object_sigma_p_m,
                 "objects.sigma: largest axis σ relative to the anchor [m]")
      ->capture_default_str()
      ->check(pos)->group("Thresholds");
  sub.add_option("--max-object-sigma-rot", t.max_object_sigma_rot_deg,
                 "objects.sigma: largest axis σ relative to the anchor [deg]")
      ->capture_default_str()
      ->check(pos)->group("Thresholds");
  sub.add_option("--max-err-p", t.max_err_p_m, "truth.extrinsics: position error [m]")
      ->capture_default_str()
      ->check(pos)->group("Thresholds");
  sub.add_option("--max-err-rot", t.max_err_rot_deg, "truth.extrinsics: rotation error [deg]")
      ->capture_default_str()
      ->check(pos)->group("Thresholds");
  sub.add_option("--max-object-err-p", t.max_object_err_p_m, "truth.objects: anchor-relative position error [m]")
      ->capture_default_str()
      ->check(pos)->group("Thresholds");
  sub.add_option("--max-object-err-rot", t.max_object_err_rot_deg,
                 "truth.objects: anchor-relative rotation error [deg]")
      ->capture_default_str()
      ->check(pos)->group("Thresholds");
  sub.add_option("--max-time-offset", t.max_time_offset_s,
                 "camera.time_offset: |estimated − declared| camera-IMU offset [s]")
      ->capture_default_str()
      ->check(pos)->group("Thresholds");
  sub.add_option("--time-offset-search", a->opt.time_offset.search_s,
                 "camera.time_offset: search the offset within ± this [s]")
      ->capture_default_str()
      ->check(CLI::Range(0.005, 1.0))->group("Thresholds");
  return [a]() {
    const auto r = app::calib_check(a->run_dir, a->opt);
    emit(r.to_json(), r.to_text());
    return r.exit_code();
  };
}

const Registrar reg_calib_check("", "calib-check",
                                "Check a run's self-calibration: extrinsics, object poses, time offset", 70,
                                &setup_calib_check);

}  // namespace
}  // namespace roe::cli
