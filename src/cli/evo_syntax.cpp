// evo's command line in `roe eval`: the positional forms, -r/--pose_relation, refused options (evo_syntax.hpp).
#include "evo_syntax.hpp"

#include <array>
#include <fmt/format.h>
#include <memory>

#include "roe/core/error.hpp"

namespace roe::cli {
namespace {

bool is_format_word(const std::string& w) {
  return w == "tum" || w == "kitti" || w == "euroc" || w == "bag" || w == "bag2";
}

[[noreturn]] void refuse(const std::string& msg, const std::string& key = "") {
  throw InputError(msg, {"roe eval", 0, 0, key});
}

/// evo's form: FORMAT REF EST (files) or bag|bag2 BAG REF_TOPIC EST_TOPIC; with --ref the reference is
/// taken from it and the words hold the estimate only.
EvalInputs evo_form(const std::vector<std::string>& words, const std::string& ref) {
  const std::string& f = words[0];
  EvalInputs in;
  const bool bag = f == "bag" || f == "bag2";
  const std::size_t need = (bag ? 2 : 1) + (ref.empty() ? 1 : 0);  // after the format word
  const std::string usage = bag ? fmt::format("roe eval {} BAG REF_TOPIC EST_TOPIC", f)
                                : fmt::format("roe eval {} REF EST", f);
  if (words.size() - 1 < need)
    refuse(fmt::format("evo's form needs the reference and one estimate after '{}': {} (or --ref REF)", f, usage));
  if (words.size() - 1 > need)
    refuse(fmt::format("roe evaluates one estimate at a time: {} (run it once per estimate, then "
                       "`roe eval --summary` over their report.json files)",
                       usage));
  if (bag) {
    const std::string& file = words[1];
    in.est = file + ":" + words.back();
    in.gt = file + ":" + (ref.empty() ? words[2] : ref);
    return in;
  }
  in.gt = ref.empty() ? words[1] : ref;
  in.est = words.back();
  if (f == "euroc") {
    in.gt_format = "euroc";  // evo_ape euroc: the ground truth is EuRoC's csv, the estimate TUM
    in.est_format = "tum";
  } else {
    in.gt_format = in.est_format = f;
  }
  return in;
}

struct Refusal {
  const char* names;   ///< CLI11 names
  bool takes_value;
  const char* answer;  ///< what to do in roe instead
};

// evo options roe has no use for, and what a roe user does instead.
constexpr std::array<Refusal, 8> kRefusals{{
    {"--save_plot", true, "roe eval --plot writes the figures (PNG + PDF) into OUT/plots"},
    {"--serialize_plot", true, "roe eval --plot writes the figures (PNG + PDF) into OUT/plots"},
    {"--project_to_plane", true, "roe evaluates in 3-D; --plot-mode xy|xz|yz chooses the plane of the figure"},
    {"--change_unit", true, "roe reports metres and degrees (ape_trans_m, ape_rot_deg)"},
    {"--silent", false, "roe's -q keeps the summary off the terminal"},
    {"--no_warnings", false, "roe asks no questions before writing; --force allows replacing an output"},
    {"--logfile", true, "roe writes its report.json and CSV files into --out DIR; warnings go to stderr"},
    {"--ros_map_yaml", true, "roe draws no map underlay"},
}};

}  // namespace

EvalInputs read_eval_words(const std::vector<std::string>& words, const std::string& ref) {
  if (words.empty()) {
    if (!ref.empty()) refuse("--ref names the reference: give the estimate too (roe eval EST --ref REF)", "ref");
    return {};
  }
  if (is_format_word(words[0]) && (words.size() > 1 || !ref.empty())) return evo_form(words, ref);
  if (words.size() == 1) {
    EvalInputs in;
    in.est = words[0];
    in.gt = ref;
    return in;
  }
  if (words.size() == 2)
    refuse(fmt::format("roe eval takes one estimate and the ground truth after --gt: roe eval {1} --gt {0} "
                       "(or evo's order, the reference first, with its format: roe eval tum|kitti|euroc {0} {1})",
                       words[0], words[1]));
  refuse(fmt::format("roe eval takes one estimate ({} words given): roe eval EST --gt GT, or evo's "
                     "roe eval tum|kitti|euroc REF EST / roe eval bag|bag2 BAG REF_TOPIC EST_TOPIC",
                     words.size()));
}

void check_pose_relation(const std::string& r) {
  if (r == "trans_part" || r == "point_distance" || r == "angle_deg" || r.empty()) return;
  if (r == "angle_rad")
    refuse("-r angle_rad: roe reports the rotation error in degrees (ape_rot_deg, evo's angle_deg)",
           "pose_relation");
  if (r == "rot_part" || r == "full")
    refuse(fmt::format("-r {}: roe does not compute the Frobenius norm of the {}; its report holds evo's "
                       "trans_part (ape_trans_m) and angle_deg (ape_rot_deg) together, and per-axis RMSE",
                       r, r == "full" ? "full error matrix" : "rotation error matrix"),
           "pose_relation");
  refuse(fmt::format("-r {}: evo's pose relations are trans_part, rot_part, full, angle_deg, angle_rad and "
                     "point_distance; roe reports trans_part and angle_deg together",
                     r),
         "pose_relation");
}

std::function<void()> add_evo_refusals(CLI::App& sub) {
  std::vector<std::pair<CLI::Option*, const Refusal*>> given;
  auto sink = std::make_shared<std::vector<std::string>>(kRefusals.size());
  for (std::size_t i = 0; i < kRefusals.size(); ++i) {
    const Refusal& r = kRefusals[i];
    CLI::Option* op = r.takes_value ? sub.add_option(r.names, (*sink)[i]) : sub.add_flag(r.names);
    op->group("");  // hidden from --help: accepted only to be answered
    given.emplace_back(op, &r);
  }
  return [given, sink]() {
    for (const auto& [op, r] : given)
      if (op->count() > 0)
        throw InputError(fmt::format("{} is evo's: {}", r->names, r->answer),
                         {"roe eval", 0, 0, std::string(r->names).substr(2)});
  };
}

}  // namespace roe::cli
