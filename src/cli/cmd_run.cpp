// roe run DATASET [--config NAME|FILE] [--detections NAME] [--output full|standard|minimal] --out RUN_DIR
// roe run --list-configs
#include <fmt/format.h>

#include <iostream>
#include <memory>

#include "command.hpp"
#include "roe/app/run.hpp"
#include "roe/app/shipped_configs.hpp"
#include "roe/core/error.hpp"
#include "roe/io/json.hpp"

namespace roe::cli {
namespace {

struct Args {
  std::string dataset;
  std::string out;
  app::RunOptions opt;
  bool list = false;
};

RunFn setup(CLI::App& sub) {
  auto a = std::make_shared<Args>();
  sub.add_option("DATASET", a->dataset, "Dataset folder (roe.json, mav0/imu0, detections/<name>/)");
  sub.add_option("--config", a->opt.config_file,
                 "Run config: a shipped name (default, paper, euroc-flight; see --list-configs) or a JSON file "
                 "{\"filter\": {...}, \"output\": {...}}");
  sub.add_flag("--list-configs", a->list, "List the shipped run configs and exit");
  sub.add_option("--detections", a->opt.detections, "Detection set detections/NAME (default: the only one)");
  sub.add_option("--output", a->opt.output_level,
                 "What RUN_DIR holds: full (every file, σ at every row; default), standard (σ only after each "
                 "image: faster, smaller), minimal (trajectory.csv/.tum and run.json only); overrides the "
                 "config's \"output\": {\"level\"}")
      ->check(CLI::IsMember(store::output_levels()));
  sub.add_option("--estimator", a->opt.estimator,
                 "What writes the main files: filter (causal), smoother (the filter + RTS smoother; roe's default) or "
                 "batch (the smoother's estimate refined by roe refine's batch MAP in the same run; needs Ceres); "
                 "overrides the config's \"estimator\" (docs/refine.md §8)")
      ->check(CLI::IsMember(store::estimators()));
  sub.add_option("--out", a->out, "Output run folder (must not exist or be empty, unless --force)");
  return [a]() {
    if (a->list) {
      nlohmann::json j = nlohmann::json::array();
      std::string human;
      for (const auto& c : app::shipped_run_configs()) {
        j.push_back({{"name", c.name}, {"path", c.path.string()}, {"description", c.description}});
        human += fmt::format("{:<14} {}\n{:<14} {}\n", c.name, c.summary, "", c.path.string());
      }
      emit({{"configs", j}}, human);
      return 0;
    }
    if (a->dataset.empty()) throw InputError("DATASET is required", {"roe run"});
    if (a->out.empty()) throw InputError("--out RUN_DIR is required", {"roe run"});
    if (!a->opt.config_file.empty()) a->opt.config_file = app::resolve_run_config(a->opt.config_file).string();
    a->opt.force = globals().force;
    // The batch estimator needs Ceres, which only the helper roe-refine links: hand it the whole command line
    // before anything is read or written (docs/architecture.md, "Executables").
    if (app::effective_run_config(a->opt).estimator == store::Estimator::kBatch && !runs_here("", "refine")) {
      std::string error;
      int code = 3;
      const std::string asked = a->opt.estimator.empty() ? "run with \"estimator\": \"batch\" (" + a->opt.config_file + ")"
                                                         : std::string("run --estimator batch");
      if (exec_helper(kRefineCommand, globals().argc, globals().argv, error, code, asked)) return 0;
      if (code == 2) throw InputError(error);
      std::cerr << "roe: error: " << error << "\n";  // 3: the helper is not installed (main's forwarding says the same)
      if (globals().json)
        std::cout << io::dump_json({{"command", "run"}, {"error", {{"message", error}}}, {"exit_code", code}}, 2)
                  << std::endl;
      return code;
    }
    const auto r = app::run(a->dataset, a->out, a->opt);
    emit(r.to_json(), r.to_text());
    // An unsupported estimate must not look like a result: RUN_DIR is written (to look into), the exit
    // code says the run cannot be trusted and why (run.json "health", limits in the config's "health").
    if (!r.output.health.healthy()) {
      std::cerr << "roe: error: the run in " << a->out
                << " cannot be trusted (limits: the config's \"health\", docs/filter.md §11):\n";
      for (const auto& p : r.output.health.problems) std::cerr << "  " << p << "\n";
      return 1;
    }
    return 0;
  };
}

const Registrar reg("", "run", "Run the self-calibrating multi-object EKF on a dataset", 40, &setup);

}  // namespace
}  // namespace roe::cli
