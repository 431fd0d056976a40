// Hostile inputs through the executable (issue 28): special files, symlink loops and out-of-range
// integers end in exit 2 with a located message, within 10 s and 1 GB of address space.
#include <sys/stat.h>
#include <sys/wait.h>

#include <array>
#include <catch2/catch.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>

#include "roe/io/output.hpp"
#include "support/test_util.hpp"

namespace fs = std::filesystem;
using Catch::Contains;

namespace {

struct Limited {
  int code;  ///< exit status; 137 when killed by the 10 s limit
  std::string out;
  double seconds;
};

/// Runs roe with `args` in `cwd` under `ulimit -v` 1 GB and a 10 s SIGKILL limit; stdout and stderr merged.
Limited run_limited(const fs::path& cwd, const std::string& args) {
  const std::string cmd = "cd '" + cwd.string() + "' && (ulimit -v 1048576; exec timeout -s KILL 10 " +
                          std::string(ROE_BINARY) + " " + args + ") 2>&1";
  const auto t0 = std::chrono::steady_clock::now();
  FILE* p = popen(cmd.c_str(), "r");
  REQUIRE(p != nullptr);
  std::string out;
  std::array<char, 4096> buf;
  for (std::size_t n; (n = std::fread(buf.data(), 1, buf.size(), p)) > 0;) out.append(buf.data(), n);
  const int status = pclose(p);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return {WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status), out, s};
}

const std::string kCamchain =
    "cam0:\n  T_cam_imu:\n  - [1.0, 0.0, 0.0, 0.1]\n  - [0.0, 1.0, 0.0, 0.0]\n  - [0.0, 0.0, 1.0, 0.0]\n"
    "  - [0.0, 0.0, 0.0, 1.0]\n  camera_model: pinhole\n  distortion_coeffs: [0, 0, 0, 0]\n"
    "  distortion_model: radtan\n  intrinsics: [600, 600, 320, 240]\n  resolution: [640, 480]\n";

}  // namespace

TEST_CASE("roe: /dev/zero, a FIFO without writer, a folder and a symlink loop as inputs: exit 2 at once",
          "[cli][hostile]") {
  roe::test::TempDir d("roe_cli_hostile");
  REQUIRE(::mkfifo((d / "fifo").c_str(), 0600) == 0);
  fs::create_symlink("loop", d / "loop");
  fs::create_directories(d / "folder");
  d.write("cc.yaml", kCamchain);
  d.write("est.txt", "1 0 0 0 0 0 0 1\n2 0 0 0 0 0 0 1\n3 0 0 0 0 0 0 1\n");
  fs::copy(fs::path(ROE_SOURCE_DIR) / "datasets" / "sample", d / "pds", fs::copy_options::recursive);
  for (const std::string special : {"/dev/zero", "fifo", "loop", "folder"}) {
    for (const std::string& args :
         {"import mocap " + special + " --into ds --format tum", "import mocap " + special + " --into ds",
          "eval " + special + " --gt est.txt --no-out", "eval est.txt --gt " + special + " --no-out",
          "import kalibr " + special + " --into ds", "import kalibr cc.yaml " + special + " --into ds",
          "import poet " + special + " --into pds"}) {
      INFO(args);
      const Limited r = run_limited(d.path, args);
      INFO(r.out);
      CHECK(r.code == 2);
      CHECK(r.seconds < 5);
      CHECK_THAT(r.out, Contains(fs::path(special).filename().string()));
    }
  }
  // What is there is named.
  CHECK_THAT(run_limited(d.path, "eval fifo --gt est.txt --no-out").out, Contains("FIFO"));
  CHECK_THAT(run_limited(d.path, "eval loop --gt est.txt --no-out").out, Contains("symlink loop"));
  CHECK_THAT(run_limited(d.path, "import mocap /dev/zero --into ds").out, Contains("character device"));
}

TEST_CASE("roe run: roe.json or imu0 as a folder, a FIFO or a symlink loop says so (exit 2)", "[cli][hostile]") {
  roe::test::TempDir d("roe_cli_hostile");
  const fs::path sample = fs::path(ROE_SOURCE_DIR) / "datasets" / "sample";
  for (const std::string rel : {"roe.json", "mav0/imu0/data.csv"}) {
    for (const std::string kind : {"folder", "fifo", "loop"}) {
      const fs::path ds = d / ("ds-" + kind + "-" + fs::path(rel).filename().string());
      fs::copy(sample, ds, fs::copy_options::recursive);
      fs::remove(ds / rel);
      if (kind == "folder") fs::create_directories(ds / rel);
      if (kind == "fifo") REQUIRE(::mkfifo((ds / rel).c_str(), 0600) == 0);
      if (kind == "loop") fs::create_symlink((ds / rel).filename(), ds / rel);
      INFO(rel << " as " << kind);
      const Limited r = run_limited(d.path, "run " + ds.filename().string() + " --out out-" + kind);
      INFO(r.out);
      CHECK(r.code == 2);
      CHECK_THAT(r.out, Contains(rel) &&
                            Contains(kind == "folder" ? "folder" : kind == "fifo" ? "FIFO" : "symlink loop"));
      CHECK_FALSE(fs::exists(d / ("out-" + kind)));
    }
  }
}

TEST_CASE("roe import kalibr: a resolution of 1e12 and chained aliases are input errors at their line",
          "[cli][hostile]") {
  roe::test::TempDir d("roe_cli_hostile");
  std::string cc = kCamchain;
  cc.replace(cc.find("[640, 480]"), 10, "[1e12, 480]");
  d.write("big.yaml", cc);
  Limited r = run_limited(d.path, "import kalibr big.yaml --into ds");
  CHECK(r.code == 2);
  CHECK_THAT(r.out, Contains("big.yaml:11:") && Contains("resolution"));
  std::string laughs = "a0: &a0 [x, x, x, x, x, x, x, x, x]\n";
  for (int i = 1; i < 10; ++i) {
    laughs += "a" + std::to_string(i) + ": &a" + std::to_string(i) + " [";
    for (int k = 0; k < 9; ++k) laughs += (k ? ", *a" : "*a") + std::to_string(i - 1);
    laughs += "]\n";
  }
  d.write("laughs.yaml", laughs);
  r = run_limited(d.path, "import kalibr laughs.yaml --into ds");
  CHECK(r.code == 2);
  CHECK(r.seconds < 5);
  CHECK_THAT(r.out, Contains("laughs.yaml:1:") && Contains("anchor"));
}

TEST_CASE("roe import mocap: a negative stamp is an input error at its line", "[cli][hostile]") {
  roe::test::TempDir d("roe_cli_hostile");
  d.write("neg.txt", "-2.5 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n3.0 0 0 0 0 0 0 1\n");
  d.write("neg.csv", "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z []\n"
                     "-1000,0,0,0,1,0,0,0\n2000,0,0,0,1,0,0,0\n");
  Limited r = run_limited(d.path, "import mocap neg.txt --into ds --format tum");
  CHECK(r.code == 2);
  CHECK_THAT(r.out, Contains("neg.txt:1") && Contains("negative"));
  r = run_limited(d.path, "import mocap neg.csv --into ds2 --format euroc");
  CHECK(r.code == 2);
  CHECK_THAT(r.out, Contains("neg.csv:2") && Contains("negative"));
  CHECK_FALSE(fs::exists(d / "ds2" / "mav0"));
}

TEST_CASE("roe calib-check: a NaN anywhere in states.csv is an input error at its row and column", "[cli][hostile]") {
  roe::test::TempDir d("roe_cli_hostile");
  const fs::path sample = fs::path(ROE_SOURCE_DIR) / "datasets" / "sample";
  Limited r = run_limited(d.path, "run '" + sample.string() + "' --out run");
  REQUIRE(r.code == 0);
  REQUIRE(run_limited(d.path, "calib-check run").code != 2);
  // v_W_I_x (column 5) of the third data row: a column no check reads. The default run is smoothed, so
  // calib-check reads the filter's states_filter.csv.
  std::string states = roe::io::read_file(d / "run" / "states_filter.csv");
  std::size_t at = 0;
  for (int k = 0; k < 3; ++k) at = states.find('\n', at) + 1;
  std::size_t c = at;
  for (int k = 0; k < 4; ++k) c = states.find(',', c) + 1;
  states.replace(c, states.find(',', c) - c, "nan");
  roe::io::write_file_atomic(d / "run" / "states_filter.csv", states);
  r = run_limited(d.path, "calib-check run");
  CHECK(r.code == 2);
  CHECK_THAT(r.out, Contains("states_filter.csv:4:5") && Contains("v_W_I_x"));
}
