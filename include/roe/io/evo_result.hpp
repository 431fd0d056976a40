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

/// True when the file starts like a ZIP archive (a local file header).
bool looks_like_zip(const std::filesystem::path& file);

}  // namespace roe::io
