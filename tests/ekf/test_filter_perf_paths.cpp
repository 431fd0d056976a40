// The fast paths of the filter against dense reference computations: the block-sparse propagation
// (P_cc column-wise, Φ kept transposed on its non-trivial columns, lazy cross-covariance sync) against
// F P Fᵀ + Q on the whole covariance, and the stacked update (P Hᵀ from H's runs of non-zero columns,
// S from the gate's 6x6 blocks, Cholesky + one triangular solve, P − W Wᵀ as one rank-m product on the
// lower triangle) against (I−KH)P(I−KH)ᵀ + KRKᵀ with the full 6 x n H of measurement_jacobian.
#include <catch2/catch.hpp>
#include <limits>
#include <random>
#include <string>

#include "roe/core/error.hpp"
#include "roe/ekf/filter.hpp"
#include "roe/ekf/imu.hpp"
#include "roe/math/euler.hpp"
#include "roe/math/so3.hpp"

using namespace roe;
using namespace roe::ekf;
using math::exp_quat;

namespace {

std::mt19937_64 rng(777);
double U(double a = -1.0, double b = 1.0) { return std::uniform_real_distribution<double>(a, b)(rng); }
Vec3 U3(double s = 1.0) { return Vec3(U(), U(), U()) * s; }

const Vec3 kGyro0(0.1, 0.2, -0.1), kAccel0(0.2, 0.1, 9.7);

// Objects 1 (anchor), 2, 3 and 4 initialised (n = 15 [+ 6] + anchor + 18: not a multiple of 4, so the
// odd block sizes are exercised), a non-trivial state and covariance.
Filter make_filter(AnchorGauge gauge, bool extrinsics, ResidualFrame frame) {
  FilterOptions opt;
  opt.residual_frame = frame;
  opt.meas_sigma_in_camera = false;  // R diagonal on the residual's axes (the reference below)
  opt.init_min_detections = 1;
  opt.anchor_id = 1;
  opt.anchor_gauge = gauge;
  opt.estimate_extrinsics = extrinsics;
  opt.chi2_gate = true;
  ImuNoiseParams noise{1e-3, 1e-4, 1e-2, 1e-3};
  Filter f(opt, noise, Pose(exp_quat(Vec3(0.1, -0.2, 0.05)), Vec3(0.02, 0.01, -0.03)));
  f.initialize(0, Vec3::Zero(), Vec3(0, 0, 9.81), Vec3(0.3, -0.2, 9.8));
  f.propagate(10'000'000, kGyro0, kAccel0);
  std::vector<Detection> dets;
  for (int id : {1, 2, 3, 4}) {
    Detection d;
    d.t_ns = f.time();
    d.object_id = id;
    d.T_C_O = Pose(exp_quat(U3(1.0)), U3(0.5) + Vec3(0, 0, 1.5));
    dets.push_back(d);
  }
  f.update(dets);
  return f;
}

double max_abs(const Eigen::MatrixXd& A) { return A.cwiseAbs().maxCoeff(); }

}  // namespace

TEST_CASE("block-sparse propagation equals the dense F P Fᵀ + Q on the whole covariance",
          "[ekf][perf_paths]") {
  for (bool extr : {true, false}) {
    Filter f = make_filter(AnchorGauge::kPositionYaw, extr, ResidualFrame::kCamera);
    const int n = f.dim();
    Eigen::MatrixXd P_ref = f.covariance();
    ImuNoiseParams noise{1e-3, 1e-4, 1e-2, 1e-3};
    Vec3 w0 = kGyro0, a0 = kAccel0;
    CoreState x = f.core();
    Timestamp t = f.time();
    for (int k = 0; k < 37; ++k) {
      const Vec3 w1 = kGyro0 + U3(0.5), a1 = kAccel0 + U3(0.5);
      const Timestamp dt_ns = 2'500'000 + 100'000 * (k % 3);  // 400 Hz with jitter
      const double dt = dt_seconds(t, t + dt_ns);
      CoreTransition F;
      x = integrate(x, w0, a0, w1, a1, dt, &F);
      Eigen::MatrixXd Fbig = Eigen::MatrixXd::Identity(n, n);
      Fbig.topLeftCorner<15, 15>() = F.dense();
      P_ref = (Fbig * P_ref * Fbig.transpose()).eval();
      auto Pcc = P_ref.topLeftCorner<15, 15>();
      add_process_noise(noise, dt, Pcc);
      t += dt_ns;
      f.propagate(t, w1, a1);
      w0 = w1;
      a0 = a1;
      // The core block is current after every sample (the cross-covariance only on request).
      double d = 0.0;
      for (int i = 0; i < 15; ++i)
        for (int j = 0; j < 15; ++j) d = std::max(d, std::abs(f.core_covariance(i, j) - P_ref(i, j)));
      REQUIRE(d <= 1e-12 * max_abs(P_ref.topLeftCorner<15, 15>()));
      // variance() reads the propagated core block too (held apart from P until the next sync), and the
      // unchanged rest of the diagonal.
      for (int i = 0; i < n; ++i)
        CHECK(std::abs(f.variance(i) - P_ref(i, i)) <= 1e-12 * max_abs(P_ref.topLeftCorner<15, 15>()));
      if (k % 10 == 9) {  // sync the cross-covariance now and then (as an update would)
        const Eigen::MatrixXd& P = f.covariance();
        CHECK(max_abs(P - P_ref) <= 1e-12 * max_abs(P_ref));
        CHECK(max_abs(P - P.transpose()) == 0.0);
      }
    }
    CHECK((f.core().p_W_I - x.p_W_I).norm() <= 1e-12);
    CHECK(math::angle_between(f.core().q_W_I, x.q_W_I) <= 1e-12);
    const Eigen::MatrixXd& P = f.covariance();
    CHECK(max_abs(P - P_ref) <= 1e-12 * max_abs(P_ref));
  }
}

TEST_CASE("stacked update equals the dense Joseph-form reference, with a gated-out first detection",
          "[ekf][perf_paths]") {
  for (ResidualFrame frame : {ResidualFrame::kCamera, ResidualFrame::kObject}) {
    for (AnchorGauge gauge : {AnchorGauge::kPose, AnchorGauge::kPosition, AnchorGauge::kPositionYaw}) {
      for (bool extr : {true, false}) {
        for (int outlier : {-1, 0, 2}) {  // -1: all inliers; else that detection is far off (χ² reject)
          Filter f = make_filter(gauge, extr, frame);
          f.propagate(f.time() + 5'000'000, kGyro0, kAccel0);
          const int n = f.dim();
          const Eigen::MatrixXd P = f.covariance();
          const FilterOptions& opt = f.options();
          const double sp = opt.meas_sigma_p_m, sr = opt.meas_sigma_rot_deg * math::kRadPerDeg;
          Vec6 var;
          var << sp * sp, sp * sp, sp * sp, sr * sr, sr * sr, sr * sr;
          std::vector<Detection> dets;
          const std::vector<int> ids{3, 1, 4, 2};
          for (int k = 0; k < 4; ++k) {
            Detection d;
            d.t_ns = f.time();
            d.object_id = ids[k];
            const Pose T_O_C = f.predict(ids[k]);
            const Vec3 dp = k == outlier ? Vec3(3.0, -2.0, 2.5) : U3(0.05);
            d.T_C_O = Pose(T_O_C.q * exp_quat(U3(0.05)), T_O_C.p + dp).inverse();
            dets.push_back(d);
          }
          // Dense reference over the inliers (in detection order, as the filter stacks them).
          std::vector<int> in;
          for (int k = 0; k < 4; ++k)
            if (k != outlier) in.push_back(k);
          const int m = 6 * static_cast<int>(in.size());
          Eigen::MatrixXd H(m, n), R = Eigen::MatrixXd::Zero(m, m);
          Eigen::VectorXd r(m);
          for (std::size_t a = 0; a < in.size(); ++a) {
            Vec6 ra;
            Eigen::MatrixXd Ha;
            f.measurement_jacobian(ids[in[a]], dets[in[a]].T_C_O.inverse(), ra, Ha);
            H.middleRows(6 * a, 6) = Ha;
            r.segment<6>(6 * a) = ra;
            R.block<6, 6>(6 * a, 6 * a) = var.asDiagonal();
          }
          const Eigen::MatrixXd S = H * P * H.transpose() + R;
          const Eigen::MatrixXd K = S.ldlt().solve(H * P).transpose();
          const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(n, n) - K * H;
          const Eigen::MatrixXd P_ref = IKH * P * IKH.transpose() + K * R * K.transpose();
          const Eigen::VectorXd dx = K * r;
          const Vec3 p_ref = f.core().p_W_I + dx.segment<3>(kP);

          const FrameResult res = f.update(dets);
          REQUIRE(res.n_inliers == static_cast<int>(in.size()));
          for (int k = 0; k < 4; ++k)
            CHECK(res.detections[k].status ==
                  (k == outlier ? DetectionStatus::kRejectedChi2 : DetectionStatus::kAccepted));
          // Per-object NIS on its own 6x6 S.
          for (std::size_t a = 0; a < in.size(); ++a) {
            const Eigen::MatrixXd Sa = S.block<6, 6>(6 * a, 6 * a);
            const double nis = r.segment<6>(6 * a).dot(Sa.ldlt().solve(r.segment<6>(6 * a)));
            CHECK(res.detections[in[a]].nis == Approx(nis).epsilon(1e-9));
          }
          const Eigen::MatrixXd& P_new = f.covariance();
          CHECK(max_abs(P_new - P_ref) <= 1e-10 * max_abs(P_ref));
          CHECK(max_abs(P_new - P_new.transpose()) == 0.0);
          CHECK((f.core().p_W_I - p_ref).norm() <= 1e-10 * (1.0 + p_ref.norm()));
        }
      }
    }
  }
}

TEST_CASE("propagation guard rails: the squared-norm fast path throws exactly when check_state would",
          "[ekf][perf_paths]") {
  const ImuNoiseParams noise{1e-3, 1e-4, 1e-2, 1e-3};
  // Initialised level (mean accelerometer kLevel), then 1 m/s² along x: |v| grows by about 1 m/s per s.
  const Vec3 gyro(0.0, 0.0, 0.3), accel(1.0, 0.0, 9.81), kLevel(0.0, 0.0, 9.81);
  SECTION("velocity bound: no throw while |v| <= max, a throw naming the bound on the first sample above") {
    for (double max_v : {0.5, 1.0, 0.73}) {
      FilterOptions opt;
      opt.max_velocity_mps = max_v;
      Filter f(opt, noise, Pose());
      f.initialize(0, gyro, accel, kLevel);
      bool thrown = false;
      for (int k = 1; k <= 200 && !thrown; ++k) {
        try {
          f.propagate(Timestamp(k) * 10'000'000, gyro, accel);  // 100 Hz
          REQUIRE(f.core().v_W_I.norm() <= max_v);
        } catch (const NumericError& e) {
          thrown = true;
          CHECK(f.core().v_W_I.norm() > max_v);
          CHECK(std::string(e.what()).find("max_velocity_mps") != std::string::npos);
        }
      }
      CHECK(thrown);
    }
  }
  SECTION("a bias outside its bound from the start is caught on the first sample") {
    FilterOptions opt;
    opt.init_gyro_bias = Vec3(0.0, 0.0, 1.5);  // max_gyro_bias = 1 rad/s
    Filter f(opt, noise, Pose());
    f.initialize(0, gyro, accel, kLevel);
    try {
      f.propagate(10'000'000, gyro, accel);
      FAIL("no throw");
    } catch (const NumericError& e) {
      CHECK(std::string(e.what()).find("max_gyro_bias") != std::string::npos);
    }
  }
  SECTION("non-finite measurements stop the run") {
    Filter f(FilterOptions(), noise, Pose());
    f.initialize(0, gyro, accel, kLevel);
    f.propagate(10'000'000, gyro, accel);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_AS(f.propagate(20'000'000, gyro, Vec3(nan, 0.0, 9.81)), NumericError);
  }
}

TEST_CASE("first sight: a new object's predicted detection has exactly the detection's covariance",
          "[ekf][perf_paths]") {
  // An object-world initialised from detection z makes the predicted detection equal z for any state, so
  // right after first sight H P Hᵀ = R: the augmentation's cross-covariances and the anchor's gauge fix
  // (a change of W, which no relative pose sees) must preserve it. A wrong sign in the gauge transform, or
  // a wrong factor on the new block, breaks it.
  for (ResidualFrame frame : {ResidualFrame::kCamera, ResidualFrame::kObject}) {
    for (AnchorGauge gauge : {AnchorGauge::kPose, AnchorGauge::kPosition, AnchorGauge::kPositionYaw}) {
      for (bool extr : {true, false}) {
        FilterOptions opt;
        opt.residual_frame = frame;
        opt.init_min_detections = 1;
        opt.anchor_id = 1;
        opt.anchor_gauge = gauge;
        opt.estimate_extrinsics = extr;
        Filter f(opt, ImuNoiseParams{1e-3, 1e-4, 1e-2, 1e-3},
                 Pose(exp_quat(Vec3(0.1, -0.2, 0.05)), Vec3(0.02, 0.01, -0.03)));
        f.initialize(0, Vec3::Zero(), Vec3(0, 0, 9.81), Vec3(0.3, -0.2, 9.8));
        for (int k = 1; k <= 40; ++k) f.propagate(k * 2'500'000, kGyro0 + U3(0.3), kAccel0 + U3(0.3));
        std::vector<Detection> dets;
        for (int id : {1, 2, 3}) {
          Detection d;
          d.t_ns = f.time();
          d.object_id = id;
          d.T_C_O = Pose(exp_quat(U3(1.0)), U3(0.5) + Vec3(0, 0, 1.5));
          dets.push_back(d);
        }
        const FrameResult res = f.update(dets);
        const Eigen::MatrixXd P = f.covariance();
        for (const Detection& d : dets) {
          INFO("frame " << static_cast<int>(frame) << " gauge " << to_string(gauge) << " extr " << extr
                        << " object " << d.object_id);
          REQUIRE(f.object(d.object_id) != nullptr);
          Vec6 r;
          Eigen::MatrixXd H;
          f.measurement_jacobian(d.object_id, d.T_C_O.inverse(), r, H);
          const Mat6 R = f.measurement_covariance(d, frame == ResidualFrame::kObject);
          CHECK(r.norm() < 1e-12);
          CHECK(max_abs(H * P * H.transpose() - R) <= 1e-9 * max_abs(R));
        }
        CHECK(res.n_inliers == 0);  // first sight only initialises
      }
    }
  }
}

TEST_CASE("a detection's implied IMU pose (reprojection.csv) is the state's pose for an exact detection",
          "[ekf][perf_paths]") {
  // T_W_I implied by detection z of object O: T_O_W⁻¹ z T_I_C⁻¹ (z = T_O_C). For the detection the state
  // predicts, it is the state's own T_W_I (the update does not move a state with zero residuals).
  for (AnchorGauge gauge : {AnchorGauge::kPose, AnchorGauge::kPositionYaw}) {
    Filter f = make_filter(gauge, true, ResidualFrame::kCamera);
    f.propagate(f.time() + 5'000'000, kGyro0, kAccel0);
    const Pose T_W_I(f.core().q_W_I, f.core().p_W_I);
    std::vector<Detection> dets;
    for (int id : {2, 1, 4}) {
      Detection d;
      d.t_ns = f.time();
      d.object_id = id;
      d.T_C_O = f.predict(id).inverse();
      dets.push_back(d);
    }
    const FrameResult res = f.update(dets);
    for (const DetectionOutcome& o : res.detections) {
      INFO("object " << o.object_id);
      REQUIRE(o.has_T_W_I);
      CHECK((o.T_W_I.p - T_W_I.p).norm() < 1e-9);
      CHECK(math::angle_between(o.T_W_I.q, T_W_I.q) < 1e-9);
    }
  }
}
