#pragma once
/// @file
/// Where the files roe ships live at run time, for a build tree and for an installation alike
/// (`make install PREFIX=...`, docs/install.md):
///   build tree:    SRC/build/roe, SRC/build/roe-image, SRC/build/roe-infer, SRC/configs/*.json
///   installation:  PREFIX/bin/roe, PREFIX/libexec/roe/roe-{image,infer}, PREFIX/share/roe/configs/*.json
/// Both are found relative to the running executable, so a relocated installation keeps working.

#include <filesystem>
#include <string>
#include <vector>

namespace roe::io {

/// The folder of the running executable (from /proc/self/exe); empty when it cannot be read.
std::filesystem::path executable_dir();

/// The folders that may hold roe's shipped data (configs/, scripts/), most specific first:
/// EXE_DIR/../share/roe (installed), EXE_DIR/.. (a build folder inside the source tree).
std::vector<std::filesystem::path> shipped_data_roots();

/// A shipped run config by name (`paper` -> .../configs/paper.json), or empty when there is none.
std::filesystem::path find_shipped_run_config(const std::string& name);

/// The names of the shipped run configs (configs/*.json of the first root that has any), sorted.
std::vector<std::string> shipped_run_config_names();

}  // namespace roe::io
