// Start-up cost (issues 24 and 53): `roe` itself maps neither OpenCV, LibTorch nor Ceres (with SuiteSparse,
// BLAS, LAPACK and glog); the commands that need them run in helper executables that `roe` replaces itself
// with, transparently for the caller.
#include <catch2/catch.hpp>
#include <filesystem>
#include <string>

#include "support/test_util.hpp"

namespace fs = std::filesystem;
using roe::test::run_roe;

namespace {

/// Runs a shell command and returns its output (stderr merged).
std::string shell(const std::string& cmd) { return roe::test::run_shell(cmd).out; }

/// The shared libraries the dynamic loader maps for `exe` (ldd's list: the whole closure of DT_NEEDED).
std::string loaded_libraries(const fs::path& exe) {
  const std::string out = shell("ldd '" + exe.string() + "'");
  REQUIRE(out.find("libc.so") != std::string::npos);  // ldd worked
  return out;
}

const fs::path kRoe = ROE_BINARY;

}  // namespace

TEST_CASE("roe maps neither OpenCV, LibTorch nor Ceres, and cannot load them later", "[cli][startup]") {
  const std::string libs = loaded_libraries(kRoe);
  INFO(libs);
  CHECK(libs.find("libceres") == std::string::npos);
  CHECK(libs.find("libcholmod") == std::string::npos);
  CHECK(libs.find("libglog") == std::string::npos);
  CHECK(libs.find("libblas") == std::string::npos);
  CHECK(libs.find("liblapack") == std::string::npos);
  CHECK(libs.find("libopencv") == std::string::npos);
  CHECK(libs.find("libtorch") == std::string::npos);
  CHECK(libs.find("libc10") == std::string::npos);
  CHECK(libs.find("libgdal") == std::string::npos);
  const std::string dyn = shell("nm -D --undefined-only '" + kRoe.string() + "'");
  REQUIRE(dyn.find("execv") != std::string::npos);  // nm worked, and the forwarder is linked in
  // No dlopen in roe's own code: what ldd lists is all that roe itself ever maps. The binary may import dlopen
  // for the static libcrypto and SQLite (cmake/static_deps.cmake: OpenSSL's provider modules, SQLite's
  // load_extension, neither called by roe), so roe's own archives are checked, each of them.
  const std::string own = shell("cd '" + kRoe.parent_path().string() + "' && for a in libroe_*.a; do nm -u \"$a\"; done");
  REQUIRE(own.find("_ZN3roe") != std::string::npos);  // nm read roe's archives
  CHECK(own.find("dlopen") == std::string::npos);
}

TEST_CASE("the image helper maps OpenCV but not LibTorch", "[cli][startup]") {
  const std::string libs = loaded_libraries(kRoe.parent_path() / "roe-image");
  INFO(libs);
  CHECK(libs.find("libopencv_imgcodecs") != std::string::npos);
  CHECK(libs.find("libopencv_dnn") == std::string::npos);
  CHECK(libs.find("libtorch") == std::string::npos);
}

TEST_CASE("the refine helper maps Ceres but neither OpenCV nor LibTorch", "[cli][startup]") {
  const std::string libs = loaded_libraries(kRoe.parent_path() / "roe-refine");
  INFO(libs);
  // Debian's Ceres config links libceres.a: what ldd shows are its shared dependencies.
  CHECK(libs.find("libcholmod") != std::string::npos);
  CHECK(libs.find("libglog") != std::string::npos);
  CHECK(libs.find("libopencv") == std::string::npos);
  CHECK(libs.find("libtorch") == std::string::npos);
}

TEST_CASE("roe lists the helpers' commands and hands them over with their arguments and exit codes",
          "[cli][startup]") {
  auto r = run_roe("--help");
  CHECK(r.out.find("infer") != std::string::npos);
  r = run_roe("import --help");
  CHECK(r.out.find("realsense") != std::string::npos);
  // The helper parses: its own options in the help, its own usage errors (exit 2) under roe's name.
  r = run_roe("infer --help");
  CHECK(r.code == 0);
  CHECK(r.out.find("--model") != std::string::npos);
  r = run_roe("-q import realsense --help");
  CHECK(r.code == 0);
  CHECK(r.out.find("--png-compression") != std::string::npos);
  r = run_roe("refine --help");
  CHECK(r.code == 0);
  CHECK(r.out.find("--linear-solver") != std::string::npos);
  r = run_roe("--json refine no-such-run");
  CHECK(r.code == 2);
  CHECK(r.out.find("--out RUN_DIR2 is required") != std::string::npos);
  r = run_roe("infer no-such-dataset");
  CHECK(r.code == 2);
  CHECK(r.out.find("(see roe infer --help)") != std::string::npos);
  roe::test::TempDir d;
  r = run_roe("import realsense /no/such.bag --out " + (d / "ds").string());
  CHECK(r.code == 2);
  CHECK(r.out.find("/no/such.bag: no such bag file or folder") != std::string::npos);
  // roe run with the batch estimator is handed to roe-refine, which runs it (docs/refine.md §8).
  REQUIRE(run_roe("-q simulate --preset matched --seed 1 --duration 4 --out " + (d / "sim").string()).code == 0);
  r = run_roe("-q run " + (d / "sim").string() + " --estimator batch --out " + (d / "batch").string());
  CHECK(r.code == 0);
  const std::string run_json = shell("cat '" + (d / "batch" / "run.json").string() + "'");
  CHECK(run_json.find("\"estimator\": \"batch\"") != std::string::npos);
  CHECK(run_json.find("\"detection_error_model\"") != std::string::npos);
  // A command's argument that happens to be a helper's command name is not forwarded.
  r = run_roe("run infer --out " + (d / "run").string());
  CHECK(r.code == 2);
  CHECK(r.out.find("infer: dataset folder not found") != std::string::npos);
}

TEST_CASE("a missing helper is an internal error that says what to do", "[cli][startup]") {
  roe::test::TempDir d;
  const fs::path lone = d / "roe";
  fs::copy_file(kRoe, lone);
  const std::string out = shell("'" + lone.string() + "' infer x --model y; echo \"exit=$?\"");
  CHECK(out.find("helper roe-infer, which is not installed") != std::string::npos);
  CHECK(out.find("exit=3") != std::string::npos);
  // With --json, that failure is one JSON document on stdout like every other.
  const std::string js = shell("'" + lone.string() + "' --json infer x --model y 2>/dev/null");
  CHECK(js.find("\"exit_code\": 3") != std::string::npos);
  CHECK(js.find("\"command\": \"infer\"") != std::string::npos);
  const std::string rf = shell("'" + lone.string() + "' refine run --out run2; echo \"exit=$?\"");
  CHECK(rf.find("helper roe-refine, which is not installed") != std::string::npos);
  CHECK(rf.find("cmake --build BUILD --target roe-refine") != std::string::npos);
  CHECK(rf.find("exit=3") != std::string::npos);
  // roe run's batch estimator needs roe-refine too: said before anything is read (no such dataset here).
  const std::string rb = shell("'" + lone.string() + "' run no-such-ds --estimator batch --out " + (d / "r").string() +
                               "; echo \"exit=$?\"");
  CHECK(rb.find("'run --estimator batch' runs in the helper roe-refine, which is not installed") != std::string::npos);
  CHECK(rb.find("exit=3") != std::string::npos);
  CHECK(!fs::exists(d / "r"));
  const std::string rbj = shell("'" + lone.string() + "' --json run no-such-ds --estimator batch --out x 2>/dev/null");
  CHECK(rbj.find("\"exit_code\": 3") != std::string::npos);
  // Every other command works without the helpers.
  CHECK(shell("'" + lone.string() + "' --version").find("roe 0.") != std::string::npos);
}
