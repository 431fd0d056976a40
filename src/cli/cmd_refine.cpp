// roe refine RUN_DIR --out RUN_DIR2 [--dataset DATASET] [--loss huber|cauchy|none] [--loss-scale K] ...
// Linked into the helper roe-refine only (it needs Ceres; `roe` forwards the command, forward.cpp), which
// exists only in a build with Ceres.
#include <memory>

#include "command.hpp"
#include "roe/app/refine.hpp"
#include "roe/app/run.hpp"
#include "roe/core/error.hpp"

namespace roe::cli {
namespace {

struct Args {
  std::string run;
  std::string out;
  std::string loss = "cauchy";
  app::RefineCommandOptions opt;
  bool no_covariance = false;
};

RunFn setup(CLI::App& sub) {
  auto a = std::make_shared<Args>();
  sub.add_option("RUN_DIR", a->run, "Run folder written by roe run");
  sub.add_option("--out", a->out, "Output run folder (must not exist or be empty, unless --force)");
  sub.add_option("--dataset", a->opt.dataset, "The run's dataset (default: the one run.json names)");
  sub.add_option("--loss", a->loss, "Robust loss of the detection residuals: cauchy (default), huber or none")
      ->check(CLI::IsMember({"cauchy", "huber", "none"}));
  sub.add_option("--loss-scale", a->opt.refine.loss_scale,
                 "Where the loss leaves the quadratic, in σ of the whitened 6-dof residual (default 3.55 = √χ²₆(0.95))")
      ->check(number_in("positive"));
  sub.add_option("--max-iterations", a->opt.refine.max_iterations, "Ceres iterations (default 50)")
      ->check(number_in("integer>=1"));
  sub.add_option("--linear-solver", a->opt.refine.linear_solver,
                 "sparse_normal_cholesky (default) or sparse_schur")
      ->check(CLI::IsMember({"sparse_normal_cholesky", "sparse_schur"}));
  sub.add_option("--tau", a->opt.refine.tau_s,
                 "Time constant (s) of the detections' Gauss-Markov error the solve whitens with: fitted to the "
                 "residuals when absent; 0 = white (independent detections) (docs/refine.md §2)")
      ->check(number_in("non-negative"));
  sub.add_option("--imu-noise-scale", a->opt.refine.imu_noise_scale,
                 "IMU noise of the batch as a multiple of the nominal (the run's with its imu_noise_scale undone; "
                 "default 1)")
      ->check(number_in("positive"));
  sub.add_option("--fit-rounds", a->opt.refine.fit_rounds,
                 "Error-model fits, each followed by a solve (default 2: at the start, then at the first solution)")
      ->check(number_in("integer>=1"));
  sub.add_flag("--no-covariance", a->no_covariance, "Skip the marginal covariances (σ columns written as 0)");
  return [a]() -> int {
    if (a->run.empty()) throw InputError("RUN_DIR is required", {"roe refine"});
    if (a->out.empty()) throw InputError("--out RUN_DIR2 is required", {"roe refine"});
    a->opt.refine.loss = refine::parse_loss(a->loss);
    a->opt.refine.covariance = !a->no_covariance;
    a->opt.force = globals().force;
    const auto r = app::refine_run(a->run, a->out, a->opt);
    emit(r.to_json(), r.to_text());
    return 0;
  };
}

// roe run's batch estimator runs here: roe-refine is the executable that links it (app/run.hpp).
const bool batch_registered = (app::set_batch_estimator(&app::batch_estimate), true);

const Registrar reg(kRefineCommand.parent, kRefineCommand.name, kRefineCommand.description, kRefineCommand.order,
                    &setup);

}  // namespace
}  // namespace roe::cli
