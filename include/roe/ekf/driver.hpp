#pragma once
/// @file
/// Runs the filter over a time-sorted IMU stream and a time-sorted list of images (the detections of
/// each image already grouped), in the IMU clock. I/O-free: the states go to an observer; what a run
/// report needs (anchor, per-object counts, NIS, update times, final state) to FilterRunSummary.
///
/// Timeline: the filter starts at the first IMU sample (roll/pitch from the accelerometer mean over
/// FilterOptions::init_window_s). Between samples k−1 and k an image at t_f is handled by propagating
/// to t_f with the IMU measurement linearly interpolated at t_f, updating, and then propagating on to
/// sample k. Images before the first or after the last IMU sample are reported as rejected_no_imu.

#include <map>
#include <string>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/ekf/filter.hpp"
#include "roe/ekf/images.hpp"

namespace roe::ekf {

class FilterObserver {
 public:
  virtual ~FilterObserver() = default;
  /// Once, on the new filter before its initialisation (tests: Filter::set_reference_arithmetic).
  virtual void on_start(Filter& /*filter*/) {}
  /// After initialisation and after every IMU propagation step (the IMU-rate trajectory).
  virtual void on_imu(const Filter& /*filter*/) {}
  /// After each image.
  virtual void on_image(Filter& /*filter*/, const FrameResult& /*result*/) {}
};

/// The IMU samples of the init window [t0, t0 + init_window_s] (at least the first sample).
struct InitWindow {
  int samples = 0;
  double duration_s = 0.0;  ///< last − first stamp of the window
  Vec3 mean_gyro = Vec3::Zero();
  Vec3 mean_accel = Vec3::Zero();
  Vec3 std_gyro = Vec3::Zero();  ///< per-axis sample σ (0 for one sample)
  Vec3 std_accel = Vec3::Zero();
};

/// Means and per-axis σ of the samples of `imu` (non-empty, sorted) within window_s of the first.
InitWindow init_window(const std::vector<ImuSample>& imu, double window_s);

/// The gyro bias the filter starts with: the window's gyro mean when options.init_gyro_bias_from_rest
/// and the window is at rest (≥ 2 samples, σ within the thresholds), else options.init_gyro_bias.
/// `why_not` (may be null) receives the reason when the rest estimate was asked for but not taken.
Vec3 initial_gyro_bias(const InitWindow& w, const FilterOptions& options, std::string* why_not);

/// What happened to the detections of one object (or of all: operator+=), by status.
struct DetectionCounts {
  std::size_t detections = 0, accepted = 0, initialized = 0, rejected_chi2 = 0, rejected_no_main = 0,
              rejected_score = 0, rejected_no_imu = 0, pending_init = 0;
  void add(DetectionStatus s);
  DetectionCounts& operator+=(const DetectionCounts& o);
};

struct FilterRunSummary {
  std::size_t imu_samples = 0;
  std::size_t images = 0;
  std::size_t updates = 0;
  Timestamp t_first_ns = 0, t_last_ns = 0;  ///< the IMU span (the trajectory's)
  InitWindow init;                   ///< the init window's statistics
  Vec3 init_gyro_bias = Vec3::Zero();  ///< the gyro bias the filter started with
  bool gyro_bias_from_rest = false;  ///< init_gyro_bias is the window's gyro mean
  std::string gyro_bias_rest_refused;  ///< why not, when init_gyro_bias_from_rest was asked for
  AnchorChoice anchor;                 ///< the anchor and how it was chosen (choose_anchor)
  std::map<int, DetectionCounts> counts;  ///< per object id
  /// rejected_no_main detections in images whose anchor detection was awaiting or getting its
  /// initialisation (init_min_detections): the anchor was there, just not usable yet.
  std::size_t no_main_anchor_pending = 0;
  std::vector<double> nis;                ///< every finite NIS (6 dof), in time order
  /// Images whose accepted update used a detection's position (with gate_mode split an update of
  /// rotations alone does not count: it does not bound the position's drift).
  std::vector<Timestamp> update_times;
  /// Where the position estimate was declared lost and re-locked (FilterOptions::relock_after_s).
  struct RelockEvent {
    Timestamp t_ns = 0;
    Relock what;
  };
  std::vector<RelockEvent> relocks;
  Pose final_T_I_C;                       ///< the filter's extrinsics at the end
  Pose prior_T_I_C;                       ///< the extrinsics it started from
  /// σ of the extrinsics at the start and at the end [p (m), θ (rad)] (0 when held fixed).
  Vector6d prior_sigma_I_C = Vector6d::Zero(), final_sigma_I_C = Vector6d::Zero();
  /// The camera–IMU time offset t_d (s) at the start (the declared value) and at the end, and its σ (0 when it
  /// is not estimated: FilterOptions::estimate_time_offset).
  double prior_time_offset_s = 0.0, final_time_offset_s = 0.0;
  double prior_sigma_time_offset_s = 0.0, final_sigma_time_offset_s = 0.0;
  /// Per object, the rotation residual angle (deg) of its gated 6-row detections in time order
  /// (DetectionOutcome::rot_residual_deg): an object-world that keeps a large one is suspect (health.hpp).
  std::map<int, std::vector<double>> rot_residual_deg;
  bool detection_sigmas_present = false;  ///< some detection carries its own σ
  /// The factor on the per-detection σ at the end (adapt_detection_sigma_scale; 1 otherwise).
  double detection_sigma_scale = 1.0;
  std::map<int, Pose> final_T_O_W;        ///< the filter's object-worlds at the end
};

/// Runs the whole stream. With FilterOptions::anchor_id −1 the anchor is chosen by choose_anchor over
/// all `images` (images.hpp) before the filter starts. Throws roe::DataError when the IMU stream is too short or not strictly
/// increasing, or the images are not sorted; roe::NumericError when the filter diverges. With
/// `recording`, the filter records what smooth() (smoother.hpp) needs. `symmetries`: the objects'
/// symmetries (Filter::set_symmetries), e.g. from the dataset's models_info files; an empty entry marks an
/// object symmetric with its group unknown (the anchor rule avoids it; the filter ignores it).
/// `time_offset_prior_s`: the declared camera–IMU offset the images' stamps hold (group_images); with
/// FilterOptions::estimate_time_offset each image is processed at its stamp + t̂_d − this (docs/filter.md §16).
FilterRunSummary run_filter(const std::vector<ImuSample>& imu, const std::vector<ImageDetections>& images,
                            const FilterOptions& options, const ImuNoiseParams& noise,
                            const Pose& T_I_C_prior, FilterObserver& observer,
                            FilterRecording* recording = nullptr,
                            const std::map<int, ObjectSymmetry>& symmetries = {},
                            double time_offset_prior_s = 0.0);

}  // namespace roe::ekf
