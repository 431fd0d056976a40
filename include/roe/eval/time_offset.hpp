#pragma once
/// @file
/// The estimate–ground-truth clock offset of `roe eval --t-offset auto`, I/O-free: the correlator of
/// math/rate_correlation.hpp (which also serves `roe import mocap --estimate-offset`) on the two pose
/// tracks' angular rates, refined by minimising the APE.

#include <cstddef>
#include <optional>
#include <utility>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/eval/align.hpp"
#include "roe/math/rate_correlation.hpp"

namespace roe::eval {

/// The estimate–ground-truth clock offset (`roe eval --t-offset auto`).
struct TrajectoryOffset {
  double offset_s = 0.0;  ///< t_gt = t_est + offset_s (evo's --t_offset: added to the estimate stamps)
  /// 1σ of offset_s from the refinement's curvature, with the residuals' autocorrelation
  /// (effective_sample_fraction) taken into account; nan when the refinement did not run.
  double sigma_s = 0.0;
  math::RateCorrelation coarse;       ///< the angular-rate correlation
  double coarse_offset_s = 0.0; ///< coarse.offset_s as an estimate→GT offset
  bool refined = false;         ///< the APE minimisation converged (else offset_s = coarse_offset_s)
  int iterations = 0;
  std::size_t n_pairs = 0;  ///< pairs of the refinement (estimate stamps inside the ground truth)
  double ape_rmse_m = 0.0;  ///< APE translation RMSE at offset_s (interpolated ground truth, refinement's alignment)
};

/// Coarse offset by math::correlate_rates (the denser track binned, the other interpolated), refined by
/// Gauss–Newton on two blocks of residuals with the ground truth interpolated at t_est + offset: the aligned
/// positions (d r / d offset = −v_gt) and the orientations with the two bodies' mean rotation removed
/// (d r / d offset = −ω_gt, the body rate), each block weighted by its effective samples over its residual
/// variance; the alignment (`align`: se3, sim3 or posyaw; others use se3) re-fitted at each step. σ from the
/// curvature of that weighted cost. DataError when the tracks do not overlap or carry no rotation.
TrajectoryOffset estimate_trajectory_offset(const std::vector<Timestamp>& est_t, const std::vector<Pose>& est,
                                            const std::vector<Timestamp>& gt_t, const std::vector<Pose>& gt,
                                            AlignType align, double max_offset_s = 1.0);

/// How far the APE minimum lies from the evaluated offset: a few Gauss–Newton steps of the refinement
/// above from `offset_s` (steps of at most 0.1 s), with σ. The check behind the warning "the pairs look
/// time-shifted" when no offset was asked for; valid = false when it did not converge or has no σ.
struct OffsetCheck {
  double shift_s = 0.0;  ///< the APE minimum at offset_s + shift_s
  double sigma_s = 0.0;
  bool valid = false;
};
OffsetCheck check_trajectory_offset(const std::vector<Timestamp>& est_t, const std::vector<Pose>& est,
                                    const std::vector<Timestamp>& gt_t, const std::vector<Pose>& gt, AlignType align,
                                    double offset_s);

/// The fraction of a residual series' samples that count as independent: 1 / (1 + 2 Σ ρ_k), ρ_k the
/// autocorrelation at lag k summed until it first drops below 0.05 (a batch-means style correction for
/// σ from correlated residuals); in (0, 1]. Each sample may be a vector (the sum of the per-component
/// products is used). Every lag's sum comes from one FFT per component (O(n log n), equal to the
/// lag-by-lag sums to rounding: tests/eval/test_frames_time.cpp).
double effective_sample_fraction(const std::vector<Eigen::Vector3d>& residuals);

}  // namespace roe::eval
