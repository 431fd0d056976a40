// The split χ² gate (FilterOptions::gate_mode = split): the gate's decisions on given r and S, and one
// image through Filter::update whose detection has a good position and a grossly wrong rotation: the
// split gate updates with the position rows only (posterior checked against a 3-row Kalman update written
// out here), the joint gate rejects the detection whole.
#include <catch2/catch.hpp>
#include <cmath>
#include <limits>

#include "roe/math/distributions.hpp"
#include "roe/ekf/filter.hpp"
#include "roe/math/so3.hpp"

using namespace roe;
using namespace roe::ekf;
using math::exp_quat;

TEST_CASE("split_gate tests the position and rotation parts on their marginal S blocks", "[ekf][split]") {
  // S with cross terms between the parts: the marginal blocks, not the joint S, decide.
  Mat6 A;
  A << 1.0, 0.2, 0.0, 0.3, 0.0, 0.1,  //
      0.0, 1.2, 0.1, 0.0, 0.2, 0.0,   //
      0.1, 0.0, 0.9, 0.0, 0.0, 0.3,   //
      0.0, 0.1, 0.0, 0.8, 0.1, 0.0,   //
      0.2, 0.0, 0.0, 0.0, 1.1, 0.2,   //
      0.0, 0.0, 0.3, 0.1, 0.0, 1.0;
  const Mat6 S = A * A.transpose();
  const double g3 = math::chi2_quantile(0.95, 3.0);
  Vec6 r;
  r << 0.1, -0.2, 0.05, 0.1, 0.0, -0.1;
  SplitGate g = split_gate(r, S, g3, g3);
  CHECK(g.used == ResidualPart::kBoth);
  const Vec3 rp = r.head<3>(), rr = r.tail<3>();
  CHECK(g.nis_position == Approx(rp.dot(S.topLeftCorner<3, 3>().inverse() * rp)).epsilon(1e-12));
  CHECK(g.nis_rotation == Approx(rr.dot(S.bottomRightCorner<3, 3>().inverse() * rr)).epsilon(1e-12));

  r.tail<3>() *= 100.0;  // rotation outlier
  g = split_gate(r, S, g3, g3);
  CHECK(g.used == ResidualPart::kPosition);
  CHECK(g.nis_rotation > g3);
  r.head<3>() *= 100.0;  // both
  CHECK(split_gate(r, S, g3, g3).used == ResidualPart::kNone);
  r.tail<3>() /= 100.0;  // position outlier only
  CHECK(split_gate(r, S, g3, g3).used == ResidualPart::kRotation);

  // A non-finite rotation part (a detection 180° off: 2 q_v / q_w with q_w = 0) fails even an infinite
  // gate; the position part is still tested.
  r << 0.1, -0.2, 0.05, std::numeric_limits<double>::infinity(), 0.0, 0.0;
  const double inf = std::numeric_limits<double>::infinity();
  g = split_gate(r, S, inf, inf);
  CHECK(g.used == ResidualPart::kPosition);
  CHECK(std::isinf(g.nis_rotation));

  int rows[6];
  CHECK(residual_rows(ResidualPart::kNone, rows) == 0);
  REQUIRE(residual_rows(ResidualPart::kRotation, rows) == 3);
  CHECK((rows[0] == 3 && rows[1] == 4 && rows[2] == 5));
  REQUIRE(residual_rows(ResidualPart::kBoth, rows) == 6);
  CHECK(rows[5] == 5);
}

namespace {

// A started filter with objects 1 (anchor) and 2 initialised from exact detections, 10 ms of IMU later.
Filter two_objects(GateMode mode, ResidualFrame frame) {
  FilterOptions opt;
  opt.init_min_detections = 1;
  opt.anchor_id = 1;
  opt.require_anchor = false;
  opt.residual_frame = frame;
  opt.gate_mode = mode;
  Filter f(opt, ImuNoiseParams{1e-3, 1e-4, 1e-2, 1e-3}, Pose(exp_quat(Vec3(0.1, -0.05, 0.02)), Vec3(0.02, 0, 0)));
  f.initialize(0, Vec3::Zero(), Vec3(0, 0, 9.81), Vec3(0, 0, 9.81));
  Detection a, b;
  a.object_id = 1;
  a.T_C_O = Pose(exp_quat(Vec3(0.3, -0.2, 0.1)), Vec3(0.2, -0.1, 1.8));
  b.object_id = 2;
  b.T_C_O = Pose(exp_quat(Vec3(-0.4, 0.5, 0.2)), Vec3(-0.3, 0.2, 2.2));
  f.update({a, b});
  f.propagate(10'000'000, Vec3(0.01, -0.02, 0.03), Vec3(0.1, 0.0, 9.8));
  return f;
}

// Object 2 seen where the filter predicts it (plus 2 cm), its rotation 120° off about the camera axes.
Detection rotation_outlier(const Filter& f) {
  const Pose T_C_O_hat = f.predict(2).inverse();
  Detection d;
  d.object_id = 2;
  d.T_C_O = Pose(exp_quat(Vec3(0.0, 2.0944, 0.0)) * T_C_O_hat.q, T_C_O_hat.p + Vec3(0.02, -0.01, 0.02));
  return d;
}

}  // namespace

TEST_CASE("split gate: a gross rotation outlier with a good position updates the position only",
          "[ekf][split]") {
  const ResidualFrame frame = ResidualFrame::kCamera;
  Filter f = two_objects(GateMode::kSplit, frame);
  const Detection d = rotation_outlier(f);

  // The expected posterior: one Kalman update with the position rows (r_p, H_p) and the marginal R_pp.
  Eigen::VectorXd r;
  Eigen::MatrixXd H;
  f.measurement_rows(2, d.T_C_O.inverse(), ResidualPart::kPosition, r, H);
  const Eigen::MatrixXd P = f.covariance();
  const Eigen::Matrix3d R = f.measurement_covariance(d, false).topLeftCorner<3, 3>();
  const Eigen::MatrixXd S = H * P * H.transpose() + R;
  const Eigen::MatrixXd K = P * H.transpose() * S.inverse();
  const Eigen::VectorXd dx = K * r;
  const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(f.dim(), f.dim()) - K * H;
  const Eigen::MatrixXd P_post = IKH * P * IKH.transpose() + K * R * K.transpose();
  Filter expect = f;
  expect.boxplus(dx);

  const FrameResult res = f.update({d});
  REQUIRE(res.detections.size() == 1);
  CHECK(res.detections[0].status == DetectionStatus::kAccepted);
  CHECK(res.detections[0].used == ResidualPart::kPosition);
  CHECK(res.detections[0].nis > math::chi2_quantile(0.95, 6.0));  // the joint 6-dof NIS, as reported
  CHECK(res.n_inliers == 1);
  CHECK((f.covariance() - P_post).cwiseAbs().maxCoeff() < 1e-12);
  CHECK((f.core().p_W_I - expect.core().p_W_I).norm() < 1e-12);
  CHECK(math::pose_difference(f.object(2)->T_O_W, expect.object(2)->T_O_W).norm() < 1e-12);
  CHECK(math::pose_difference(f.T_I_C(), expect.T_I_C()).norm() < 1e-12);
  CHECK(dx.norm() > 1e-4);  // the update did something

  // The joint gate rejects the same detection whole: state and covariance unchanged.
  Filter j = two_objects(GateMode::kJoint, frame);
  const Eigen::MatrixXd Pj = j.covariance();
  const Vec3 pj = j.core().p_W_I;
  const FrameResult rj = j.update({rotation_outlier(j)});
  CHECK(rj.detections[0].status == DetectionStatus::kRejectedChi2);
  CHECK(rj.detections[0].used == ResidualPart::kNone);
  CHECK(rj.n_inliers == 0);
  CHECK(j.covariance() == Pj);
  CHECK(j.core().p_W_I == pj);
}

TEST_CASE("split gate: inliers use both parts and match the joint update, stacked with a split block",
          "[ekf][split]") {
  for (const ResidualFrame frame : {ResidualFrame::kObject, ResidualFrame::kCamera}) {
    INFO("frame " << to_string(frame));
    // Two good detections: the split and the joint gate make the same update.
    Filter s = two_objects(GateMode::kSplit, frame), j = two_objects(GateMode::kJoint, frame);
    std::vector<Detection> good;
    for (int id : {1, 2}) {
      Detection d;
      d.object_id = id;
      const Pose p = s.predict(id).inverse();
      d.T_C_O = Pose(exp_quat(Vec3(0.02, -0.01, 0.03)) * p.q, p.p + Vec3(0.01, 0.02, -0.01));
      good.push_back(d);
    }
    const FrameResult rs = s.update(good), rjj = j.update(good);
    for (int k = 0; k < 2; ++k) {
      CHECK(rs.detections[k].used == ResidualPart::kBoth);
      CHECK(rjj.detections[k].used == ResidualPart::kBoth);
      CHECK(rs.detections[k].nis == rjj.detections[k].nis);
    }
    CHECK((s.covariance() - j.covariance()).cwiseAbs().maxCoeff() == 0.0);
  }
  // A stacked update of a 3-row block (object 2, rotation outlier) after a 6-row block (the anchor)
  // equals the two-block Kalman update written out.
  Filter f = two_objects(GateMode::kSplit, ResidualFrame::kCamera);
  Detection a;
  a.object_id = 1;
  {
    const Pose p = f.predict(1).inverse();
    a.T_C_O = Pose(exp_quat(Vec3(0.01, 0.02, -0.01)) * p.q, p.p + Vec3(-0.01, 0.01, 0.02));
  }
  const Detection b = rotation_outlier(f);
  Eigen::VectorXd ra, rb;
  Eigen::MatrixXd Ha, Hb;
  f.measurement_rows(1, a.T_C_O.inverse(), ResidualPart::kBoth, ra, Ha);
  f.measurement_rows(2, b.T_C_O.inverse(), ResidualPart::kPosition, rb, Hb);
  Eigen::MatrixXd H(9, f.dim());
  H << Ha, Hb;
  Eigen::VectorXd r(9);
  r << ra, rb;
  Eigen::MatrixXd R = Eigen::MatrixXd::Zero(9, 9);
  R.topLeftCorner<6, 6>() = f.measurement_covariance(a, false);
  R.bottomRightCorner<3, 3>() = f.measurement_covariance(b, false).topLeftCorner<3, 3>();
  const Eigen::MatrixXd P = f.covariance();
  const Eigen::MatrixXd K = P * H.transpose() * (H * P * H.transpose() + R).inverse();
  const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(f.dim(), f.dim()) - K * H;
  const Eigen::MatrixXd P_post = IKH * P * IKH.transpose() + K * R * K.transpose();
  const FrameResult res = f.update({a, b});
  CHECK(res.detections[0].used == ResidualPart::kBoth);
  CHECK(res.detections[1].used == ResidualPart::kPosition);
  CHECK(res.n_inliers == 2);
  CHECK((f.covariance() - P_post).cwiseAbs().maxCoeff() < 1e-12);
}
