// The smoothed rows' temporary file (store::SpilledStateRows, issue 53): blocks handed over from the last to the
// first come back in time order with every field the run files hold, bit for bit, and the file is gone after
// the run and after a failure; and the run folder writer's selection of files (RunFolderRows).
#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <random>
#include <set>
#include <stdexcept>

#include "roe/core/error.hpp"
#include "roe/io/input.hpp"
#include "roe/store/run_files.hpp"
#include "support/test_util.hpp"

using namespace roe;
using namespace roe::store;
namespace fs = std::filesystem;

namespace {

std::vector<RecordedState> random_rows(std::size_t n, std::mt19937& g) {
  std::normal_distribution<double> N(0.0, 3.0);
  std::vector<RecordedState> rows(n);
  for (std::size_t i = 0; i < n; ++i) {
    RecordedState& s = rows[i];
    s.t_ns = 1700000000000000000LL + static_cast<Timestamp>(i) * 2500000;
    s.x.p_W_I = {N(g), N(g), N(g)};
    s.x.v_W_I = {N(g), N(g), N(g)};
    s.x.q_W_I = Eigen::Quaterniond(N(g), N(g), N(g), N(g)).normalized();
    s.x.b_g = {N(g), N(g), N(g)};
    s.x.b_a = {N(g), N(g), N(g)};
    s.T_I_C = Pose(Eigen::Quaterniond(N(g), N(g), N(g), N(g)).normalized(), Eigen::Vector3d(N(g), N(g), N(g)));
    for (int k = 0; k < 21; ++k) s.sigma(k) = i % 5 == 0 ? std::abs(N(g)) : std::nan("");
    s.time_offset_s = N(g) * 1e-3;
    s.sigma_time_offset_s = i % 5 == 0 ? 1e-4 : std::nan("");
    s.pose_cov.setConstant(N(g));  // no file holds it: not kept
  }
  return rows;
}

/// The bits of a double (nan compares unequal to itself).
std::uint64_t bits(double v) {
  std::uint64_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}

template <class M>
bool same_bits(const M& a, const M& b) {
  for (Eigen::Index i = 0; i < a.size(); ++i)
    if (bits(a.data()[i]) != bits(b.data()[i])) return false;
  return true;
}

struct Collect : RunRowSink {
  std::vector<RecordedState> states;
  void state(const RecordedState& row) override { states.push_back(row); }
  void object(const ObjectRow&) override { FAIL("an object row"); }
  void reprojection(const ReprojectionRow&) override { FAIL("a reprojection row"); }
};

/// The rows cut into blocks of 1 to 17 rows, handed over from the last block to the first (as the smoother's
/// backward pass does).
void give_backwards(const std::vector<RecordedState>& rows, BackwardStateRows& to, std::mt19937& g) {
  std::vector<std::size_t> cuts{rows.size()};
  std::uniform_int_distribution<std::size_t> len(1, 17);
  while (cuts.back() > 0) cuts.push_back(cuts.back() - std::min(cuts.back(), len(g)));
  for (std::size_t k = 0; k + 1 < cuts.size(); ++k)
    to.block(std::vector<RecordedState>(rows.begin() + static_cast<std::ptrdiff_t>(cuts[k + 1]),
                                        rows.begin() + static_cast<std::ptrdiff_t>(cuts[k])));
}

}  // namespace

TEST_CASE("spilled state rows: blocks from the last to the first come back in time order, bit for bit",
          "[store][run_files][spill]") {
  test::TempDir tmp("roe_spilled_rows");
  std::mt19937 g(53);
  const std::vector<RecordedState> rows = random_rows(5000, g);
  const fs::path file = tmp / ".rows.tmp";
  Collect got;
  {
    SpilledStateRows spill(file);
    CHECK(fs::exists(file));
    give_backwards(rows, spill, g);
    CHECK(spill.rows() == rows.size());
    CHECK(fs::file_size(file) >= rows.size() * 47 * sizeof(double));  // on disk, not in memory
    spill.replay(got);
  }
  CHECK_FALSE(fs::exists(file));  // removed with the object
  REQUIRE(got.states.size() == rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const RecordedState &a = rows[i], &b = got.states[i];
    INFO("row " << i);
    REQUIRE(a.t_ns == b.t_ns);
    REQUIRE(same_bits(a.x.p_W_I, b.x.p_W_I));
    REQUIRE(same_bits(a.x.v_W_I, b.x.v_W_I));
    REQUIRE(same_bits(a.x.q_W_I.coeffs(), b.x.q_W_I.coeffs()));
    REQUIRE(same_bits(a.x.b_g, b.x.b_g));
    REQUIRE(same_bits(a.x.b_a, b.x.b_a));
    REQUIRE(same_bits(a.T_I_C.p, b.T_I_C.p));
    REQUIRE(same_bits(a.T_I_C.q.coeffs(), b.T_I_C.q.coeffs()));
    REQUIRE(same_bits(a.sigma, b.sigma));
    REQUIRE(bits(a.time_offset_s) == bits(b.time_offset_s));
    REQUIRE(bits(a.sigma_time_offset_s) == bits(b.sigma_time_offset_s));
    REQUIRE(b.pose_cov.isZero(0.0));
  }
  // The states.csv of the replayed rows is the file of the rows themselves.
  CHECK(format_states_csv(got.states) == format_states_csv(rows));
}

TEST_CASE("spilled state rows: the temporary file is gone after a failure, and one that cannot be made is named",
          "[store][run_files][spill]") {
  test::TempDir tmp("roe_spilled_rows_fail");
  std::mt19937 g(7);
  const fs::path file = tmp / ".rows.tmp";
  try {
    SpilledStateRows spill(file);
    give_backwards(random_rows(300, g), spill, g);
    REQUIRE(fs::file_size(file) > 0);
    throw std::runtime_error("the smoother failed");  // an exception before the rows were replayed
  } catch (const std::runtime_error&) {
  }
  CHECK_FALSE(fs::exists(file));
  CHECK(fs::is_empty(tmp.path));
  const fs::path nowhere = tmp / "no-such-folder" / ".rows.tmp";
  CHECK_THROWS_AS(SpilledStateRows(nowhere), InputError);
  CHECK_THROWS_WITH(SpilledStateRows(nowhere), Catch::Contains("no-such-folder"));
}

TEST_CASE("run folder writer: the filter's state rows under a suffix, the smoothed ones without the other rows",
          "[store][run_files]") {
  test::TempDir tmp("roe_run_folder_rows");
  std::mt19937 g(3);
  const std::vector<RecordedState> rows = random_rows(50, g);
  RunConfig config;  // the smoother, level full: the _filter files are in the run folder
  const auto path_of = [&](const std::string& f) { return tmp / f; };
  RunFolderWriter filter(config, path_of, RunFolderRows{true, "_filter", true});
  RunFolderWriter smoothed(config, path_of, RunFolderRows{true, "", false});
  for (const auto& r : rows) {
    filter.state(r);
    smoothed.state(r);
  }
  CHECK_THROWS_AS(smoothed.object(ObjectRow{}), InternalError);
  CHECK_THROWS_AS(smoothed.reprojection(ReprojectionRow{}), InternalError);
  filter.commit();
  smoothed.commit();
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(tmp.path)) names.insert(e.path().filename().string());
  CHECK(names == std::set<std::string>{"objects.csv", "reprojection.csv", "states.csv", "states_filter.csv",
                                       "trajectory.csv", "trajectory.tum", "trajectory_filter.csv",
                                       "trajectory_filter.tum"});
  CHECK(io::read_file(tmp / "states_filter.csv") == format_states_csv(rows));
  CHECK(io::read_file(tmp / "states.csv") == format_states_csv(rows));
  CHECK(io::read_file(tmp / "trajectory_filter.tum") == io::read_file(tmp / "trajectory.tum"));
}
