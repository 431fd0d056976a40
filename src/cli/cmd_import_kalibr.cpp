// roe import kalibr CAMCHAIN [IMU_YAML] --into DATASET
#include <fmt/format.h>

#include <memory>
#include <optional>

#include "command.hpp"
#include "roe/app/import.hpp"

namespace roe::cli {
namespace {

struct KalibrArgs {
  std::string camchain, imu, dataset;
  app::ImportKalibrOptions opt;
};

RunFn setup_kalibr(CLI::App& sub) {
  auto a = std::make_shared<KalibrArgs>();
  sub.add_option("CAMCHAIN", a->camchain, "Kalibr camchain-imucam.yaml")->required();
  sub.add_option("IMU_YAML", a->imu, "Kalibr imu.yaml (noise densities and random walks)");
  sub.add_option("--into", a->dataset, "Dataset folder (roe.json is created when missing)")->required();
  sub.add_option("--camera", a->opt.camera, "Camera of the camchain to import")->capture_default_str();
  return [a]() {
    a->opt.force = globals().force;
    std::optional<std::filesystem::path> imu;
    if (!a->imu.empty()) imu = a->imu;
    const auto s = app::import_kalibr(a->camchain, imu, a->dataset, a->opt);
    std::string human = fmt::format("imported the Kalibr calibration of {} into {}\n", s.camera, s.dataset.string());
    human += fmt::format("  T_I_C (inverse of T_cam_imu): p=[{:.6f} {:.6f} {:.6f}] q_xyzw=[{:.6f} {:.6f} {:.6f} {:.6f}]\n",
                         s.T_I_C.p.x(), s.T_I_C.p.y(), s.T_I_C.p.z(), s.T_I_C.q.x(), s.T_I_C.q.y(), s.T_I_C.q.z(),
                         s.T_I_C.q.w());
    human += fmt::format("  timeshift_cam_imu {} s (t_imu = t_cam + shift)\n", s.timeshift_cam_imu);
    human += fmt::format("  intrinsics {}: {}x{} {} {}\n", s.intrinsics_written ? "written" : "NOT written", s.width,
                         s.height, s.camera_model, s.distortion_model);
    if (s.imu_noise)
      human += fmt::format("  IMU noise: gyro {} rad/s/sqrt(Hz), {} rad/s^2/sqrt(Hz); accel {} m/s^2/sqrt(Hz), {} m/s^3/sqrt(Hz)\n",
                           s.imu_noise->gyro_noise_density, s.imu_noise->gyro_random_walk,
                           s.imu_noise->accel_noise_density, s.imu_noise->accel_random_walk);
    if (s.created_manifest) human += "  created a new roe.json\n";
    emit(s.to_json(), human);
    return 0;
  };
}

const Registrar reg_kalibr("import", "kalibr",
                           "Import a Kalibr camera-IMU calibration (camchain-imucam.yaml, imu.yaml)", 30,
                           &setup_kalibr);

}  // namespace
}  // namespace roe::cli
