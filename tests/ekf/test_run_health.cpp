// The measurement stream and a run's verdicts, without files: image grouping, the one anchor rule
// (choose_anchor, used by Filter::update and run_filter alike), the counts run_filter collects, the
// warnings they call for, robust NIS statistics and the health verdict.
#include <catch2/catch.hpp>

#include <algorithm>

#include "filter_support.hpp"
#include "roe/ekf/driver.hpp"
#include "roe/ekf/health.hpp"
#include "roe/ekf/images.hpp"

// GCC 12 warns that copying a disengaged std::optional<Eigen::Matrix> (Detection::sigma) out of an
// initializer list reads its payload; it does not (the optional's engaged flag guards it): a false positive.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

using namespace roe;
using namespace roe::ekf;

namespace {

Detection det(double t_s, int id, double score = std::numeric_limits<double>::quiet_NaN()) {
  Detection d;
  d.t_ns = from_seconds(t_s);
  d.object_id = id;
  d.T_C_O = Pose(Eigen::Quaterniond::Identity(), Vec3(0.0, 0.0, 2.0));
  d.score = score;
  return d;
}

bool contains(const std::vector<std::string>& v, const std::string& part) {
  return std::any_of(v.begin(), v.end(), [&](const std::string& s) { return s.find(part) != std::string::npos; });
}

struct Ids : FilterObserver {
  int anchor = -1;
  DetectionCounts counts;
  std::vector<double> nis;
  std::size_t updated_images = 0;
  void on_image(Filter& f, const FrameResult& r) override {
    anchor = f.anchor_id();
    for (const auto& d : r.detections) {
      counts.add(d.status);
      if (std::isfinite(d.nis)) nis.push_back(d.nis);
    }
    updated_images += r.n_inliers > 0;
  }
};

}  // namespace

TEST_CASE("group_images: one entry per stamp, shifted into the IMU clock, unsorted stamps refused", "[ekf][run]") {
  const std::vector<Detection> dets = {det(0.0, 1), det(0.0, 2), det(0.1, 2), det(0.2, 1), det(0.2, 3)};
  const auto im = group_images(dets, from_seconds(0.5));
  REQUIRE(im.size() == 3);
  CHECK(im[0].t_ns == from_seconds(0.5));
  CHECK(im[0].detections.size() == 2);
  CHECK(im[0].detections[1].t_ns == from_seconds(0.5));  // the detections carry the shifted stamp
  CHECK(im[1].detections.size() == 1);
  CHECK(im[2].detections[1].object_id == 3);
  CHECK(group_images({}).empty());
  CHECK_THROWS_AS(group_images({det(0.2, 1), det(0.1, 1)}), DataError);
}

TEST_CASE("choose_anchor: the first usable image's most-seen object, then the lowest id", "[ekf][run][anchor]") {
  FilterOptions o;
  // Image 0 lies before the IMU span; image 1 holds objects 4 and 7; 7 is detected more often.
  const auto images = group_images({det(0.0, 2), det(1.0, 4), det(1.0, 7), det(1.1, 7), det(1.2, 7), det(1.2, 4),
                                    det(1.3, 7), det(1.3, 2), det(1.4, 2), det(1.5, 2), det(1.6, 2)});
  const Timestamp t0 = from_seconds(0.5), t1 = from_seconds(10.0);
  AnchorChoice c = choose_anchor(images, t0, t1, o);
  CHECK(c.automatic);
  CHECK(c.id == 7);  // object 2 is seen most of all, but not in the first image
  CHECK(c.images == 4);
  CHECK(c.t_ns == from_seconds(1.0));
  // Equal counts: the lowest id.
  c = choose_anchor(group_images({det(1.0, 9), det(1.0, 5), det(1.1, 9), det(1.1, 5)}), t0, t1, o);
  CHECK(c.id == 5);
  // One image (what Filter::update knows alone): every count is 1, the lowest id.
  CHECK(choose_anchor(group_images({det(1.0, 8), det(1.0, 3)}), t0, t1, o).id == 3);
  // Detections below min_score are neither candidates nor counted.
  o.min_score = 0.5;
  c = choose_anchor(group_images({det(1.0, 1, 0.2), det(1.0, 6, 0.9), det(1.1, 1, 0.9), det(1.2, 1, 0.9)}), t0, t1, o);
  CHECK(c.id == 6);
  // Nothing usable in the IMU span: none.
  CHECK(choose_anchor(group_images({det(0.1, 1)}), t0, t1, o).id == -1);
  // A configured anchor is taken as it is.
  o.anchor_id = 2;
  c = choose_anchor(images, t0, t1, FilterOptions{o});
  CHECK_FALSE(c.automatic);
  CHECK(c.id == 2);
}

TEST_CASE("choose_anchor prefers a non-symmetric object of the first image, then the rule", "[ekf][run][anchor]") {
  FilterOptions o;
  const Timestamp t0 = from_seconds(0.5), t1 = from_seconds(10.0);
  // Object 3 is seen most and has the lowest id, but it is symmetric (a group, or only the flag).
  const auto images = group_images({det(1.0, 3), det(1.0, 8), det(1.0, 9), det(1.1, 3), det(1.1, 9), det(1.2, 3)});
  ObjectSymmetry group;
  group.discrete.push_back(Pose(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ())), Eigen::Vector3d::Zero()));
  CHECK(choose_anchor(images, t0, t1, o).id == 3);
  for (const ObjectSymmetry& s : {group, ObjectSymmetry{}}) {
    const AnchorChoice c = choose_anchor(images, t0, t1, o, {{3, s}});
    CHECK(c.automatic);
    CHECK(c.id == 9);  // among the non-symmetric 8 and 9: the most images
    CHECK(c.images == 2);
  }
  // Every object of the first image symmetric: the rule as without symmetries.
  CHECK(choose_anchor(images, t0, t1, o, {{3, group}, {8, group}, {9, group}}).id == 3);
  // A symmetric object not in the first image changes nothing; a configured anchor is kept.
  CHECK(choose_anchor(images, t0, t1, o, {{5, group}}).id == 3);
  o.anchor_id = 3;
  CHECK(choose_anchor(images, t0, t1, o, {{3, group}}).id == 3);
}

TEST_CASE("run_filter and Filter::update follow the same anchor rule, the summary's counts are the outcomes",
          "[ekf][run][anchor]") {
  // paper-seq1 (3 objects in view from the start). The lowest id is dropped from all but the first 10
  // images, so the rule (most images) and "lowest id" disagree.
  const Dataset d = test::simulate_preset("paper-seq1", 4, 4.0);
  std::vector<ImageDetections> images = group_images(d.detections.at("sim"));
  REQUIRE(images.size() > 30);
  int lowest = images.front().detections.front().object_id;
  for (const auto& x : images.front().detections) lowest = std::min(lowest, x.object_id);
  for (std::size_t j = 10; j < images.size(); ++j) {
    auto& v = images[j].detections;
    v.erase(std::remove_if(v.begin(), v.end(), [&](const Detection& x) { return x.object_id == lowest; }), v.end());
  }
  images.erase(std::remove_if(images.begin(), images.end(), [](const auto& im) { return im.detections.empty(); }),
               images.end());
  FilterOptions o;
  const ImuNoiseParams noise{d.manifest.imu->noise.gyro_noise_density, d.manifest.imu->noise.gyro_random_walk,
                             d.manifest.imu->noise.accel_noise_density, d.manifest.imu->noise.accel_random_walk};
  Ids obs;
  const FilterRunSummary s = run_filter(d.imu, images, o, noise, d.manifest.camera->T_I_C, obs);
  const AnchorChoice want = choose_anchor(images, d.imu.front().t_ns, d.imu.back().t_ns, o);
  CHECK(want.id != lowest);
  CHECK(s.anchor.id == want.id);
  CHECK(obs.anchor == want.id);  // the filter ran with the rule's anchor
  DetectionCounts total;
  for (const auto& [id, c] : s.counts) total += c;
  CHECK(total.detections == obs.counts.detections);
  CHECK(total.accepted == obs.counts.accepted);
  CHECK(total.rejected_chi2 == obs.counts.rejected_chi2);
  CHECK(total.initialized == obs.counts.initialized);
  CHECK(total.pending_init == obs.counts.pending_init);
  CHECK(s.nis == obs.nis);
  CHECK(s.update_times.size() == obs.updated_images);
  CHECK(s.update_times.size() == s.updates);
  CHECK(std::is_sorted(s.update_times.begin(), s.update_times.end()));
  CHECK(s.final_T_O_W.size() == 3);
  // The filter alone, given the same first image, takes the lowest id: the rule with no look-ahead.
  Filter f(o, noise, d.manifest.camera->T_I_C);
  f.initialize(images.front().t_ns, Vec3::Zero(), Vec3(0, 0, 9.81), Vec3(0, 0, 9.81));
  f.update(images.front().detections);
  CHECK(f.anchor_id() == lowest);
}

TEST_CASE("nis_stats: quantiles as Python's statistics.quantiles(method='inclusive'), one outlier moves only the mean",
          "[ekf][run][health]") {
  // Expected values: python3 -c "import statistics as s; d=[...]; print(s.quantiles(d, n=4,
  // method='inclusive'), s.quantiles(d, n=20, method='inclusive')[18], s.mean(d))"
  const std::vector<double> v = {0.4, 1.3, 2.2, 5.1, 0.9, 7.7, 3.3, 12.0, 193295.0, 4.4, 6.0};
  const NisStats n = nis_stats(v, 12.591587);
  CHECK(n.count == 11);
  CHECK(n.p25 == Approx(1.75));
  CHECK(n.median == Approx(4.4));
  CHECK(n.p75 == Approx(6.85));
  CHECK(n.p95 == Approx(96653.5));
  CHECK(n.mean == Approx(17576.20909090909));
  CHECK(n.max == 193295.0);
  CHECK(n.fraction_above_gate == Approx(1.0 / 11.0));
  CHECK(n.median_ratio == Approx(4.4 / 5.348120627));
  CHECK(nis_stats({}, 1.0).count == 0);
}

TEST_CASE("assess_health: supported share, longest dead reckoning, NIS median, the 5-frame case is unhealthy",
          "[ekf][run][health]") {
  FilterOptions o;
  HealthLimits l;  // 1 s window, 50 %, 10 s, NIS median ratio 10
  FilterRunSummary s;
  s.t_first_ns = from_seconds(100.0);
  s.t_last_ns = from_seconds(160.0);
  const auto at = [&](double t) { return s.t_first_ns + from_seconds(t); };
  SECTION("detections that end after 0.13 s of a 60 s recording") {
    s.update_times = {at(0.0667), at(0.1), at(0.1333)};
    const RunHealth h = assess_health(s, o, l);
    CHECK(h.duration_s == Approx(60.0));
    CHECK(h.supported_fraction == Approx((0.0333 + 0.0333 + 1.0) / 60.0).margin(1e-6));
    CHECK(h.longest_dead_reckoning_s == Approx(60.0 - 0.1333));
    CHECK(h.dead_reckoning_from_ns == at(0.1333));
    CHECK(h.dead_reckoning_to_ns == s.t_last_ns);
    REQUIRE_FALSE(h.healthy());
    REQUIRE(h.problems.size() == 2);
    CHECK(contains(h.problems, "only 1.8 % of the trajectory lies within 1 s after an accepted update"));
    CHECK(contains(h.problems, "the last accepted update is at 0.13 s"));
    CHECK(contains(h.problems, "59.87 s without an accepted update (0.13 s → 60.00 s of the 60.00 s trajectory"));
  }
  SECTION("updates at 30 Hz with one 12 s gap") {
    for (double t = 0.0; t < 60.0; t += 1.0 / 30.0)
      if (t < 20.0 || t > 32.0) s.update_times.push_back(at(t));
    const RunHealth h = assess_health(s, o, l);
    CHECK(h.longest_dead_reckoning_s == Approx(12.05).margin(0.05));
    CHECK(h.supported_fraction == Approx(49.0 / 60.0).margin(0.003));  // ~11 s of the gap are unsupported
    REQUIRE(h.problems.size() == 1);
    CHECK(contains(h.problems, "without an accepted update (19.97 s → 32.0"));
    l.max_dead_reckoning_s = -1.0;  // that check off
    CHECK(assess_health(s, o, l).healthy());
    l.max_dead_reckoning_s = 12.2;
    CHECK(assess_health(s, o, l).healthy());
    l.min_supported_fraction = 0.9;
    CHECK(contains(assess_health(s, o, l).problems, "health.min_supported_fraction 90 %"));
  }
  SECTION("no update at all") {
    const RunHealth h = assess_health(s, o, l);
    CHECK(h.supported_fraction == 0.0);
    CHECK(h.longest_dead_reckoning_s == Approx(60.0));
    REQUIRE(h.problems.size() == 1);
    CHECK(contains(h.problems, "no detection was accepted"));
  }
  SECTION("an overconfident filter: NIS median 20x the chi2 median") {
    for (double t = 0.0; t < 60.0; t += 0.1) s.update_times.push_back(at(t));
    s.nis.assign(29, 107.0);
    CHECK(assess_health(s, o, l).healthy());  // fewer than 30 values: no verdict
    s.nis.push_back(107.0);
    const RunHealth h = assess_health(s, o, l);
    CHECK(h.nis.median_ratio == Approx(107.0 / 5.348120627));
    REQUIRE(h.problems.size() == 1);
    CHECK(contains(h.problems, "the median NIS is 107.0"));
    // One huge outlier among consistent values does not trip it (the mean would).
    s.nis.assign(200, 5.0);
    s.nis.push_back(1e7);
    CHECK(assess_health(s, o, l).healthy());
  }
}

TEST_CASE("run_warnings: what the counts call for", "[ekf][run]") {
  FilterOptions o;
  FilterRunSummary s;
  s.anchor.id = 3;
  s.anchor.automatic = true;
  s.anchor.images = 40;
  s.t_first_ns = 0;
  s.anchor.t_ns = from_seconds(0.5);
  s.updates = 0;
  DetectionCounts a, b;
  for (int i = 0; i < 40; ++i) a.add(DetectionStatus::kAccepted);
  for (int i = 0; i < 50; ++i) b.add(DetectionStatus::kRejectedNoMain);
  for (int i = 0; i < 4; ++i) b.add(DetectionStatus::kPendingInit);
  b.add(DetectionStatus::kRejectedNoImu);
  s.counts = {{3, a}, {5, b}};
  s.no_main_anchor_pending = 10;
  std::vector<std::string> w = run_warnings(s, o);
  CHECK(contains(w, "anchor chosen automatically: object 3 (first seen at 0.50 s, detected in 40 images)"));
  CHECK(contains(w, "object 5 was detected 55 times but never initialised: 4 awaited initialisation"));
  CHECK(contains(w, "50 had no initialised anchor in their image; 1 lay outside the IMU stream"));
  CHECK(contains(w, "1 detections lie outside the IMU stream"));
  CHECK(contains(w, "40 of 95 detections (42 %) were rejected because their image lacks the anchor object 3"));
  CHECK(contains(w, "(10 more were in images with the anchor, before it was initialised)"));
  CHECK(contains(w, "no update was made"));
  o.require_anchor = false;
  s.updates = 5;
  w = run_warnings(s, o);
  CHECK_FALSE(contains(w, "lacks the anchor"));
  CHECK_FALSE(contains(w, "no update was made"));
}

TEST_CASE("calibration_warnings: extrinsics beyond their prior σ, an object that keeps a large rotation residual",
          "[ekf][run]") {
  FilterRunSummary s;
  s.prior_sigma_I_C << 0.02, 0.02, 0.02, 0.035, 0.035, 0.035;
  s.final_sigma_I_C << 0.01, 0.01, 0.01, 0.005, 0.005, 0.005;
  s.final_T_I_C = Pose(Eigen::Quaterniond::Identity(), Vec3(0.019, 0.0, 0.0));  // 0.95 prior σ: quiet
  CHECK(calibration_warnings(s).empty());
  s.final_T_I_C = Pose(Eigen::Quaterniond::Identity(), Vec3(0.021, 0.0, 0.0));  // 1.05 prior σ
  auto w = calibration_warnings(s);
  REQUIRE(w.size() == 1);
  CHECK_THAT(w[0], Catch::Contains("the extrinsics moved 21.0 mm"));
  CHECK_THAT(w[0], Catch::Contains("p_x 1.1 σ"));
  // Held fixed (σ 0): never a warning, whatever the shift.
  FilterRunSummary fixed = s;
  fixed.prior_sigma_I_C.setZero();
  CHECK(calibration_warnings(fixed).empty());
  s.final_T_I_C = s.prior_T_I_C;
  // Object 7: its last 100 residuals are mostly a flip (180°); object 8 is fine; object 9 flipped long ago.
  std::vector<double> flipped(60, 4.0), fine(300, 8.0), early(300, 6.0);
  flipped.insert(flipped.end(), 70, 179.0);
  for (int i = 0; i < 100; ++i) early[i] = 180.0;
  s.rot_residual_deg = {{7, flipped}, {8, fine}, {9, early}};
  w = calibration_warnings(s);
  REQUIRE(w.size() == 1);
  CHECK_THAT(w[0], Catch::Contains("object 7 keeps a rotation residual of 179°"));
  // Too few detections to judge: quiet.
  s.rot_residual_deg = {{7, std::vector<double>(40, 179.0)}};
  CHECK(calibration_warnings(s).empty());
  // run_warnings carries them.
  s.rot_residual_deg = {{7, flipped}};
  CHECK(contains(run_warnings(s, FilterOptions{}), "object 7 keeps a rotation residual"));
}
