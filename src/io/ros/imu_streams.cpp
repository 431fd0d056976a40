#include "roe/io/ros/imu_streams.hpp"

namespace roe::io {

std::vector<ImuSample> merge_accel_gyro(const std::vector<std::pair<Timestamp, Eigen::Vector3d>>& accel,
                                        const std::vector<std::pair<Timestamp, Eigen::Vector3d>>& gyro,
                                        std::size_t* dropped) {
  std::vector<ImuSample> out;
  out.reserve(gyro.size());
  std::size_t n_drop = 0, j = 0;
  for (const auto& [t, w] : gyro) {
    if (accel.empty() || t < accel.front().first || t > accel.back().first) {
      ++n_drop;
      continue;
    }
    while (j + 1 < accel.size() && accel[j + 1].first < t) ++j;
    // accel[j].first < t <= accel[j+1].first, or t == accel[j].first at the very start.
    ImuSample s;
    s.t_ns = t;
    s.gyro = w;
    if (accel[j].first == t || j + 1 >= accel.size()) {
      s.accel = accel[j].second;
    } else {
      const Timestamp t0 = accel[j].first, t1 = accel[j + 1].first;
      const double a = static_cast<double>(t - t0) / static_cast<double>(t1 - t0);
      s.accel = (1.0 - a) * accel[j].second + a * accel[j + 1].second;
    }
    out.push_back(s);
  }
  if (dropped) *dropped = n_drop;
  return out;
}

}  // namespace roe::io
