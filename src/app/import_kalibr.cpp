// roe import kalibr: Kalibr camchain-imucam.yaml (+ imu.yaml) → roe.json camera/imu priors + calib/.
#include <algorithm>
#include <cmath>
#include <map>

#include <fmt/format.h>

#include "roe/app/import.hpp"
#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/output.hpp"
#include "roe/io/pose_json.hpp"

namespace roe::app {

nlohmann::json ImportKalibrSummary::to_json() const {
  nlohmann::json j = {{"command", "import kalibr"},
                      {"dataset", dataset.string()},
                      {"camera", camera},
                      {"T_cam_imu", io::pose_to_json(T_cam_imu)},
                      {"T_I_C", io::pose_to_json(T_I_C)},
                      {"timeshift_cam_imu", timeshift_cam_imu},
                      {"camera_model", camera_model},
                      {"distortion_model", distortion_model},
                      {"intrinsics", intrinsics},
                      {"distortion_coeffs", distortion_coeffs},
                      {"resolution", {width, height}},
                      {"intrinsics_written", intrinsics_written},
                      {"created_manifest", created_manifest},
                      {"warnings", warnings}};
  if (imu_noise) {
    j["imu_noise"] = io::imu_noise_to_json(*imu_noise);
    j["imu_noise"]["update_rate"] = imu_rate_hz;
  }
  return j;
}

namespace {
bool has_distortion(const KalibrCamchain& c) {
  return c.distortion_model != "none" &&
         std::any_of(c.distortion_coeffs.begin(), c.distortion_coeffs.end(), [](double k) { return k != 0.0; });
}
}  // namespace

ImportKalibrSummary import_kalibr(const fs::path& camchain, const std::optional<fs::path>& imu_yaml,
                                  const fs::path& dataset, const ImportKalibrOptions& opt) {
  ImportKalibrSummary S;
  S.dataset = dataset;
  S.camera = opt.camera;
  // Validate everything before touching the dataset.
  const KalibrCamchain c = read_kalibr_camchain(camchain, opt.camera);
  std::optional<KalibrImu> imu;
  if (imu_yaml) imu = read_kalibr_imu(*imu_yaml);
  const fs::path calib_dir = dataset / "calib";
  const fs::path cam_out = calib_dir / "camchain-imucam.yaml", imu_out = calib_dir / "imu.yaml";
  io::refuse_special_output(cam_out, io::OutputKind::file);
  if (imu_yaml) io::refuse_special_output(imu_out, io::OutputKind::file);
  if (!opt.force && (io::path_exists(cam_out) || (imu_yaml && io::path_exists(imu_out))))
    throw InputError("the dataset already has a Kalibr calibration (use --force to replace it)",
                     {io::path_exists(cam_out) ? cam_out.string() : imu_out.string()});
  // The dataset is changed as one (calib files staged, roe.json last) under its lock.
  io::StagedFiles staged;
  begin_dataset_change(staged, dataset);
  std::error_code ec;
  if (!opt.force && (fs::exists(cam_out, ec) || (imu_yaml && fs::exists(imu_out, ec))))
    throw InputError("the dataset already has a Kalibr calibration (use --force to replace it)",
                     {fs::exists(cam_out, ec) ? cam_out.string() : imu_out.string()});
  bool created = false;
  DatasetManifest m = open_or_create_manifest(dataset, created);
  S.created_manifest = created;

  const Eigen::Matrix3d R = c.T_cam_imu.topLeftCorner<3, 3>();
  S.T_cam_imu = Pose(R, c.T_cam_imu.topRightCorner<3, 1>());
  S.T_I_C = S.T_cam_imu.inverse();  // x_C = T_cam_imu x_I  ⇒  T_I_C = T_cam_imu⁻¹
  S.timeshift_cam_imu = c.timeshift_cam_imu;
  S.camera_model = c.camera_model;
  S.distortion_model = c.distortion_model;
  S.intrinsics = c.intrinsics;
  S.distortion_coeffs = c.distortion_coeffs;
  S.width = c.width;
  S.height = c.height;

  CameraInfo cam = m.camera.value_or(CameraInfo{});
  const bool have_camera = m.camera.has_value();
  const bool same_size = have_camera && cam.width == c.width && cam.height == c.height;
  if (c.camera_model != "pinhole") {
    S.warnings.push_back("camera_model " + c.camera_model +
                         " cannot be stored in roe.json (pinhole only): intrinsics not written, extrinsics and time "
                         "shift imported");
  } else if (have_camera && !same_size) {
    S.warnings.push_back(fmt::format("Kalibr calibrated {}x{} images but the dataset's processed images are {}x{}: "
                                     "its intrinsics are kept; only T_I_C and the time shift are imported",
                                     c.width, c.height, cam.width, cam.height));
  } else if (have_camera && m.camera->distortion_model == "none" && has_distortion(c)) {
    // The dataset's images are already undistorted (roe.json says so): Kalibr calibrated the raw camera,
    // and its distortion written here would be applied a second time. Keep the processed images' model.
    S.warnings.push_back(fmt::format(
        "the dataset's images are already undistorted (roe.json: distortion_model none) but the Kalibr camera has "
        "{} distortion, i.e. Kalibr calibrated the raw images: the processed images' pinhole model and intrinsics "
        "are kept; only T_I_C and the time shift are imported (docs/import.md)",
        c.distortion_model));
  } else {
    cam.width = c.width;
    cam.height = c.height;
    cam.fx = c.intrinsics[0];
    cam.fy = c.intrinsics[1];
    cam.cx = c.intrinsics[2];
    cam.cy = c.intrinsics[3];
    cam.distortion_model = c.distortion_model;
    cam.distortion = c.distortion_coeffs;
    if (c.distortion_model == "none") cam.distortion.clear();
    S.intrinsics_written = true;
  }
  if (!have_camera && !S.intrinsics_written) {
    // A camera section needs valid intrinsics; without them there is nowhere to put T_I_C.
    throw InputError("the dataset has no camera yet and the Kalibr camera (" + c.camera_model +
                         ") cannot provide pinhole intrinsics; import the recording first",
                     {camchain.string()});
  }
  cam.T_I_C = S.T_I_C;
  cam.time_offset_s = c.timeshift_cam_imu;  // both: t_imu = t_cam + shift
  m.camera = cam;
  if (imu) {
    S.imu_noise = imu->noise;
    S.imu_rate_hz = imu->update_rate;
    ImuInfo ii = m.imu.value_or(ImuInfo{});
    ii.noise = imu->noise;
    if (!(ii.rate_hz > 0)) ii.rate_hz = imu->update_rate > 0 ? imu->update_rate : 200.0;
    if (imu->update_rate > 0 && std::abs(ii.rate_hz - imu->update_rate) > 0.05 * imu->update_rate)
      S.warnings.push_back(fmt::format("imu.yaml update_rate {} Hz differs from the dataset's IMU rate {} Hz (kept)",
                                       imu->update_rate, ii.rate_hz));
    m.imu = ii;
  }
  // Sources and copies of the files. A forced re-import replaces the previous camchain record, and the
  // imu.yaml record only when a new imu.yaml is given: without one the IMU noise (and calib/imu.yaml)
  // stay those of the earlier import, and so does their provenance.
  const bool new_imu = imu_yaml.has_value();
  m.sources.erase(std::remove_if(m.sources.begin(), m.sources.end(),
                                 [new_imu](const SourceRecord& r) {
                                   return r.kind == "kalibr-camchain" || (new_imu && r.kind == "kalibr-imu");
                                 }),
                  m.sources.end());
  SourceRecord sc;
  sc.kind = "kalibr-camchain";
  sc.path = io::provenance_path(camchain);
  sc.sha256 = io::sha256_file(camchain);
  sc.options["camera"] = opt.camera;
  sc.options["copied_to"] = "calib/camchain-imucam.yaml";
  sc.options["T_I_C"] = "inverse of T_cam_imu";
  m.sources.push_back(sc);
  io::write_file_atomic(staged.stage(cam_out), io::read_file(camchain));
  if (imu_yaml) {
    SourceRecord si;
    si.kind = "kalibr-imu";
    si.path = io::provenance_path(*imu_yaml);
    si.sha256 = io::sha256_file(*imu_yaml);
    si.options["copied_to"] = "calib/imu.yaml";
    m.sources.push_back(si);
    io::write_file_atomic(staged.stage(imu_out), io::read_file(*imu_yaml));
  }
  store::write_manifest(m, staged.stage(store::manifest_path(dataset)));
  staged.commit();
  for (const auto& w : S.warnings) log::warn("{}", w);
  return S;
}

}  // namespace roe::app
