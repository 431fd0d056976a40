#pragma once
/// @file
/// What a finished filter run can be trusted for: the warnings its counts call for, robust NIS
/// statistics and a health verdict (how much of the trajectory is supported by accepted updates, the
/// longest stretch of IMU dead reckoning, the NIS median). I/O-free; `roe run` writes them to run.json
/// and the console and exits 1 when the run is unhealthy (docs/filter.md §11).

#include <cstddef>
#include <string>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/ekf/driver.hpp"
#include "roe/ekf/options.hpp"

namespace roe::ekf {

/// Warnings about what the data allowed, from the counts of a run: objects detected but never
/// initialised (and why), detections outside the IMU stream, most detections rejected for lack of the
/// anchor, no update at all, the gyro bias at rest refused.
std::vector<std::string> run_warnings(const FilterRunSummary& s, const FilterOptions& options);

/// Warnings about the self-calibration states at the end of a run (part of run_warnings; docs/filter.md §11):
/// - the extrinsics moved from their prior by more than kCalibrationMoveSigmas prior σ on some axis: the
///   prior is wrong, or the extrinsics absorbed detection errors (correlated in time, docs/filter.md §15);
/// - an object keeps a median rotation residual above kRotationResidualWarnDeg over its last
///   kRotationResidualWindow gated detections: its object-world disagrees with most of what is detected
///   now (e.g. initialised as a flipped pose of a symmetric object that has no models_info).
std::vector<std::string> calibration_warnings(const FilterRunSummary& s);
inline constexpr double kCalibrationMoveSigmas = 1.0;
inline constexpr double kRotationResidualWarnDeg = 45.0;
inline constexpr std::size_t kRotationResidualWindow = 100;

/// Order statistics of the NIS of the gated detections (6 dof): the median and quantiles, which one
/// outlier cannot move, and the mean, which it can (a 180° symmetric flip gives NIS ~1e6).
struct NisStats {
  std::size_t count = 0;
  double median = 0.0, p25 = 0.0, p75 = 0.0, p95 = 0.0, max = 0.0, mean = 0.0;
  double gate = 0.0;                 ///< χ²₆ quantile at FilterOptions::chi2_confidence
  double fraction_above_gate = 0.0;  ///< share of the NIS above the gate
  /// median / the χ²₆ median (5.348): ≈ 1 for a consistent filter, ≫ 1 for an overconfident one.
  double median_ratio = 0.0;
};
/// Quantiles by linear interpolation between order statistics (the "type 7" rule of R and numpy).
NisStats nis_stats(std::vector<double> nis, double gate);

/// Limits of a trustworthy run (run config "health"; defaults measured on the presets, the sample and
/// the EuRoC snippet, docs/filter.md §11). A limit of 0 (fraction, median) or a negative one
/// (dead reckoning) switches that check off.
struct HealthLimits {
  /// A trajectory time counts as supported when an accepted update lies at most this long before it.
  double support_window_s = 1.0;
  double min_supported_fraction = 0.5;  ///< share of the trajectory's duration that must be supported
  double max_dead_reckoning_s = 10.0;   ///< longest stretch without an accepted update
  /// Largest median NIS / χ²₆ median (overconfidence); checked with at least 30 NIS values.
  double max_nis_median_ratio = 10.0;
};

struct RunHealth {
  double duration_s = 0.0;           ///< the trajectory's (first to last IMU sample)
  std::size_t accepted_updates = 0;  ///< images with an accepted update
  double supported_fraction = 0.0;
  double longest_dead_reckoning_s = 0.0;
  Timestamp dead_reckoning_from_ns = 0, dead_reckoning_to_ns = 0;  ///< where that stretch lies
  NisStats nis;
  /// Why the run cannot be trusted, one sentence per failed limit; empty when healthy.
  std::vector<std::string> problems;
  bool healthy() const { return problems.empty(); }
};

/// The health of a finished run against `limits`.
RunHealth assess_health(const FilterRunSummary& s, const FilterOptions& options, const HealthLimits& limits);

}  // namespace roe::ekf
