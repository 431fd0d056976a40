// roe infer DATASET --model BUNDLE_DIR [--name NAME]
#include <fmt/format.h>

#include <memory>

#include "command.hpp"
#include "roe/app/infer.hpp"

namespace roe::cli {
namespace {

struct Args {
  std::string dataset;
  app::InferOptions opt;
  bool no_cache = false;
};

RunFn setup(CLI::App& sub) {
  auto a = std::make_shared<Args>();
  sub.add_option("DATASET", a->dataset, "Dataset folder with images (mav0/cam0/data.csv + mav0/cam0/data/)")->required();
  sub.add_option("--model", a->opt.model_dir, "Model bundle folder (poet_bundle.json; see scripts/export_poet.py)")->required();
  sub.add_option("--name", a->opt.name, "Detections set name: DATASET/detections/NAME (default: the model id)");
  sub.add_option("--frames", a->opt.frames, "Frame index range A:B (0-based, B exclusive), A:, :B or A");
  sub.add_option("--every", a->opt.every, "Use every N-th frame of the range")->capture_default_str()->check(number_in("integer>=1"));
  sub.add_option("--warp", a->opt.warp, "Virtual-camera warp to the training intrinsics: auto, on, off")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "on", "off"}));
  sub.add_option("--device", a->opt.device, "LibTorch device: auto, cpu, cuda")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "cpu", "cuda"}));
  sub.add_option("--threads", a->opt.threads, "CPU threads of the pose head (0 = one per core; 1 is faster on a busy machine)")
      ->capture_default_str()
      ->check(number_in("integer>=0"));
  sub.add_option("--boxes", a->opt.boxes_file,
                 "External boxes CSV timestamp_ns,class,x1,y1,x2,y2,score (replaces the detector)");
  sub.add_option("--class-map", a->opt.class_map_file,
                 "JSON {\"<model class>\": <object id>} (default: match class names with roe.json objects)");
  sub.add_flag("--no-cache", a->no_cache, "Recompute every selected frame (their cache entries are replaced)");
  return [a]() {
    a->opt.force = globals().force;
    a->opt.use_cache = !a->no_cache;
    Progress bar("infer", 0);
    const auto s = app::run_infer(a->dataset, a->opt, bar.callback());
    bar.finish();
    const std::string human = fmt::format(
        "model {} (config {}), {} of {} frame(s): {} computed, {} reused from the cache\n"
        "  {} detection(s) written to {}\n"
        "  mean time per computed frame: {:.1f} ms{}\n",
        s.model_id, s.config_hash, s.frames_selected, s.frames_in_dataset, s.frames_computed, s.frames_reused,
        s.detections_written, s.output_dir.string(), s.mean_ms_computed, s.warp ? " (virtual-camera warp on)" : "");
    emit(s.to_json(), human);
    return 0;
  };
}

const Registrar reg(kInferCommand.parent, kInferCommand.name, kInferCommand.description, kInferCommand.order,
                    &setup);

}  // namespace
}  // namespace roe::cli
