// Association edge cases: evo's nearest-neighbour rule, offsets, gaps, duplicates, the unique
// policy, and the no-match diagnosis (ns vs s, relative vs absolute time).
#include <catch2/catch.hpp>
#include <limits>

#include "roe/core/error.hpp"
#include "roe/eval/associate.hpp"

using namespace roe;
using namespace roe::eval;

namespace {
std::vector<Timestamp> seq(Timestamp t0, Timestamp step, int n) {
  std::vector<Timestamp> t;
  for (int i = 0; i < n; ++i) t.push_back(t0 + step * i);
  return t;
}
constexpr Timestamp ms = 1'000'000;
}  // namespace

TEST_CASE("associate: exact and jittered stamps", "[eval][assoc]") {
  const auto gt = seq(1000 * ms, 10 * ms, 100);  // 100 Hz
  std::vector<Timestamp> est;
  for (int i = 0; i < 20; ++i) est.push_back(gt[5 * i] + ((i % 3) - 1) * 2 * ms);  // ±2 ms jitter
  const Association a = associate(est, gt);
  REQUIRE(a.size() == 20);
  for (std::size_t k = 0; k < a.size(); ++k) {
    CHECK(a.est_index[k] == k);
    CHECK(a.gt_index[k] == 5 * k);
    CHECK(a.dt_ns[k] == gt[5 * k] - est[k]);
  }
}

TEST_CASE("associate: |dt| == max_dt is accepted (evo), just above is not", "[eval][assoc]") {
  const std::vector<Timestamp> gt{0, 100 * ms};
  const std::vector<Timestamp> est{10 * ms, 100 * ms + 10 * ms + 1};
  const Association a = associate(est, gt, {0.01, 0.0, AssocPolicy::kNearest});
  REQUIRE(a.size() == 1);
  CHECK(a.est_index[0] == 0);
  CHECK(a.dt_ns[0] == -10 * ms);
}

TEST_CASE("associate: offset is added to the estimate stamps", "[eval][assoc]") {
  const auto gt = seq(5000 * ms, 10 * ms, 50);
  std::vector<Timestamp> est;
  for (Timestamp t : seq(5000 * ms, 20 * ms, 10)) est.push_back(t - 250 * ms);  // estimate clock 0.25 s early
  CHECK(associate(est, gt).size() == 0);
  const Association a = associate(est, gt, {0.001, 0.25, AssocPolicy::kNearest});
  REQUIRE(a.size() == 10);
  for (std::size_t k = 0; k < 10; ++k) {
    CHECK(a.gt_index[k] == 2 * k);
    CHECK(a.dt_ns[k] == 0);
  }
}

TEST_CASE("associate: gaps drop pairs, the longer list is searched", "[eval][assoc]") {
  // ground truth with a hole between 1 s and 2 s
  std::vector<Timestamp> gt = seq(0, 10 * ms, 101);
  for (Timestamp t : seq(2000 * ms, 10 * ms, 101)) gt.push_back(t);
  const auto est = seq(0, 100 * ms, 31);  // 0 .. 3 s at 10 Hz
  const Association a = associate(est, gt);
  // stamps 1.1 .. 1.9 s fall in the hole; 1.0 and 2.0 s still match
  CHECK(a.size() == 31 - 9);
  for (std::size_t k = 0; k < a.size(); ++k) CHECK(a.dt_ns[k] == 0);

  // Estimate longer than GT: iterate over GT, estimate poses may repeat.
  const auto dense = seq(0, 1 * ms, 1001);
  const std::vector<Timestamp> sparse{0, 500 * ms, 1000 * ms};
  const Association b = associate(dense, sparse);
  REQUIRE(b.size() == 3);
  CHECK(b.est_index == std::vector<std::size_t>{0, 500, 1000});
  CHECK(b.gt_index == std::vector<std::size_t>{0, 1, 2});
}

TEST_CASE("associate: ties pick the earlier stamp (numpy argmin)", "[eval][assoc]") {
  const std::vector<Timestamp> gt{0, 10 * ms, 20 * ms, 30 * ms};
  const std::vector<Timestamp> est{5 * ms};
  const Association a = associate(est, gt);
  REQUIRE(a.size() == 1);
  CHECK(a.gt_index[0] == 0);
}

TEST_CASE("associate: duplicated stamps, nearest vs unique", "[eval][assoc]") {
  const auto gt = seq(0, 5 * ms, 400);
  // estimate with two duplicated stamps carrying different poses (evo's V1_02 test estimate has 4)
  std::vector<Timestamp> est{100 * ms, 200 * ms, 200 * ms, 300 * ms, 400 * ms, 400 * ms, 500 * ms};
  const Association near = associate(est, gt);
  CHECK(near.size() == 7);  // evo keeps both poses of each duplicate
  CHECK(near.n_duplicate_est == 2);
  CHECK(near.gt_index[1] == near.gt_index[2]);
  const Association uniq = associate(est, gt, {0.01, 0.0, AssocPolicy::kUnique});
  CHECK(uniq.size() == 5);  // cnspy keeps the first pose of each duplicate
  CHECK(uniq.n_dropped_unique == 2);
  CHECK(uniq.est_index == std::vector<std::size_t>{0, 1, 3, 4, 6});

  // unique: two estimate stamps competing for one GT pose → the closer one wins
  const std::vector<Timestamp> g2{0, 100 * ms, 200 * ms};
  const std::vector<Timestamp> e2{96 * ms, 99 * ms};
  const Association u2 = associate(e2, g2, {0.01, 0.0, AssocPolicy::kUnique});
  REQUIRE(u2.size() == 1);
  CHECK(u2.est_index[0] == 1);
  CHECK(associate(e2, g2).size() == 2);

  // duplicates in the longer list: the first of the run is used
  const std::vector<Timestamp> g3{0, 10 * ms, 10 * ms, 20 * ms};
  const Association a3 = associate({10 * ms}, g3);
  REQUIRE(a3.size() == 1);
  CHECK(a3.gt_index[0] == 1);
  CHECK(a3.n_duplicate_gt == 1);
}

TEST_CASE("associate: refuses decreasing stamps and bad options", "[eval][assoc]") {
  CHECK_THROWS_AS(associate({0, 20 * ms, 10 * ms}, {0, 10 * ms}), InputError);
  CHECK_THROWS_AS(associate({0}, {0}, {-1.0, 0.0, AssocPolicy::kNearest}), InputError);
  CHECK(associate({}, {0}).size() == 0);
  CHECK(parse_assoc_policy("unique") == AssocPolicy::kUnique);
  CHECK_THROWS_AS(parse_assoc_policy("greedy"), InputError);
}

TEST_CASE("explain_no_match: ranges and likely causes", "[eval][assoc]") {
  const auto gt = seq(1'403'715'524'000 * ms, 5 * ms, 1000);
  SECTION("nanosecond stamps read as seconds somewhere (factor 1e9)") {
    std::vector<Timestamp> est;
    for (Timestamp t : seq(1'403'715'524, 1, 10)) est.push_back(t);  // 'seconds' that were ns / 1e9
    const std::string m = explain_no_match(est, gt, {});
    CHECK(m.find("span") != std::string::npos);
    CHECK(m.find("1e9") != std::string::npos);
    CHECK(m.find("ns vs s") != std::string::npos);
  }
  SECTION("relative time vs epoch") {
    const auto est = seq(0, 100 * ms, 20);
    const std::string m = explain_no_match(est, gt, {});
    CHECK(m.find("estimate starts near 0 s") != std::string::npos);
    CHECK(m.find("--t-offset 1403715524.000000000") != std::string::npos);
    CHECK(m.find("scaled by") == std::string::npos);
    // the estimate is the relative one: no import hint for the ground truth
    CHECK(m.find("roe import mocap") == std::string::npos);
  }
  SECTION("overlapping but sparse") {
    std::vector<Timestamp> est;
    for (Timestamp t : seq(gt.front() + 2 * ms, 100 * ms, 20)) est.push_back(t);
    const std::string m = explain_no_match(est, gt, {0.001, 0.0, AssocPolicy::kNearest});
    CHECK(m.find("--max-dt") != std::string::npos);
    CHECK(m.find("0.002 s apart") != std::string::npos);
  }
}

// The nearest-neighbour search at the ends of the searched list, with an offset on the searched side,
// duplicates at the very start, and the message for decreasing stamps.
TEST_CASE("associate: list ends, offset on the longer list, leading duplicates, messages", "[eval][assoc]") {
  // An estimate stamp after the last ground-truth stamp, within max_dt, and one before the first.
  const std::vector<Timestamp> gt{100 * ms, 110 * ms, 120 * ms};
  const Association a = associate({95 * ms, 124 * ms}, gt);
  REQUIRE(a.size() == 2);
  CHECK(a.gt_index == std::vector<std::size_t>{0, 2});
  CHECK(a.dt_ns == std::vector<Timestamp>{5 * ms, -4 * ms});

  // The estimate is the longer list (it is searched for each ground-truth stamp) and its clock runs
  // 0.25 s early: the offset moves the searched stamps.
  std::vector<Timestamp> dense;
  for (Timestamp t : seq(1000 * ms, 1 * ms, 1001)) dense.push_back(t - 250 * ms);
  const std::vector<Timestamp> sparse{1000 * ms, 1500 * ms, 2000 * ms};
  const Association b = associate(dense, sparse, {0.0005, 0.25, AssocPolicy::kNearest});
  REQUIRE(b.size() == 3);
  CHECK(b.est_index == std::vector<std::size_t>{0, 500, 1000});
  CHECK(b.dt_ns == std::vector<Timestamp>{0, 0, 0});

  // Duplicates at the start of each list are counted; the unique policy keeps the first of the run.
  const std::vector<Timestamp> e3{100 * ms, 100 * ms, 200 * ms};
  const std::vector<Timestamp> g3{100 * ms, 100 * ms, 150 * ms, 200 * ms};
  const Association n3 = associate(e3, g3);
  CHECK(n3.n_duplicate_est == 1);
  CHECK(n3.n_duplicate_gt == 1);
  const Association u3 = associate(e3, g3, {0.01, 0.0, AssocPolicy::kUnique});
  CHECK(u3.est_index == std::vector<std::size_t>{0, 2});
  CHECK(u3.gt_index == std::vector<std::size_t>{0, 3});
  // A duplicate run after the start whose pairs are better than the first pose's: the run is one key,
  // whichever of its poses is looked at first.
  const Association u4 = associate({101 * ms, 200 * ms, 200 * ms, 300 * ms}, seq(0, 5 * ms, 100),
                                   {0.01, 0.0, AssocPolicy::kUnique});
  CHECK(u4.est_index == std::vector<std::size_t>{0, 1, 3});

  // Decreasing stamps: the message names the pose (1-based) and both stamps.
  try {
    associate({0, 20 * ms, 10 * ms, 30 * ms}, {0});
    FAIL("no error");
  } catch (const InputError& e) {
    const std::string m = e.what();
    INFO(m);
    CHECK(m.find("at pose 3 (0.010000000 s after 0.020000000 s)") != std::string::npos);
  }
}

// With an offset, the diagnosis reports the estimate's stamps with the offset applied, and the
// closest pair after it.
TEST_CASE("explain_no_match: ranges and the closest pair with an offset", "[eval][assoc]") {
  const auto gt = seq(100'000 * ms, 10 * ms, 101);  // 100 .. 101 s
  const auto est = seq(50'000 * ms, 100 * ms, 11);  // 50 .. 51 s
  AssociationOptions o{0.001, 49.5, AssocPolicy::kNearest};  // → 99.5 .. 100.5 s, stamps 0.5 s apart
  const std::string m = explain_no_match(est, gt, o);
  INFO(m);
  CHECK(m.find("span [99.500000, 100.500000] s (11 poses)") != std::string::npos);
  CHECK(m.find("ground truth [100.000000, 101.000000] s (101 poses)") != std::string::npos);
  // 3 ms more offset: every shifted estimate stamp inside the ground truth's span is 3 ms off its
  // nearest ground-truth stamp (the ones before the span are 0.4 s or more off).
  AssociationOptions o2{0.001, 49.503, AssocPolicy::kNearest};
  const std::string m2 = explain_no_match(est, gt, o2);
  INFO(m2);
  CHECK(m2.find("the closest pair is 0.003 s apart") != std::string::npos);
  // The closest pair away from the ends: ground truth at 100.05, 100.5003 and 101.05 s, the shifted
  // estimate at 99.503 + 0.1 k s: 100.503 vs 100.5003.
  const std::vector<Timestamp> g3{100'050 * ms, 100'500'300'000, 101'050 * ms};
  const std::string m3 = explain_no_match(est, g3, o2);
  INFO(m3);
  CHECK(m3.find("the closest pair is 0.0027 s apart") != std::string::npos);
  // Ranges apart, both relative: the suggested --t-offset is the total one (it includes the offset
  // already given): 1000 − (10 + 5) + 5 = 990.
  const std::string m4 = explain_no_match(seq(10'000 * ms, 100 * ms, 11), seq(1'000'000 * ms, 100 * ms, 11),
                                          {0.01, 5.0, AssocPolicy::kNearest});
  INFO(m4);
  CHECK(m4.find("(e.g. 990.000000000 aligns the starts)") != std::string::npos);
}

// The unit mix-up rule: the scaled estimate range lines up with the ground truth when its start lies
// within 1 % plus the ground truth's span of the ground truth's start, or when the ranges overlap and
// the starts are within half the ground truth's start of each other. Each clause alone is enough.
TEST_CASE("explain_no_match: each clause of the unit mix-up rule on its own", "[eval][assoc]") {
  struct Case {
    const char* what;
    std::vector<Timestamp> est, gt;
    const char* blamed;  // the factor named, or nullptr for none
  };
  const std::vector<Case> cases{
      // ×1e9: [1403715520, 1403715522] s, 2 s before the ground truth starts.
      {"starts close, ranges apart (first clause only)",
       {1'403'715'520, 1'403'715'521, 1'403'715'522},
       seq(1'403'715'524'000 * ms, 5 * ms, 1000),
       "1e9"},
      // ×1e3: [201, 210] s against [100, 200] s.
      {"start within the ground truth's span after its end (first clause only)", seq(201 * ms, 1 * ms, 10),
       seq(100'000 * ms, 1000 * ms, 101), "1e3"},
      // ×1e3: [60, 120] s against [100, 101] s.
      {"overlapping, starts 40 % apart (second clause only)", seq(60 * ms, 1 * ms, 61),
       seq(100'000 * ms, 100 * ms, 11), "1e3"},
      // ×1e3: [400, 409] s against [100, 101] s.
      {"neither: no unit is blamed", seq(400 * ms, 1 * ms, 10), seq(100'000 * ms, 100 * ms, 11), nullptr},
  };
  for (const Case& c : cases) {
    const std::string m = explain_no_match(c.est, c.gt, {});
    INFO(c.what << ": " << m);
    const bool blames = m.find("only when scaled by ") != std::string::npos;
    CHECK(blames == (c.blamed != nullptr));
    if (c.blamed) CHECK(m.find(std::string("only when scaled by ") + c.blamed) != std::string::npos);
  }
}

// A ground truth in relative time (a mocap take: 0 .. 2 s at 100 Hz) against an estimate in epoch
// time (20 s at 20 Hz): scaled by 1e-9 the estimate starts at 1.6 s, inside the ground truth's range,
// but its 20 s span becomes 2e-8 s: not a unit mix-up. The diagnosis names the clocks and suggests
// the --t-offset that aligns the starts, and roe import mocap's offset options.
TEST_CASE("explain_no_match: relative ground truth vs epoch estimate is not a unit mix-up", "[eval][assoc]") {
  const Timestamp e0 = 1'600'000'000'000 * ms;
  const auto est = seq(e0, 50 * ms, 400);
  const auto gt = seq(0, 10 * ms, 201);
  const std::string m = explain_no_match(est, gt, {});
  INFO(m);
  CHECK(m.find("scaled by") == std::string::npos);
  CHECK(m.find("ns vs s") == std::string::npos);
  CHECK(m.find("ground truth starts near 0 s") != std::string::npos);
  CHECK(m.find("epoch") != std::string::npos);
  CHECK(m.find("--t-offset -1600000000.000000000") != std::string::npos);
  CHECK(m.find("roe import mocap FILE --into DATASET --time-offset S") != std::string::npos);
  CHECK(m.find("S = 1600000000.000000000") != std::string::npos);
  CHECK(m.find("--estimate-offset") != std::string::npos);
  // With an offset already given, the suggestion is the total offset and the import S the clock's own.
  const std::string m2 = explain_no_match(est, gt, {0.01, -100.0, AssocPolicy::kNearest});
  INFO(m2);
  CHECK(m2.find("--t-offset -1600000000.000000000") != std::string::npos);
  CHECK(m2.find("S = 1600000000.000000000") != std::string::npos);
  // A ground truth starting 2 days after 0 is not "relative": the generic no-overlap hint.
  const std::string m3 = explain_no_match(est, seq(2 * 86'400'000 * ms, 10 * ms, 201), {});
  INFO(m3);
  CHECK(m3.find("starts near 0 s") == std::string::npos);
  CHECK(m3.find("aligns the starts") != std::string::npos);
}

// A real unit mix-up still says so: the same recording with one side in ns read as s (×1e9) or in
// ms (×1e3), both in relative time and in epoch time; the scaled spans match.
TEST_CASE("explain_no_match: a unit mix-up is still diagnosed when the scaled spans match", "[eval][assoc]") {
  const Timestamp e0 = 1'600'000'000'000 * ms;
  // epoch: the estimate's seconds were taken for nanoseconds → 1e9 times too small (1.6 .. 1.6 + 2e-8 s).
  std::vector<Timestamp> est_s_as_ns;
  for (Timestamp t : seq(e0, 50 * ms, 400)) est_s_as_ns.push_back(t / 1'000'000'000);
  const auto gt = seq(e0 - 5'000 * ms, 5 * ms, 6000);
  const std::string m = explain_no_match(est_s_as_ns, gt, {});
  INFO(m);
  CHECK(m.find("only when scaled by 1e9") != std::string::npos);
  CHECK(m.find("starts near 0 s") == std::string::npos);
  // relative time: the ground truth in ms read as s (0 .. 20000 "s") vs the estimate 0 .. 20 s.
  std::vector<Timestamp> gt_ms_as_s;
  for (Timestamp t : seq(0, 10 * ms, 2001)) gt_ms_as_s.push_back(t * 1000);
  const std::string m2 = explain_no_match(seq(0, 50 * ms, 400), gt_ms_as_s, {0.001, 0.0, AssocPolicy::kNearest});
  INFO(m2);
  CHECK(m2.find("only when scaled by 1e3") != std::string::npos);
}

// The most pairs to expect: the sparser stream inside the span both cover.
TEST_CASE("overlap: poses of each trajectory inside the common span", "[eval][assoc]") {
  // EuRoC-style: 83 s of ground truth at 40 Hz, a 40 s estimate at 200 Hz from 20 s on.
  const auto gt = seq(0, 25 * ms, 3321);            // 0 .. 83 s
  const auto est = seq(20'000 * ms, 5 * ms, 8001);  // 20 .. 60 s
  const Overlap o = overlap(est, gt, {});
  CHECK(o.begin_ns == 20'000 * ms - 10 * ms);
  CHECK(o.end_ns == 60'000 * ms + 10 * ms);
  CHECK(o.n_est == 8001);
  CHECK(o.n_gt == 1601);
  CHECK(o.n_max() == 1601);
  CHECK(associate(est, gt).size() == 1601);  // every ground-truth pose in the span matches
  // The offset shifts the estimate: 30 .. 70 s.
  const Overlap o2 = overlap(est, gt, {0.0, 10.0, AssocPolicy::kNearest});
  CHECK(o2.n_est == 8001);
  CHECK(o2.n_gt == 1601);
  CHECK(o2.begin_ns == 30'000 * ms);
  // Disjoint ranges: nothing.
  const Overlap o3 = overlap(seq(100'000 * ms, 5 * ms, 10), gt, {});
  CHECK(o3.n_max() == 0);
  CHECK(o3.begin_ns > o3.end_ns);
  CHECK(overlap({}, gt, {}).n_max() == 0);
  CHECK_THROWS_AS(overlap(est, gt, {-1.0, 0.0, AssocPolicy::kNearest}), InputError);
  // Epoch stamps with the largest accepted max_dt / offset: no overflow, everything inside the span.
  const Timestamp epoch = 1'700'000'000'000'000'000LL;
  const auto gt_e = seq(epoch, 25 * ms, 100), est_e = seq(epoch, 5 * ms, 500);
  const Overlap big = overlap(est_e, gt_e, {9e9, 0.0, AssocPolicy::kNearest});
  CHECK(big.end_ns == std::numeric_limits<Timestamp>::max());
  CHECK(big.n_est == 500);
  CHECK(big.n_gt == 100);
  // Shifted by 9e9 s the estimate starts far after the ground truth, but the 9e9 s window still reaches
  // it: every ground-truth pose, and the estimate's poses up to the ground truth's end + max_dt − offset.
  const Overlap shifted = overlap(est_e, gt_e, {9e9, 9e9, AssocPolicy::kNearest});
  CHECK(shifted.n_gt == 100);
  CHECK(shifted.n_est == 496);  // est_e[k] ≤ epoch + 99·25 ms for k ≤ 495
}

TEST_CASE("associate: a shorter ground truth with duplicated stamps pairs only the first pose of each", "[eval][assoc]") {
  // The ground truth is the shorter list (it is iterated): its repeated stamp must not give a second pair.
  const std::vector<Timestamp> est = seq(0, 5 * ms, 100);
  const std::vector<Timestamp> gt{100 * ms, 200 * ms, 200 * ms, 300 * ms, 300 * ms, 300 * ms, 400 * ms};
  for (AssocPolicy policy : {AssocPolicy::kNearest, AssocPolicy::kUnique}) {
    const Association a = associate(est, gt, {0.01, 0.0, policy});
    CHECK(a.n_duplicate_gt == 3);
    CHECK(a.gt_index == std::vector<std::size_t>{0, 1, 3, 6});
    CHECK(a.est_index == std::vector<std::size_t>{20, 40, 60, 80});
  }
}
