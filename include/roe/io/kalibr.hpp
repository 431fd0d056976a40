#pragma once
/// @file
/// Kalibr calibration files: camchain-imucam.yaml and imu.yaml (docs/import.md, "roe import kalibr").
///
/// The YAML is read strictly: a syntax error, a key given twice in one mapping, or an anchor or alias
/// (Kalibr writes neither; refusing them bounds the work on a hostile file, where chained aliases
/// expand exponentially) is an InputError with its line and column. Numbers are range-checked where
/// they are read (a resolution must fit an int).

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "roe/core/dataset.hpp"

namespace roe::io {

namespace fs = std::filesystem;

/// Parsed Kalibr files.
struct KalibrCamchain {
  std::string camera_model, distortion_model, rostopic;
  std::vector<double> intrinsics, distortion_coeffs;
  int width = 0, height = 0;
  Eigen::Matrix4d T_cam_imu = Eigen::Matrix4d::Identity();
  double timeshift_cam_imu = 0.0;
};
struct KalibrImu {
  ImuNoise noise;
  double update_rate = 0.0;
  std::string rostopic;
};
/// InputError naming file and key: missing keys, wrong shapes, a non-orthonormal rotation or a
/// bottom row other than [0 0 0 1], non-positive intrinsics, negative/zero noise.
KalibrCamchain read_kalibr_camchain(const fs::path& file, const std::string& camera = "cam0");
KalibrImu read_kalibr_imu(const fs::path& file);
/// The same from text; `source` names it in errors (fuzzing, tests).
KalibrCamchain parse_kalibr_camchain(const std::string& text, const std::string& source,
                                     const std::string& camera = "cam0");
KalibrImu parse_kalibr_imu(const std::string& text, const std::string& source);


}  // namespace roe::io
