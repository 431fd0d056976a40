// roe import kalibr: Kalibr camchain-imucam.yaml (+ imu.yaml) → roe.json camera/imu priors + calib/.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <map>

#include <fmt/format.h>

#include "roe/app/import.hpp"
#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/io/dataset.hpp"
#include "roe/io/output.hpp"

namespace roe::app {
namespace {

/// A key given twice in one mapping is an error. yaml-cpp keeps both and `node[key]` returns the
/// first, while PyYAML (Kalibr's own reader) keeps the last: silently taking either would differ from
/// what Kalibr meant for somebody.
void refuse_duplicate_keys(const fs::path& file, const YAML::Node& n, const std::string& path) {
  if (n.IsSequence()) {
    for (std::size_t i = 0; i < n.size(); ++i) refuse_duplicate_keys(file, n[i], fmt::format("{}[{}]", path, i));
    return;
  }
  if (!n.IsMap()) return;
  std::map<std::string, YAML::Mark> seen;
  for (const auto& kv : n) {
    const std::string key = kv.first.IsScalar() ? kv.first.Scalar() : std::string("?");
    const std::string here = path.empty() ? key : path + "." + key;
    const auto m = kv.first.Mark();
    const auto [it, fresh] = seen.emplace(key, m);
    if (!fresh)
      throw InputError(fmt::format("key \"{}\" appears twice in the same mapping (first at line {}); Kalibr would "
                                   "take the last one, roe refuses to guess",
                                   key, it->second.line + 1),
                       {file.string(), m.line + 1, m.column + 1, here});
    refuse_duplicate_keys(file, kv.second, here);
  }
}

YAML::Node load_yaml(const fs::path& file) {
  if (!fs::exists(file)) throw InputError("no such file", {file.string()});
  YAML::Node root;
  try {
    root = YAML::LoadFile(file.string());
  } catch (const YAML::Exception& e) {
    throw InputError("YAML syntax error: " + e.msg, {file.string(), e.mark.line + 1, e.mark.column + 1});
  }
  refuse_duplicate_keys(file, root, "");
  return root;
}

ErrorContext at(const fs::path& file, const YAML::Node& n, const std::string& key) {
  const auto m = n.Mark();
  return {file.string(), m.is_null() ? 0 : m.line + 1, m.is_null() ? 0 : m.column + 1, key};
}

double number(const fs::path& file, const YAML::Node& n, const std::string& key) {
  if (!n || !n.IsScalar()) throw InputError("expected a number", at(file, n, key));
  try {
    const double v = n.as<double>();
    if (!std::isfinite(v)) throw InputError("value is not finite", at(file, n, key));
    return v;
  } catch (const YAML::Exception&) {
    throw InputError("expected a number, got \"" + n.Scalar() + "\"", at(file, n, key));
  }
}

std::vector<double> numbers(const fs::path& file, const YAML::Node& n, const std::string& key) {
  if (!n || !n.IsSequence()) throw InputError("expected a list of numbers", at(file, n, key));
  std::vector<double> v;
  for (std::size_t i = 0; i < n.size(); ++i) v.push_back(number(file, n[i], fmt::format("{}[{}]", key, i)));
  return v;
}

std::string text(const fs::path& file, const YAML::Node& n, const std::string& key) {
  if (!n || !n.IsScalar()) throw InputError("expected a string", at(file, n, key));
  return n.Scalar();
}

const YAML::Node required(const fs::path& file, const YAML::Node& parent, const std::string& key,
                          const std::string& path) {
  const YAML::Node n = parent[key];
  if (!n) throw InputError("missing required key", at(file, parent, path.empty() ? key : path + "." + key));
  return n;
}

}  // namespace

KalibrCamchain read_kalibr_camchain(const fs::path& file, const std::string& camera) {
  const YAML::Node root = load_yaml(file);
  if (!root.IsMap()) throw InputError("expected a YAML mapping with cam0, cam1, ...", {file.string()});
  const YAML::Node cam = root[camera];
  if (!cam && (root["accelerometer_noise_density"] || root["imu0"]))
    throw InputError("this is a Kalibr imu.yaml, not a camchain: pass the camchain first, "
                     "`roe import kalibr camchain-imucam.yaml imu.yaml --into DATASET` (the camchain carries T_I_C, "
                     "which roe needs; the imu.yaml only adds the noise)",
                     {file.string()});
  if (!cam) throw InputError("no camera \"" + camera + "\" in the camchain", {file.string(), 0, 0, camera});
  KalibrCamchain c;
  c.camera_model = text(file, required(file, cam, "camera_model", camera), camera + ".camera_model");
  c.intrinsics = numbers(file, required(file, cam, "intrinsics", camera), camera + ".intrinsics");
  c.distortion_model = text(file, required(file, cam, "distortion_model", camera), camera + ".distortion_model");
  c.distortion_coeffs = numbers(file, required(file, cam, "distortion_coeffs", camera), camera + ".distortion_coeffs");
  const auto res = numbers(file, required(file, cam, "resolution", camera), camera + ".resolution");
  if (cam["rostopic"]) c.rostopic = text(file, cam["rostopic"], camera + ".rostopic");
  if (res.size() != 2 || res[0] < 1 || res[1] < 1 || res[0] != std::floor(res[0]) || res[1] != std::floor(res[1]))
    throw InputError("resolution must be [width, height] (positive integers)", at(file, cam["resolution"], camera + ".resolution"));
  c.width = static_cast<int>(res[0]);
  c.height = static_cast<int>(res[1]);
  const std::size_t n_intr = c.camera_model == "pinhole" ? 4 : c.camera_model == "omni" ? 5 : c.camera_model == "eucm" ? 6
                             : c.camera_model == "ds" ? 6 : 0;
  if (n_intr == 0)
    throw InputError("unknown camera_model \"" + c.camera_model + "\" (pinhole, omni, eucm, ds)",
                     at(file, cam["camera_model"], camera + ".camera_model"));
  if (c.intrinsics.size() != n_intr)
    throw InputError(fmt::format("{} intrinsics need {} values, got {}", c.camera_model, n_intr, c.intrinsics.size()),
                     at(file, cam["intrinsics"], camera + ".intrinsics"));
  const std::size_t f0 = n_intr - 4;  // fu, fv, pu, pv are the last four
  if (!(c.intrinsics[f0] > 0) || !(c.intrinsics[f0 + 1] > 0))
    throw InputError("focal lengths must be > 0", at(file, cam["intrinsics"], camera + ".intrinsics"));
  const std::size_t n_dist = c.distortion_model == "radtan" ? 4 : c.distortion_model == "equidistant" ? 4
                             : c.distortion_model == "fov" ? 1 : c.distortion_model == "none" ? 0 : 99;
  if (n_dist == 99)
    throw InputError("unknown distortion_model \"" + c.distortion_model + "\" (radtan, equidistant, fov, none)",
                     at(file, cam["distortion_model"], camera + ".distortion_model"));
  if (c.distortion_coeffs.size() != n_dist)
    throw InputError(fmt::format("{} needs {} coefficients, got {}", c.distortion_model, n_dist,
                                 c.distortion_coeffs.size()),
                     at(file, cam["distortion_coeffs"], camera + ".distortion_coeffs"));
  // T_cam_imu: 4x4 list of rows.
  const YAML::Node T = required(file, cam, "T_cam_imu", camera);
  if (!T.IsSequence() || T.size() != 4)
    throw InputError("T_cam_imu must be a 4x4 list of rows", at(file, T, camera + ".T_cam_imu"));
  for (int i = 0; i < 4; ++i) {
    const auto row = numbers(file, T[i], fmt::format("{}.T_cam_imu[{}]", camera, i));
    if (row.size() != 4) throw InputError("T_cam_imu must be a 4x4 list of rows", at(file, T[i], camera + ".T_cam_imu"));
    for (int j = 0; j < 4; ++j) c.T_cam_imu(i, j) = row[j];
  }
  const Eigen::Matrix3d R = c.T_cam_imu.topLeftCorner<3, 3>();
  const double ortho = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (ortho > 1e-4 || R.determinant() < 0)
    throw InputError(fmt::format("T_cam_imu rotation is not orthonormal (max |R^T R - I| = {:.3g}, det = {:.6f})", ortho,
                                 R.determinant()),
                     at(file, T, camera + ".T_cam_imu"));
  if ((c.T_cam_imu.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9)
    throw InputError("T_cam_imu bottom row must be [0, 0, 0, 1]", at(file, T[3], camera + ".T_cam_imu"));
  if (cam["timeshift_cam_imu"]) c.timeshift_cam_imu = number(file, cam["timeshift_cam_imu"], camera + ".timeshift_cam_imu");
  return c;
}

KalibrImu read_kalibr_imu(const fs::path& file) {
  const YAML::Node root = load_yaml(file);
  if (!root.IsMap()) throw InputError("expected a YAML mapping", {file.string()});
  // Kalibr's imu.yaml is flat; a multi-IMU file nests the same keys under imu0.
  const YAML::Node n = root["imu0"] ? root["imu0"] : root;
  const std::string p = root["imu0"] ? "imu0" : "";
  auto key = [&](const char* k) { return p.empty() ? std::string(k) : p + "." + k; };
  KalibrImu k;
  auto positive = [&](const char* name, double& out) {
    out = number(file, required(file, n, name, p), key(name));
    if (!(out > 0)) throw InputError("must be > 0", at(file, n[name], key(name)));
  };
  positive("accelerometer_noise_density", k.noise.accel_noise_density);
  positive("accelerometer_random_walk", k.noise.accel_random_walk);
  positive("gyroscope_noise_density", k.noise.gyro_noise_density);
  positive("gyroscope_random_walk", k.noise.gyro_random_walk);
  if (n["update_rate"]) {
    k.update_rate = number(file, n["update_rate"], key("update_rate"));
    if (!(k.update_rate > 0)) throw InputError("must be > 0", at(file, n["update_rate"], key("update_rate")));
  }
  if (n["rostopic"]) k.rostopic = text(file, n["rostopic"], key("rostopic"));
  return k;
}

nlohmann::json ImportKalibrSummary::to_json() const {
  auto pose = [](const Pose& T) {
    return nlohmann::json{{"p", {T.p.x(), T.p.y(), T.p.z()}}, {"q", {T.q.x(), T.q.y(), T.q.z(), T.q.w()}}};
  };
  nlohmann::json j = {{"command", "import kalibr"},
                      {"dataset", dataset.string()},
                      {"camera", camera},
                      {"T_cam_imu", pose(T_cam_imu)},
                      {"T_I_C", pose(T_I_C)},
                      {"timeshift_cam_imu", timeshift_cam_imu},
                      {"camera_model", camera_model},
                      {"distortion_model", distortion_model},
                      {"intrinsics", intrinsics},
                      {"distortion_coeffs", distortion_coeffs},
                      {"resolution", {width, height}},
                      {"intrinsics_written", intrinsics_written},
                      {"created_manifest", created_manifest},
                      {"warnings", warnings}};
  if (imu_noise)
    j["imu_noise"] = {{"gyro_noise_density", imu_noise->gyro_noise_density},
                      {"gyro_random_walk", imu_noise->gyro_random_walk},
                      {"accel_noise_density", imu_noise->accel_noise_density},
                      {"accel_random_walk", imu_noise->accel_random_walk},
                      {"update_rate", imu_rate_hz}};
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
  if (!opt.force && (fs::exists(cam_out) || (imu_yaml && fs::exists(imu_out))))
    throw InputError("the dataset already has a Kalibr calibration (use --force to replace it)",
                     {fs::exists(cam_out) ? cam_out.string() : imu_out.string()});
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
  io::write_manifest(m, staged.stage(io::manifest_path(dataset)));
  staged.commit();
  for (const auto& w : S.warnings) log::warn("{}", w);
  return S;
}

}  // namespace roe::app
