#include "roe/ekf/driver.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "roe/core/error.hpp"

namespace roe::ekf {

InitWindow init_window(const std::vector<ImuSample>& imu, double window_s) {
  if (imu.empty()) throw DataError("no IMU samples for the init window");
  const Timestamp t0 = imu.front().t_ns;
  const Timestamp t_end = t0 + from_seconds(std::max(0.0, window_s));
  InitWindow w;
  Vec3 sq_g = Vec3::Zero(), sq_a = Vec3::Zero();
  std::size_t k = 0;
  for (; k < imu.size() && (k == 0 || imu[k].t_ns <= t_end); ++k) {
    w.mean_gyro += imu[k].gyro;
    w.mean_accel += imu[k].accel;
  }
  w.samples = static_cast<int>(k);
  w.duration_s = to_seconds(imu[k - 1].t_ns - t0);
  w.mean_gyro /= w.samples;
  w.mean_accel /= w.samples;
  if (w.samples > 1) {
    // Two-pass σ (numerically safe for the accelerometer's large mean).
    for (std::size_t i = 0; i < k; ++i) {
      sq_g += (imu[i].gyro - w.mean_gyro).cwiseAbs2();
      sq_a += (imu[i].accel - w.mean_accel).cwiseAbs2();
    }
    w.std_gyro = (sq_g / (w.samples - 1)).cwiseSqrt();
    w.std_accel = (sq_a / (w.samples - 1)).cwiseSqrt();
  }
  return w;
}

Vec3 initial_gyro_bias(const InitWindow& w, const FilterOptions& options, std::string* why_not) {
  if (why_not) why_not->clear();
  if (!options.init_gyro_bias_from_rest) return options.init_gyro_bias;
  std::string why;
  if (w.samples < 2)
    why = fmt::format("the init window holds {} IMU sample(s)", w.samples);
  else if (!(w.std_gyro.maxCoeff() <= options.init_rest_max_gyro_std))
    why = fmt::format("the gyro moves in the init window (sample sigma {:.4f} rad/s > init_rest_max_gyro_std {})",
                      w.std_gyro.maxCoeff(), options.init_rest_max_gyro_std);
  else if (!(w.std_accel.maxCoeff() <= options.init_rest_max_accel_std))
    why = fmt::format(
        "the accelerometer moves in the init window (sample sigma {:.4f} m/s^2 > init_rest_max_accel_std {})",
        w.std_accel.maxCoeff(), options.init_rest_max_accel_std);
  else if (!(w.mean_gyro.norm() <= options.max_gyro_bias))
    why = fmt::format("the gyro mean {:.4f} rad/s exceeds max_gyro_bias {}", w.mean_gyro.norm(),
                      options.max_gyro_bias);
  if (why_not) *why_not = why;
  return why.empty() ? w.mean_gyro : options.init_gyro_bias;
}

void DetectionCounts::add(DetectionStatus s) {
  ++detections;
  switch (s) {
    case DetectionStatus::kAccepted:
      ++accepted;
      break;
    case DetectionStatus::kInitialized:
      ++initialized;
      break;
    case DetectionStatus::kRejectedChi2:
      ++rejected_chi2;
      break;
    case DetectionStatus::kRejectedNoMain:
      ++rejected_no_main;
      break;
    case DetectionStatus::kRejectedScore:
      ++rejected_score;
      break;
    case DetectionStatus::kRejectedNoImu:
      ++rejected_no_imu;
      break;
    case DetectionStatus::kPendingInit:
      ++pending_init;
      break;
  }
}

DetectionCounts& DetectionCounts::operator+=(const DetectionCounts& o) {
  detections += o.detections;
  accepted += o.accepted;
  initialized += o.initialized;
  rejected_chi2 += o.rejected_chi2;
  rejected_no_main += o.rejected_no_main;
  rejected_score += o.rejected_score;
  rejected_no_imu += o.rejected_no_imu;
  pending_init += o.pending_init;
  return *this;
}

namespace {

// Tallies one image's outcomes into the summary.
// σ of the extrinsics [p; θ] (0 when they are held fixed).
Vector6d extrinsics_sigma(const Filter& f) {
  Vector6d s = Vector6d::Zero();
  if (f.extrinsics_offset() >= 0)
    for (int k = 0; k < 6; ++k) s(k) = std::sqrt(f.variance(f.extrinsics_offset() + k));
  return s;
}

// σ of the time offset (0 when it is held at the declared value).
double time_offset_sigma(const Filter& f) {
  return f.time_offset_offset() >= 0 ? std::sqrt(f.variance(f.time_offset_offset())) : 0.0;
}

void tally(const FrameResult& r, int anchor_id, FilterRunSummary& s) {
  bool anchor_pending = false;
  std::size_t no_main = 0;
  for (const auto& d : r.detections) {
    s.counts[d.object_id].add(d.status);
    if (std::isfinite(d.nis)) s.nis.push_back(d.nis);
    if (!std::isnan(d.rot_residual_deg)) s.rot_residual_deg[d.object_id].push_back(d.rot_residual_deg);
    // The anchor is in the image but not usable yet (awaiting or just getting its initialisation); an
    // anchor detection below min_score or rejected does not count: that image lacks a usable anchor.
    anchor_pending |= d.object_id == anchor_id &&
                      (d.status == DetectionStatus::kPendingInit || d.status == DetectionStatus::kInitialized);
    no_main += d.status == DetectionStatus::kRejectedNoMain;
  }
  if (anchor_pending) s.no_main_anchor_pending += no_main;
  if (r.n_inliers > 0 && r.position_used) s.update_times.push_back(r.t_ns);
  if (r.relock) s.relocks.push_back({r.t_ns, *r.relock});
}

}  // namespace

FilterRunSummary run_filter(const std::vector<ImuSample>& imu, const std::vector<ImageDetections>& images,
                            const FilterOptions& options, const ImuNoiseParams& noise,
                            const Pose& T_I_C_prior, FilterObserver& observer,
                            FilterRecording* recording, const std::map<int, ObjectSymmetry>& symmetries,
                            double time_offset_prior_s) {
  if (imu.size() < 2) throw DataError(fmt::format("need at least 2 IMU samples, got {}", imu.size()));
  for (std::size_t k = 1; k < imu.size(); ++k)
    if (imu[k].t_ns <= imu[k - 1].t_ns)
      throw DataError(
          fmt::format("IMU stamps not strictly increasing at sample {} (t = {} ns)", k, imu[k].t_ns));
  for (std::size_t j = 1; j < images.size(); ++j)
    if (images[j].t_ns <= images[j - 1].t_ns)
      throw DataError(
          fmt::format("image stamps not strictly increasing at image {} (t = {} ns)", j, images[j].t_ns));

  // Roll/pitch from the accelerometer mean over the init window; the gyro bias from its gyro mean when
  // asked for and at rest.
  const Timestamp t0 = imu.front().t_ns;
  FilterRunSummary summary;
  summary.imu_samples = imu.size();
  summary.init = init_window(imu, options.init_window_s);
  summary.init_gyro_bias = initial_gyro_bias(summary.init, options, &summary.gyro_bias_rest_refused);
  summary.gyro_bias_from_rest = options.init_gyro_bias_from_rest && summary.gyro_bias_rest_refused.empty();

  summary.t_first_ns = t0;
  summary.t_last_ns = imu.back().t_ns;
  summary.anchor = choose_anchor(images, t0, summary.t_last_ns, options, symmetries);
  FilterOptions opt = options;
  opt.anchor_id = summary.anchor.id;  // −1 only when no image has a usable detection

  Filter filter(opt, noise, T_I_C_prior, time_offset_prior_s);
  filter.set_symmetries(symmetries);
  filter.set_recording(recording);
  observer.on_start(filter);
  if (recording != nullptr) {
    // One step per IMU sample and per image between samples; a node per segment, per update and per new
    // object. Reserved once: a growing vector would copy every node (~4 kB each) at each doubling.
    recording->steps.reserve(imu.size() + images.size());
    recording->nodes.reserve(2 * images.size() + 16);
  }
  filter.initialize(t0, imu.front().gyro, imu.front().accel, summary.init.mean_accel, &summary.init_gyro_bias);
  summary.prior_T_I_C = filter.T_I_C();
  summary.prior_sigma_I_C = extrinsics_sigma(filter);
  summary.prior_time_offset_s = filter.time_offset_s();
  summary.prior_sigma_time_offset_s = time_offset_sigma(filter);
  observer.on_imu(filter);
  std::size_t j = 0;
  // An image's time in the IMU clock: its stamp (shifted by the declared offset, images.hpp) plus t̂_d − the
  // declared offset (0 unless the filter estimates t_d): OpenVINS's rule, the image is processed where the
  // current estimate of the offset puts it.
  // Kept in time order (reprojection.csv, objects.csv): an update can move t̂_d back, never an image before the last.
  Timestamp last_image_t = std::numeric_limits<Timestamp>::min();
  const auto image_time = [&](const ImageDetections& im) {
    return std::max(im.t_ns + filter.time_offset_shift_ns(), last_image_t);
  };
  const auto reject_no_imu = [&](const ImageDetections& im) {
    FrameResult r;
    r.t_ns = image_time(im);  // in time order with the processed images
    for (const auto& d : im.detections) {
      DetectionOutcome o;
      o.object_id = d.object_id;
      o.status = DetectionStatus::kRejectedNoImu;
      r.detections.push_back(o);
    }
    tally(r, summary.anchor.id, summary);
    observer.on_image(filter, r);
    last_image_t = r.t_ns;
  };
  const auto update = [&](const ImageDetections& im, double dt_image_s) {
    const FrameResult r = filter.update(im.detections, dt_image_s);
    last_image_t = r.t_ns;
    tally(r, summary.anchor.id, summary);
    observer.on_image(filter, r);
    ++summary.images;
  };
  while (j < images.size() && image_time(images[j]) < t0) reject_no_imu(images[j++]);
  while (j < images.size() && image_time(images[j]) == t0) update(images[j++], 0.0);
  for (std::size_t k = 1; k < imu.size(); ++k) {
    const ImuSample& a = imu[k - 1];
    const ImuSample& b = imu[k];
    for (Timestamp te; j < images.size() && (te = image_time(images[j])) < b.t_ns;) {
      if (te < filter.time()) {  // t̂_d moved the image before the filter's time: predicted shifted back
        update(images[j++], dt_seconds(filter.time(), te));
        continue;
      }
      const double alpha = static_cast<double>(te - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
      filter.propagate(te, a.gyro + alpha * (b.gyro - a.gyro), a.accel + alpha * (b.accel - a.accel));
      update(images[j++], 0.0);
    }
    filter.propagate(b.t_ns, b.gyro, b.accel);
    observer.on_imu(filter);
    for (Timestamp te; j < images.size() && (te = image_time(images[j])) <= b.t_ns;)
      update(images[j++], dt_seconds(filter.time(), te));
  }
  while (j < images.size()) reject_no_imu(images[j++]);
  filter.finish_recording();
  summary.updates = filter.n_updates();
  summary.final_T_I_C = filter.T_I_C();
  summary.final_sigma_I_C = extrinsics_sigma(filter);
  summary.final_time_offset_s = filter.time_offset_s();
  summary.final_sigma_time_offset_s = time_offset_sigma(filter);
  summary.detection_sigma_scale = filter.detection_sigma_scale();
  for (const auto& im : images)
    for (const auto& d : im.detections) summary.detection_sigmas_present |= d.sigma.has_value();
  for (const auto& o : filter.objects()) summary.final_T_O_W[o.id] = o.T_O_W;
  return summary;
}

}  // namespace roe::ekf
