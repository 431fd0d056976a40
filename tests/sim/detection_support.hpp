#pragma once
// Shared pieces of the detection-model tests: the processed camera and an error model reduced to its
// white Gaussian part (no correlation, outliers, flips or blur).
#include <cmath>

#include "roe/sim/detection_model.hpp"

namespace roe::sim::test {

inline const PinholeCamera kCam{640, 480, 919.806, 920.129, 319.909, 238.775};

inline DetectionNoiseConfig gaussian_only() {
  DetectionNoiseConfig d;
  d.correlation_time_s = 0.0;
  d.outlier_prob = 0.0;
  d.symmetric_flip_prob = 0.0;
  d.blur_rate_threshold_deg_s = 0.0;
  d.blur_frame_prob = 0.0;
  return d;
}

}  // namespace roe::sim::test
