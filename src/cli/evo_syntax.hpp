#pragma once
/// @file
/// evo's command line as `roe eval` reads it (docs/eval.md, "evo's command line"): evo_ape's
///   roe eval tum|kitti|euroc REF EST [options]      roe eval bag|bag2 BAG REF_TOPIC EST_TOPIC [options]
/// (the reference first, as evo), evo_traj's --ref, -r/--pose_relation, and evo's options that roe has no
/// use for, answered with roe's spelling. Internal to src/cli: the command's words and options in, roe's
/// estimate / ground truth / formats out; every refusal an InputError naming the option.

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace roe::cli {

/// Where `roe eval`'s positional words and --ref point.
struct EvalInputs {
  std::string est, gt;                          ///< empty: not given by the words
  std::string est_format = "auto", gt_format = "auto";
};

/// The estimate and ground truth that the positional `words` (and evo_traj's --ref, "" when absent) name:
/// one word is the estimate (roe's own form); a format word (tum, kitti, euroc, bag, bag2) starts evo's form
/// with the reference first. Two plain words are refused with the roe and the evo spelling of the call.
EvalInputs read_eval_words(const std::vector<std::string>& words, const std::string& ref);

/// evo's -r/--pose_relation: trans_part, point_distance (the same APE magnitudes as trans_part) and
/// angle_deg are what roe's report holds (ape_trans_m, ape_rot_deg); the others are refused naming them.
void check_pose_relation(const std::string& relation);

/// evo options that roe does not take, registered (hidden) so that giving one is answered with what to do
/// in roe instead of "not expected". Returns a function that throws for the first one given.
std::function<void()> add_evo_refusals(CLI::App& sub);

}  // namespace roe::cli
