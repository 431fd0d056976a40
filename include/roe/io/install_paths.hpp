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

/// The installed copy of a shipped run config (`paper` -> .../configs/paper.json), or empty when there is
/// none. The configs themselves are compiled into roe (app/shipped_configs.hpp); this copy is what a
/// user reads and what run.json names.
std::filesystem::path find_shipped_run_config(const std::string& name);

}  // namespace roe::io
