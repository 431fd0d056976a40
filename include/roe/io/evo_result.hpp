#pragma once
/// @file
/// evo's result files (evo_ape/evo_rpe --save_results, read by evo_res and evo_fig): a ZIP archive with
/// info.json (title, ref_name, est_name, label), stats.json (rmse, mean, median, std, min, max, sse), one
/// NumPy array per `{name}.npy` member (older evo wrote the same arrays as `.npz` members: both are read)
/// and the trajectories as `{name}.tum` (or `.kitti`) text. Same members, keys and array names as evo's
/// evo/tools/file_interface.py save_res_file / load_res_file.

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "roe/eval/evaluate.hpp"
#include "roe/io/npy.hpp"

namespace roe::io {

struct EvoResult {
  nlohmann::json info = nlohmann::json::object();
  nlohmann::json stats = nlohmann::json::object();
  std::vector<std::pair<std::string, NpyArray>> arrays;          ///< name (member stem) -> array
  std::vector<std::pair<std::string, std::string>> trajectories;  ///< member name (with .tum/.kitti) -> text

  const NpyArray* array(const std::string& name) const;
};

/// Reads an evo result zip; InputError naming the file (and the member) when it is not one: no info.json
/// or stats.json, JSON that is not an object, stats that are not numbers, an array that is not .npy.
EvoResult read_evo_result(const std::filesystem::path& zip);
/// Writes it (members stored, in evo's order: info, stats, arrays, trajectories), atomically.
void write_evo_result(const std::filesystem::path& zip, const EvoResult& r);

/// What evo_ape --pose_relation trans_part --save_results writes for the same evaluation: the title with the
/// alignment, stats of the translation errors |p_est − p_gt| (evo's APE trans_part; equal to
/// report.json's ape_trans_m), error_array, timestamps, seconds_from_start, distances_from_start (along the
/// matched ground truth), distances (along the aligned matched estimate), alignment_transformation_sim3
/// (when aligned) and both matched trajectories as TUM text named after `ref_name` / `est_name`.
EvoResult evo_ape_result(const eval::Report& rep, const std::string& ref_name, const std::string& est_name);

/// What evo_rpe --pose_relation trans_part --save_results writes (evo's default settings: no trajectories in the
/// zip) for the report's RPE block `block`: the title (evo's RPE metric name, the delta, consecutive or all
/// pairs, then the alignment), stats and error_array of |trans(E_ij)| per pair, and for stamped trajectories
/// (`stamped`: not KITTI files associated by index, which evo reads as unstamped paths) seconds_from_start,
/// timestamps, distances_from_start and distances at each pair's second pose j; alignment_transformation_sim3
/// when aligned.
EvoResult evo_rpe_result(const eval::Report& rep, std::size_t block, bool stamped, const std::string& ref_name,
                         const std::string& est_name);

/// True when the file starts like a ZIP archive (a local file header, or the end record of an empty one).
bool looks_like_zip(const std::filesystem::path& file);

}  // namespace roe::io
