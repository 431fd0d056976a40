#include "roe/ekf/driver.hpp"

#include <fmt/format.h>

#include "roe/core/error.hpp"

namespace roe::ekf {

FilterRunSummary run_filter(const std::vector<ImuSample>& imu, const std::vector<ImageDetections>& images,
                            const FilterOptions& options, const ImuNoiseParams& noise,
                            const Pose& T_I_C_prior, FilterObserver& observer) {
  if (imu.size() < 2) throw DataError(fmt::format("need at least 2 IMU samples, got {}", imu.size()));
  for (std::size_t k = 1; k < imu.size(); ++k)
    if (imu[k].t_ns <= imu[k - 1].t_ns)
      throw DataError(
          fmt::format("IMU stamps not strictly increasing at sample {} (t = {} ns)", k, imu[k].t_ns));
  for (std::size_t j = 1; j < images.size(); ++j)
    if (images[j].t_ns <= images[j - 1].t_ns)
      throw DataError(
          fmt::format("image stamps not strictly increasing at image {} (t = {} ns)", j, images[j].t_ns));

  // Accelerometer mean over the init window.
  const Timestamp t0 = imu.front().t_ns;
  const Timestamp t_end_window = t0 + from_seconds(std::max(0.0, options.init_window_s));
  Vec3 sum = Vec3::Zero();
  int count = 0;
  for (const auto& s : imu) {
    if (s.t_ns > t_end_window && count > 0) break;
    sum += s.accel;
    ++count;
  }

  Filter filter(options, noise, T_I_C_prior);
  filter.initialize(t0, imu.front().gyro, imu.front().accel, sum / count);
  observer.on_imu(filter);

  FilterRunSummary summary;
  summary.imu_samples = imu.size();
  std::size_t j = 0;
  const auto reject_no_imu = [&](const ImageDetections& im) {
    FrameResult r;
    r.t_ns = im.t_ns;
    for (const auto& d : im.detections) {
      DetectionOutcome o;
      o.object_id = d.object_id;
      o.status = DetectionStatus::kRejectedNoImu;
      r.detections.push_back(o);
    }
    observer.on_image(filter, r);
  };
  while (j < images.size() && images[j].t_ns < t0) reject_no_imu(images[j++]);
  while (j < images.size() && images[j].t_ns == t0) {
    observer.on_image(filter, filter.update(images[j++].detections));
    ++summary.images;
  }
  for (std::size_t k = 1; k < imu.size(); ++k) {
    const ImuSample& a = imu[k - 1];
    const ImuSample& b = imu[k];
    while (j < images.size() && images[j].t_ns < b.t_ns) {
      const double alpha =
          static_cast<double>(images[j].t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
      filter.propagate(images[j].t_ns, a.gyro + alpha * (b.gyro - a.gyro),
                       a.accel + alpha * (b.accel - a.accel));
      observer.on_image(filter, filter.update(images[j++].detections));
      ++summary.images;
    }
    filter.propagate(b.t_ns, b.gyro, b.accel);
    observer.on_imu(filter);
    while (j < images.size() && images[j].t_ns == b.t_ns) {
      observer.on_image(filter, filter.update(images[j++].detections));
      ++summary.images;
    }
  }
  while (j < images.size()) reject_no_imu(images[j++]);
  summary.updates = filter.n_updates();
  return summary;
}

}  // namespace roe::ekf
