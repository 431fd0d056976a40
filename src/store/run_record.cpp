// run.json, typed (store/run_record.hpp): one field mapping per block, walked by the writer and by the strict
// reader (json_fields.hpp), so each key is spelled once, here (the "config" block is run_config.cpp's).
#include "roe/store/run_record.hpp"

#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <set>

#include "roe/core/dataset.hpp"
#include "roe/core/error.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"
#include "roe/io/pose_json.hpp"
#include "json_fields.hpp"

namespace roe::store {
namespace fs = std::filesystem;
using io::json;
using io::JsonObject;

namespace {

using json_fields::Problem;

/// run.json's dialect: strict (an unknown key is an error, with io::JsonObject's hints), errors are ConfigErrors
/// (exit 2) naming the file and the key path; poses in io's form.
struct RunJson : json_fields::StrictDialect {
  [[noreturn]] static void fail(const std::string& file, const std::string& path, Problem p, const std::string& detail) {
    throw ConfigError(json_fields::config_words(p, detail, "missing key (is this a run.json written by this version of roe?)"),
                      {file, 0, 0, path});
  }
  static json write_leaf(const Pose& T) { return io::pose_to_json(T); }
  static void read_leaf(const json& x, Pose& T, const std::string& file, const std::string& path) {
    T = io::pose_from_json(x, file, path);
  }
};

// ---------------------------------------------------------------------------------------------- the blocks

template <class A>
void fields(A& a, RunInputs& in) {
  a("dataset", in.dataset), a("dataset_abs", in.dataset_abs), a("detections", in.detections);
  a("sha256", in.sha256);
  a.opt("config", in.config, !in.config.empty()), a.opt("config_abs", in.config_abs, !in.config.empty());
}

template <class A>
void fields(A& a, ekf::DetectionCounts& c) {
  a("detections", c.detections), a("accepted", c.accepted), a("initialized", c.initialized);
  a("rejected_chi2", c.rejected_chi2), a("rejected_no_main", c.rejected_no_main);
  a("rejected_score", c.rejected_score), a("rejected_no_imu", c.rejected_no_imu), a("pending_init", c.pending_init);
}

template <class A>
void fields(A& a, RunCounts& c) {
  a("imu_samples", c.imu_samples), a("camera_frames", c.camera_frames);
  a("images_with_detections", c.images_with_detections), a("updates", c.updates);
  a("trajectory_rows", c.trajectory_rows);
  a.nested("detections", [&](auto& d) {  // every status summed over the objects, and per object
    fields(d, c.detections);
    d("per_object", c.per_object);
  });
}

/// The 6-dof detection NIS; with no value only its count, dof and gate.
template <class A>
void fields(A& a, ekf::NisStats& n) {
  int dof = 6;
  a("count", n.count), a("gate", n.gate);
  a("dof", dof, [](int d) { return std::string(d == 6 ? "" : "expected 6 (the 6-dof detection NIS)"); });
  if (n.count == 0) return;
  a("median", n.median), a("p25", n.p25), a("p75", n.p75), a("p95", n.p95), a("max", n.max), a("mean", n.mean);
  a("fraction_above_gate", n.fraction_above_gate), a("median_ratio", n.median_ratio);
}

/// The limits the run was judged by, in the config's form (run_config.hpp), every key required.
ekf::HealthLimits read_limits(const json* x, const std::string& file, const std::string& path) {
  if (!x) RunJson::fail(file, path, Problem::kMissing, {});
  const json every = health_limits_to_json(ekf::HealthLimits{});
  if (x->is_object())
    for (const auto& [key, value] : every.items())
      if (!x->contains(key)) RunJson::fail(file, path + "." + key, Problem::kMissing, {});
  return health_limits_from_json(*x, file, path);
}

template <class A>
void fields(A& a, RunHealthRecord& h) {
  bool healthy = h.healthy();  // derived: written, and read as a check of problems
  a("problems", h.problems);
  a("healthy", healthy, [&](bool v) {
    return std::string(v == h.healthy() ? "" : "contradicts problems (healthy means no problem)");
  });
  a("duration_s", h.duration_s), a("accepted_updates", h.accepted_updates);
  a("supported_fraction", h.supported_fraction), a("longest_dead_reckoning_s", h.longest_dead_reckoning_s);
  a("longest_dead_reckoning_from_s", h.longest_dead_reckoning_from_s);
  a("longest_dead_reckoning_to_s", h.longest_dead_reckoning_to_s), a("nis_median_ratio", h.nis_median_ratio);
  a.custom(
      "limits", [&] { return health_limits_to_json(h.limits); },
      [&](const json* x, const std::string& file, const std::string& path) { h.limits = read_limits(x, file, path); });
}

template <class A>
void fields(A& a, RelockRecord& e) {
  a("t_s", e.t_s), a("refused_since_s", e.refused_since_s), a("offset", e.offset), a("drift_per_s", e.drift_per_s);
  a("residual_sigma", e.residual_sigma), a("detections", e.detections), a("objects", e.objects);
}

template <class A>
void fields(A& a, DetectionSigmasRecord& d) {
  a("present", d.present), a("used", d.used);
  a("final_scale", d.final_scale, [](double k) {
    return k >= kMinDetectionSigmaScale && k <= kMaxDetectionSigmaScale
               ? std::string()
               : fmt::format("{:g} is not a scale the filter writes (it keeps the detections' σ scale within [{:g}, "
                             "{:g}])",
                             k, kMinDetectionSigmaScale, kMaxDetectionSigmaScale);
  });
}

template <class A>
void fields(A& a, RunInit& s) {
  a("T_I_C", s.T_I_C), a("window_samples", s.window_samples), a("window_s", s.window_s);
  a("accel_mean", s.accel_mean), a("accel_std", s.accel_std), a("gyro_mean", s.gyro_mean);
  a("gyro_std", s.gyro_std), a("gyro_bias", s.gyro_bias);
  a("gyro_bias_from", s.gyro_bias_from, [](const std::string& v) {
    return std::string(v == "rest" || v == "config" ? "" : "expected rest or config");
  });
  a.opt("gyro_bias_rest_refused", s.gyro_bias_rest_refused, !s.gyro_bias_rest_refused.empty());
}

template <class A>
void fields(A& a, FinalObject& f) {
  a("id", f.id), a("anchor", f.anchor), a("T_O_W", f.T_O_W);
}

template <class A>
void fields(A& a, FinalTimeOffset& f) {
  a("estimated", f.estimated), a("declared_s", f.declared_s), a("value_s", f.value_s), a("sigma_s", f.sigma_s);
}

/// The four noise values (io's keys, io::imu_noise_to_json; all required here) and where each came from.
template <class A>
void imu_noise_fields(A& a, RunRecord& r) {
  a.merge([&](json& j) { j.update(io::imu_noise_to_json(r.imu_noise)); },
          [&](io::JsonObject& o, const std::string& path) {
            ImuNoise n;
            io::read_imu_noise(o, n);
            if (!n.known()) throw ConfigError("the four noise values are required", {o.source(), 0, 0, path});
            r.imu_noise = {n.gyro_noise_density, n.gyro_random_walk, n.accel_noise_density, n.accel_random_walk};
          });
  a.nested("from", [&](auto& f) {
    for (int i = 0; i < 4; ++i)
      f(io::kImuNoiseKeys[i], r.imu_noise_from[i], [](const std::string& v) {
        return std::string(v == "config" || v == "dataset" ? "" : "expected config or dataset");
      });
  });
}

/// The refine block (docs/refine.md §2). A roe refine before issue 48 (2026-12-07) wrote white detection
/// factors whose marginals were inflated by a fitted correlation ("options.correlated_errors",
/// "detection_error_model.autocovariance"): its options are read as far as today's record has them; its error
/// model has no counterpart and is checked to be an object and left out (RefineRecord::earlier_layout says so,
/// the model's numbers read as nan). The writer writes today's layout.
template <class A>
void fields(A& a, RefineRecord& r) {
  static constexpr const char* kOptions = "options";
  static constexpr const char* kModel = "detection_error_model";
  static constexpr const char* kCorrelated = "correlated_errors";
  const json* options = a.peek(kOptions);
  const bool earlier = options && options->is_object() && options->contains(kCorrelated);
  a.nested(kOptions, [&](auto& p) {
    p("loss", r.loss), p("loss_scale", r.loss_scale), p("max_iterations", r.max_iterations);
    p("linear_solver", r.linear_solver), p("covariance", r.covariance);
    if (earlier) {
      bool correlated = false;
      return p(kCorrelated, correlated);
    }
    p("tau_s", r.tau_s_option), p("fit_rounds", r.fit_rounds), p("gross_chi2", r.gross_chi2);
    p("imu_noise_scale", r.imu_noise_scale);
  });
  if (earlier) {
    const json* m = a.peek(kModel);
    a.check(kModel, m && m->is_object(), "expected an object");
    a.fixed(kModel, nullptr);
    if constexpr (A::kReading) {
      r.earlier_layout = true;
      r.solves = r.fit_rounds = 1;
      RefineRecord::ErrorModel& e = r.error_model;
      e.tau_s = e.scale_translation = e.scale_rotation = e.whitened_lag1 = std::numeric_limits<double>::quiet_NaN();
    }
  } else {
    a(kModel, r.error_model), a("solves", r.solves);
  }
  a("nodes", r.nodes), a("imu_factors", r.imu_factors), a("detection_factors", r.detection_factors);
  a("detections_weight_below_half", r.detections_weight_below_half), a("parameters", r.parameters);
  a("residuals", r.residuals), a("iterations", r.iterations), a("initial_cost", r.initial_cost);
  a("final_cost", r.final_cost), a("termination", r.termination), a("covariance_ok", r.covariance_ok);
  a("input_run", r.input_run), a("input_run_abs", r.input_run_abs), a("dataset", r.dataset);
}

template <class A>
void fields(A& a, RefineRecord::ErrorModel& m) {
  a("tau_s", m.tau_s), a("fitted_tau", m.fitted_tau), a("scale_translation", m.scale_translation);
  a("scale_rotation", m.scale_rotation), a("whitened_lag1", m.whitened_lag1), a("used", m.used), a("gross", m.gross);
}

RunConfig read_config(const json* x, const std::string& file, const std::string& path);

template <class A>
void fields(A& a, RunRecord& r) {
  a("roe_version", r.roe_version);
  a("command", r.command, [](const std::string& c) {
    return c == "run" || c == "refine" ? std::string() : fmt::format("a run.json of roe run or roe refine, not of roe {}", c);
  });
  a.custom(
      "config", [&] { return run_config_to_json(r.config); },
      [&](const json* x, const std::string& file, const std::string& path) { r.config = read_config(x, file, path); });
  a("inputs", r.inputs), a("anchor_id", r.anchor_id), a("counts", r.counts), a("nis", r.nis);
  a("health", r.health), a("relocks", r.relocks), a("detection_sigmas", r.detection_sigmas), a("init", r.init);
  a.nested("imu_noise", [&](auto& n) { imu_noise_fields(n, r); });
  a.nested("final", [&](auto& f) {
    f("T_I_C", r.final_T_I_C), f("objects", r.final_objects), f.omittable("time_offset", r.final_time_offset);
  });
  a("warnings", r.warnings), a("timing_s", r.timing_s);
  // roe refine, or roe run's batch estimator: the block is there exactly then.
  a.omittable("refine", r.refine, r.command == "refine" || r.config.estimator == Estimator::kBatch);
}

}  // namespace

/// run.json records the whole configuration a run ran with (run_config_to_json writes every key): a key of
/// `whole` (the defaults, written the same way) missing from `written` is refused, naming its path, instead of
/// being filled with a default the run may not have used. Object values are compared key by key.
///
/// The one exception is a key added to the configuration after run.json files were already written (an older
/// roe wrote none): each is listed here with what its default means, and that default must be exactly what
/// the older roe did, so an absent key reads as the configuration the run really used (docs/filter.md §9).
namespace {
const std::set<std::string>& keys_added_later() {
  static const std::set<std::string> keys = {
      "config.filter.estimate_time_offset",  // issue 49, 2026-12-07: false = no t_d state (the older filter)
      "config.filter.time_offset_sigma_s",   // its prior σ: unused while estimate_time_offset is false
      "config.filter.max_time_offset_s",      // its guard rail: unused while estimate_time_offset is false
      "config.filter.detection_error_states",  // issue 49 item 1, 2026-12-07: false = no Gauss–Markov error states
      "config.filter.detection_error_correlated_share",  // their share of the variance: unused while they are off
      "config.filter.consider_correlated_errors",  // issue 49 item 1: false = no consider covariance (σ from P)
  };
  return keys;
}

void require_whole_config(const json& written, const json& whole, const std::string& source, const std::string& path) {
  if (!written.is_object() || !whole.is_object()) return;  // the strict reader says what is wrong with the value
  for (const auto& [key, value] : whole.items()) {
    const std::string at = path + "." + key;
    if (!written.contains(key) && keys_added_later().count(at)) continue;
    // "estimator" replaced "smoother" (issue 48): a run.json written before has the old key, read as its value.
    if (at == "config.estimator" && written.contains("smoother")) continue;
    if (!written.contains(key))
      throw ConfigError("missing key: run.json records the whole configuration the run used (a run.json of another "
                        "version of roe, or edited?)",
                        {source, 0, 0, at});
    require_whole_config(written[key], value, source, at);
  }
}
}  // namespace

namespace {
/// run.json's "config": every key of today's configuration (require_whole_config), then its own strict reader,
/// whose key paths are put under "config.".
RunConfig read_config(const json* x, const std::string& file, const std::string& path) {
  if (!x) RunJson::fail(file, path, Problem::kMissing, {});
  require_whole_config(*x, run_config_to_json(RunConfig{}), file, path);
  try {
    return run_config_from_json(*x, file);
  } catch (const ConfigError& e) {
    const ErrorContext& c = e.context();
    throw ConfigError(e.bare_message(), {c.file, c.line, c.column, c.key.empty() ? path : path + "." + c.key});
  }
}
}  // namespace

json run_record_to_json(const RunRecord& r) { return json_fields::write<RunJson>(r); }

RunRecord run_record_from_json(const json& j, const std::string& source) {
  if (!j.is_object()) throw ConfigError("expected a JSON object (a run.json of roe run)", {source});
  RunRecord r;
  json_fields::read<RunJson>(j, r, source);
  return r;
}

std::string format_run_json(const RunRecord& r) { return io::dump_json(run_record_to_json(r), 2) + "\n"; }

void write_run_json(const fs::path& file, const RunRecord& r) { io::write_file_atomic(file, format_run_json(r)); }

RunRecord read_run_json(const fs::path& file) { return io::read_json_file(file, run_record_from_json); }

RunRecord read_run_folder_record(const fs::path& run_dir) {
  std::error_code ec;
  if (!fs::is_regular_file(run_dir / "run.json", ec))
    throw InputError("not a run folder: run.json is missing", {run_dir.string()});
  return read_run_json(run_dir / "run.json");
}

std::optional<fs::path> find_run_dataset(const RunRecord& r) {
  std::error_code ec;
  for (const std::string& d : {r.inputs.dataset_abs, r.inputs.dataset})
    if (!d.empty() && fs::is_regular_file(fs::path(d) / "roe.json", ec)) return fs::path(d);
  return std::nullopt;
}

}  // namespace roe::store
