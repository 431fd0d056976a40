// Trajectory readers/writers: TUM, EuRoC, cnspy CSV (set-matched header, covariance columns), roe
// csv-ns; format detection; exact seconds<->ns; malformed input with line and column.
#include <fmt/format.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <functional>

#include "roe/core/error.hpp"
#include "roe/io/trajectory_io.hpp"
#include "support/test_util.hpp"

using namespace roe;
using namespace roe::io;

namespace {

/// Runs `f` and checks it throws an InputError located at `line`:`col` whose message has `needle`.
template <typename F>
void check_error_at(F&& f, std::int64_t line, std::int64_t col, const std::string& needle) {
  try {
    f();
    FAIL("no error thrown; expected one at line " << line << " column " << col);
  } catch (const InputError& e) {
    INFO(e.what());
    CHECK(e.context().line == line);
    CHECK(e.context().column == col);
    CHECK(std::string(e.what()).find(needle) != std::string::npos);
  }
}

}  // namespace

TEST_CASE("trajectory stamps: seconds text to exact ns", "[io][trajectory]") {
  // The V1_02 estimate writes stamps as 1.403715529112143517e+09: parsed without double rounding.
  const Trajectory t =
      parse_trajectory("1.403715529112143517e+09 0 0 0 0 0 0 1\n1403715529.2 0 0 0 0 0 0 1\n", "s");
  CHECK(t.t_ns[0] == 1403715529112143517LL);
  CHECK(t.t_ns[1] == 1403715529200000000LL);
}

TEST_CASE("format detection from the header", "[io][trajectory]") {
  CHECK(detect_trajectory_format("# comment\n1.0 0 0 0 0 0 0 1\n", "x") == TrajectoryFormat::kTum);
  CHECK(detect_trajectory_format("# timestamp tx ty tz qx qy qz qw\n1 0 0 0 0 0 0 1\n", "x") ==
        TrajectoryFormat::kTum);
  CHECK(detect_trajectory_format("#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],"
                                 "q_RS_y [],q_RS_z []\n",
                                 "x") == TrajectoryFormat::kEuroc);
  CHECK(
      detect_trajectory_format("#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], "
                               "q_RS_y [], q_RS_z [], v_RS_R_x [m s^-1]\n",
                               "x") == TrajectoryFormat::kEuroc);
  CHECK(detect_trajectory_format("t,tx,ty,tz,qx,qy,qz,qw\n", "x") == TrajectoryFormat::kCsv);
  CHECK(detect_trajectory_format("#t,tx,ty,tz,qx,qy,qz,qw\n", "x") == TrajectoryFormat::kCsv);
  CHECK(detect_trajectory_format("\n\nqw,qx,t,tx,ty,tz,qy,qz\n", "x") == TrajectoryFormat::kCsv);
  CHECK(detect_trajectory_format("timestamp_ns,tx,ty,tz,qx,qy,qz,qw\n", "x") == TrajectoryFormat::kCsvNs);
  check_error_at([] { detect_trajectory_format("\n1,2,3,4,5,6,7,8\n", "f.csv"); }, 2, 1, "without a header");
  check_error_at([] { detect_trajectory_format("a,b,c\n", "f.csv"); }, 1, 1,
                 "unrecognised trajectory header");
  check_error_at([] { detect_trajectory_format("hello world\n", "f.txt"); }, 1, 1, "unrecognised");
  CHECK_THROWS_AS(detect_trajectory_format("# only comments\n", "f.txt"), InputError);
  CHECK(parse_trajectory_format("cnspy") == TrajectoryFormat::kCsv);
  CHECK(parse_trajectory_format("roe") == TrajectoryFormat::kCsvNs);
  CHECK(parse_trajectory_format("kitti") == TrajectoryFormat::kKitti);
  CHECK_THROWS_AS(parse_trajectory_format("kitty"), InputError);
}

TEST_CASE("KITTI poses: 12 fields [R|t] row-major, stamped by index, a times file, a bag is named", "[trajectory_io]") {
  // Rz(90°) then identity: evo's kitti layout r11 r12 r13 tx r21 r22 r23 ty r31 r32 r33 tz.
  const std::string text = "0 -1 0 1.5 1 0 0 -2 0 0 1 0.25\n1 0 0 0 0 1 0 0 0 0 1 0\n";
  CHECK(detect_trajectory_format(text, "k.txt") == TrajectoryFormat::kKitti);
  Trajectory t = parse_trajectory(text, "k.txt");
  REQUIRE(t.size() == 2);
  CHECK(t.t_ns[0] == 0);
  CHECK(t.t_ns[1] == 1'000'000'000);
  CHECK(t.poses[0].p.isApprox(Eigen::Vector3d(1.5, -2, 0.25)));
  CHECK(t.poses[0].R().isApprox(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix(), 1e-12));
  // Written back as KITTI, read again: the same poses.
  const Trajectory back = parse_trajectory(format_trajectory(t.t_ns, t.poses, TrajectoryFormat::kKitti), "b.txt");
  CHECK(back.poses[0].R().isApprox(t.poses[0].R(), 1e-15));
  check_error_at([] { parse_trajectory("1 0 0 0 0 2 0 0 0 0 1 0\n", "s.txt"); }, 1, 1, "not a rotation");
  CHECK_THROWS_AS(parse_trajectory("1 0 0 0 0 1 0 0 0 0 1\n", "s.txt", TrajectoryFormat::kKitti), InputError);
  roe::test::TempDir d;
  const auto times = d.write("times.txt", "0.000000e+00\n1.036000e-01\n");
  apply_kitti_times(t, times);
  CHECK(t.t_ns[1] == 103'600'000);
  const auto three = d.write("three.txt", "0\n1\n2\n");
  CHECK_THROWS_WITH(apply_kitti_times(t, three), Catch::Contains("more stamps than poses"));
  Trajectory tum = parse_trajectory("1 0 0 0 0 0 0 1\n", "t.tum");
  CHECK_THROWS_WITH(apply_kitti_times(tum, times), Catch::Contains("KITTI"));
  CHECK_THROWS_WITH(detect_trajectory_format(std::string("#ROSBAG V2.0\n\x04\x00", 15), "r.bag"),
                    Catch::Contains("ROS bag (rosbag v2)"));
}

TEST_CASE("TUM reader", "[io][trajectory]") {
  const Trajectory t = parse_trajectory(
      "# TF frame\n1305031102.160407 1.344379 0.627206 1.661754 0.658249 0.611043 -0.294444 -0.326553\n"
      "1305031102.194330 1 2 3 0 0 0 1\n",
      "tum.txt");
  REQUIRE(t.size() == 2);
  CHECK(t.format == TrajectoryFormat::kTum);
  CHECK(t.t_ns[0] == 1305031102160407000LL);
  CHECK(t.lines[1] == 3);
  CHECK(t.poses[0].p.x() == 1.344379);
  CHECK(t.poses[0].q.w() == Approx(-0.326553).epsilon(1e-5));
  CHECK(t.poses[1].p.z() == 3.0);
  CHECK(t.cov.empty());
  // duplicates accepted and counted
  const Trajectory d = parse_trajectory("1 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n2 0 0 0 0 0 0 1\n", "d");
  CHECK(d.count_duplicate_stamps() == 1);
}

TEST_CASE("TUM reader: malformed input names line and column", "[io][trajectory]") {
  check_error_at([] { parse_trajectory("1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n", "f", TrajectoryFormat::kTum); }, 2,
                 8,
                 "expected 8 columns");  // the first missing field
  check_error_at([] { parse_trajectory("1 0 0 0 0 0 0 1\n2 0 x 0 0 0 0 1\n", "f"); }, 2, 3, "");
  check_error_at([] { parse_trajectory("1 0 0 0 0 0 0 1\n2 0 nan 0 0 0 0 1\n", "f"); }, 2, 3, "");
  check_error_at([] { parse_trajectory("1 0 0 0 0 0 0 1\n0.5 0 0 0 0 0 0 1\n", "f"); }, 2, 1,
                 "must not decrease");
  check_error_at([] { parse_trajectory("1 0 0 0 0 0 0 1\n2 0 0 1e300 0 0 0 1\n", "f"); }, 2, 4,
                 "beyond any trajectory's range");
  CHECK(parse_trajectory("1 6.4e6 -1e9 0 0 0 0 1\n", "f").poses.size() == 1);
  check_error_at([] { parse_trajectory("1 0 0 0 0 0 0 2\n", "f"); }, 1, 8, "quaternion norm");
  check_error_at([] { parse_trajectory("1 0 0 0 0 0 0 0\n", "f"); }, 1, 8, "quaternion norm");
  check_error_at([] { parse_trajectory("1403715524907143168 0 0 0 0 0 0 1\n", "f"); }, 1, 1,
                 "looks like nanoseconds");
  check_error_at([] { parse_trajectory("1,5 0 0 0 0 0 0 1\n", "f", TrajectoryFormat::kTum); }, 1, 1,
                 "seconds");
}

TEST_CASE("EuRoC reader: ns, w first, 8 or 17 columns", "[io][trajectory]") {
  const std::string h8 =
      "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z []\n";
  const Trajectory t = parse_trajectory(h8 + "1403715524907143168,1,2,3,0,1,0,0\n", "gt.csv");
  REQUIRE(t.size() == 1);
  CHECK(t.format == TrajectoryFormat::kEuroc);
  CHECK(t.t_ns[0] == 1403715524907143168LL);
  CHECK(t.poses[0].q.x() == 1.0);
  CHECK(t.poses[0].q.w() == 0.0);
  check_error_at([&] { parse_trajectory(h8 + "1,1,2,3,1,0,0,0\n1.5,1,2,3,1,0,0,0\n", "gt.csv"); }, 3, 1, "");
  check_error_at([&] { parse_trajectory(h8 + "1,1,2,3,1,0,0,0\n2,1,2,3,1,0,0\n", "gt.csv"); }, 3, 8,
                 "columns");
  check_error_at([&] { parse_trajectory(h8 + "1,1,2,3,1,0,0,0,9\n", "gt.csv"); }, 2, 9, "columns");
  check_error_at(
      [] {
        parse_trajectory("#timestamp,a,b,c,d,e,f,g\n1,1,2,3,1,0,0,0\n", "gt.csv", TrajectoryFormat::kEuroc);
      },
      1, 1, "not an EuRoC");
}

TEST_CASE("CSV reader: any column order, covariance columns", "[io][trajectory]") {
  SECTION("PoseStamped in a shuffled order") {
    const Trajectory t = parse_trajectory("qw,tz,t,qx,ty,qy,tx,qz\n1,3,0.5,0,2,0,1,0\n", "x.csv");
    REQUIRE(t.size() == 1);
    CHECK(t.t_ns[0] == 500000000);
    CHECK(t.poses[0].p == Eigen::Vector3d(1, 2, 3));
    CHECK(t.poses[0].q.w() == 1.0);
  }
  SECTION("cnspy TUM header #t") {
    CHECK(parse_trajectory("#t,tx,ty,tz,qx,qy,qz,qw\n1,0,0,0,0,0,0,1\n", "x.csv").size() == 1);
  }
  SECTION("PosOrientWithCov (+ typed), columns as in cnspy's OpenVINS sample (cov first)") {
    const Trajectory t = parse_trajectory(
        "qrr,qrp,qry,qpp,qpy,qyy,pxx,pxy,pxz,pyy,pyz,pzz,t,tx,ty,tz,qx,qy,qz,qw,est_err_type,err_"
        "representation\n"
        "0.1,0.01,0.02,0.2,0.03,0.3,1,0.5,0.25,2,0.75,3,10,0,0,0,0,0,0,1,type1,theta_R\n",
        "x.csv");
    REQUIRE(t.cov.size() == 1);
    CHECK(t.cov_position_local);
    // Every entry in its place: two symmetric 3x3 blocks, no position-orientation correlation.
    Eigen::Matrix<double, 6, 6> want = Eigen::Matrix<double, 6, 6>::Zero();
    want.topLeftCorner<3, 3>() << 1, 0.5, 0.25, 0.5, 2, 0.75, 0.25, 0.75, 3;
    want.bottomRightCorner<3, 3>() << 0.1, 0.01, 0.02, 0.01, 0.2, 0.03, 0.02, 0.03, 0.3;
    CHECK(t.cov[0] == want);
  }
  SECTION("PoseWithCov 21 entries") {
    std::string h =
        "t,tx,ty,tz,qx,qy,qz,qw,Txx,Txy,Txz,Txa,Txb,Txc,Tyy,Tyz,Tya,Tyb,Tyc,Tzz,Tza,Tzb,Tzc,Taa,Tab,Tac,Tbb,"
        "Tbc,Tcc\n";
    std::string row = "1,0,0,0,0,0,0,1";
    for (int k = 1; k <= 21; ++k) row += "," + std::to_string(k);
    const Trajectory t = parse_trajectory(h + row + "\n", "x.csv");
    REQUIRE(t.cov.size() == 1);
    CHECK(t.cov[0](0, 0) == 1);
    CHECK(t.cov[0](0, 5) == 6);
    CHECK(t.cov[0](5, 0) == 6);
    CHECK(t.cov[0](1, 1) == 7);
    CHECK(t.cov[0](5, 5) == 21);
    // Row-major upper triangle: entry (a, b), a <= b, is number 1 + 6a - a(a-1)/2 + (b - a).
    for (int a = 0; a < 6; ++a)
      for (int b = a; b < 6; ++b) {
        CHECK(t.cov[0](a, b) == 1 + 6 * a - a * (a - 1) / 2 + (b - a));
        CHECK(t.cov[0](b, a) == t.cov[0](a, b));
      }
    CHECK_FALSE(t.cov_position_local);
  }
  SECTION("PoseTypedStamped (an err_matched_aligned.csv)") {
    const Trajectory t =
        parse_trajectory("t,tx,ty,tz,qx,qy,qz,qw,scale,est_err_type\n1,0,0,0,0,0,0,1,1.0,type5\n", "e.csv");
    CHECK(t.size() == 1);
    CHECK(t.cov.empty());
  }
  SECTION("errors") {
    check_error_at(
        [] { parse_trajectory("t,tx,ty,tz,qx,qy,qz\n1,0,0,0,0,0,0\n", "x.csv", TrajectoryFormat::kCsv); }, 1,
        0, "no column 'qw'");
    check_error_at([] { parse_trajectory("t,tx,ty,tz,qx,qy,qz,qw,foo\n1,0,0,0,0,0,0,1,2\n", "x.csv"); }, 1, 0,
                   "unexpected column 'foo'");
    check_error_at([] { parse_trajectory("t,tx,ty,tz,qx,qy,qz,qw,pxx\n1,0,0,0,0,0,0,1,2\n", "x.csv"); }, 1, 0,
                   "unexpected column 'pxx'");
    check_error_at([] { parse_trajectory("t,tx,tx,tz,qx,qy,qz,qw\n1,0,0,0,0,0,0,1\n", "x.csv"); }, 1, 3,
                   "duplicate column");
    check_error_at(
        [] { parse_trajectory("qw,t,tx,ty,tz,qx,qy,qz\n1,2,0,0,0,0,0,0\n1,1,0,0,0,0,0,0\n", "x.csv"); }, 3, 2,
        "must not decrease");
    check_error_at(
        [] { parse_trajectory("t,tx,ty,tz,qx,qy,qz,qw\n1,0,0,0,0,0,0,1\n2,0,,0,0,0,0,1\n", "x.csv"); }, 3, 3,
        "");
    CHECK_THROWS_AS(parse_trajectory("t,tx,ty,tz,qx,qy,qz,qw\n", "x.csv"), InputError);  // no poses
  }
}

TEST_CASE("csv-ns reader: malformed input", "[io][trajectory]") {
  const std::string h = "timestamp_ns,tx,ty,tz,qx,qy,qz,qw\n";
  check_error_at([&] { parse_trajectory(h + "1,0,0,0,0,0,0,1\n1.5,0,0,0,0,0,0,1\n", "n.csv"); }, 3, 1, "");
  check_error_at([&] { parse_trajectory(h + "2,0,0,0,0,0,0,1\n1,0,0,0,0,0,0,1\n", "n.csv"); }, 3, 1,
                 "must not decrease");
  check_error_at([&] { parse_trajectory(h + "1,0,0,0,0,0,0,1,7\n", "n.csv"); }, 2, 9, "columns");
  check_error_at([&] { parse_trajectory(h + "1,0,0,inf,0,0,0,1\n", "n.csv"); }, 2, 4, "");
  CHECK_THROWS_AS(read_trajectory(std::filesystem::temp_directory_path()), InputError);  // a folder
  CHECK_THROWS_AS(read_trajectory("/nonexistent/roe/traj.txt"), InputError);
}

TEST_CASE("csv-ns reader and writers round-trip exactly", "[io][trajectory]") {
  std::vector<Timestamp> t{1403715529112143517LL, 1403715529212143517LL, 1403715529212143517LL};
  std::vector<Pose> p;
  for (int i = 0; i < 3; ++i)
    p.push_back(Pose(Eigen::Quaterniond(Eigen::AngleAxisd(0.1 + i, Eigen::Vector3d(1, 2, 3).normalized())),
                     Eigen::Vector3d(0.1 * i, -1.0 / 3.0, 1e-7 * i)));
  for (auto f :
       {TrajectoryFormat::kTum, TrajectoryFormat::kEuroc, TrajectoryFormat::kCsv, TrajectoryFormat::kCsvNs}) {
    INFO(to_string(f));
    const std::string text = format_trajectory(t, p, f);
    const Trajectory back = parse_trajectory(text, "rt");  // auto-detected
    CHECK(back.format == f);
    REQUIRE(back.size() == 3);
    CHECK(back.t_ns == t);
    for (int i = 0; i < 3; ++i) {
      CHECK(back.poses[i].p == p[i].p);
      CHECK(back.poses[i].q.coeffs().isApprox(p[i].q.coeffs(), 1e-15));
    }
  }
  CHECK(format_trajectory({0}, {Pose()}, TrajectoryFormat::kTum)
            .rfind("# timestamp tx ty tz qx qy qz qw\n", 0) == 0);
  CHECK(format_trajectory({0}, {Pose()}, TrajectoryFormat::kCsv) ==
        "t,tx,ty,tz,qx,qy,qz,qw\n0.000000000,0,0,0,0,0,0,1\n");
  // files
  const auto dir = std::filesystem::temp_directory_path() / "roe_test_trajectory_io";
  std::filesystem::create_directories(dir);
  write_trajectory(dir / "a.tum", t, p, TrajectoryFormat::kTum);
  CHECK(read_trajectory(dir / "a.tum").t_ns == t);
  std::filesystem::remove_all(dir);
}

TEST_CASE("real files in ../shared/data", "[io][trajectory][real]") {
  const std::filesystem::path d = ROE_SHARED_DATA_DIR;
  if (!std::filesystem::exists(d / "eval")) {
    WARN("skipped: ../shared/data/eval is absent");
    return;
  }
  const Trajectory tum = read_trajectory(d / "eval/freiburg1_xyz-groundtruth.txt");
  CHECK(tum.format == TrajectoryFormat::kTum);
  CHECK(tum.size() == 3000);
  const Trajectory est = read_trajectory(d / "eval/V102.txt");
  CHECK(est.size() == 807);
  CHECK(est.count_duplicate_stamps() == 4);
  const Trajectory gt = read_trajectory(d / "eval/V102_groundtruth.csv");
  CHECK(gt.format == TrajectoryFormat::kEuroc);
  CHECK(gt.size() == 16702);
  const Trajectory cn = read_trajectory(d / "cnspy/ID1-pose-gt.csv");
  CHECK(cn.format == TrajectoryFormat::kCsv);
  CHECK(cn.size() > 0);
  const Trajectory cov = read_trajectory(d / "cnspy/ID1-pose-est-posorient-cov-type1-thetaR.csv");
  CHECK(cov.cov.size() == cov.size());
  CHECK(cov.cov_position_local);
  const Trajectory tumvi = read_trajectory(d / "tumvi/dataset-room1_512_16_gt.csv");
  CHECK(tumvi.format == TrajectoryFormat::kEuroc);
}

namespace {

/// What a reader made of a text: the poses (bit for bit) and their lines, or the error and its location.
std::string outcome(const std::function<Trajectory()>& read) {
  try {
    const Trajectory t = read();
    std::string s = fmt::format("{} poses, format {}\n", t.size(), to_string(t.format));
    for (std::size_t i = 0; i < t.size(); ++i)
      s += fmt::format("{} {} {} {} {} {} {} {} line {}\n", t.t_ns[i], t.poses[i].p.x(), t.poses[i].p.y(),
                       t.poses[i].p.z(), t.poses[i].q.x(), t.poses[i].q.y(), t.poses[i].q.z(), t.poses[i].q.w(),
                       t.lines[i]);
    return s;
  } catch (const InputError& e) {
    return fmt::format("error at {}:{} [{}]: {}", e.context().line, e.context().column, e.context().key,
                       e.bare_message());
  }
}

}  // namespace

TEST_CASE("a trajectory file is read in chunks exactly as its text is parsed whole", "[io][trajectory]") {
  // read_trajectory parses the file as it reads it, 1 MiB at a time (CsvReader), and detects the format
  // from its first 64 KiB; parse_trajectory holds the text whole. Each file below must give the same
  // poses, lines and errors both ways: rows across chunk boundaries, a head of comments longer than
  // the detection's 64 KiB, CRLF, a BOM, no final line end, and malformed rows deep in the file.
  roe::test::TempDir dir("roe_traj_chunks");
  std::string tum;  // ~2.5 MiB of TUM rows of varying length: rows straddle both chunk boundaries
  for (int i = 0; i < 40000; ++i)
    tum += fmt::format("{}.{:09d}   {} {} {}\t0 0 {} {}\n", 1000 + i, (i * 7919) % 1000000000, 0.1 * i, -1.0 / (i + 1),
                       i % 3 ? "1e-3" : "42", std::sin(0.001 * i), std::cos(0.001 * i));
  std::string euroc = "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z []\r\n";
  for (int i = 0; i < 30000; ++i)
    euroc += fmt::format("{}, {} ,{},{},{},0,0,{}\r\n", 1'000'000'000LL * i + 17, 0.5 * i, -0.25 * i, i % 7,
                         std::cos(0.002 * i), std::sin(0.002 * i));
  const std::string comments = std::string(70000, '#') + "\n# more\n\n";
  const std::string csv = "t,tx,ty,tz,qx,qy,qz,qw\n1.5,\"2\",3,4,0,0,0,1\n2.5,+1,3 , 4,0,0,0,1\n";
  std::vector<std::pair<std::string, std::string>> cases = {
      {"tum", tum},
      {"tum_unterminated", tum.substr(0, tum.size() - 1)},
      {"tum_comment_head", comments + tum},
      {"tum_bom", "\xEF\xBB\xBF" + tum},
      {"euroc_crlf", euroc},
      {"csv_quoted_plus", csv},
      {"tum_bad_number_deep", tum + "99999.5 0 0 1.5x 0 0 0 1\n"},
      {"tum_out_of_range_deep", tum + "99999.5 0 0 1e400 0 0 0 1\n"},
      {"tum_short_row_deep", tum + "99999.5 0 0 0 0 0 1\n"},
      {"tum_decreasing_deep", tum + "5.5 0 0 0 0 0 0 1\n"},
      {"euroc_bad_stamp_deep", euroc + "12.5,0,0,0,1,0,0,0\r\n"},
      {"euroc_nan_deep", euroc + "99999999999999,0,nan,0,1,0,0,0\r\n"},
      {"only_comments", comments},
  };
  for (const auto& [name, text] : cases) {
    INFO(name);
    const fs::path file = dir.write(name + ".txt", text);
    const std::string from_file = outcome([&] { return read_trajectory(file); });
    const std::string from_text = outcome([&] { return parse_trajectory(text, file.string()); });
    CHECK(from_file == from_text);
    CHECK(from_file.size() > 20);
  }
  // The whole-text outcome itself is right: spot checks.
  CHECK(outcome([&] { return parse_trajectory(tum, "t"); }).rfind("40000 poses, format tum", 0) == 0);
  CHECK(outcome([&] { return parse_trajectory(euroc, "e"); }).rfind("30000 poses, format euroc", 0) == 0);
  CHECK(outcome([&] { return parse_trajectory(csv, "c"); }) ==
        "2 poses, format csv\n1500000000 2 3 4 0 0 0 1 line 2\n2500000000 1 3 4 0 0 0 1 line 3\n");
  CHECK(outcome([&] { return parse_trajectory(tum + "99999.5 0 0 1.5x 0 0 0 1\n", "t"); }) ==
        "error at 40001:4 []: trailing characters after the number: '1.5x'");
  CHECK(outcome([&] { return parse_trajectory(tum + "99999.5 0 0 1e400 0 0 0 1\n", "t"); }) ==
        "error at 40001:4 []: number out of range: '1e400'");
}
