// Kalibr camchain-imucam.yaml and imu.yaml readers (roe/io/kalibr.hpp).
#include "roe/io/kalibr.hpp"

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <map>
#include <sstream>

#include <fmt/format.h>

#include "roe/core/error.hpp"
#include "roe/io/input.hpp"

namespace roe::io {
namespace {

/// A key given twice in one mapping is an error. yaml-cpp keeps both and `node[key]` returns the
/// first, while PyYAML (Kalibr's own reader) keeps the last: silently taking either would differ from
/// what Kalibr meant for somebody.
void refuse_duplicate_keys(const fs::path& file, const std::string& text, const YAML::Node& n,
                           const std::string& path);

/// yaml-cpp reads a line without ':' in a block mapping (a stray `nan` under the cameras) as a key with no
/// value, where PyYAML, Kalibr's reader, refuses the file ("could not find expected ':'"). Kalibr writes
/// no such keys, so a key whose line has no ':' after it is refused at its line.
void refuse_key_without_colon(const fs::path& file, const std::string& text, const YAML::Node& key,
                              const YAML::Node& value, const std::string& here) {
  const auto m = key.Mark();
  if (!value.IsNull() || m.is_null() || m.pos < 0 || static_cast<std::size_t>(m.pos) >= text.size()) return;
  const auto eol = text.find('\n', static_cast<std::size_t>(m.pos));
  if (text.find(':', static_cast<std::size_t>(m.pos)) < eol) return;
  throw InputError("a line without ':' in a mapping (PyYAML, Kalibr's reader, refuses it)",
                   {file.string(), m.line + 1, m.column + 1, here});
}

void refuse_duplicate_keys(const fs::path& file, const std::string& text, const YAML::Node& n,
                           const std::string& path) {
  if (n.IsSequence()) {
    for (std::size_t i = 0; i < n.size(); ++i) refuse_duplicate_keys(file, text, n[i], fmt::format("{}[{}]", path, i));
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
    refuse_key_without_colon(file, text, kv.first, kv.second, here);
    refuse_duplicate_keys(file, text, kv.second, here);
  }
}

/// Refuses anchors and aliases (Kalibr writes neither): an alias makes the same node reachable from
/// many places, and a few chained ones make any walk over the tree exponential in the file's size.
class RefuseAliases final : public YAML::EventHandler {
 public:
  explicit RefuseAliases(std::string source) : source_(std::move(source)) {}
  void OnDocumentStart(const YAML::Mark& m) override { start_ = m; }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& m, YAML::anchor_t a) override { check(m, a); }
  void OnAlias(const YAML::Mark& m, YAML::anchor_t) override { refuse(m, "an alias (*name)"); }
  void OnScalar(const YAML::Mark& m, const std::string&, YAML::anchor_t a, const std::string&) override {
    check(m, a);
  }
  void OnSequenceStart(const YAML::Mark& m, const std::string&, YAML::anchor_t a, YAML::EmitterStyle::value) override {
    check(m, a);
  }
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark& m, const std::string&, YAML::anchor_t a, YAML::EmitterStyle::value) override {
    check(m, a);
  }
  void OnMapEnd() override {}
  /// Where the last document handled started.
  const YAML::Mark& document_start() const { return start_; }

 private:
  void check(const YAML::Mark& m, YAML::anchor_t a) const {
    if (a != YAML::NullAnchor) refuse(m, "an anchor (&name)");
  }
  [[noreturn]] void refuse(const YAML::Mark& m, const std::string& what) const {
    throw InputError(what + ": Kalibr files use neither anchors nor aliases, and roe does not expand them",
                     {source_, m.line + 1, m.column + 1});
  }
  std::string source_;
  YAML::Mark start_ = YAML::Mark::null_mark();
};

YAML::Node load_yaml(const std::string& text, const fs::path& file) {
  YAML::Node root;
  try {
    {
      std::istringstream in(text);
      YAML::Parser parser(in);
      RefuseAliases refuse(file.string());
      // The first document only, as YAML::Load reads: yaml-cpp 0.7's loop over the next documents never
      // ends on some input (",m0:", a fuzz finding; YAML::LoadAll hangs on it too).
      parser.HandleNextDocument(refuse);
      // A second document would be ignored silently: refuse it (one more call only, never a loop).
      RefuseAliases rest(file.string());
      if (parser.HandleNextDocument(rest)) {
        const auto& m = rest.document_start();
        throw InputError("content after the first YAML document: a Kalibr file holds one mapping",
                         {file.string(), m.is_null() ? 0 : m.line + 1, m.is_null() ? 0 : m.column + 1});
      }
    }
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw InputError("YAML syntax error: " + e.msg, {file.string(), e.mark.line + 1, e.mark.column + 1});
  }
  refuse_duplicate_keys(file, text, root, "");
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
  return parse_kalibr_camchain(read_file(file), file.string(), camera);
}

KalibrImu read_kalibr_imu(const fs::path& file) { return parse_kalibr_imu(read_file(file), file.string()); }

namespace {

/// yaml-cpp throws on a subscript of a scalar or a sequence (a camera given as a list): whatever the
/// checks above did not foresee is still this file's error, at yaml-cpp's mark.
template <typename Fn>
auto yaml_structure_errors(const fs::path& file, Fn&& fn) {
  try {
    return fn();
  } catch (const YAML::Exception& e) {
    throw InputError("unexpected YAML structure: " + e.msg,
                     {file.string(), e.mark.is_null() ? 0 : e.mark.line + 1, e.mark.is_null() ? 0 : e.mark.column + 1});
  }
}

KalibrCamchain camchain_from_yaml(const YAML::Node& root, const fs::path& file, const std::string& camera);
KalibrImu imu_from_yaml(const YAML::Node& root, const fs::path& file);

}  // namespace

KalibrCamchain parse_kalibr_camchain(const std::string& yaml, const std::string& source, const std::string& camera) {
  const fs::path file(source);
  const YAML::Node root = load_yaml(yaml, file);
  return yaml_structure_errors(file, [&] { return camchain_from_yaml(root, file, camera); });
}

KalibrImu parse_kalibr_imu(const std::string& yaml, const std::string& source) {
  const fs::path file(source);
  const YAML::Node root = load_yaml(yaml, file);
  return yaml_structure_errors(file, [&] { return imu_from_yaml(root, file); });
}

namespace {

KalibrCamchain camchain_from_yaml(const YAML::Node& root, const fs::path& file, const std::string& camera) {
  if (!root.IsMap()) throw InputError("expected a YAML mapping with cam0, cam1, ...", {file.string()});
  const YAML::Node cam = root[camera];
  if (!cam && (root["accelerometer_noise_density"] || root["imu0"]))
    throw InputError("this is a Kalibr imu.yaml, not a camchain: pass the camchain first, "
                     "`roe import kalibr camchain-imucam.yaml imu.yaml --into DATASET` (the camchain carries T_I_C, "
                     "which roe needs; the imu.yaml only adds the noise)",
                     {file.string()});
  if (!cam) throw InputError("no camera \"" + camera + "\" in the camchain", {file.string(), 0, 0, camera});
  if (!cam.IsMap()) throw InputError("expected a mapping (camera_model, intrinsics, ...)", at(file, cam, camera));
  KalibrCamchain c;
  c.camera_model = text(file, required(file, cam, "camera_model", camera), camera + ".camera_model");
  c.intrinsics = numbers(file, required(file, cam, "intrinsics", camera), camera + ".intrinsics");
  c.distortion_model = text(file, required(file, cam, "distortion_model", camera), camera + ".distortion_model");
  c.distortion_coeffs = numbers(file, required(file, cam, "distortion_coeffs", camera), camera + ".distortion_coeffs");
  const auto res = numbers(file, required(file, cam, "resolution", camera), camera + ".resolution");
  if (cam["rostopic"]) c.rostopic = text(file, cam["rostopic"], camera + ".rostopic");
  // Checked here, where the numbers are read: a width that does not fit an int (1e12) must be this
  // file's error, not a broken manifest later.
  constexpr double kMaxSide = 100000;
  if (res.size() != 2 || !(res[0] >= 1 && res[0] <= kMaxSide) || !(res[1] >= 1 && res[1] <= kMaxSide) ||
      res[0] != std::floor(res[0]) || res[1] != std::floor(res[1]))
    throw InputError("resolution must be [width, height] (integers from 1 to 100000)",
                     at(file, cam["resolution"], camera + ".resolution"));
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

KalibrImu imu_from_yaml(const YAML::Node& root, const fs::path& file) {
  if (!root.IsMap()) throw InputError("expected a YAML mapping", {file.string()});
  // Kalibr's imu.yaml is flat; a multi-IMU file nests the same keys under imu0.
  const YAML::Node n = root["imu0"] ? root["imu0"] : root;
  const std::string p = root["imu0"] ? "imu0" : "";
  if (!n.IsMap()) throw InputError("expected a mapping of noise densities", at(file, n, p));
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

}  // namespace

}  // namespace roe::io
