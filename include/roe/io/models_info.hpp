#pragma once
/// @file
/// Object symmetries from a BOP `models_info.json` (the BOP toolkit's format; Hodaň et al., ECCV 2018):
/// a JSON object keyed by the object id as a decimal string, each entry with the model's `diameter`,
/// `min_x/y/z`, `size_x/y/z` (mm) and optionally
///   `symmetries_discrete`: a list of 4x4 transforms S, each 16 numbers row-major, translation in mm;
///   `symmetries_continuous`: a list of {"axis": [3], "offset": [3] (mm)}.
/// Read strictly: unknown keys, a transform that is not a rigid motion (last row 0 0 0 1, rotation
/// orthonormal with det +1 within 1e-4), a zero axis or more than one continuous symmetry are errors naming
/// the file, line, column and key path (exit 2). Translations are converted to metres, axes normalised.

#include <filesystem>
#include <map>
#include <string>

#include "roe/core/symmetry.hpp"
#include "roe/io/json.hpp"

namespace roe::io {

/// Object id → its symmetries (objects without any have an empty ObjectSymmetry).
std::map<int, ObjectSymmetry> models_info_from_json(const json& j, const std::string& source);
std::map<int, ObjectSymmetry> read_models_info(const std::filesystem::path& file);

/// The symmetries as a BOP models_info object (ids as keys, translations and offsets in mm; no model
/// dimensions, which the reader does not need), and written atomically to `file`. Reading it back gives
/// the same symmetries (to the rounding of the mm conversion).
json models_info_to_json(const std::map<int, ObjectSymmetry>& symmetries);
void write_models_info(const std::filesystem::path& file, const std::map<int, ObjectSymmetry>& symmetries);

}  // namespace roe::io
