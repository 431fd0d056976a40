// Filter::update on inputs only the library API can produce or that sit on a singularity: a detection
// exactly 180° from the prediction (the orientation residual 2 q_v / q_w has q_w = 0), and two detections
// of one object in one image.
#include <catch2/catch.hpp>
#include <cmath>

#include "roe/core/error.hpp"
#include "roe/ekf/filter.hpp"

using namespace roe;
using namespace roe::ekf;

namespace {
Filter started(ResidualFrame frame, bool gate = true) {
  FilterOptions opt;
  opt.init_min_detections = 1;
  opt.anchor_id = 1;
  opt.residual_frame = frame;
  opt.chi2_gate = gate;
  Filter f(opt, ImuNoiseParams{1e-3, 1e-4, 1e-2, 1e-3}, Pose());
  f.initialize(0, Vec3::Zero(), Vec3(0, 0, 9.81), Vec3(0, 0, 9.81));
  return f;
}
Detection det(int id, const Eigen::Quaterniond& q, const Vec3& p) {
  Detection d;
  d.object_id = id;
  d.T_C_O = Pose(q, p);
  return d;
}
}  // namespace

TEST_CASE("a detection exactly 180 deg off the prediction is rejected as an outlier, not a failed run",
          "[ekf][guard]") {
  for (const ResidualFrame frame : {ResidualFrame::kObject, ResidualFrame::kCamera}) {
    for (const bool gate : {true, false}) {
      INFO("residual frame " << static_cast<int>(frame) << ", gate " << gate);
      Filter f = started(frame, gate);
      const Detection d = det(1, Eigen::Quaterniond::Identity(), Vec3(0, 0, 2));
      REQUIRE(f.update({d}).detections[0].status == DetectionStatus::kInitialized);
      f.propagate(5'000'000, Vec3::Zero(), Vec3(0, 0, 9.81));
      const Vec3 p_before = f.core().p_W_I;
      // A symmetric object's flip: the same position, turned by exactly π about the viewing axis.
      const FrameResult r = f.update({det(1, Eigen::Quaterniond(0, 0, 0, 1), Vec3(0, 0, 2))});
      CHECK(r.detections[0].status == DetectionStatus::kRejectedChi2);
      CHECK(std::isinf(r.detections[0].nis));
      CHECK(r.n_inliers == 0);
      CHECK((f.core().p_W_I - p_before).norm() == 0.0);
      // The filter goes on: the next good detection is used.
      f.propagate(10'000'000, Vec3::Zero(), Vec3(0, 0, 9.81));
      CHECK(f.update({d}).detections[0].status == DetectionStatus::kAccepted);
    }
  }
}

TEST_CASE("two detections of one object in one image are refused by the library", "[ekf][guard]") {
  Filter f = started(ResidualFrame::kCamera);
  const Detection a = det(1, Eigen::Quaterniond::Identity(), Vec3(0, 0, 2));
  const Detection b = det(2, Eigen::Quaterniond::Identity(), Vec3(0.5, 0, 2));
  Detection c = b;
  c.T_C_O.p.x() = 0.6;
  CHECK_THROWS_AS(f.update({a, b, c}), InputError);
  CHECK_THROWS_WITH(f.update({a, a}), Catch::Contains("two detections of object 1"));
  // Nothing entered the state.
  CHECK(f.objects().empty());
  CHECK(f.update({a, b}).detections[1].status == DetectionStatus::kInitialized);
  CHECK(f.objects().size() == 2);
}
