// The run folder's tables (io/run_files.hpp): the headers roe run has always written, write → read
// round trips, and located errors (a missing column, a bad value, decreasing stamps).
#include <catch2/catch.hpp>
#include <cmath>
#include <map>
#include <random>
#include <set>

#include "roe/core/error.hpp"
#include "roe/io/csv.hpp"
#include "roe/io/output.hpp"
#include "roe/store/run_files.hpp"
#include "roe/io/trajectory_io.hpp"
#include "support/test_util.hpp"

using namespace roe;
using namespace roe::io;
using namespace roe::store;

namespace {

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ",") + x;
  return s;
}

Eigen::Quaterniond random_unit(std::mt19937& g) {
  std::normal_distribution<double> n;
  return Eigen::Quaterniond(n(g), n(g), n(g), n(g)).normalized();  // either hemisphere
}

Eigen::Vector3d random_vec(std::mt19937& g) {
  std::normal_distribution<double> n(0.0, 10.0);
  return {n(g), n(g), n(g)};
}

/// q read back: the canonical hemisphere of what was written, to the last bits (normalised on reading).
void check_same_rotation(const Eigen::Quaterniond& written, const Eigen::Quaterniond& read) {
  const Eigen::Quaterniond c = written.w() < 0 ? Eigen::Quaterniond(-written.coeffs()) : written;
  CHECK(read.w() >= 0.0);
  CHECK((read.coeffs() - c.coeffs()).cwiseAbs().maxCoeff() < 1e-15);
}

}  // namespace

TEST_CASE("run files: the headers are the columns of DESIGN §4", "[io][run_files]") {
  CHECK(join(states_csv_columns()) ==
        "timestamp_ns,p_W_I_x,p_W_I_y,p_W_I_z,v_W_I_x,v_W_I_y,v_W_I_z,q_W_I_x,q_W_I_y,q_W_I_z,q_W_I_w,b_g_x,b_g_y,"
        "b_g_z,b_a_x,b_a_y,b_a_z,p_I_C_x,p_I_C_y,p_I_C_z,q_I_C_x,q_I_C_y,q_I_C_z,q_I_C_w,sigma_p_W_I_x,"
        "sigma_p_W_I_y,sigma_p_W_I_z,sigma_v_W_I_x,sigma_v_W_I_y,sigma_v_W_I_z,sigma_theta_W_I_x,"
        "sigma_theta_W_I_y,sigma_theta_W_I_z,sigma_b_g_x,sigma_b_g_y,sigma_b_g_z,sigma_b_a_x,sigma_b_a_y,"
        "sigma_b_a_z,sigma_p_I_C_x,sigma_p_I_C_y,sigma_p_I_C_z,sigma_theta_I_C_x,sigma_theta_I_C_y,"
        "sigma_theta_I_C_z,time_offset_s,sigma_time_offset_s");
  CHECK(join(objects_csv_columns()) ==
        "timestamp_ns,object_id,anchor,p_O_W_x,p_O_W_y,p_O_W_z,q_O_W_x,q_O_W_y,q_O_W_z,q_O_W_w,sigma_p_x,sigma_p_y,"
        "sigma_p_z,sigma_theta_x,sigma_theta_y,sigma_theta_z,sigma_p_W_O_x,sigma_p_W_O_y,sigma_p_W_O_z,"
        "sigma_theta_W_O_x,sigma_theta_W_O_y,sigma_theta_W_O_z,sigma_p_A_O_x,sigma_p_A_O_y,sigma_p_A_O_z,"
        "sigma_theta_A_O_x,sigma_theta_A_O_y,sigma_theta_A_O_z");
  CHECK(join(reprojection_csv_columns()) == "timestamp_ns,object_id,tx,ty,tz,qx,qy,qz,qw,status,nis,used");
  // One row as text: the shortest round-trip numbers, canonical quaternions, nan for a missing pose.
  ReprojectionRow r;
  r.t_ns = 1403715523912140000;
  r.object_id = 3;
  r.outcome.status = ekf::DetectionStatus::kRejectedChi2;
  r.outcome.nis = 0.1;
  r.outcome.has_T_W_I = true;
  r.outcome.T_W_I = Pose(Eigen::Quaterniond(-1, 0, 0, 0), Eigen::Vector3d(1.5, -2, 1e-300));
  ReprojectionRow none;
  none.t_ns = r.t_ns;
  none.outcome.status = ekf::DetectionStatus::kPendingInit;
  CHECK(format_reprojection_csv({r, none}) ==
        "timestamp_ns,object_id,tx,ty,tz,qx,qy,qz,qw,status,nis,used\n"
        "1403715523912140000,3,1.5,-2,1e-300,-0,-0,-0,1,rejected_chi2,0.1,none\n"
        "1403715523912140000,0,nan,nan,nan,nan,nan,nan,nan,pending_init,nan,none\n");
}

TEST_CASE("run files: write then read gives the rows back", "[io][run_files]") {
  test::TempDir tmp("roe_run_files");
  std::mt19937 g(7);
  std::uniform_real_distribution<double> u(0.0, 2.0);
  SECTION("states.csv") {
    std::vector<RecordedState> rows(50);
    for (std::size_t i = 0; i < rows.size(); ++i) {
      RecordedState& s = rows[i];
      s.t_ns = 1000000000LL * 1700000000 + static_cast<Timestamp>(i / 2) * 2500000;  // pairs of equal stamps
      s.x.p_W_I = random_vec(g);
      s.x.v_W_I = random_vec(g);
      s.x.q_W_I = random_unit(g);
      s.x.b_g = random_vec(g) * 1e-4;
      s.x.b_a = random_vec(g) * 1e-3;
      s.T_I_C = Pose(random_unit(g), random_vec(g));
      for (int k = 0; k < 21; ++k) s.sigma(k) = k % 7 == 0 ? 0.0 : u(g);
      s.time_offset_s = (u(g) - 1.0) * 0.03;
      s.sigma_time_offset_s = i % 5 == 0 ? 0.0 : u(g) * 1e-3;
    }
    write_states_csv(tmp / "states.csv", rows);
    const std::vector<RecordedState> back = read_states_csv(tmp / "states.csv");
    REQUIRE(back.size() == rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
      CHECK(back[i].t_ns == rows[i].t_ns);
      CHECK(back[i].x.p_W_I == rows[i].x.p_W_I);
      CHECK(back[i].x.v_W_I == rows[i].x.v_W_I);
      CHECK(back[i].x.b_g == rows[i].x.b_g);
      CHECK(back[i].x.b_a == rows[i].x.b_a);
      CHECK(back[i].T_I_C.p == rows[i].T_I_C.p);
      CHECK(back[i].sigma == rows[i].sigma);
      CHECK(back[i].time_offset_s == rows[i].time_offset_s);
      CHECK(back[i].sigma_time_offset_s == rows[i].sigma_time_offset_s);
      check_same_rotation(rows[i].x.q_W_I, back[i].x.q_W_I);
      check_same_rotation(rows[i].T_I_C.q, back[i].T_I_C.q);
    }
    // A subset of the columns: the others keep their defaults.
    RunFileRead some;
    some.columns = {"timestamp_ns", "sigma_theta_W_I_y"};
    const auto part = read_states_csv(tmp / "states.csv", some);
    REQUIRE(part.size() == rows.size());
    std::size_t n = 0;
    CHECK(for_each_state_row(tmp / "states.csv", some, [&](const RecordedState& r) { CHECK(r.sigma(7) == rows[n++].sigma(7)); }));
    CHECK(n == rows.size());
    CHECK(part[5].sigma(7) == rows[5].sigma(7));
    CHECK(part[5].sigma(6) == 0.0);
    CHECK(part[5].x.p_W_I.isZero());
    // A file written before issue 49, without the time-offset columns: they read as nan.
    std::string text = format_states_csv(rows);
    std::string old;
    for (std::size_t at = 0; at < text.size();) {
      const std::size_t end = text.find('\n', at);
      const std::string line = text.substr(at, end - at);
      const std::size_t cut = line.rfind(',', line.rfind(',') - 1);  // drop the last two cells
      old += line.substr(0, cut) + "\n";
      at = end + 1;
    }
    const auto back_old = read_states_csv(tmp.write("old.csv", old));
    REQUIRE(back_old.size() == rows.size());
    CHECK(std::isnan(back_old[3].time_offset_s));
    CHECK(std::isnan(back_old[3].sigma_time_offset_s));
    CHECK(back_old[3].sigma == rows[3].sigma);
  }
  SECTION("objects.csv") {
    std::vector<ObjectRow> rows(30);
    for (std::size_t i = 0; i < rows.size(); ++i) {
      ObjectRow& o = rows[i];
      o.t_ns = static_cast<Timestamp>(i / 3) * 50000000;
      o.object_id = static_cast<int>(i % 3) - 1;  // -1, 0, 1
      o.anchor = o.object_id == 0;
      o.T_O_W = Pose(random_unit(g), random_vec(g));
      for (int k = 0; k < 6; ++k) {
        o.sigma(k) = u(g);
        o.sigma_W_O(k) = u(g);
        o.sigma_A_O(k) = o.anchor ? 0.0 : u(g);
      }
    }
    write_objects_csv(tmp / "objects.csv", rows);
    const auto back = read_objects_csv(tmp / "objects.csv");
    REQUIRE(back.size() == rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
      CHECK(back[i].t_ns == rows[i].t_ns);
      CHECK(back[i].object_id == rows[i].object_id);
      CHECK(back[i].anchor == rows[i].anchor);
      CHECK(back[i].T_O_W.p == rows[i].T_O_W.p);
      check_same_rotation(rows[i].T_O_W.q, back[i].T_O_W.q);
      CHECK(back[i].sigma == rows[i].sigma);
      CHECK(back[i].sigma_W_O == rows[i].sigma_W_O);
      CHECK(back[i].sigma_A_O == rows[i].sigma_A_O);
    }
  }
  SECTION("reprojection.csv, as eval reads it") {
    std::vector<ReprojectionRow> rows(40);
    for (std::size_t i = 0; i < rows.size(); ++i) {
      ReprojectionRow& r = rows[i];
      r.t_ns = static_cast<Timestamp>(i / 4) * 33333333;
      r.object_id = static_cast<int>(i % 4);
      r.outcome.object_id = r.object_id;
      r.outcome.status = static_cast<ekf::DetectionStatus>(i % 7);
      r.outcome.has_T_W_I = i % 5 != 0;
      r.outcome.T_W_I = Pose(random_unit(g), random_vec(g));
      r.outcome.nis = i % 3 == 0 ? std::nan("") : u(g) * 10;
      r.outcome.used = static_cast<ekf::ResidualPart>(i % 4);
    }
    write_reprojection_csv(tmp / "reprojection.csv", rows);
    const auto back = read_reprojection_csv(tmp / "reprojection.csv");
    REQUIRE(back.size() == rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
      CHECK(back[i].t_ns == rows[i].t_ns);
      CHECK(back[i].object_id == rows[i].object_id);
      CHECK(back[i].status == ekf::to_string(rows[i].outcome.status));
      CHECK(back[i].used == ekf::to_string(rows[i].outcome.used));
      if (std::isnan(rows[i].outcome.nis))
        CHECK(std::isnan(back[i].nis));
      else
        CHECK(back[i].nis == rows[i].outcome.nis);
      if (rows[i].outcome.has_T_W_I) {
        CHECK(back[i].T_W_I.p == rows[i].outcome.T_W_I.p);
        check_same_rotation(rows[i].outcome.T_W_I.q, back[i].T_W_I.q);
      } else {
        CHECK_FALSE(back[i].T_W_I.p.allFinite());
      }
    }
  }
}

TEST_CASE("run files: readers name the file, line and column of what is wrong", "[io][run_files]") {
  test::TempDir tmp("roe_run_files_bad");
  RecordedState s;
  s.t_ns = 100;
  ObjectRow o;
  o.t_ns = 100;
  const std::string states = format_states_csv({s, s});
  const std::string objects = format_objects_csv({o});

  SECTION("a missing column: at the header line, named") {
    std::string text = states;
    const std::size_t c = text.find(",sigma_p_I_C_y");
    text.erase(c, std::string(",sigma_p_I_C_y").size());
    const std::size_t row = text.find('\n') + 1;  // drop one field of each row too
    for (std::size_t p = row; p < text.size(); p = text.find('\n', p) + 1) {
      text.erase(text.find(',', p), 2);
      if (text.find('\n', p) == std::string::npos) break;
    }
    const auto f = tmp.write("states.csv", text);
    const InputError e = test::expect_input_error([&] { read_states_csv(f); });
    CHECK_THAT(e.context().file, Catch::Contains("states.csv"));
    CHECK(e.context().line == 1);
    CHECK_THAT(e.what(), Catch::Contains("sigma_p_I_C_y"));
    // With `missing`, the same is a reason instead of an error.
    std::string why;
    std::size_t n = 0;
    CHECK_FALSE(for_each_state_row(f, {}, [&](const RecordedState&) { ++n; }, &why));
    CHECK(n == 0);
    CHECK_THAT(why, Catch::Contains("sigma_p_I_C_y"));
    // A column the reader is not asked for may be missing.
    RunFileRead some;
    some.columns = {"timestamp_ns", "sigma_p_I_C_x"};
    CHECK(read_states_csv(f, some).size() == 2);
  }
  SECTION("eval's reading: extra columns are ignored, a written nan σ is refused as by every reader") {
    std::string text = states;
    text.replace(text.find('\n'), 1, ",extra\n");
    for (std::size_t p = text.find('\n') + 1; p < text.size(); p = text.find('\n', p) + 1) {
      text.insert(text.find('\n', p), ",x");
    }
    const std::size_t last_comma = text.rfind(',', text.rfind(",x") - 1);  // the last σ of the last row
    RunFileRead eval;
    eval.allow_nonfinite = true;
    const auto valid = tmp.write("valid.csv", text);
    CHECK(read_states_csv(valid, eval).size() == 2);  // the extra column is ignored
    text.replace(last_comma + 1, 1, "nan");
    const auto f = tmp.write("states.csv", text);
    // An unrecorded σ is an empty cell; a written nan is refused by eval's reading (issue 51) as by refine's.
    for (const RunFileRead& how : {eval, RunFileRead{}}) {
      const InputError e = test::expect_input_error([&] { read_states_csv(f, how); });
      CHECK(e.context().line == 3);
      CHECK(e.context().column == 47);  // the last σ column, sigma_time_offset_s (issue 49)
    }
  }
  SECTION("a missing objects.csv column") {
    std::string text = objects;
    text.replace(text.find("anchor"), 6, "anchr");
    const InputError e = test::expect_input_error([&] { read_objects_csv(tmp.write("objects.csv", text)); });
    CHECK(e.context().line == 1);
    CHECK_THAT(e.what(), Catch::Contains("anchor"));
  }
  SECTION("reprojection.csv without nis is read (nan); without status it is not") {
    const auto f = tmp.write("reprojection.csv", "timestamp_ns,object_id,tx,ty,tz,qx,qy,qz,qw,status\n"
                                                 "5,1,,,,,,,,pending_init\n6,1,1,2,3,0,0,0,1,accepted\n");
    const auto rows = read_reprojection_csv(f);
    REQUIRE(rows.size() == 2);
    CHECK(std::isnan(rows[0].nis));
    CHECK(std::isnan(rows[0].T_W_I.p.x()));
    CHECK(rows[1].T_W_I.p == Eigen::Vector3d(1, 2, 3));
    CHECK(rows[1].used.empty());  // a file written before the column existed
    const auto g = tmp.write("r2.csv", "timestamp_ns,object_id,tx,ty,tz,qx,qy,qz,qw,nis\n5,1,1,2,3,0,0,0,1,1\n");
    const InputError e = test::expect_input_error([&] { read_reprojection_csv(g); });
    CHECK(e.context().line == 1);
    CHECK_THAT(e.what(), Catch::Contains("status"));
  }
  SECTION("bad values") {
    const std::string header = states.substr(0, states.find('\n') + 1);
    std::string row = states.substr(header.size(), states.find('\n', header.size()) - header.size() + 1);
    // column 5 (v_W_I_x) nan: roe run never writes one
    std::string bad = row;
    std::size_t p = 0;
    for (int c = 1; c < 5; ++c) p = bad.find(',', p) + 1;
    bad.replace(p, bad.find(',', p) - p, "nan");
    auto e = test::expect_input_error([&] { read_states_csv(tmp.write("a.csv", header + row + bad)); });
    CHECK(e.context().line == 3);
    CHECK(e.context().column == 5);
    // a negative σ (column 25, sigma_p_W_I_x)
    bad = row;
    p = 0;
    for (int c = 1; c < 25; ++c) p = bad.find(',', p) + 1;
    bad.replace(p, bad.find(',', p) - p, "-1");
    e = test::expect_input_error([&] { read_states_csv(tmp.write("b.csv", header + bad)); });
    CHECK(e.context().line == 2);
    CHECK(e.context().column == 25);
    CHECK_THAT(e.what(), Catch::Contains("negative"));
    // a quaternion that is not unit: at its w column (11)
    bad = row;
    p = 0;
    for (int c = 1; c < 11; ++c) p = bad.find(',', p) + 1;
    bad.replace(p, bad.find(',', p) - p, "2");
    e = test::expect_input_error([&] { read_states_csv(tmp.write("c.csv", header + bad)); });
    CHECK(e.context().column == 11);
    CHECK_THAT(e.what(), Catch::Contains("quaternion"));
    // decreasing stamps
    std::string earlier = row;
    earlier.replace(0, 3, "99");
    e = test::expect_input_error([&] { read_states_csv(tmp.write("d.csv", header + row + earlier)); });
    CHECK(e.context().line == 3);
    CHECK(e.context().column == 1);
    CHECK_THAT(e.what(), Catch::Contains("decrease"));
    // objects.csv anchor must be 0 or 1 (column 3)
    std::string obj = objects;
    const std::size_t a = obj.find('\n') + 1;
    const std::size_t c3 = obj.find(',', obj.find(',', a) + 1) + 1;
    obj.replace(c3, 1, "2");
    e = test::expect_input_error([&] { read_objects_csv(tmp.write("o.csv", obj)); });
    CHECK(e.context().line == 2);
    CHECK(e.context().column == 3);
  }
}

TEST_CASE("run files: a states row without σ (output level standard) is empty cells, read back as nan",
          "[io][run_files]") {
  test::TempDir tmp("roe_run_files_no_sigma");
  RecordedState with, without;
  with.t_ns = 100;
  with.sigma.setConstant(0.25);
  without.t_ns = 200;
  without.x.p_W_I = {1.5, -2.0, 3.0};
  without.sigma.setConstant(std::nan(""));
  without.time_offset_s = 0.012;
  without.sigma_time_offset_s = std::nan("");
  const std::string text = format_states_csv({with, without});
  // The second row: its 23 values, then 21 empty σ cells, the time offset and its empty σ.
  const std::string last = text.substr(text.find('\n', text.find('\n') + 1) + 1);
  CHECK(last.substr(last.size() - 29) == std::string(21, ',') + ",0.012,\n");
  CHECK(last.find("nan") == std::string::npos);
  const auto f = tmp.write("states.csv", text);
  const auto rows = read_states_csv(f);  // the strict reader takes them
  REQUIRE(rows.size() == 2);
  CHECK(rows[0].sigma == with.sigma);
  CHECK(rows[1].sigma.array().isNaN().all());
  CHECK(std::isnan(rows[1].sigma_time_offset_s));
  CHECK(rows[1].time_offset_s == 0.012);
  CHECK(rows[1].x.p_W_I == without.x.p_W_I);
  CHECK(format_states_csv(rows) == text);
  // A "nan" written out is still refused by the strict reader (roe never writes one); a negative σ too.
  std::string bad = text;
  bad.insert(bad.size() - 1, "nan");
  const InputError e = test::expect_input_error([&] { read_states_csv(tmp.write("bad.csv", bad)); });
  CHECK(e.context().line == 3);
  CHECK(e.context().column == static_cast<std::int64_t>(states_csv_columns().size()));
  std::string negative = text;
  negative.insert(negative.size() - 1, "-1");
  CHECK_THROWS_AS(read_states_csv(tmp.write("neg.csv", negative)), InputError);
}

TEST_CASE("run files: tables streamed into the file in pieces have the bytes of their text", "[io][run_files]") {
  test::TempDir tmp("roe_run_files_stream");
  std::mt19937 g(11);
  // 6000 rows of ~560 bytes: 3.4 MB, so the writer appends several 1 MiB pieces and a tail.
  std::vector<RecordedState> rows(6000);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    rows[i].t_ns = 1700000000000000000LL + static_cast<Timestamp>(i) * 5000000;
    rows[i].x.p_W_I = random_vec(g);
    rows[i].x.q_W_I = random_unit(g);
    rows[i].T_I_C = Pose(random_unit(g), random_vec(g));
    for (int k = 0; k < 21; ++k) rows[i].sigma(k) = std::abs(random_vec(g).x());
  }
  const std::string text = format_states_csv(rows);
  REQUIRE(text.size() > 3 * CsvWriter::kFlushBytes);
  write_states_csv(tmp / "states.csv", rows);
  CHECK(read_file(tmp / "states.csv") == text);

  std::vector<Timestamp> t;
  std::vector<Pose> poses;
  for (std::size_t i = 0; i < 40000; ++i) {  // ~3.4 MB of TUM text
    t.push_back(rows[i % rows.size()].t_ns + static_cast<Timestamp>(i / rows.size()) * 100000000000LL);
    poses.push_back(Pose(random_unit(g), random_vec(g)));
  }
  for (const auto format : {TrajectoryFormat::kTum, TrajectoryFormat::kCsv, TrajectoryFormat::kKitti}) {
    write_trajectory(tmp / "traj.txt", t, poses, format);
    CHECK(read_file(tmp / "traj.txt") == format_trajectory(t, poses, format));
  }
}

TEST_CASE("run files: a run folder written row by row has the bytes of the in-memory tables, and nothing until commit",
          "[io][run_files]") {
  test::TempDir tmp("roe_run_folder_writer");
  std::mt19937 g(12);
  // 8000 state rows (3.2 MB: several 1 MiB pieces), σ recorded at every 7th row only (empty cells elsewhere).
  std::vector<RecordedState> states(8000);
  std::vector<ObjectRow> objects;
  std::vector<ReprojectionRow> reprojection;
  for (std::size_t i = 0; i < states.size(); ++i) {
    RecordedState& s = states[i];
    s.t_ns = 1700000000000000000LL + static_cast<Timestamp>(i) * 2500000;
    s.x.p_W_I = random_vec(g);
    s.x.q_W_I = random_unit(g);
    s.T_I_C = Pose(random_unit(g), random_vec(g));
    s.time_offset_s = random_vec(g).x() * 1e-3;
    for (int k = 0; k < 21; ++k) s.sigma(k) = i % 7 == 0 ? std::abs(random_vec(g).x()) : std::nan("");
    s.sigma_time_offset_s = i % 7 == 0 ? 1e-4 : std::nan("");
    if (i % 13 != 0) continue;
    ObjectRow o;
    o.t_ns = s.t_ns;
    o.object_id = static_cast<int>(i % 3);
    o.anchor = o.object_id == 0;
    o.T_O_W = Pose(random_unit(g), random_vec(g));
    o.sigma = random_vec(g).cwiseAbs().replicate(2, 1);
    objects.push_back(o);
    ReprojectionRow r;
    r.t_ns = s.t_ns;
    r.object_id = o.object_id;
    r.outcome.status = i % 2 == 0 ? ekf::DetectionStatus::kAccepted : ekf::DetectionStatus::kRejectedChi2;
    r.outcome.has_T_W_I = i % 5 != 0;
    r.outcome.T_W_I = Pose(random_unit(g), random_vec(g));
    r.outcome.nis = std::abs(random_vec(g).y());
    reprojection.push_back(r);
  }
  std::vector<Timestamp> t;
  std::vector<Pose> poses;
  for (const auto& s : states) {
    t.push_back(s.t_ns);
    poses.push_back(Pose(s.x.q_W_I, s.x.p_W_I));
  }
  const std::map<std::string, std::string> all = {
      {"states.csv", format_states_csv(states)},
      {"objects.csv", format_objects_csv(objects)},
      {"reprojection.csv", format_reprojection_csv(reprojection)},
      {"trajectory.csv", format_trajectory(t, poses, TrajectoryFormat::kCsv)},
      {"trajectory.tum", format_trajectory(t, poses, TrajectoryFormat::kTum)}};
  REQUIRE(all.at("states.csv").size() > 2 * CsvWriter::kFlushBytes);
  const auto entries = [](const fs::path& dir) {
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
    return names;
  };
  // Rows in the order the filter gives them: a state, then the image's objects and detections.
  const auto feed = [&](RunFolderWriter& w) {
    std::size_t o = 0;
    for (const auto& s : states) {
      w.state(s);
      for (; o < objects.size() && objects[o].t_ns == s.t_ns; ++o) {
        w.object(objects[o]);
        w.reprojection(reprojection[o]);
      }
    }
  };
  for (const char* level : {"full", "minimal"}) {
    INFO(level);
    RunConfig config;
    config.estimator = Estimator::kFilter;
    REQUIRE(parse(level, config.output_level));
    const fs::path dir = tmp / level;
    fs::create_directories(dir);
    {  // abandoned (an exception in the filter): nothing left, not even a temporary
      RunFolderWriter w(config, [&](const std::string& f) { return dir / f; });
      feed(w);
      CHECK_FALSE(entries(dir).empty());  // the temporaries, written as the rows came
      for (const auto& name : entries(dir)) CHECK(name.front() == '.');
    }
    CHECK(entries(dir).empty());
    RunFolderWriter w(config, [&](const std::string& f) { return dir / f; });
    feed(w);
    w.commit();
    std::set<std::string> want;
    for (const auto& [file, text] : all)
      if (run_folder_has(config, file)) {
        want.insert(file);
        INFO(file);
        const bool same = read_file(dir / file) == text;
        CHECK(same);
      }
    CHECK(entries(dir) == want);
    CHECK(want.size() == (std::string(level) == "full" ? 5u : 2u));
  }
}

TEST_CASE("AtomicFile: the final path appears only at commit, an abandoned one leaves nothing",
          "[io][output]") {
  test::TempDir tmp("roe_atomic_file");
  const auto entries = [&] {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(tmp.path)) names.push_back(e.path().filename().string());
    return names;
  };
  {
    AtomicFile f(tmp / "a.csv");
    f.append("x,y\n");
    f.append("1,2\n");
    CHECK_FALSE(fs::exists(tmp / "a.csv"));  // only the temporary so far
    CHECK(entries().size() == 1);
    f.commit();
  }
  CHECK(read_file(tmp / "a.csv") == "x,y\n1,2\n");
  {
    AtomicFile f(tmp / "a.csv");  // replacing: the old content stays until the commit that never comes
    f.append("partial");
  }
  CHECK(read_file(tmp / "a.csv") == "x,y\n1,2\n");
  CHECK(entries() == std::vector<std::string>{"a.csv"});
  CHECK_THROWS_AS(AtomicFile(tmp / "a.csv", false), InputError);
  CHECK_THROWS_AS(AtomicFile(tmp / "a.csv" / "under_a_file"), InputError);
  CHECK(entries() == std::vector<std::string>{"a.csv"});
}

TEST_CASE("reprojection.csv against the run's detections: every detection has its row, every row its detection",
          "[store][run_files][hostile]") {
  const auto det = [](int id) {
    Detection d;
    d.object_id = id;
    return d;
  };
  const std::vector<ekf::ImageDetections> images = {{100, {det(1), det(2)}}, {200, {det(1)}}};
  const auto row = [](Timestamp t, int id) {
    eval::DetectionPose p;
    p.t_ns = t;
    p.object_id = id;
    return p;
  };
  const std::vector<eval::DetectionPose> all = {row(100, 1), row(100, 2), row(200, 1)};
  CHECK_NOTHROW(store::check_reprojection_rows(all, images, "r.csv"));
  CHECK_THROWS_WITH(store::check_reprojection_rows({}, images, "r.csv"),
                    Catch::Contains("r.csv") && Catch::Contains("no row for 3 of the run's 3 detections"));
  CHECK_THROWS_WITH(store::check_reprojection_rows({row(100, 1), row(200, 1)}, images, "r.csv"),
                    Catch::Contains("no row for 1 of") && Catch::Contains("object 2 at 100 ns"));
  CHECK_THROWS_WITH(store::check_reprojection_rows({row(101, 1), row(100, 2), row(200, 1)}, images, "r.csv"),
                    Catch::Contains("object 1 at 100 ns"));  // shifted by 1 ns
  CHECK_THROWS_WITH(store::check_reprojection_rows({row(100, 1), row(100, 2), row(200, 1), row(300, 7)}, images,
                                                   "r.csv"),
                    Catch::Contains("1 rows name no detection") && Catch::Contains("object 7 at 300 ns"));
}
