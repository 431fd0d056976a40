// The measurement noise the filter assigns to a detection (fixed isotropic, depth-dependent and
// ray-aligned, per detection) and the agreement test of the first-sight initialisation.
#include <catch2/catch.hpp>

#include "roe/ekf/filter.hpp"
#include "roe/ekf/measurement.hpp"
#include "roe/math/euler.hpp"
#include "roe/math/so3.hpp"

using namespace roe;
using namespace roe::ekf;
using math::exp_quat;

namespace {

Filter make(const FilterOptions& opt) {
  Filter f(opt, ImuNoiseParams{1e-3, 1e-4, 1e-2, 1e-3}, Pose());
  f.initialize(0, Vec3::Zero(), Vec3(0, 0, 9.81), Vec3(0, 0, 9.81));
  return f;
}

Detection detection(int id, const Pose& T_C_O) {
  Detection d;
  d.object_id = id;
  d.T_C_O = T_C_O;
  return d;
}

}  // namespace

TEST_CASE("fixed measurement noise: isotropic by default, ray-aligned and depth-dependent when set", "[ekf][noise]") {
  const Pose T_C_O(exp_quat(Vec3(0.2, -0.4, 0.3)), Vec3(0.6, -0.3, 1.8));
  const Detection d = detection(1, T_C_O);
  const double depth = T_C_O.p.norm();
  const Vec3 u = T_C_O.p / depth;
  FilterOptions opt;
  opt.residual_frame = ResidualFrame::kCamera;

  SECTION("defaults: the paper's 10 cm / 20 deg on every axis") {
    const Mat6 R = make(opt).measurement_covariance(d, false);
    Vec6 var;
    var << Vec3::Constant(0.01), Vec3::Constant(std::pow(20.0 * math::kRadPerDeg, 2));
    CHECK((R - Mat6(var.asDiagonal())).cwiseAbs().maxCoeff() < 1e-15);
  }
  SECTION("lateral and along-ray sigma growing with the depth") {
    opt.meas_sigma_p_m = 0.02;
    opt.meas_sigma_p_per_depth = 0.01;
    opt.meas_sigma_ray_m = 0.05;
    opt.meas_sigma_ray_per_depth = 0.1;
    const Mat6 R = make(opt).measurement_covariance(d, false);
    const Mat3 Rp = R.topLeftCorner<3, 3>();
    const double s_lat = 0.02 + 0.01 * depth, s_ray = 0.05 + 0.1 * depth;
    // Along the viewing ray: σ_ray²; any direction perpendicular to it: σ_lat²; no coupling.
    CHECK(u.dot(Rp * u) == Approx(s_ray * s_ray).epsilon(1e-12));
    const Vec3 w1 = u.cross(Vec3::UnitX()).normalized(), w2 = u.cross(w1);
    CHECK(w1.dot(Rp * w1) == Approx(s_lat * s_lat).epsilon(1e-12));
    CHECK(w2.dot(Rp * w2) == Approx(s_lat * s_lat).epsilon(1e-12));
    CHECK(std::abs(w1.dot(Rp * u)) < 1e-15);
    CHECK(std::abs(w1.dot(Rp * w2)) < 1e-15);
    CHECK(R.topRightCorner<3, 3>().cwiseAbs().maxCoeff() == 0.0);
    CHECK(R(3, 3) == Approx(std::pow(20.0 * math::kRadPerDeg, 2)));
    // In the T_O_C frame of the first-sight initialisation: the same covariance through the inversion.
    const Mat6 Ro = make(opt).measurement_covariance(d, true);
    CHECK((Ro - detection_covariance_in_residual_frame(T_C_O, R)).cwiseAbs().maxCoeff() < 1e-15);
  }
  SECTION("per-detection sigmas take precedence") {
    opt.use_detection_sigmas = true;
    opt.meas_sigma_ray_m = 0.5;
    Detection ds = d;
    ds.sigma = (Vec6() << 0.01, 0.02, 0.03, 0.04, 0.05, 0.06).finished();
    const Mat6 R = make(opt).measurement_covariance(ds, false);
    CHECK((R - Mat6(ds.sigma->cwiseProduct(*ds.sigma).asDiagonal())).cwiseAbs().maxCoeff() < 1e-15);
  }
}

TEST_CASE("full-covariance overload of the residual-frame mapping equals the diagonal one", "[ekf][noise]") {
  const Pose T_C_O(exp_quat(Vec3(-0.5, 0.1, 0.7)), Vec3(0.2, 0.4, 1.2));
  const Vec6 sigma = (Vec6() << 0.01, 0.02, 0.05, 0.03, 0.04, 0.05).finished();
  const Mat6 a = detection_covariance_in_residual_frame(T_C_O, sigma);
  const Mat6 b = detection_covariance_in_residual_frame(T_C_O, Mat6(sigma.cwiseProduct(sigma).asDiagonal()));
  CHECK((a - b).cwiseAbs().maxCoeff() < 1e-15);
}

// The first-sight agreement test compares where the object is (T_W_O). Comparing the T_O_W state
// instead would move its position by |p_W_O| · δθ with every rotation error of the detection: with the
// object 3 m from W's origin, ±5° of alternating rotation error moves p_O_W by ~0.5 m between
// detections, and the object would never pass the 0.3 m gate.
TEST_CASE("first sight: init_min_detections agreeing detections of a distant object initialise it", "[ekf][noise]") {
  FilterOptions opt;
  opt.anchor_id = 1;
  opt.init_min_detections = 3;
  opt.init_gate_p_m = 0.3;
  opt.init_gate_rot_deg = 30.0;
  const Pose anchor(Eigen::Quaterniond::Identity(), Vec3(0.1, 0.0, 1.0));
  const Pose far(exp_quat(Vec3(0.3, 0.2, -0.1)), Vec3(0.4, -0.2, 3.0));
  // The anchor's own first sight needs init_min_detections frames too.
  const auto with_anchor = [&]() {
    Filter f = make(opt);
    for (int k = 1; k <= 3; ++k) {
      f.propagate(k * 33'333'333, Vec3::Zero(), Vec3(0, 0, 9.81));
      Detection a = detection(1, anchor);
      a.t_ns = f.time();
      f.update({a});
    }
    REQUIRE(f.object(1) != nullptr);
    return f;
  };
  Filter f = with_anchor();
  std::vector<DetectionStatus> status;
  for (int k = 4; k <= 7; ++k) {
    const Timestamp t = k * 33'333'333;
    f.propagate(t, Vec3::Zero(), Vec3(0, 0, 9.81));
    const double s = (k % 2 == 0 ? 1.0 : -1.0) * 5.0 * math::kRadPerDeg;
    const Pose noisy(far.q * exp_quat(Vec3(s, 0.0, 0.0)), far.p);
    Detection a = detection(1, anchor), o = detection(2, noisy);
    a.t_ns = o.t_ns = t;
    const FrameResult r = f.update({a, o});
    REQUIRE(r.detections.size() == 2);
    status.push_back(r.detections[1].status);
  }
  CHECK(status[0] == DetectionStatus::kPendingInit);
  CHECK(status[1] == DetectionStatus::kPendingInit);
  CHECK(status[2] == DetectionStatus::kInitialized);
  CHECK(status[3] == DetectionStatus::kAccepted);
  // A detection that disagrees (here 0.5 m away) restarts the count.
  Filter g = with_anchor();
  for (int k = 4; k <= 6; ++k) {
    const Timestamp t = k * 33'333'333;
    g.propagate(t, Vec3::Zero(), Vec3(0, 0, 9.81));
    Pose o_pose = far;
    if (k == 5) o_pose.p.x() += 0.5;
    Detection a = detection(1, anchor), o = detection(2, o_pose);
    a.t_ns = o.t_ns = t;
    CHECK(g.update({a, o}).detections[1].status == DetectionStatus::kPendingInit);
  }
}
