// roe simulate --preset NAME|--config FILE [--seed N] [--duration S] --out DATASET
// roe simulate --from-groundtruth EUROC_MAV0_DIR [--objects N] [--seed N] --out DATASET
// roe simulate --list-presets
#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <memory>

#include "command.hpp"
#include "roe/app/simulate.hpp"
#include "roe/core/error.hpp"

namespace roe::cli {
namespace {

struct SimulateArgs {
  app::SimulateOptions opt;
  std::string out;
  double duration = 0.0;
  double time_offset = 0.0;
  CLI::Option* time_offset_opt = nullptr;
  int objects = 0;
  std::int64_t seed = 1;
  bool list = false;
  CLI::Option* duration_opt = nullptr;
  CLI::Option* objects_opt = nullptr;
};

RunFn setup_simulate(CLI::App& sub) {
  auto a = std::make_shared<SimulateArgs>();
  sub.add_flag("--list-presets", a->list, "List the built-in presets (configs/sim/*.json) and exit");
  sub.add_option("--preset", a->opt.preset, "Built-in preset, e.g. paper-seq4, noise-free, matched");
  sub.add_option("--config", a->opt.config_file, "Simulator config JSON (keys: docs/simulator.md)");
  sub.add_option("--seed", a->seed, "Random seed (integer >= 0): varies the trajectory and all noise")
      ->check(CLI::Validator(
          [](std::string& s) {
            const bool digits = !s.empty() && s.size() <= 18 &&
                                std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
            return digits ? std::string() : "must be an integer >= 0 (at most 18 digits), got '" + s + "'";
          },
          "INT>=0"))
      ->capture_default_str();
  a->duration_opt =
      sub.add_option("--duration", a->duration, "Sequence length in seconds (overrides the config)");
  sub.add_option("--from-groundtruth", a->opt.from_groundtruth,
                 "EuRoC mav0 folder: keep its IMU and ground truth, synthesise detections");
  a->objects_opt =
      sub.add_option("--objects", a->objects, "Number of objects for --from-groundtruth (default 3)");
  a->time_offset_opt = sub.add_option(
      "--time-offset", a->time_offset,
      "True camera-IMU time offset in seconds, t_imu = t_cam + S (overrides camera.time_offset_s of the config; "
      "roe.json keeps the declared offset)");
  sub.add_option("--out", a->out, "Output dataset folder (must not exist or be empty, unless --force)");
  sub.add_flag("--models-info", a->opt.models_info,
               "Write the symmetric objects' symmetries (the ones the flips use) to models_info.json and point "
               "roe.json's objects at it");
  return [a]() {
    if (a->list) {
      nlohmann::json j = nlohmann::json::array();
      std::string human;
      for (const auto& n : app::list_presets()) {
        const std::string d = app::preset_description(n);
        j.push_back({{"name", n}, {"description", d}});
        human += fmt::format("{:<12} {}\n", n, d);
      }
      emit({{"presets", j}}, human, /*listing=*/true);
      return 0;
    }
    if (a->out.empty()) throw InputError("--out DATASET is required", {"roe simulate"});
    if (*a->duration_opt) a->opt.duration_s = a->duration;
    if (*a->time_offset_opt) a->opt.time_offset_s = a->time_offset;
    if (*a->objects_opt) a->opt.objects = a->objects;
    a->opt.force = globals().force;
    a->opt.seed = static_cast<std::uint64_t>(a->seed);
    const auto r = app::simulate(a->opt, a->out);
    emit(r.to_json(), r.to_text());
    return 0;
  };
}

const Registrar reg_simulate("", "simulate",
                             "Simulate a dataset (IMU, mocap, PoET-like detections) or detections on EuRoC",
                             10, &setup_simulate);

}  // namespace
}  // namespace roe::cli
