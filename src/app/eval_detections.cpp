// roe eval: the detections whose σ are calibrated against the ground truth (docs/eval.md, "Detection
// uncertainty calibration"), and the truth that goes with them (roe.json).
#include <fmt/format.h>

#include <algorithm>

#include "roe/app/eval.hpp"
#include "roe/core/error.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/input.hpp"
#include "roe/io/json.hpp"
#include "roe/store/run_files.hpp"
#include "roe/store/run_record.hpp"

namespace roe::app {
namespace fs = std::filesystem;

namespace {

/// The detection set a run folder's run.json names (inputs.detections), "" when the folder has no run.json.
std::string run_detection_set(const fs::path& run_dir) {
  const fs::path rj = run_dir / "run.json";
  return io::path_exists(rj) ? store::read_run_json(rj).inputs.detections : std::string();
}

}  // namespace

std::optional<DetectionSigmaSource> load_detection_sigmas(const EvalOptions& o, bool est_is_run,
                                                          std::vector<std::string>& warnings) {
  const bool asked = !o.detections.empty();
  const fs::path gt = o.gt;
  const bool dataset = !gt.empty() && io::is_folder(gt) && io::path_exists(store::manifest_path(gt));
  if (asked && !dataset)
    throw InputError("--detections needs --gt DATASET (a roe dataset folder): the true T_C_O is computed from "
                     "its ground truth and roe.json's truth.T_I_C and truth.objects",
                     {"", 0, 0, "detections"});
  if (!dataset) return std::nullopt;
  fs::path csv;
  if (asked) {
    const fs::path as_file = o.detections;
    csv = io::path_exists(as_file) && !io::is_folder(as_file)
              ? as_file
              : store::detections_dir(gt, o.detections) / "detections.csv";
    if (!io::path_exists(csv))
      throw InputError(fmt::format("--detections {}: neither a detections.csv file nor a detection set of {} ({})",
                                   o.detections, gt.string(), csv.string()),
                       {"", 0, 0, "detections"});
  } else {
    if (!est_is_run) return std::nullopt;
    const std::string set = run_detection_set(o.est);
    if (set.empty()) return std::nullopt;
    csv = store::detections_dir(gt, set) / "detections.csv";
    if (!io::path_exists(csv)) return std::nullopt;
  }
  DetectionSigmaSource s;
  s.detections = store::read_detections_csv(csv);
  const bool any_sigma = std::any_of(s.detections.begin(), s.detections.end(), [](const Detection& d) { return d.sigma.has_value(); });
  if (!any_sigma) {
    if (asked)
      throw InputError("no detection carries sigmas (the six sigma columns are absent or empty): nothing to calibrate",
                       {csv.string()});
    return std::nullopt;
  }
  // The truth: roe.json's truth section (a simulation, or a real recording whose objects were surveyed in
  // the ground truth's world); without truth.T_I_C the calibrated camera.T_I_C stands in.
  const DatasetManifest man = store::read_manifest(gt);
  const std::string mpath = store::manifest_path(gt).string();
  if (!man.truth || man.truth->objects.empty()) {
    const std::string why = mpath + " has no truth.objects: the true object poses T_W_O are needed";
    if (asked) throw InputError("cannot calibrate the detection sigmas: " + why, {mpath, 0, 0, "truth.objects"});
    warnings.push_back("detection sigmas not calibrated: " + why);
    return std::nullopt;
  }
  for (const auto& ob : man.truth->objects) s.T_W_O[ob.id] = ob.T_W_O;
  s.T_I_C = man.truth->T_I_C;
  s.camera_time_offset_s = man.camera ? man.camera->time_offset_s : 0.0;
  s.description = fmt::format("{} against the ground truth with {}'s truth.T_I_C, truth.objects ({}) and camera "
                              "time offset {} s",
                              csv.string(), mpath, s.T_W_O.size(), s.camera_time_offset_s);
  return s;
}

std::optional<eval::GaugeTruth> load_gauge_truth(const fs::path& run_dir, const EvalInput& gt, std::string* why) {
  const auto none = [why](std::string reason) {
    if (why) *why = std::move(reason);
    return std::nullopt;
  };
  const fs::path rj = run_dir / "run.json", objects = run_dir / "objects.csv";
  if (!gt.truth_world || !io::path_exists(store::manifest_path(gt.path)))
    return none("the ground truth is not a dataset's state_groundtruth_estimate0 with a roe.json truth section");
  if (!io::path_exists(rj)) return none("the run folder has no run.json");
  const store::RunRecord run = store::read_run_json(rj);
  if (!io::path_exists(objects)) {
    const std::string level = store::run_file_absent_reason(run.config, "objects.csv");
    return none(level.empty() ? "the run folder has no objects.csv" : level);
  }
  const ekf::AnchorGauge g = run.config.filter.anchor_gauge;
  if (g != ekf::AnchorGauge::kPose && g != ekf::AnchorGauge::kPositionYaw)
    return none(fmt::format("anchor_gauge '{}' leaves the yaw of W to the initial prior, not to the anchor: the truth "
                            "in that gauge is not determined",
                            ekf::to_string(g)));
  if (!run.relocks.empty()) return none("the anchor was re-locked during the run: W changed");
  const int anchor = run.anchor_id;
  const DatasetManifest man = store::read_manifest(gt.path);
  const TruthObject* truth = nullptr;
  if (man.truth)
    for (const auto& ob : man.truth->objects)
      if (ob.id == anchor) truth = &ob;
  if (!truth) return none(fmt::format("{} has no truth for the anchor object {}", store::manifest_path(gt.path).string(), anchor));
  const std::vector<store::ObjectRow> rows = store::read_objects_csv(objects);
  const store::ObjectRow* first = nullptr;
  const store::ObjectRow* last = nullptr;
  for (const auto& r : rows) {
    if (r.object_id != anchor) continue;
    if (!first) first = &r;
    last = &r;
  }
  if (!first) return none(fmt::format("{} has no row of the anchor object {}", objects.string(), anchor));
  const eval::GaugeKind kind = g == ekf::AnchorGauge::kPose ? eval::GaugeKind::kPose : eval::GaugeKind::kPositionYaw;
  eval::GaugeTruth t;
  t.T_Wt_Wg = eval::estimator_gauge(kind, last->T_O_W, truth->T_W_O);
  t.t_from_ns = first->t_ns;
  t.description = fmt::format("anchor_gauge {}: anchor object {} (its T_O_W in {}, its true pose in {}), from its first "
                              "sight at {:.6f} s",
                              ekf::to_string(g), anchor, objects.string(), store::manifest_path(gt.path).string(), to_seconds(first->t_ns));
  return t;
}

}  // namespace roe::app
