// The mocap–IMU clock offset by cross-correlating angular-rate magnitudes (calib/mocap_time_offset.hpp), with
// the one correlator (math/rate_correlation.hpp), which also serves `roe eval --t-offset auto`.
#include "roe/calib/mocap_time_offset.hpp"

#include <algorithm>

#include "roe/core/error.hpp"
#include "roe/math/rate_correlation.hpp"

namespace roe::calib {

MocapOffsetEstimate estimate_mocap_time_offset(const std::vector<ImuSample>& imu, const std::vector<StampedPose>& mocap,
                                               double max_offset_s, double grid_dt_s) {
  if (imu.size() < 10 || mocap.size() < 10)
    throw DataError("time-offset estimate needs at least 10 IMU samples and 10 mocap poses");
  std::vector<Timestamp> t;
  std::vector<Pose> q;
  for (const StampedPose& m : mocap) t.push_back(m.t_ns), q.push_back(m.T);
  // The mocap body's rate (interpolated, gaps over 3 periods not bridged) against the gyro magnitude
  // binned on the grid (IMU clock).
  const double rate = median_rate_hz(t);
  const math::RateSignal m = math::pose_rate_signal(t, q, rate > 0 ? 1.0 / rate : 0.0);
  math::RateSignal g;
  g.origin_ns = imu.front().t_ns;
  for (const ImuSample& s : imu) g.t_s.push_back(dt_seconds(g.origin_ns, s.t_ns)), g.value.push_back(s.gyro.norm());
  if (grid_dt_s <= 0) grid_dt_s = std::min(m.max_gap_s / 3.0, 0.005);
  return math::correlate_rates(g, m, max_offset_s, grid_dt_s);  // t_imu = t_mocap + offset
}

}  // namespace roe::calib
