#pragma once
/// @file
/// The one correlator of angular-rate magnitudes, I/O-free: the mocap–IMU clock offset of `roe import mocap
/// --estimate-offset` (calib/mocap_time_offset.hpp: gyro against a mocap body's rate) and the
/// estimate–ground-truth offset of `roe eval --t-offset auto` (eval/time_offset.hpp: two pose tracks) are
/// both the peak of correlate_rates.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "roe/math/se3.hpp"

namespace roe::math {

/// A sampled scalar signal (an angular-rate magnitude): times in seconds relative to `origin_ns`.
struct RateSignal {
  std::int64_t origin_ns = 0;
  std::vector<double> t_s;
  std::vector<double> value;
  /// Consecutive samples further apart than this are a gap (never interpolated across); 0: none.
  double max_gap_s = 0.0;
  double length_s() const { return t_s.empty() ? 0.0 : t_s.back(); }
};

/// The peak of the normalised cross-correlation of two rate signals over lags.
struct RateCorrelation {
  double offset_s = 0.0;      ///< t_binned = t_interpolated + offset_s
  double correlation = 0.0;   ///< normalised cross-correlation at the peak (quality, 1 = perfect)
  double peak_ratio = 0.0;    ///< peak / best value outside ±0.25 s of the peak (>1: distinct)
  std::size_t samples = 0;    ///< overlapping grid samples used at the peak
  double grid_dt_s = 0.0;
  /// The peak is the first or last lag searched: the true offset may lie beyond ±max_offset_s.
  bool peak_at_edge = false;
};

/// `binned` is averaged into cells of `grid_dt_s` (on its own clock), `interpolated` is read linearly
/// at each cell's time minus the lag; the normalised cross-correlation is searched over lags in
/// [c − max, c + max] (c = 0 when the clocks overlap, else the lag that aligns the starts) and the best
/// lag refined by a parabola through its neighbours. DataError when no lag has 20 overlapping samples with
/// variation in both.
RateCorrelation correlate_rates(const RateSignal& binned, const RateSignal& interpolated, double max_offset_s,
                                double grid_dt_s);

/// The angular-rate magnitude |Log(R_kᵀ R_k+1)| / dt of a pose track (stamps in ns) at the mid-points of
/// consecutive poses, relative to the first stamp; pairs further apart than 3 `period_s` (the track's
/// median period) are skipped and are the signal's gaps.
RateSignal pose_rate_signal(const std::vector<std::int64_t>& t_ns, const std::vector<Pose>& poses, double period_s);

}  // namespace roe::math
