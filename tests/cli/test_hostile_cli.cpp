// Hostile inputs through the executable (issue 28): special files, symlink loops and out-of-range
// integers end in exit 2 with a located message, within 10 s and 1 GB of address space.
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <catch2/catch.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "roe/io/ros/compression.hpp"
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

// ---- Third round (issue 40) -------------------------------------------------------------------------

namespace {

fs::path shared_data(const char* rel) { return fs::path(ROE_SHARED_DATA_DIR) / rel; }

/// A rosbag2 folder whose one file is zstd-compressed as a whole (compression_mode FILE).
void file_compressed_bag(const fs::path& dir, const std::string& file) {
  fs::create_directories(dir);
  std::ofstream(dir / "metadata.yaml") << "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n"
                                          "  relative_file_paths: [" << file << "]\n  compression_format: zstd\n"
                                          "  compression_mode: FILE\n  message_count: 1\n";
}

std::vector<std::string> entries(const fs::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) out.push_back(e.path().filename().string());
  return out;
}

}  // namespace

TEST_CASE("roe report: --out naming a file inside its run folder or dataset is refused, even with --force",
          "[cli][hostile][report]") {
  roe::test::TempDir d("roe_cli_report_out");
  fs::copy(fs::path(ROE_SOURCE_DIR) / "datasets" / "sample", d / "ds", fs::copy_options::recursive);
  REQUIRE(roe::test::run_roe("run " + (d / "ds").string() + " --out " + (d / "run").string() + " -q").code == 0);
  const std::string run_json = roe::test::run_shell("cat " + (d / "run" / "run.json").string()).out;
  for (const std::string& args : {std::string("--out run/run.json"), std::string("--out run/trajectory.csv"),
                                  std::string("--gt ds --out ds/roe.json")}) {
    const auto r = run_limited(d.path, "report run " + args + " --force");
    CHECK(r.code == 2);
    CHECK_THAT(r.out, Contains("inside the input"));
  }
  CHECK(roe::test::run_shell("cat " + (d / "run" / "run.json").string()).out == run_json);
  CHECK(roe::test::run_shell("head -c 1 " + (d / "ds" / "roe.json").string()).out == "{");
}

TEST_CASE("roe import mocap: a FILE-compressed rosbag2 bomb stops at its limit and leaves nothing in TMPDIR",
          "[cli][hostile][ros2]") {
  roe::test::TempDir d("roe_cli_zstd_bomb");
  fs::create_directories(d / "tmp");
  file_compressed_bag(d / "bag", "bomb_0.db3.zstd");
  {  // 300 MiB of zeros in about 10 KB of zstd (the catalogue's case has 1 GiB)
    const std::string z = roe::io::zstd_compress(std::string(300u << 20, '\0'), 1);
    std::ofstream(d / "bag" / "bomb_0.db3.zstd", std::ios::binary) << z;
  }
  const auto r = run_limited(d.path, "import mocap bag --into newds --topic /tf");
  CHECK(r.code == 2);
  CHECK_THAT(r.out, Contains("bomb_0.db3.zstd") && Contains("decompresses to more than 268435456 bytes"));
  CHECK(r.seconds < 10);
}

TEST_CASE("roe import mocap: TERM, INT or HUP while a rosbag2 file decompresses remove the copy in TMPDIR",
          "[cli][hostile][ros2][signals]") {
  for (const int sig : {SIGTERM, SIGINT, SIGHUP}) {
    CAPTURE(sig);
    roe::test::TempDir d("roe_cli_zstd_signal");
    fs::create_directories(d / "tmp");
    file_compressed_bag(d / "bag", "slow_0.db3.zstd");
    REQUIRE(::mkfifo((d / "bag" / "slow_0.db3.zstd").c_str(), 0600) == 0);
    const pid_t pid = fork();
    if (pid == 0) {
      setpgid(0, 0);
      ::setenv("TMPDIR", (d / "tmp").c_str(), 1);
      if (::chdir(d.path.c_str()) != 0) _exit(127);
      execl(ROE_BINARY, ROE_BINARY, "import", "mocap", "bag", "--into", "newds", "--topic", "/tf", "-q",
            static_cast<char*>(nullptr));
      _exit(127);
    }
    // The writer side: 4 MB of a 64 MB stream, then the signal while roe waits for the rest.
    const std::string z = roe::io::zstd_compress(std::string(64u << 20, 'x'), 1);
    std::FILE* w = std::fopen((d / "bag" / "slow_0.db3.zstd").c_str(), "wb");
    REQUIRE(w != nullptr);
    std::fwrite(z.data(), 1, z.size() / 2, w);
    std::fflush(w);
    bool copy_seen = false;
    for (int i = 0; i < 200 && !copy_seen; ++i) {
      for (const auto& e : entries(d / "tmp")) copy_seen = copy_seen || e.rfind("roe-bag-", 0) == 0;
      if (!copy_seen) std::this_thread::sleep_for(std::chrono::milliseconds(25));
    }
    CHECK(copy_seen);
    ::kill(pid, sig);
    int status = 0;
    ::waitpid(pid, &status, 0);
    std::fclose(w);
    CHECK(WIFSIGNALED(status));
    CHECK(entries(d / "tmp").empty());
  }
}

TEST_CASE("roe import mocap and roe eval BAG:TOPIC read a rosbag2 folder without metadata.yaml",
          "[cli][hostile][ros2][real]") {
  const fs::path folder = shared_data("rosbag2/tf_example");
  if (!fs::exists(folder)) {
    WARN("skipped: " << folder << " absent");
    return;
  }
  roe::test::TempDir d("roe_cli_no_metadata");
  fs::create_directories(d / "bag");
  fs::copy_file(folder / "tf_example.db3", d / "bag" / "tf_example.db3");
  auto r = run_limited(d.path, "import mocap bag --into ds --topic /tf --parent odom --child base_footprint -q");
  CHECK(r.code == 0);
  CHECK(fs::exists(d / "ds" / "mav0" / "mocap0" / "data.csv"));
  r = run_limited(d.path, "eval bag:/tf:odom.base_footprint --gt bag:/tf:odom.base_footprint --no-out -q");
  CHECK(r.code == 0);
}
