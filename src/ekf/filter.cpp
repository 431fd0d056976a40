#include "roe/ekf/filter.hpp"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

#include "roe/core/error.hpp"
#include "roe/math/distributions.hpp"
#include "roe/ekf/images.hpp"
#include "roe/ekf/stacked_update.hpp"
#include "roe/math/euler.hpp"
#include "roe/math/so3.hpp"

namespace roe::ekf {

using math::exp_quat;
using math::skew;

std::string to_string(AnchorGauge g) {
  switch (g) {
    case AnchorGauge::kPose:
      return "pose";
    case AnchorGauge::kPosition:
      return "position";
    case AnchorGauge::kPositionYaw:
      return "position_yaw";
  }
  return "unknown";
}

bool parse_anchor_gauge(const std::string& s, AnchorGauge& out) {
  if (s == "pose") {
    out = AnchorGauge::kPose;
    return true;
  }
  if (s == "position") {
    out = AnchorGauge::kPosition;
    return true;
  }
  if (s == "position_yaw") {
    out = AnchorGauge::kPositionYaw;
    return true;
  }
  return false;
}

std::string to_string(ResidualFrame f) { return f == ResidualFrame::kObject ? "object" : "camera"; }

bool parse_residual_frame(const std::string& s, ResidualFrame& out) {
  if (s == "object")
    out = ResidualFrame::kObject;
  else if (s == "camera")
    out = ResidualFrame::kCamera;
  else
    return false;
  return true;
}

std::string to_string(GateMode m) { return m == GateMode::kJoint ? "joint" : "split"; }

bool parse_gate_mode(const std::string& s, GateMode& out) {
  if (s == "joint")
    out = GateMode::kJoint;
  else if (s == "split")
    out = GateMode::kSplit;
  else
    return false;
  return true;
}

std::string to_string(DetectionStatus s) {
  switch (s) {
    case DetectionStatus::kAccepted:
      return "accepted";
    case DetectionStatus::kInitialized:
      return "initialized";
    case DetectionStatus::kRejectedChi2:
      return "rejected_chi2";
    case DetectionStatus::kRejectedNoMain:
      return "rejected_no_main";
    case DetectionStatus::kRejectedScore:
      return "rejected_score";
    case DetectionStatus::kRejectedNoImu:
      return "rejected_no_imu";
    case DetectionStatus::kPendingInit:
      return "pending_init";
  }
  return "unknown";
}

Filter::Filter(const FilterOptions& options, const ImuNoiseParams& noise, const Pose& T_I_C_prior,
               double time_offset_prior_s)
    : opt_(options),
      noise_(noise),
      td_prior_s_(time_offset_prior_s),
      lost_position_(options.relock_after_s, options.relock_min_detections, options.init_gate_p_m) {
  ROE_CHECK(opt_.chi2_confidence > 0.0 && opt_.chi2_confidence < 1.0, "chi2_confidence must be in (0, 1)");
  gate_ = math::chi2_quantile(opt_.chi2_confidence, 6.0);
  gate3_ = math::chi2_quantile(opt_.chi2_confidence, 3.0);
  gate5_ = math::chi2_quantile(opt_.chi2_confidence, 5.0);
  gate2_ = math::chi2_quantile(opt_.chi2_confidence, 2.0);
  chi2_median6_ = math::chi2_quantile(0.5, 6.0);
  chi2_median5_ = math::chi2_quantile(0.5, 5.0);
  s_.T_I_C = T_I_C_prior;
  if (opt_.estimate_extrinsics) {
    s_.extr_offset = kCore;
    s_.dim = kCore + 6;
  }
  s_.t_d = time_offset_prior_s;
  if (opt_.estimate_time_offset) {
    ROE_CHECK(opt_.time_offset_sigma_s > 0.0, "time_offset_sigma_s must be positive");
    s_.td_offset = s_.dim;  // right after the extrinsics: a column every detection's H shares
    s_.dim += 1;
  }
  if (opt_.detection_error_states) {
    ROE_CHECK(opt_.detection_error_correlation_s > 0.0,
              "detection_error_states needs detection_error_correlation_s > 0 (the correlation time)");
    ROE_CHECK(opt_.detection_error_correlated_share > 0.0 && opt_.detection_error_correlated_share < 1.0,
              "detection_error_correlated_share must be in (0, 1)");
  }
  if (opt_.consider_correlated_errors && !(opt_.detection_error_correlation_s > 0.0))
    throw ConfigError("consider_correlated_errors needs detection_error_correlation_s > 0 (the errors' correlation "
                      "time, e.g. 3 s for a network's pose errors)",
                      {"config", 0, 0, "filter.consider_correlated_errors"});
  if (opt_.consider_correlated_errors && opt_.detection_error_states)
    throw ConfigError("consider_correlated_errors and detection_error_states are two models of the same errors: "
                      "set one of them",
                      {"config", 0, 0, "filter.consider_correlated_errors"});
  cov_.set_consider(opt_.consider_correlated_errors);
  cov_.reset(Eigen::MatrixXd::Zero(s_.dim, s_.dim));
  blocks_.reserve(16);
}

std::string Filter::when() const {
  const Timestamp s = s_.t_ns / kNsPerSecond, ns = s_.t_ns % kNsPerSecond;
  return fmt::format("t = {}.{:09d} s", s, ns < 0 ? -ns : ns);
}

void Filter::initialize(Timestamp t0, const Vec3& gyro0, const Vec3& accel0, const Vec3& mean_accel,
                        const Vec3* gyro_bias) {
  const Vec3 f = mean_accel - opt_.init_accel_bias;
  if (!f.allFinite() || f.norm() < 1e-6)
    throw NumericError(
        fmt::format("cannot initialise roll/pitch at t = {:.9f} s: mean accelerometer is zero "
                    "or not finite",
                    to_seconds(t0)));
  // R_W_I = Ry(pitch) Rx(roll) (yaw 0) with R_W_Iᵀ e_z ∥ f: roll = atan2(f_y, f_z), pitch = atan2(−f_x,
  // |f_yz|).
  const double roll = std::atan2(f.y(), f.z());
  const double pitch = std::atan2(-f.x(), std::hypot(f.y(), f.z()));
  s_.x = CoreState();
  s_.x.q_W_I = Eigen::Quaterniond(math::from_euler_zyx(Vec3(roll, pitch, 0.0))).normalized();
  s_.x.b_g = gyro_bias ? *gyro_bias : opt_.init_gyro_bias;
  s_.x.b_a = opt_.init_accel_bias;
  s_.t_ns = t0;
  gyro_ = gyro0;
  accel_ = accel0;

  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(s_.dim, s_.dim);
  const auto sq = [](double s) { return s * s; };
  const double d2r = math::kRadPerDeg;
  for (int i = 0; i < 3; ++i) {
    P(kP + i, kP + i) = sq(opt_.init_sigma_p_m);
    P(kV + i, kV + i) = sq(opt_.init_sigma_v_mps);
    P(kBg + i, kBg + i) = sq(opt_.init_sigma_gyro_bias);
    P(kBa + i, kBa + i) = sq(opt_.init_sigma_accel_bias);
  }
  // Attitude: roll/pitch and yaw σ are given about W's axes (tilt about x, y; yaw about z) and mapped
  // into the local error: δθ_local = R_W_Iᵀ δθ_W.
  const Mat3 R = s_.x.q_W_I.toRotationMatrix();
  const Vec3 var_W(sq(opt_.init_sigma_roll_pitch_deg * d2r), sq(opt_.init_sigma_roll_pitch_deg * d2r),
                   sq(opt_.init_sigma_yaw_deg * d2r));
  P.block<3, 3>(kTheta, kTheta) = R.transpose() * var_W.asDiagonal() * R;
  if (s_.extr_offset >= 0) {
    for (int i = 0; i < 3; ++i) {
      P(s_.extr_offset + i, s_.extr_offset + i) = sq(opt_.extrinsics_sigma_p_m);
      P(s_.extr_offset + 3 + i, s_.extr_offset + 3 + i) = sq(opt_.extrinsics_sigma_rot_deg * d2r);
    }
  }
  if (s_.td_offset >= 0) P(s_.td_offset, s_.td_offset) = sq(opt_.time_offset_sigma_s);
  cov_.reset(std::move(P));
  initialized_ = true;
  check_covariance(true, "initialisation");
  if (rec_) {
    rec_->steps.clear();
    rec_->nodes.clear();
    push_node(RecordedNode::Kind::kInit);
  }
}

StateEstimate Filter::snapshot() const { return s_; }

Timestamp Filter::time_offset_shift_ns() const {
  return s_.td_offset < 0 ? 0 : static_cast<Timestamp>(std::llround((s_.t_d - td_prior_s_) * 1e9));
}

RecordedNode& Filter::push_node(RecordedNode::Kind kind) {
  RecordedNode& nd = rec_->nodes.emplace_back();
  nd.kind = kind;
  nd.x = snapshot();
  nd.P = cov_.full();
  nd.steps = rec_->steps.size();
  nd.first_step = nd.steps;
  return nd;
}

void Filter::close_segment() {
  if (rec_ == nullptr || rec_->nodes.empty()) return;
  const std::size_t first = rec_->nodes.back().steps;
  if (rec_->steps.size() == first) return;
  RecordedNode& nd = rec_->nodes.emplace_back();
  nd.kind = RecordedNode::Kind::kPropagate;
  nd.x = snapshot();
  nd.steps = rec_->steps.size();
  nd.first_step = first;
  cov_.take_segment(nd.Phi, nd.P_cc);
}

void Filter::finish_recording() { close_segment(); }

const ObjectEntry* Filter::object(int id) const {
  for (const auto& o : s_.objects)
    if (o.id == id) return &o;
  return nullptr;
}


void Filter::propagate(Timestamp t, const Vec3& gyro, const Vec3& accel) {
  ROE_CHECK(initialized_, "propagate before initialize");
  ROE_CHECK(t >= s_.t_ns, "propagation backwards in time");
  if (t == s_.t_ns) {
    gyro_ = gyro;
    accel_ = accel;
    return;
  }
  const double dt = dt_seconds(s_.t_ns, t);
  CoreTransition F;
  s_.x = integrate(s_.x, gyro_, accel_, gyro, accel, dt, &F);
  s_.t_ns = t;
  gyro_ = gyro;
  accel_ = accel;
  if (rec_) {
    rec_->steps.push_back({t, s_.x, F});
    cov_.record_step(F);
  }
  if (reference_)
    cov_.propagate_dense(F, noise_, dt);
  else
    cov_.propagate(F, noise_, dt);
  check_propagated();
}

void Filter::check_propagated() {
  // Cheap guard rails every sample: core state and core variances.
  bool ok = s_.x.p_W_I.allFinite() && s_.x.v_W_I.allFinite() && s_.x.q_W_I.coeffs().allFinite();
  for (int i = 0; i < kCore && ok; ++i) ok = std::isfinite(cov_.variance(i)) && cov_.variance(i) > 0.0;
  if (!ok) check_covariance(false, "propagation");
  // check_state(core_only) on squared norms: a state clearly inside the bounds (norm² ≤ (0.999999·max)², so
  // that the rounded norm is ≤ max) skips it; anything else (near or over a bound, non-finite: NaN fails every
  // comparison, ∞ exceeds the bound) goes through check_state, which decides and words the error as before.
  const auto inside = [](const Vec3& v, double max) {
    const double b = 0.999999 * max, b2 = b * b;  // b2 finite: a finite norm² ≤ b2 has finite components
    return max > 0.0 && b2 <= std::numeric_limits<double>::max() && v.squaredNorm() <= b2;
  };
  if (!(inside(s_.x.p_W_I, opt_.max_position_m) && inside(s_.x.v_W_I, opt_.max_velocity_mps) &&
        inside(s_.x.b_g, opt_.max_gyro_bias) && inside(s_.x.b_a, opt_.max_accel_bias) &&
        s_.x.q_W_I.coeffs().squaredNorm() <= 2.0))
    check_state("propagation", /*core_only=*/true);
}

const Eigen::MatrixXd& Filter::covariance() { return cov_.full(); }

Mat6 Filter::object_covariance(const ObjectEntry& o) const {
  Mat6 C = Mat6::Zero();
  if (o.dim == 0) return C;
  // The anchor's estimated components are its leading rotation components (δθ_x, δθ_y[, δθ_z]).
  const int first = o.dim == 6 ? 0 : 3;
  C.block(first, first, o.dim, o.dim) = cov_.reported_stored().block(o.offset, o.offset, o.dim, o.dim);
  return C;
}

Mat6 Filter::object_covariance_in_world(const ObjectEntry& o) const {
  const Mat6 J = inverse_pose_jacobian(o.T_O_W);
  return J * object_covariance(o) * J.transpose();
}

Mat6 Filter::object_covariance_relative_to_anchor(const ObjectEntry& o) const {
  const ObjectEntry* a = object(anchor_id_);
  if (o.anchor || a == nullptr) return Mat6::Zero();
  // Error-state columns of [δp_A_W; δθ_A_W; δp_O_W; δθ_O_W] (−1: held fixed by the gauge).
  int idx[12];
  std::fill(idx, idx + 12, -1);
  const int first = a->dim == 6 ? 0 : 3;  // the anchor estimates its leading rotation components
  for (int k = 0; k < a->dim; ++k) idx[first + k] = a->offset + k;
  for (int k = 0; k < 6; ++k) idx[6 + k] = o.offset + k;
  Eigen::Matrix<double, 12, 12> C = Eigen::Matrix<double, 12, 12>::Zero();
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 12; ++j)
      if (idx[i] >= 0 && idx[j] >= 0) C(i, j) = cov_.reported_stored()(idx[i], idx[j]);
  const Eigen::Matrix<double, 6, 12> J = relative_pose_jacobian(a->T_O_W, o.T_O_W);
  return J * C * J.transpose();
}

void Filter::boxplus(const Eigen::VectorXd& dx) {
  ROE_CHECK(dx.size() == s_.dim, "boxplus: wrong size");
  ekf::boxplus(s_, dx);  // the one definition of ⊞ (state.hpp), on the held state
}

Pose Filter::predict(int object_id) const {
  const ObjectEntry* o = object(object_id);
  ROE_CHECK(o != nullptr, "predict: object not initialised");
  return predict_object(s_.x, s_.T_I_C, o->T_O_W).T_O_C_hat;
}

namespace {

/// Calls f(std::integral_constant<int, L>, state_offset, compact_col) for each run of a block's H
/// (fixed-size lengths 1, 2, 3, 6: the products below unroll completely).
template <typename Block, typename F>
inline void for_each_run(const Block& b, F&& f) {
  for (int k = 0; k < b.nruns; ++k) {
    switch (b.run_len[k]) {
      case 6:
        f(std::integral_constant<int, 6>(), b.run_off[k], b.run_col[k]);
        break;
      case 3:
        f(std::integral_constant<int, 3>(), b.run_off[k], b.run_col[k]);
        break;
      case 2:
        f(std::integral_constant<int, 2>(), b.run_off[k], b.run_col[k]);
        break;
      default:
        for (int j = 0; j < b.run_len[k]; ++j)
          f(std::integral_constant<int, 1>(), b.run_off[k] + j, b.run_col[k] + j);
        break;
    }
  }
}

/// H_a (P H_cᵀ) (6 x m_c) from the rows of P H_cᵀ (n x m_c, m_c ≤ 6) at H_a's non-zero columns.
template <typename Block, typename Y>
inline Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, 6> h_pht(const Block& a, const Y& pht_c) {
  Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, 6> S = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, 6>::Zero(6, pht_c.cols());
  for_each_run(a, [&](auto len, int off, int col) {
    constexpr int L = decltype(len)::value;
    S.noalias() += a.H.template middleCols<L>(col) * pht_c.template middleRows<L>(off);
  });
  return S;
}

}  // namespace

const ObjectSymmetry* Filter::symmetry(int object_id) const {
  const auto it = symmetries_.find(object_id);
  return it == symmetries_.end() || it->second.empty() ? nullptr : &it->second;
}

Mat6 Filter::error_state_jacobian(const Detection& d, bool object_frame) const {
  const double share = opt_.detection_error_correlated_share;
  const bool camera_cov = (opt_.use_detection_sigmas && d.sigma.has_value()) || opt_.meas_sigma_in_camera ||
                          opt_.residual_frame == ResidualFrame::kCamera;
  // The paper's fixed σ on the residual's own axes (T_O_C): the factors are on those axes.
  if (!camera_cov) return std::sqrt(share) * symmetric_sqrt(measurement_covariance(d, true));
  const Mat6 G_C = gauss_markov_error_jacobian(measurement_covariance(d, false), d.T_C_O.R(), share);
  return object_frame ? Mat6(detection_error_to_residual_frame(d.T_C_O) * G_C) : G_C;
}

void Filter::build_block(const ObjectEntry& o, const Pose& z_detected, MeasBlock& b, const Detection* det) const {
  const CoreState x_img = image_core();
  const ObjectPrediction pr = predict_object(x_img, s_.T_I_C, o.T_O_W);
  const ObjectSymmetry* sym = symmetry(o.id);
  const Pose z = sym ? nearest_equivalent(pr.T_O_C_hat, z_detected, *sym) : z_detected;
  b.r = object_residual(pr.T_O_C_hat, z);
  int c = 0;
  b.nruns = 0;
  // A run of contiguous state columns; a run directly continuing the previous one (p and θ of the
  // extrinsics or of an object) extends it to 6 columns.
  auto put = [&](int off, const auto& blk, int len) {
    const int k = b.nruns;
    if (k > 0 && b.run_len[k - 1] == 3 && len == 3 && b.run_off[k - 1] + 3 == off &&
        b.run_col[k - 1] + 3 == c) {
      b.run_len[k - 1] = 6;
    } else {
      b.run_off[k] = off;
      b.run_col[k] = c;
      b.run_len[k] = len;
      ++b.nruns;
    }
    for (int j = 0; j < len; ++j) {
      b.H.col(c) = blk.col(j);
      b.idx[c++] = off + j;
    }
  };
  put(kP, pr.H_p_WI, 3);
  put(kTheta, pr.H_theta_WI, 3);
  if (s_.extr_offset >= 0) {
    put(s_.extr_offset, pr.H_p_IC, 3);
    put(s_.extr_offset + 3, pr.H_theta_IC, 3);
  }
  if (s_.td_offset >= 0)  // ∂ẑ/∂t_d = H_p v + H_θ ω (measurement.hpp)
    put(s_.td_offset, time_offset_column(pr.H_p_WI, pr.H_theta_WI, x_img.v_W_I, gyro_ - x_img.b_g), 1);
  const int c_err = c;  // the error state's columns: set below, in the residual frame (no J_inv)
  if (o.err_offset >= 0) put(o.err_offset, Mat6::Zero(), 6);
  if (o.dim == 6) {
    put(o.offset, pr.H_p_OW, 3);
    put(o.offset + 3, pr.H_theta_OW, 3);
  } else if (o.dim > 0) {
    put(o.offset, pr.H_theta_OW, o.dim);  // anchor: the first o.dim components of δθ_O_W
  }
  b.nc = c;
  if (opt_.residual_frame == ResidualFrame::kCamera) {
    // Residual on T_C_O = ẑ⁻¹ (translation additive, rotation left error) and H = J_inv H with
    //   δt = −R_C_O δp_O_C + [t̂]× ε,  δθ_C = −ε   (ε the right error of R_O_C).
    const Pose zc_hat = pr.T_O_C_hat.inverse();
    const Pose zc = z.inverse();
    b.r.head<3>() = zc.p - zc_hat.p;
    // left error q ⊗ q̂⁻¹ (quat_residual(a, b) forms a⁻¹ ⊗ b)
    b.r.tail<3>() = math::quat_residual(zc.q.conjugate(), zc_hat.q.conjugate());
    const Mat3 R_C_O = zc_hat.R();
    Eigen::Matrix<double, 6, kMaxCols> Hc;
    Hc.topRows<3>().noalias() = -R_C_O * b.H.topRows<3>() + skew(zc_hat.p) * b.H.bottomRows<3>();
    Hc.bottomRows<3>() = -b.H.bottomRows<3>();
    b.H = Hc;
  }
  if (o.err_offset >= 0) {
    // The object's Gauss–Markov detection error enters like the detection's own error: r = z ⊟ ẑ(x) − G ê,
    // with G at the detection (its σ, the equivalent z's T_C_O).
    Detection dz = det ? *det : Detection{};
    dz.object_id = o.id;
    dz.T_C_O = z.inverse();
    const Mat6 G = error_state_jacobian(dz, opt_.residual_frame == ResidualFrame::kObject);
    b.H.middleCols<6>(c_err) = G;
    b.r -= G * o.err;
  }
  b.m = 6;
  b.A.setIdentity();
  b.separable = true;
  if (sym && sym->continuous) {
    // The rotation about the axis leaves residual and gate: r, H ← A r, A H (5 rows, row 5 zero).
    const Mat56 A = symmetry_reduction(symmetry_direction(opt_.residual_frame, pr.T_O_C_hat, *sym->continuous),
                                       b.separable);
    b.m = 5;
    b.A.topRows<5>() = A;
    b.A.row(5).setZero();
    b.r.head<5>() = (A * b.r).eval();
    b.r(5) = 0.0;
    const Eigen::Matrix<double, 5, kMaxCols> H5 = A * b.H;
    b.H.topRows<5>() = H5;
    b.H.row(5).setZero();
  }
}

void Filter::reduce_covariance(MeasBlock& b) {
  if (b.m == 6) return;
  const Eigen::MatrixXd Rm = b.A.topRows(b.m) * b.R * b.A.topRows(b.m).transpose();
  b.R.setIdentity();
  b.R.topLeftCorner(b.m, b.m) = 0.5 * (Rm + Rm.transpose());
}

void Filter::measurement_jacobian(int object_id, const Pose& z, Vec6& r, Eigen::MatrixXd& H) const {
  const ObjectEntry* o = object(object_id);
  ROE_CHECK(o != nullptr, "measurement_jacobian: object not initialised");
  MeasBlock b;
  build_block(*o, z, b);
  ROE_CHECK(b.m == 6, "measurement_jacobian: the object has a continuous symmetry (5 rows): use measurement_rows");
  r = b.r;
  H = Eigen::MatrixXd::Zero(6, s_.dim);
  for (int j = 0; j < b.nc; ++j) H.col(b.idx[j]) += b.H.col(j);
}

void Filter::select_rows(ResidualPart part, MeasBlock& b, Eigen::MatrixXd& PHt, Eigen::Index col0) {
  int rows[6];
  const int m = residual_rows(part, rows, b.m);
  Vec6 r = Vec6::Zero();
  Eigen::Matrix<double, 6, kMaxCols> H = Eigen::Matrix<double, 6, kMaxCols>::Zero();
  Mat6 R = Mat6::Zero(), S = Mat6::Identity();
  for (int i = 0; i < m; ++i) {
    r(i) = b.r(rows[i]);
    H.row(i) = b.H.row(rows[i]);
    for (int j = 0; j < m; ++j) {
      R(i, j) = b.R(rows[i], rows[j]);
      S(i, j) = b.S(rows[i], rows[j]);
    }
  }
  // P Hᵀ's columns are H's rows; in place, left to right (rows[i] ≥ i).
  for (int i = 0; i < m; ++i)
    if (rows[i] != i) PHt.col(col0 + i) = PHt.col(col0 + rows[i]);
  for (int i = m; i < 6; ++i) PHt.col(col0 + i).setZero();
  b.m = m;
  b.r = r;
  b.H = H;
  b.R = R;
  b.S = S;
}

ResidualPart Filter::gate(const MeasBlock& b, const Eigen::LDLT<Mat6>& ldlt, double& nis) const {
  // Only the orientation residual 2 q_v / q_w can be non-finite with a finite state and detection: a
  // detection exactly 180° from the prediction (q_w = 0), e.g. a symmetric object's flip. That part is an
  // outlier, gate or no gate; the run goes on.
  const bool finite = b.r.allFinite();
  nis = finite ? b.r.dot(ldlt.solve(b.r)) : std::numeric_limits<double>::infinity();
  const double inf = std::numeric_limits<double>::infinity();
  if (opt_.gate_mode == GateMode::kSplit && b.separable) {
    // Rotation part: 3 rows, or 2 (continuous symmetry; r and S identity-padded: the same NIS).
    const double gp = opt_.chi2_gate ? gate3_ : inf, gr = opt_.chi2_gate ? (b.m == 6 ? gate3_ : gate2_) : inf;
    return split_gate(b.r, b.S, gp, gr).used;
  }
  // The joint test of the block's m rows (also the split mode's fallback when position and rotation mix).
  if (!finite || (opt_.chi2_gate && nis > (b.m == 6 ? gate_ : gate5_))) return ResidualPart::kNone;
  return ResidualPart::kBoth;
}

void Filter::measurement_rows(int object_id, const Pose& z, ResidualPart part, Eigen::VectorXd& r,
                              Eigen::MatrixXd& H) const {
  const ObjectEntry* o = object(object_id);
  ROE_CHECK(o != nullptr, "measurement_rows: object not initialised");
  MeasBlock b;
  build_block(*o, z, b);
  b.R.setIdentity();
  b.S.setIdentity();
  reduce_covariance(b);
  Eigen::MatrixXd no_pht(0, 6);
  select_rows(part, b, no_pht, 0);
  r = b.r.head(b.m);
  H = Eigen::MatrixXd::Zero(b.m, s_.dim);
  for (int j = 0; j < b.nc; ++j) H.col(b.idx[j]) += b.H.col(j).head(b.m);
}

Mat6 Filter::measurement_covariance(const Detection& d, bool object_frame) const {
  const bool per_detection = opt_.use_detection_sigmas && d.sigma.has_value();
  if (per_detection) {
    // Camera-frame σ of the detection, mapped through the inversion when the object frame is wanted.
    const Vector6d var = sigma_var_scale_ * d.sigma->cwiseProduct(*d.sigma);
    if (object_frame) return detection_covariance_in_residual_frame(d.T_C_O, Mat6(var.asDiagonal()));
    return Mat6(var.asDiagonal());
  }
  const double sr = opt_.meas_sigma_rot_deg * math::kRadPerDeg;
  if (!(opt_.meas_sigma_in_camera || opt_.residual_frame == ResidualFrame::kCamera)) {
    // Fixed σ on the axes of the T_O_C residual (the paper).
    Vec6 sigma;
    sigma << Vec3::Constant(opt_.meas_sigma_p_m), Vec3::Constant(sr);
    return Mat6(sigma.cwiseProduct(sigma).asDiagonal());
  }
  // Fixed σ of the detected T_C_O in the camera frame: lateral/along-ray position σ growing with depth.
  const auto sq = [](double s) { return s * s; };
  const double depth = d.T_C_O.p.norm();
  const double s_lat = opt_.meas_sigma_p_m + opt_.meas_sigma_p_per_depth * depth;
  const double s_ray =
      opt_.meas_sigma_ray_m < 0.0 ? s_lat : opt_.meas_sigma_ray_m + opt_.meas_sigma_ray_per_depth * depth;
  Mat6 cov_C = Mat6::Zero();
  cov_C.topLeftCorner<3, 3>() = sq(s_lat) * Mat3::Identity();
  if (s_ray != s_lat && depth > 0.0) {
    const Vec3 u = d.T_C_O.p / depth;
    cov_C.topLeftCorner<3, 3>() += (sq(s_ray) - sq(s_lat)) * u * u.transpose();
  }
  cov_C.bottomRightCorner<3, 3>() = sq(sr) * Mat3::Identity();
  if (object_frame) return detection_covariance_in_residual_frame(d.T_C_O, cov_C);
  return cov_C;
}

Eigen::MatrixXd Filter::gauge_generator() const {
  // x_W = Exp(φ) x_W' + t, i.e. T_W_W' = (Exp(φ), t). To first order:
  //   p' = Exp(−φ)(p − t):  δp' = δp − t + [p]× φ      v' = Exp(−φ) v:  δv' = δv + [v]× φ
  //   R' = Exp(−φ) R:       δθ' = δθ − Rᵀ φ
  //   T_O_W' = T_O_W T_W_W':  δp_O' = δp_O + R_O_W t,  δθ_O' = δθ_O + φ
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(s_.dim, 6);
  G.block<3, 3>(kP, 0) = -Mat3::Identity();
  G.block<3, 3>(kP, 3) = skew(s_.x.p_W_I);
  G.block<3, 3>(kV, 3) = skew(s_.x.v_W_I);
  G.block<3, 3>(kTheta, 3) = -s_.x.q_W_I.toRotationMatrix().transpose();
  for (const auto& o : s_.objects) {
    if (o.dim == 6) {
      G.block<3, 3>(o.offset, 0) = o.T_O_W.R();
      G.block<3, 3>(o.offset + 3, 3) = Mat3::Identity();
    } else if (o.dim > 0) {
      G.block(o.offset, 3, o.dim, o.dim).setIdentity();
    }
  }
  return G;
}

namespace {

/// The anchor's gauge fix (docs/filter.md §4): Γ with γ = Γ δa for the anchor's error δa = [δp_a; δθ_a]
/// (t = −R_O_Wᵀ δp_a; φ = −δθ_a for kPose, (0, 0, −δθ_a,z) for kPositionYaw, 0 for kPosition); returns how
/// many of the anchor's leading rotation components stay in the state.
int anchor_gauge_map(AnchorGauge gauge, const Mat3& R_O_W, Mat6& Gamma) {
  Gamma.setZero();
  Gamma.block<3, 3>(0, 0) = -R_O_W.transpose();
  switch (gauge) {
    case AnchorGauge::kPose:
      Gamma.block<3, 3>(3, 3) = -Mat3::Identity();
      return 0;
    case AnchorGauge::kPosition:
      return 3;
    case AnchorGauge::kPositionYaw:
      Gamma(5, 5) = -1.0;
      return 2;
  }
  return 0;
}

}  // namespace

void Filter::initialize_object(const Detection& d, const Pose& z, bool anchor) {
  close_segment();
  const int id = d.object_id;
  const CoreState x_img = image_core();
  const ObjectInit in = init_object(x_img, s_.T_I_C, z);
  Mat6 R = measurement_covariance(d, true);
  // The Gauss–Markov detection-error state enters first, from its stationary distribution N(0, I); the first
  // detection's error is G x + the white rest, so the object-world depends on x through −J_z G.
  const int n_u = s_.dim, err_offset = opt_.detection_error_states ? s_.dim : -1;
  Mat6 G_err = Mat6::Zero();
  if (err_offset >= 0) {
    cov_.augment(CompactJacobian6{}, Mat6::Identity());
    s_.dim += 6;
    G_err = error_state_jacobian(d, /*object_frame=*/true);
    R *= 1.0 - opt_.detection_error_correlated_share;
  }
  // J_x over the columns it touches; the covariance grows by P J_xᵀ and J_x P J_xᵀ + J_z R J_zᵀ.
  CompactJacobian6 Jx;
  Jx.append3(kP, in.J_p_WI);
  Jx.append3(kTheta, in.J_theta_WI);
  if (s_.extr_offset >= 0) {
    Jx.append3(s_.extr_offset, in.J_p_IC);
    Jx.append3(s_.extr_offset + 3, in.J_theta_IC);
  }
  if (s_.td_offset >= 0)
    Jx.append1(s_.td_offset, time_offset_column(in.J_p_WI, in.J_theta_WI, x_img.v_W_I, gyro_ - x_img.b_g));
  if (err_offset >= 0) {
    // z = z_true ⊞ (G x + n): the object-world from the measured z errs by J_x δx − J_z (G x + n).
    const Mat6 JG = -in.J_z * G_err;
    Jx.append3(err_offset, JG.leftCols<3>());
    Jx.append3(err_offset + 3, JG.rightCols<3>());
  }
  const Mat6 Q = in.J_z * R * in.J_z.transpose();
  cov_.augment(Jx, Q);

  ObjectEntry o;
  o.id = id;
  o.T_O_W = in.T_O_W;
  o.anchor = anchor;
  o.t_init_ns = s_.t_ns;
  o.err_offset = err_offset;
  o.t_err_ns = s_.t_ns;

  if (!anchor) {
    // Plain augmentation.
    o.offset = s_.dim;
    o.dim = 6;
    s_.dim += 6;
    s_.objects.push_back(o);
    check_state("object initialisation");
    check_covariance(true, "object initialisation");
    if (rec_) push_node(RecordedNode::Kind::kAugment).append_only = true;
    return;
  }

  // Anchor: augment, then fix the gauge by re-defining W (docs/filter.md §4). With δa = [δp_a; δθ_a]
  // the anchor's error, choose γ = [t; φ] so that the fixed components vanish:
  //   t = −R_O_Wᵀ δp_a,  φ = −δθ_a (kPose)  or  φ = (0, 0, −δθ_a,z) (kPositionYaw),
  // φ = 0 (kPosition), then δx' = δx + G Γ δa; the anchor keeps δθ_a (kPosition), δθ_a,xy
  // (kPositionYaw) or nothing (kPose): P' = M P_aug Mᵀ.
  Mat6 Gamma;
  const int keep = anchor_gauge_map(opt_.anchor_gauge, in.T_O_W.R(), Gamma);
  const Eigen::MatrixXd G = gauge_generator();  // s_.objects does not contain the anchor yet
  const int n_aug = s_.dim + 6;
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(s_.dim + keep, n_aug);
  M.topLeftCorner(s_.dim, s_.dim).setIdentity();
  M.topRightCorner(s_.dim, 6) = G * Gamma;
  for (int k = 0; k < keep; ++k) M(s_.dim + k, s_.dim + 3 + k) = 1.0;
  cov_.change_variables(M);
  const int n_old = s_.dim;
  o.offset = keep > 0 ? s_.dim : -1;
  o.dim = keep;
  s_.dim += keep;
  s_.objects.push_back(o);
  check_state("anchor initialisation");
  check_covariance(true, "anchor initialisation");
  if (rec_) {
    // The link for the smoother: δy = M [δu; J_x δu + J_z n] = B δu + noise.
    // (With an error state, u is the state before it: the error state and the anchor's δa are both appended,
    // δa = J_x δu + J_z G x + J_z n, so B's columns are those of u and x is part of the noise.)
    RecordedNode& nd = push_node(RecordedNode::Kind::kAugment);
    nd.append_only = false;
    nd.anchor = true;
    nd.B = M.leftCols(n_u) + M.rightCols(6) * Jx.dense(n_old).leftCols(n_u);
  }
}

void Filter::stacked_pht(int nb) {
  const Eigen::MatrixXd& P = cov_.stored();  // brought up to date by update()
  if (reference_) {  // P H_kᵀ with the full 6 x n H_k
    for (int k = 0; k < nb; ++k) {
      const MeasBlock& b = blocks_[k];
      Eigen::MatrixXd H = Eigen::MatrixXd::Zero(6, s_.dim);
      for (int j = 0; j < b.nc; ++j) H.col(b.idx[j]) += b.H.col(j);
      ws_PHt_.middleCols<6>(6 * k) = P * H.transpose();
    }
    return;
  }
  // H_k's compact columns: p, θ [, the extrinsics' p, θ] [, t_d] (shared by every block), then the object's
  // (one run of o.dim contiguous state columns; build_block).
  const int ne = s_.extr_offset >= 0 ? 6 : 0, nt = s_.td_offset >= 0 ? 1 : 0;
  const int ns = 6 + ne + nt;
  Eigen::MatrixXd& PHt = ws_PHt_;
  if (ws_W_.rows() != s_.dim || ws_W_.cols() < ns) {
    const Eigen::Index cols = std::max<Eigen::Index>(ns, ws_W_.rows() == s_.dim ? ws_W_.cols() : 0);
    ws_W_.resize(s_.dim, cols);
  }
  ws_W_.leftCols<3>() = P.middleCols<3>(kP);
  ws_W_.middleCols<3>(3) = P.middleCols<3>(kTheta);
  if (ne > 0) ws_W_.middleCols<6>(6) = P.middleCols<6>(s_.extr_offset);
  if (nt > 0) ws_W_.col(6 + ne) = P.col(s_.td_offset);
  if (ws_Hs_.cols() != ns || ws_Hs_.rows() < 6 * nb)
    ws_Hs_.resize(std::max<Eigen::Index>(6 * nb, ws_Hs_.cols() == ns ? ws_Hs_.rows() : 0), ns);
  for (int k = 0; k < nb; ++k) ws_Hs_.middleRows<6>(6 * k) = blocks_[k].H.leftCols(ns);
  // The shared columns of all blocks in one product, then each block's object columns (read in place).
  PHt.leftCols(6 * nb).setZero();
  add_abt(PHt.data(), PHt.outerStride(), ws_W_.data(), ws_W_.outerStride(), ws_Hs_.data(), ws_Hs_.outerStride(), s_.dim,
          6 * nb, ns, 1.0, /*lower=*/false);
  for (int k = 0; k < nb; ++k) {
    const MeasBlock& b = blocks_[k];
    const ObjectEntry& o = s_.objects[b.obj];
    // The object's own columns: its error state (6, right before the object-world) and its object-world.
    const int own = o.dim + (o.err_offset >= 0 ? 6 : 0), first = o.err_offset >= 0 ? o.err_offset : o.offset;
    ROE_CHECK(b.nc == ns + own, "stacked_pht: unexpected measurement Jacobian layout");
    if (own > 0)
      add_abt(&PHt(0, 6 * k), PHt.outerStride(), &P(0, first), P.outerStride(), b.H.col(ns).data(), 6, s_.dim, 6,
              own, 1.0, /*lower=*/false);
  }
}

FrameResult Filter::update(const std::vector<Detection>& dets, double dt_image_s) {
  ROE_CHECK(initialized_, "update before initialize");
  dt_img_s_ = dt_image_s;
  FrameResult res = update_image(dets);
  dt_img_s_ = 0.0;
  return res;
}

CoreState Filter::image_core() const {
  return dt_img_s_ == 0.0 ? s_.x : shift_in_time(s_.x, gyro_ - s_.x.b_g, dt_img_s_);
}

FrameResult Filter::update_image(const std::vector<Detection>& dets) {
  FrameResult res;
  res.t_ns = s_.t_ns + static_cast<Timestamp>(std::llround(dt_img_s_ * 1e9));
  res.detections.resize(dets.size());
  const int anchor_det = screen_detections(dets, res);
  std::vector<char>& usable = ws_usable_;
  const auto reject_no_anchor = [&]() {
    for (std::size_t i = 0; i < dets.size(); ++i)
      if (usable[i]) res.detections[i].status = DetectionStatus::kRejectedNoMain;
    set_implied_poses(dets, res);
    return res;
  };
  if (anchor_det < 0 && opt_.require_anchor) return reject_no_anchor();

  // The anchor's first sight fixes the gauge before anything else uses this frame.
  if (anchor_det >= 0 && object(anchor_id_) == nullptr) {
    const Detection& d = dets[anchor_det];
    if (confirm_first_sight(d.object_id, ws_z_[anchor_det])) {
      initialize_object(d, ws_z_[anchor_det], true);
      res.detections[anchor_det].status = DetectionStatus::kInitialized;
      res.detections[anchor_det].used = ResidualPart::kBoth;
    } else {
      res.detections[anchor_det].status = DetectionStatus::kPendingInit;
    }
    usable[anchor_det] = 0;
  }
  if (opt_.require_anchor && object(anchor_id_) == nullptr) return reject_no_anchor();

  relock_lost_position(res);
  ws_scale_.clear();
  decay_error_states(dets);
  cov_.full();
  build_blocks(dets);
  if (!blocks_.empty()) {
    gate_blocks(dets, res);
    if (!ws_inliers_.empty()) update_with_inliers(res);
  }
  // First sight of the other objects, from the posterior.
  for (int i : ws_new_objects_) {
    const Detection& d = dets[i];
    if (!confirm_first_sight(d.object_id, ws_z_[i])) {
      res.detections[i].status = DetectionStatus::kPendingInit;
      continue;
    }
    initialize_object(d, ws_z_[i], false);
    res.detections[i].status = DetectionStatus::kInitialized;
    res.detections[i].used = ResidualPart::kBoth;
  }
  set_implied_poses(dets, res);
  observe_lockout(dets, res);
  learn_sigma_scale(ws_scale_);
  // A decay node's covariance is not stored: the next node must store one (the smoother's rule, smoother.hpp).
  if (rec_ && rec_->nodes.back().kind == RecordedNode::Kind::kDecay) push_node(RecordedNode::Kind::kUpdate);
  return res;
}

void Filter::decay_error_states(const std::vector<Detection>& dets) {
  if (!opt_.detection_error_states) return;
  Eigen::VectorXd& b = ws_decay_;
  b.setOnes(s_.dim);
  bool any = false;
  for (std::size_t i = 0; i < dets.size(); ++i) {
    if (!ws_usable_[i]) continue;
    auto it = std::find_if(s_.objects.begin(), s_.objects.end(), [&](const auto& o) { return o.id == dets[i].object_id; });
    if (it == s_.objects.end() || it->err_offset < 0 || s_.t_ns <= it->t_err_ns) continue;
    // x ← ρ x + √(1 − ρ²) w over the time since the last decay (a composition of decays is one decay).
    const double rho = std::exp(-to_seconds(s_.t_ns - it->t_err_ns) / opt_.detection_error_correlation_s);
    b.segment<6>(it->err_offset).setConstant(rho);
    it->err *= rho;
    it->t_err_ns = s_.t_ns;
    any = true;
  }
  if (!any) return;
  close_segment();
  cov_.decay(b);
  if (rec_) {
    RecordedNode& nd = rec_->nodes.emplace_back();
    nd.kind = RecordedNode::Kind::kDecay;
    nd.x = snapshot();
    nd.steps = rec_->steps.size();
    nd.first_step = nd.steps;
    nd.decay = b;
  }
}

int Filter::screen_detections(const std::vector<Detection>& dets, FrameResult& res) {
  std::vector<char>& usable = ws_usable_;
  usable.assign(dets.size(), 1);
  for (std::size_t i = 0; i < dets.size(); ++i) {
    res.detections[i].object_id = dets[i].object_id;
    // One detection per object and image: a second one would enter the state as a second object with
    // the same id (the dataset readers refuse such files; this guards the library API).
    for (std::size_t k = 0; k < i; ++k)
      if (dets[k].object_id == dets[i].object_id)
        throw InputError(fmt::format("two detections of object {} in the image at {}: one per object and image",
                                     dets[i].object_id, when()));
    if (!usable_detection(dets[i], opt_)) {
      res.detections[i].status = DetectionStatus::kRejectedScore;
      usable[i] = 0;
    }
  }
  // Anchor choice: the configured id (run_filter passes the rule's choice over the whole run), or the rule
  // (images.hpp) on the one image known here.
  if (anchor_id_ < 0) anchor_id_ = choose_anchor({ImageDetections{s_.t_ns, dets}}, s_.t_ns, s_.t_ns, opt_).id;
  int anchor_det = -1;
  for (std::size_t i = 0; i < dets.size(); ++i)
    if (usable[i] && dets[i].object_id == anchor_id_) anchor_det = static_cast<int>(i);
  ws_z_.resize(dets.size());
  for (std::size_t i = 0; i < dets.size(); ++i) ws_z_[i] = dets[i].T_C_O.inverse();
  return anchor_det;
}

void Filter::set_implied_poses(const std::vector<Detection>& dets, FrameResult& res) const {
  for (std::size_t i = 0; i < dets.size(); ++i) {
    const ObjectEntry* o = object(dets[i].object_id);
    if (o == nullptr) continue;
    res.detections[i].has_T_W_I = true;
    res.detections[i].T_W_I = o->T_O_W.inverse() * ws_z_[i] * s_.T_I_C.inverse();
  }
}

void Filter::build_blocks(const std::vector<Detection>& dets) {
  blocks_.clear();
  std::vector<int>& new_objects = ws_new_objects_;
  new_objects.clear();
  for (std::size_t i = 0; i < dets.size(); ++i) {
    if (!ws_usable_[i]) continue;
    const ObjectEntry* o = object(dets[i].object_id);
    if (o == nullptr) {
      new_objects.push_back(static_cast<int>(i));
      continue;
    }
    MeasBlock b;
    b.det = static_cast<int>(i);
    b.obj = static_cast<int>(o - s_.objects.data());
    build_block(*o, ws_z_[i], b, &dets[i]);
    b.R = measurement_covariance(dets[i], opt_.residual_frame == ResidualFrame::kObject);
    if (o->err_offset >= 0) b.R *= 1.0 - opt_.detection_error_correlated_share;  // the white rest
    b.k = error_inflation(dets[i].object_id);
    reduce_covariance(b);
    blocks_.push_back(b);
  }
}

void Filter::gate_blocks(const std::vector<Detection>& dets, FrameResult& res) {
  const int nb = static_cast<int>(blocks_.size());
  // P H_kᵀ per block (n x 6, from H_k's ≤ 18 non-zero columns) and the block S_k for the gate.
  Eigen::MatrixXd& PHt = ws_PHt_;
  if (PHt.rows() != s_.dim || PHt.cols() < 6 * nb) PHt.resize(s_.dim, std::max<Eigen::Index>(6 * nb, PHt.cols()));
  std::vector<int>& inliers = ws_inliers_;
  inliers.clear();
  stacked_pht(nb);
  for (int k = 0; k < nb; ++k) {
    MeasBlock& b = blocks_[k];
    auto PHt_k = PHt.middleCols<6>(6 * k);
    const Mat6 S = h_pht(b, PHt_k) + b.R;
    b.S = 0.5 * (S + S.transpose());
    Eigen::LDLT<Mat6> ldlt(b.S);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().array() > 0.0).all())
      throw NumericError(
          fmt::format("filter failed at {}: innovation covariance of object {} is not "
                      "positive definite",
                      when(), dets[b.det].object_id));
    double nis = 0.0;
    const ResidualPart used = gate(b, ldlt, nis);
    // Not with the error states: their NIS runs below χ² even with the right σ (docs/filter.md §17), and a scale
    // learned from it shrinks every σ and G with it (0.6 on a clean paper-real replica: object NEES 80–280).
    if (opt_.adapt_detection_sigma_scale && !opt_.detection_error_states && opt_.use_detection_sigmas &&
        dets[b.det].sigma && std::isfinite(nis))
      ws_scale_.push_back(nis * sigma_var_scale_ / (b.m == 6 ? chi2_median6_ : chi2_median5_));
    if (b.r.allFinite() && !std::isfinite(nis))
      throw NumericError(
          fmt::format("filter failed at {}: non-finite NIS for object {}", when(), dets[b.det].object_id));
    DetectionOutcome& out = res.detections[b.det];
    out.nis = nis;
    out.used = used;
    if (b.m == 6) {  // |2 q_v / q_w| = 2 tan(θ/2)
      const double t = b.r.tail<3>().norm();
      out.rot_residual_deg = std::isfinite(t) ? 2.0 * std::atan(0.5 * t) / math::kRadPerDeg : 180.0;
    }
    if (used == ResidualPart::kNone) {
      out.status = DetectionStatus::kRejectedChi2;
      continue;
    }
    out.status = DetectionStatus::kAccepted;
    if (used != ResidualPart::kBoth) select_rows(used, b, PHt, 6 * k);
    inliers.push_back(k);
  }
}

void Filter::update_with_inliers(FrameResult& res) {
  const std::vector<int>& inliers = ws_inliers_;
  Eigen::MatrixXd& PHt = ws_PHt_;
  const int ni = static_cast<int>(inliers.size());
  close_segment();
  // Row offsets of the inliers' blocks in the stack (6 rows each, fewer for a split block).
  std::vector<int>& row0 = ws_row0_;
  row0.resize(ni + 1);
  row0[0] = 0;
  for (int a = 0; a < ni; ++a) row0[a + 1] = row0[a] + blocks_[inliers[a]].m;
  const int m = row0[ni];
  // Inliers' P Hᵀ compacted to the left column by column (in place: row0[a] ≤ 6 inliers[a]), residuals
  // stacked.
  Eigen::VectorXd& r = ws_r_;
  r.resize(m);
  for (int a = 0; a < ni; ++a) {
    const int ma = blocks_[inliers[a]].m;
    if (row0[a] != 6 * inliers[a])
      for (int j = 0; j < ma; ++j) PHt.col(row0[a] + j) = PHt.col(6 * inliers[a] + j);
    r.segment(row0[a], ma) = blocks_[inliers[a]].r.head(ma);
  }
  const auto Y = PHt.leftCols(m);  // P Hᵀ (n x m)
  // S = H P Hᵀ + R: the diagonal blocks are the gate's S_k; block (a, c), a > c, is H_a (P H_cᵀ),
  // evaluated once and mirrored (S exactly symmetric).
  if (ws_S_.rows() < m) {
    ws_S_.resize(m, m);
    ws_L_.resize(m, m);
  }
  auto S = ws_S_.topLeftCorner(m, m);
  for (int a = 0; a < ni; ++a) {
    const MeasBlock& ba = blocks_[inliers[a]];
    S.block(row0[a], row0[a], ba.m, ba.m) = ba.S.topLeftCorner(ba.m, ba.m);
    for (int c = 0; c < a; ++c) {
      const int mc = blocks_[inliers[c]].m;
      const auto Sac = h_pht(ba, Y.middleCols(row0[c], mc)).topRows(ba.m);
      S.block(row0[a], row0[c], ba.m, mc) = Sac;
      S.block(row0[c], row0[a], mc, ba.m) = Sac.transpose();
    }
  }
  // K, δx and the posterior P − W Wᵀ (stacked_update.hpp).
  Eigen::VectorXd& dx = ws_dx_;
  if (!apply_stacked_update(Y, S, inliers, row0, dx))
    throw NumericError(
        fmt::format("filter failed at {}: stacked innovation covariance is not positive definite", when()));
  boxplus(dx);
  res.n_inliers = ni;
  ++n_updates_;
  check_state("update");
  check_covariance(opt_.pd_check_every > 0 && n_updates_ % opt_.pd_check_every == 0, "update");
  if (rec_) push_node(RecordedNode::Kind::kUpdate);
}

double Filter::error_inflation(int object_id) {
  const double tau = opt_.detection_error_correlation_s;
  if (!(tau > 0.0) || opt_.detection_error_states) return 1.0;  // the error states carry the correlation
  auto it = last_detection_ns_.find(object_id);
  if (it == last_detection_ns_.end()) {
    last_detection_ns_[object_id] = s_.t_ns;
    return 1.0;
  }
  const double dt = to_seconds(s_.t_ns - it->second);
  it->second = s_.t_ns;
  // AR(1) errors with lag correlation ρ: a mean of N of them has the variance of N (1−ρ)/(1+ρ) white ones.
  const double rho = std::exp(-std::max(dt, 0.0) / tau);
  return (1.0 + rho) / std::max(1.0 - rho, 1e-6);
}

bool Filter::apply_stacked_update(const Eigen::Ref<const Eigen::MatrixXd>& Y, const Eigen::Ref<const Eigen::MatrixXd>& S,
                                  const std::vector<int>& inliers, const std::vector<int>& row0, Eigen::VectorXd& dx) {
  const int ni = static_cast<int>(inliers.size()), m = row0[ni];
  // The constant states: the extrinsics and the object-worlds (the anchor's kept components included).
  std::vector<Eigen::Index>& rows = ws_const_rows_;
  rows.clear();
  for (int i = kCore; i < s_.dim; ++i) rows.push_back(i);
  // With the consider covariance the gain stays the white one (k enters P_a only, §18).
  bool inflated = false;
  for (int a = 0; a < ni && !opt_.consider_correlated_errors; ++a) inflated |= blocks_[inliers[a]].k > 1.0;
  if ((!inflated || s_.dim == kCore) && reference_) return reference_update(inliers, row0, dx);
  if (!inflated || s_.dim == kCore) {
    if (!cov_.consider()) return cov_.update(Y, S, ws_r_.head(m), dx, {ws_L_, ws_W_, ws_u_});
    Eigen::MatrixXd H, R;
    stacked_jacobian(inliers, row0, H, R);
    const Eigen::VectorXd d = stacked_inflation(inliers, row0);
    const ConsiderNoise noise{H, R, d, rows};
    return cov_.update(Y, S, ws_r_.head(m), dx, {ws_L_, ws_W_, ws_u_}, &noise);
  }
  // The stacked R is block-diagonal (detections independent of each other); √k per row of each block.
  Eigen::MatrixXd R = Eigen::MatrixXd::Zero(m, m);
  for (int a = 0; a < ni; ++a) {
    const MeasBlock& b = blocks_[inliers[a]];
    R.block(row0[a], row0[a], b.m, b.m) = b.R.topLeftCorner(b.m, b.m);
  }
  return cov_.update_constant_gain(Y, S, R, stacked_inflation(inliers, row0), ws_r_.head(m), rows, dx);
}

Eigen::VectorXd Filter::stacked_inflation(const std::vector<int>& inliers, const std::vector<int>& row0) const {
  const int ni = static_cast<int>(inliers.size());
  Eigen::VectorXd d(row0[ni]);
  for (int a = 0; a < ni; ++a) {
    const MeasBlock& b = blocks_[inliers[a]];
    d.segment(row0[a], b.m).setConstant(std::sqrt(b.k));
  }
  return d;
}

void Filter::stacked_jacobian(const std::vector<int>& inliers, const std::vector<int>& row0, Eigen::MatrixXd& H,
                              Eigen::MatrixXd& R) const {
  const int ni = static_cast<int>(inliers.size()), m = row0[ni], n = s_.dim;
  H.setZero(m, n);
  R.setZero(m, m);
  for (int a = 0; a < ni; ++a) {
    const MeasBlock& b = blocks_[inliers[a]];
    for (int j = 0; j < b.nc; ++j) H.block(row0[a], b.idx[j], b.m, 1) += b.H.col(j).head(b.m);
    R.block(row0[a], row0[a], b.m, b.m) = b.R.topLeftCorner(b.m, b.m);
  }
}

bool Filter::reference_update(const std::vector<int>& inliers, const std::vector<int>& row0, Eigen::VectorXd& dx) {
  const int m = row0[inliers.size()];
  Eigen::MatrixXd H, R;
  stacked_jacobian(inliers, row0, H, R);
  if (!cov_.consider()) return cov_.update_dense(H, R, ws_r_.head(m), dx);
  const Eigen::VectorXd d = stacked_inflation(inliers, row0);
  const ConsiderNoise noise{H, R, d, ws_const_rows_};
  return cov_.update_dense(H, R, ws_r_.head(m), dx, &noise);
}

void Filter::learn_sigma_scale(const std::vector<double>& frame_samples) {
  for (double x : frame_samples) {
    if (sigma_scale_samples_.size() < static_cast<std::size_t>(kSigmaScaleWindow)) {
      sigma_scale_samples_.push_back(x);
    } else {
      sigma_scale_samples_[sigma_scale_next_] = x;
      sigma_scale_next_ = (sigma_scale_next_ + 1) % kSigmaScaleWindow;
    }
  }
  // Only from a window of some size on: a median of few detections is noise.
  if (frame_samples.empty() || sigma_scale_samples_.size() < kSigmaScaleMin) return;
  std::vector<double>& v = ws_scale_sorted_;
  v = sigma_scale_samples_;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  // Bounded: a factor 8 on σ either way (64 on the variance) covers any detector worth fusing.
  sigma_var_scale_ = std::clamp(v[v.size() / 2], 1.0 / 64.0, 64.0);
}

namespace {
bool uses_position(ResidualPart p) { return p == ResidualPart::kPosition || p == ResidualPart::kBoth; }
}  // namespace

void Filter::relock_lost_position(FrameResult& res) {
  if (!lost_position_.enabled()) return;
  // The inflation is process noise added at this instant. The smoother sees it as part of the open
  // propagation segment's Q (P_cc at the segment's end minus Φ P_a Φᵀ): without IMU steps since the last
  // recorded node there is no such segment, and the decision waits for the next image.
  if (rec_ != nullptr && !rec_->nodes.empty() && rec_->steps.size() == rec_->nodes.back().steps) return;
  res.relock = lost_position_.check(s_.t_ns);
  if (!res.relock) return;
  // The observed offset (and its scatter) for the position; for the velocity the drift of the offset, or
  // the offset spread over the time the position was refused, whichever the data say more of. Only the
  // core block changes: P_cc is always current and the pending cross-covariance transition is unaffected
  // by noise added now.
  const Relock& r = *res.relock;
  const double span = std::max(to_seconds(s_.t_ns - r.since_ns), opt_.relock_after_s);
  cov_.inflate_core(kP, r.offset.squaredNorm() + r.residual_sigma * r.residual_sigma);
  cov_.inflate_core(kV, r.drift_per_s.squaredNorm() + r.offset.squaredNorm() / (span * span));
  lost_position_.accepted(s_.t_ns);
}

void Filter::observe_lockout(const std::vector<Detection>& dets, FrameResult& res) {
  bool position = false;
  for (const auto& d : res.detections) {
    position |= d.status == DetectionStatus::kInitialized;
    res.position_used |= d.status == DetectionStatus::kAccepted && uses_position(d.used);
  }
  if (!lost_position_.enabled()) return;
  if (position || res.position_used) {
    lost_position_.accepted(s_.t_ns);
    return;
  }
  // Offsets of the refused detections' implied camera position from the estimate, from the detected
  // translation alone: p_W_C = p_W_O − R̂_W_C t_C_O (a flipped or noisy detected rotation does not move it).
  const Mat3 R_W_C = s_.x.q_W_I.toRotationMatrix() * s_.T_I_C.R();
  const Vec3 p_W_C = s_.x.p_W_I + s_.x.q_W_I * s_.T_I_C.p;
  for (std::size_t i = 0; i < dets.size(); ++i) {
    const DetectionOutcome& d = res.detections[i];
    const bool refused = d.status == DetectionStatus::kRejectedChi2 || d.status == DetectionStatus::kAccepted;
    if (!refused || !d.has_T_W_I) continue;
    const Pose T_W_O = object(d.object_id)->T_O_W.inverse();
    lost_position_.refused(s_.t_ns, d.object_id, T_W_O.p - R_W_C * dets[i].T_C_O.p - p_W_C);
  }
}

bool Filter::confirm_first_sight(int id, const Pose& z) {
  if (opt_.init_min_detections <= 1) return true;
  const Pose cand = init_object(image_core(), s_.T_I_C, z).T_O_W;
  auto it = std::find_if(pending_.begin(), pending_.end(), [id](const auto& p) { return p.first == id; });
  if (it == pending_.end()) {
    pending_.push_back({id, Pending{cand, 1}});
    return false;
  }
  Pending& p = it->second;
  // Agreement of where the object is (T_W_O), not of T_O_W: the position of W's origin seen from the
  // object moves by |p_W_O| · δθ with every rotation error of the detection (0.3 m for 6° at 3 m).
  const Vec6 d = math::pose_difference(p.T_O_W.inverse(), cand.inverse());
  if (d.head<3>().norm() <= opt_.init_gate_p_m &&
      d.tail<3>().norm() <= opt_.init_gate_rot_deg * math::kRadPerDeg)
    ++p.count;
  else
    p.count = 1;
  p.T_O_W = cand;
  if (p.count < opt_.init_min_detections) return false;
  pending_.erase(it);
  return true;
}

void Filter::check_state(const char* where, bool core_only) const {
  const auto fail = [&](const std::string& what) {
    throw NumericError(fmt::format("filter diverged at {} ({}): {}", when(), where, what));
  };
  if (!s_.x.p_W_I.allFinite() || !s_.x.v_W_I.allFinite() || !s_.x.q_W_I.coeffs().allFinite() ||
      !s_.x.b_g.allFinite() || !s_.x.b_a.allFinite())
    fail("non-finite core state");
  if (s_.x.p_W_I.norm() > opt_.max_position_m)
    fail(fmt::format("|p_W_I| = {:.4g} m exceeds max_position_m = {:.4g}", s_.x.p_W_I.norm(),
                     opt_.max_position_m));
  if (s_.x.v_W_I.norm() > opt_.max_velocity_mps)
    fail(fmt::format("|v_W_I| = {:.4g} m/s exceeds max_velocity_mps = {:.4g}", s_.x.v_W_I.norm(),
                     opt_.max_velocity_mps));
  if (s_.x.b_g.norm() > opt_.max_gyro_bias)
    fail(fmt::format("|b_g| = {:.4g} rad/s exceeds max_gyro_bias = {:.4g}", s_.x.b_g.norm(),
                     opt_.max_gyro_bias));
  if (s_.x.b_a.norm() > opt_.max_accel_bias)
    fail(fmt::format("|b_a| = {:.4g} m/s² exceeds max_accel_bias = {:.4g}", s_.x.b_a.norm(),
                     opt_.max_accel_bias));
  // Propagation changes only the core state; the extrinsics and object-worlds were checked when they last
  // changed (update, initialisation).
  if (core_only) return;
  if (!s_.T_I_C.p.allFinite() || !s_.T_I_C.q.coeffs().allFinite()) fail("non-finite extrinsics");
  if (!(std::abs(s_.t_d - td_prior_s_) <= opt_.max_time_offset_s))
    fail(fmt::format("the time offset {:.4g} s is more than max_time_offset_s = {:.4g} s from the declared {:.4g} s",
                     s_.t_d, opt_.max_time_offset_s, td_prior_s_));
  for (const auto& o : s_.objects)
    if (!o.T_O_W.p.allFinite() || !o.T_O_W.q.coeffs().allFinite() || o.T_O_W.p.norm() > opt_.max_position_m)
      fail(fmt::format("object-world of object {} is non-finite or out of bounds", o.id));
}

void Filter::check_covariance(bool full, const char* where) {
  if (const std::optional<std::string> problem = cov_.check(full))
    throw NumericError(fmt::format("filter diverged at {} ({}): {}", when(), where, *problem));
}

}  // namespace roe::ekf
