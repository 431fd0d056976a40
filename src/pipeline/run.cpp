// The run pipeline of `roe run` (pipeline/run.hpp): dataset in memory → measurement stream → filter →
// smoother → the rows and summary the run files and run.json are made of. No file is read or written here.
#include "roe/pipeline/run.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "roe/core/clock.hpp"
#include "roe/core/error.hpp"
#include "roe/ekf/smoother.hpp"

namespace roe::pipeline {
namespace {

using Clock = SteadyClock;
using store::ObjectRow;
using store::RecordedState;

// Which state rows carry σ (store::RunConfig::output_level): every row; the first row and the first after each
// image (level "standard" at the IMU rate); none (level "minimal": the trajectory only).
enum class SigmaRows { kEvery, kAfterImages, kNone };

SigmaRows sigma_rows(const store::RunConfig& c) {
  if (c.output_level == store::OutputLevel::kMinimal) return SigmaRows::kNone;
  return store::sigma_at_every_row(c) ? SigmaRows::kEvery : SigmaRows::kAfterImages;
}

// The rows in memory: RunOutput's vectors (the batch revises them; tests read them). With the smoother the
// filter's state rows are its own estimate beside the smoothed one: kept in filter_states when the run folder
// has states_filter.csv, else dropped.
class MemorySink : public store::RunRowSink {
 public:
  MemorySink(RunOutput& out, const store::RunConfig& c)
      : out_(out), states_(!c.smoothed() ? &out.states : store::run_folder_has(c, "states_filter.csv") ? &out.filter_states : nullptr) {}
  void state(const RecordedState& row) override {
    if (states_ != nullptr) states_->push_back(row);
  }
  void object(const ObjectRow& row) override { out_.objects.push_back(row); }
  void reprojection(const store::ReprojectionRow& row) override { out_.reprojection.push_back(row); }

 private:
  RunOutput& out_;
  std::vector<RecordedState>* states_;
};

// The smoothed state rows in memory (RunOutput::states): the blocks come from the last to the first.
class MemoryBackward : public store::BackwardStateRows {
 public:
  void block(const std::vector<RecordedState>& rows) override { blocks_.push_back(rows); }
  void take(std::vector<RecordedState>& states) {
    for (auto b = blocks_.rbegin(); b != blocks_.rend(); ++b) states.insert(states.end(), b->begin(), b->end());
    blocks_.clear();
  }

 private:
  std::vector<std::vector<RecordedState>> blocks_;
};

// The times of the filter's state rows and whether each has σ: what the smoothed rows are made of (every row
// of the filter has its smoothed counterpart at the same time, with σ where the smoother formed it).
struct RowTimes {
  std::vector<Timestamp> t;
  std::vector<char> sigma;
};

// Hands the filter's output rows to a sink as they are produced, counting them in `out` (the counts and the
// final state are run_filter's summary). A row without σ has nan in sigma and pose_cov (written as empty
// cells, store/run_files.hpp).
class Recorder : public ekf::FilterObserver {
 public:
  Recorder(RunOutput& out, store::RunRowSink& sink, bool imu_rate, SigmaRows sigma, RowTimes* times)
      : out_(out), sink_(sink), times_(times), imu_rate_(imu_rate), sigma_(sigma) {}

  void on_imu(const ekf::Filter& f) override {
    if (!imu_rate_) return;
    record_state(f, sigma_ == SigmaRows::kEvery || (sigma_ == SigmaRows::kAfterImages && sigma_due_));
    sigma_due_ = false;
  }

  void on_image(ekf::Filter& f, const ekf::FrameResult& r) override {
    if (imu_rate_)
      sigma_due_ = true;
    else
      record_state(f, sigma_ != SigmaRows::kNone);
    for (const auto& d : r.detections) sink_.reprojection({r.t_ns, d.object_id, d});
    if (!r.detections.empty() && (out_.images_with_detections == 0 || r.t_ns != last_image_ns_)) {
      ++out_.images_with_detections;
      last_image_ns_ = r.t_ns;
    }
    if (r.detections.empty() || r.detections.front().status == ekf::DetectionStatus::kRejectedNoImu) return;
    for (const auto& o : f.objects()) {
      ObjectRow row;
      row.t_ns = r.t_ns;
      row.object_id = o.id;
      row.anchor = o.anchor;
      row.T_O_W = o.T_O_W;
      row.sigma = f.object_covariance(o).diagonal().cwiseSqrt();
      row.sigma_W_O = f.object_covariance_in_world(o).diagonal().cwiseMax(0.0).cwiseSqrt();
      if (!o.anchor) row.sigma_A_O = f.object_covariance_relative_to_anchor(o).diagonal().cwiseMax(0.0).cwiseSqrt();
      sink_.object(row);
    }
  }

 private:
  void record_state(const ekf::Filter& f, bool with_sigma) {
    RecordedState s;
    s.t_ns = f.time();
    s.x = f.core();
    s.T_I_C = f.T_I_C();
    s.time_offset_s = f.time_offset_s();
    if (!with_sigma) {
      s.sigma_time_offset_s = std::numeric_limits<double>::quiet_NaN();
      s.sigma.setConstant(std::numeric_limits<double>::quiet_NaN());
      s.pose_cov.setConstant(std::numeric_limits<double>::quiet_NaN());
      put(s);
      return;
    }
    for (int i = 0; i < 15; ++i) s.sigma(i) = std::sqrt(f.variance(i));
    const int e = f.extrinsics_offset();
    for (int i = 0; i < 6; ++i) s.sigma(15 + i) = e >= 0 ? std::sqrt(f.variance(e + i)) : 0.0;
    const int td = f.time_offset_offset();
    s.sigma_time_offset_s = td >= 0 ? std::sqrt(f.variance(td)) : 0.0;
    // Pose covariance [δp; δθ]: the core block of P is always current (no sync needed).
    for (int a = 0; a < 2; ++a)
      for (int b = 0; b < 2; ++b)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            s.pose_cov(3 * a + i, 3 * b + j) = f.core_covariance(a == 0 ? ekf::kP + i : ekf::kTheta + i,
                                                                 b == 0 ? ekf::kP + j : ekf::kTheta + j);
    put(s);
  }

  void put(const RecordedState& s) {
    sink_.state(s);
    ++out_.state_rows;
    if (times_ != nullptr) {
      times_->t.push_back(s.t_ns);
      times_->sigma.push_back(!std::isnan(s.sigma(0)));
    }
  }

  RunOutput& out_;
  store::RunRowSink& sink_;
  RowTimes* times_;
  Timestamp last_image_ns_ = 0;
  bool imu_rate_;
  SigmaRows sigma_;
  bool sigma_due_ = true;  // the first row has σ (the prior), then the first after each image
};

// The smoothed state rows, made from the smoother's states as its backward pass hands them over (the segments
// from the last to the first), one block per segment: each of the filter's rows takes the smoothed state at
// its time (there is one: every row is at the filter's initial time or at the end of a propagation step). A
// constant state without process noise, the time offset, has its final filtered estimate and σ at every
// time (ekf/smoother.hpp), as the extrinsics have.
class SmoothedRows : public ekf::SmoothedStates {
 public:
  SmoothedRows(const RowTimes& rows, const ekf::FilterRunSummary& s, bool consider, store::BackwardStateRows& out)
      : rows_(rows), end_(rows.t.size()), offset_(s.final_time_offset_s), sigma_offset_(s.final_sigma_time_offset_s),
        consider_(consider), sigma_I_C_(s.final_sigma_I_C), out_(out) {}

  void segment(const std::vector<ekf::SmoothedState>& states) override {
    const auto first = rows_.t.begin();
    const auto lo = static_cast<std::size_t>(
        std::lower_bound(first, first + static_cast<std::ptrdiff_t>(end_), states.front().t_ns) - first);
    block_.clear();
    std::size_t k = 0;
    for (std::size_t i = lo; i < end_; ++i) {
      while (k < states.size() && states[k].t_ns < rows_.t[i]) ++k;
      ROE_CHECK(k < states.size() && states[k].t_ns == rows_.t[i], "smoother: a state row without a smoothed state");
      const ekf::SmoothedState& st = states[k];
      RecordedState& row = block_.emplace_back();
      row.t_ns = st.t_ns;
      row.x = st.x;
      row.T_I_C = st.T_I_C;
      row.sigma = st.sigma;
      row.pose_cov = st.pose_cov;
      // consider_correlated_errors: the extrinsics' σ are the filter's reported (consider) σ (docs/filter.md §18).
      if (consider_ && !std::isnan(row.sigma(0))) row.sigma.tail<6>() = sigma_I_C_;
      row.time_offset_s = offset_;
      row.sigma_time_offset_s = std::isnan(row.sigma(0)) ? row.sigma(0) : sigma_offset_;
    }
    end_ = lo;
    out_.block(block_);
  }
  /// Every row has had its smoothed state.
  void finish() const { ROE_CHECK(end_ == 0, "smoother: a state row without a smoothed state"); }

 private:
  const RowTimes& rows_;
  std::size_t end_;  // the rows before it wait for their segment
  double offset_, sigma_offset_;
  bool consider_;
  Vector6d sigma_I_C_;
  store::BackwardStateRows& out_;
  std::vector<RecordedState> block_;
};

}  // namespace

bool streams_rows(const store::RunConfig& config) { return config.estimator != store::Estimator::kBatch; }

std::string choose_detections(const Dataset& d, const std::string& name) {
  std::vector<std::string> names;
  for (const auto& kv : d.detections) names.push_back(kv.first);
  const std::string list = names.empty() ? "none" : fmt::format("{}", fmt::join(names, ", "));
  if (!name.empty()) {
    if (!d.detections.count(name))
      throw InputError(fmt::format("no detection set '{}' in the dataset (available: {})", name, list),
                       {"detections/" + name});
    return name;
  }
  if (names.size() == 1) return names.front();
  if (names.empty())
    throw InputError(
        "the dataset has no detections (detections/<name>/detections.csv); run `roe infer` or "
        "`roe import poet` first",
        {"detections/"});
  throw InputError(
      fmt::format("the dataset has several detection sets ({}); choose one with --detections", list),
      {"detections/"});
}

namespace {

// The filter's IMU noise: the config's value where it gives one (>= 0), else roe.json's; `from` says which.
ekf::ImuNoiseParams imu_noise(const Dataset& d, const ekf::FilterOptions& o, std::array<std::string, 4>& from) {
  ekf::ImuNoiseParams n;
  const ImuNoise* ds = d.manifest.imu ? &d.manifest.imu->noise : nullptr;
  int i = 0;
  const auto pick = [&](double opt, double ImuNoise::*field, const char* key) {
    if (opt >= 0.0) {
      from[i++] = "config";
      return opt;
    }
    if (ds == nullptr || !(ds->*field >= 0.0))
      throw ConfigError(fmt::format("IMU noise unknown: roe.json has no imu.{0}; set filter.{0} in the config "
                                    "(or import a Kalibr imu.yaml with roe import kalibr)",
                                    key),
                        {"roe.json", 0, 0, std::string("imu.") + key});
    from[i++] = "dataset";
    return ds->*field;
  };
  n.gyro_noise_density = pick(o.gyro_noise_density, &ImuNoise::gyro_noise_density, "gyro_noise_density");
  n.gyro_random_walk = pick(o.gyro_random_walk, &ImuNoise::gyro_random_walk, "gyro_random_walk");
  n.accel_noise_density = pick(o.accel_noise_density, &ImuNoise::accel_noise_density, "accel_noise_density");
  n.accel_random_walk = pick(o.accel_random_walk, &ImuNoise::accel_random_walk, "accel_random_walk");
  n.gyro_noise_density *= o.imu_noise_scale;
  n.gyro_random_walk *= o.imu_noise_scale;
  n.accel_noise_density *= o.imu_noise_scale;
  n.accel_random_walk *= o.imu_noise_scale;
  return n;
}

// The smoother over the filter's recording, its rows to `out`. It forms the covariance only where a row has σ
// (every IMU step at level "full"; the mean at the other steps costs O(15²) each, ekf/smoother.hpp).
void smooth_rows(const ekf::FilterRecording& recording, const ekf::ImuNoiseParams& noise, const store::RunConfig& config,
                 const RowTimes& rows, const ekf::FilterRunSummary& summary, store::BackwardStateRows& out) {
  std::vector<Timestamp> sigma_times;
  ekf::SmootherOptions sopt;
  if (!(config.output_rate == store::OutputRate::kImu && sigma_rows(config) == SigmaRows::kEvery)) {
    for (std::size_t i = 0; i < rows.t.size(); ++i)
      if (rows.sigma[i]) sigma_times.push_back(rows.t[i]);
    sopt.covariance_at = &sigma_times;
  }
  SmoothedRows smoothed(rows, summary, config.filter.consider_correlated_errors, out);
  ekf::smooth(recording, noise, smoothed, sopt);
  smoothed.finish();
}

}  // namespace

RunOutput run_dataset(const Dataset& dataset, const std::string& detections_name, const store::RunConfig& config,
                      const RunSinks& sinks) {
  const bool streamed = sinks.filter != nullptr;
  ROE_CHECK(!streamed || (streams_rows(config) && (sinks.smoothed != nullptr) == config.smoothed()),
            "run_dataset: rows stream with the filter alone (one sink) or the smoother (both sinks), not the batch");
  RunOutput out;
  const ekf::FilterOptions& opt = config.filter;
  if (dataset.imu.size() < 2)
    throw InputError(fmt::format("the dataset has no usable IMU stream ({} samples in mav0/imu0/data.csv; "
                                 "at least 2 needed)",
                                 dataset.imu.size()),
                     {"mav0/imu0/data.csv"});
  const std::string set = choose_detections(dataset, detections_name);
  const std::vector<Detection>& dets = dataset.detections.at(set);
  const std::string det_file = "detections/" + set + "/detections.csv";
  if (dets.empty())
    throw DataError(fmt::format("{} has no detections: nothing to fuse with the IMU", det_file), {det_file});

  // Object ids must be declared in roe.json. A dataset that declares none (a RealSense import, whose
  // detections came from `roe import poet` or `roe infer` with the detector's class ids) takes the ids
  // of its detections, with a warning; one that declares objects catches a mismatched detection set.
  std::set<int> known;
  for (const auto& o : dataset.manifest.objects) known.insert(o.id);
  if (known.empty()) {
    for (const auto& d : dets) known.insert(d.object_id);
    out.warnings.push_back(fmt::format("roe.json declares no objects: using the {} object id(s) of {} ({})",
                                       known.size(), det_file, fmt::join(known, ", ")));
  }
  for (std::size_t i = 0; i < dets.size(); ++i) {
    if (!known.count(dets[i].object_id))
      throw InputError(fmt::format("detection of unknown object id {} (roe.json objects: {}); data row {}",
                                   dets[i].object_id, fmt::join(known, ", "), i + 1),
                       {det_file, static_cast<std::int64_t>(i + 2), 2, "object_id"});
  }
  if (opt.anchor_id >= 0) {
    if (!known.count(opt.anchor_id))
      throw ConfigError(fmt::format("anchor_id {} is not an object of this dataset (roe.json objects: {})",
                                    opt.anchor_id, fmt::join(known, ", ")),
                        {"config", 0, 0, "filter.anchor_id"});
    const bool seen = std::any_of(dets.begin(), dets.end(),
                                  [&](const Detection& d) { return d.object_id == opt.anchor_id; });
    if (!seen)
      throw DataError(fmt::format("the anchor object {} is never detected in {}: no update could be made "
                                  "(choose another filter.anchor_id, or -1 for the first object seen)",
                                  opt.anchor_id, det_file),
                      {det_file});
  }

  // Extrinsics prior.
  Pose T_I_C;
  if (dataset.manifest.camera) {
    T_I_C = dataset.manifest.camera->T_I_C;
  } else {
    out.warnings.push_back("roe.json has no camera: T_I_C prior = identity");
  }
  out.prior_T_I_C = T_I_C;
  const Timestamp offset_ns =
      dataset.manifest.camera ? from_seconds(dataset.manifest.camera->time_offset_s) : 0;

  const std::vector<ekf::ImageDetections> images = ekf::group_images(dets, offset_ns);
  const ekf::ImuNoiseParams noise = imu_noise(dataset, opt, out.imu_noise_from);
  out.imu_noise = noise;
  if (noise.gyro_noise_density == 0.0 || noise.accel_noise_density == 0.0)
    out.warnings.push_back(fmt::format(
        "IMU noise density 0 (gyro {:g}, accel {:g}; from the {}): the filter trusts the IMU exactly, which "
        "only a noise-free simulation justifies",
        noise.gyro_noise_density, noise.accel_noise_density,
        out.imu_noise_from[0] == out.imu_noise_from[2] ? out.imu_noise_from[0] : "dataset and config"));
  MemorySink memory(out, config);
  if (!streamed) {
    std::vector<RecordedState>& rows = config.smoothed() ? out.filter_states : out.states;
    if (!config.smoothed() || store::run_folder_has(config, "states_filter.csv"))
      rows.reserve(config.output_rate == store::OutputRate::kImu ? dataset.imu.size() : images.size());
    out.reprojection.reserve(dets.size());
  }
  const bool smooth = config.smoothed();
  RowTimes row_times;
  Recorder rec(out, streamed ? *sinks.filter : memory, config.output_rate == store::OutputRate::kImu, sigma_rows(config),
               smooth ? &row_times : nullptr);
  const auto t0 = Clock::now();
  ekf::FilterRecording recording(sinks.recording);
  std::map<int, ObjectSymmetry> symmetries;
  for (const auto& o : dataset.manifest.objects)
    if (!o.symmetry.empty() || o.symmetric) symmetries[o.id] = o.symmetry;  // empty: symmetric, group unknown
  out.summary =
      ekf::run_filter(dataset.imu, images, opt, noise, T_I_C, rec, smooth ? &recording : nullptr, symmetries,
                      to_seconds(offset_ns));
  out.filter_wall_s = seconds_since(t0);
  if (smooth) {
    const auto t1 = Clock::now();
    MemoryBackward memory_rows;
    smooth_rows(recording, noise, config, row_times, out.summary, streamed ? *sinks.smoothed : memory_rows);
    if (!streamed) memory_rows.take(out.states);
    out.smoothed = true;
    out.smoother_wall_s = seconds_since(t1);
  }

  const std::vector<std::string> w = ekf::run_warnings(out.summary, opt);
  out.warnings.insert(out.warnings.end(), w.begin(), w.end());
  out.health = ekf::assess_health(out.summary, opt, config.health);
  return out;
}

}  // namespace roe::pipeline
