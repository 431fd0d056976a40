#pragma once
// Simulated detections whose reported σ are off by a known scale, for the detection σ calibration tests
// (tests/eval, tests/app): the simulator's PoET error model with white Gaussian errors on the camera axes
// only (no correlation, outliers, flips or blur; the `matched` preset's detection settings), σ written.

#include "roe/sim/detection_model.hpp"
#include "roe/sim/random.hpp"

namespace roe::test {

/// A detection of object `id` at camera stamp `t_cam_ns` around the true T_C_O, with errors drawn from
/// σ_true and σ_reported = σ_true / scale (so σ_true = scale · σ_reported).
class ScaledSigmaDetector {
 public:
  ScaledSigmaDetector(double scale, std::uint64_t seed) : model_(config(), {}), rng_(seed), scale_(scale) {}
  Detection operator()(Timestamp t_cam_ns, int id, const Pose& T_C_O_true) {
    Detection d = model_.measure(t_cam_ns, id, T_C_O_true, false, rng_);
    if (d.sigma) *d.sigma /= scale_;
    return d;
  }

 private:
  static sim::DetectionNoiseConfig config() {
    sim::DetectionNoiseConfig c;
    c.translation_frame = "camera";
    c.correlation_time_s = 0.0;
    c.outlier_prob = 0.0;
    c.symmetric_flip_prob = 0.0;
    c.blur_frame_prob = 0.0;
    c.write_sigmas = true;
    return c;
  }
  sim::PoetErrorModel model_;
  sim::Rng rng_;
  double scale_;
};

}  // namespace roe::test
