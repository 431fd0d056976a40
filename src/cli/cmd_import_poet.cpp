// roe import poet RESULTS_JSON --into DATASET [--name poet]
#include <fmt/format.h>

#include <memory>

#include "command.hpp"
#include "roe/app/import_poet.hpp"

namespace roe::cli {
namespace {

struct PoetArgs {
  std::string results;
  std::string dataset;
  app::ImportPoetOptions opt;
};

RunFn setup_poet(CLI::App& sub) {
  auto a = std::make_shared<PoetArgs>();
  sub.add_option("RESULTS_JSON", a->results, "PoET's results.json (main.py --inference)")->required();
  sub.add_option("--into", a->dataset, "Dataset folder (roe.json, mav0/cam0/data.csv)")->required();
  sub.add_option("--name", a->opt.name, "Detections set name: DATASET/detections/NAME")->capture_default_str();
  sub.add_option("--rotation", a->opt.rotation, "Form of \"rot\": auto (by shape), matrix (3x3 rows), quat_wxyz")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "matrix", "quat_wxyz"}));
  sub.add_option("--classes", a->opt.classes_file,
                 "PoET class-info JSON {\"1\": \"002_master_chef_can\", ...} (default: YCB-V)");
  sub.add_option("--class-map", a->opt.class_map_file,
                 "JSON {\"<poet class>\": <object id>} (default: match class names with roe.json objects)");
  return [a]() {
    a->opt.force = globals().force;
    const auto s = app::import_poet(a->results, a->dataset, a->opt);
    std::string human = fmt::format(
        "imported {} detection(s) from {} of {} image id(s) into {}\n"
        "  frames without detections: {}, unknown ids skipped: {}\n"
        "  dropped: {} non-finite, {} unmapped class, {} repeated object\n"
        "  score column empty (PoET's results.json has no score)\n",
        s.detections_written, s.images_matched, s.images_in_file, s.output_dir.string(), s.empty_images,
        s.images_unknown, s.dropped_non_finite, s.dropped_unmapped_class, s.dropped_duplicate);
    if (s.sigma_from_log_variances + s.sigma_from_covariance > 0)
      human += fmt::format("  sigma columns: {} from aleatoric log-variances, {} from 6x6 covariances\n",
                           s.sigma_from_log_variances, s.sigma_from_covariance);
    emit(s.to_json(), human);
    return 0;
  };
}

const Registrar reg_poet("import", "poet", "Import detections from PoET's own inference (results.json)", 40,
                         &setup_poet);

}  // namespace
}  // namespace roe::cli
