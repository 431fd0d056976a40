// The initial state taken from the IMU: the init window's statistics and the gyro bias at rest
// (FilterOptions::init_gyro_bias_from_rest), and run_filter's schedule of IMU samples and images.
#include <algorithm>
#include <catch2/catch.hpp>

#include <cmath>

#include "roe/ekf/driver.hpp"
#include "roe/math/euler.hpp"
#include "roe/math/so3.hpp"

using namespace roe;
using namespace roe::ekf;

namespace {

// 200 Hz samples from t = 0: a level IMU at rest with gyro bias `b_g`, small alternating noise, and
// from `t_move_s` on a rotation of 0.5 rad/s about z added to the gyro.
std::vector<ImuSample> imu_stream(const Vec3& b_g, double duration_s, double t_move_s = 1e9) {
  std::vector<ImuSample> v;
  const int n = static_cast<int>(std::lround(duration_s * 200.0));
  for (int k = 0; k <= n; ++k) {
    const double t = k / 200.0;
    const double s = (k % 2 == 0) ? 1.0 : -1.0;  // zero-mean ±
    ImuSample m;
    m.t_ns = from_seconds(t);
    m.gyro = b_g + Vec3(2e-3, -1e-3, 1.5e-3) * s;
    if (t >= t_move_s) m.gyro.z() += 0.5;
    m.accel = Vec3(0.0, 0.0, 9.81) + Vec3(0.02, 0.03, -0.01) * s;
    v.push_back(m);
  }
  return v;
}

struct Last : FilterObserver {
  CoreState first, last;
  bool have_first = false;
  void on_imu(const Filter& f) override {
    if (!have_first) {
      first = f.core();
      have_first = true;
    }
    last = f.core();
  }
};

double yaw_deg(const Eigen::Quaterniond& q) { return math::euler_zyx(q.toRotationMatrix()).z() * math::kDegPerRad; }

}  // namespace

TEST_CASE("init window: means and per-axis sample sigma of the samples within init_window_s", "[ekf][init]") {
  const Vec3 b_g(0.01, -0.02, 0.08);
  const auto imu = imu_stream(b_g, 2.0);
  const InitWindow w = init_window(imu, 0.2);
  CHECK(w.samples == 41);  // 0 … 0.2 s inclusive at 200 Hz
  CHECK(w.duration_s == Approx(0.2));
  // 21 "+" and 20 "−" samples.
  CHECK((w.mean_gyro - (b_g + Vec3(2e-3, -1e-3, 1.5e-3) / 41.0)).norm() < 1e-12);
  CHECK(w.mean_accel.z() == Approx(9.81 - 0.01 / 41.0));
  // Sample σ of ±a with 21/20 signs: a · sqrt(41 (1 − (1/41)²) / 40).
  const double f = std::sqrt(41.0 * (1.0 - 1.0 / (41.0 * 41.0)) / 40.0);
  CHECK(w.std_gyro.x() == Approx(2e-3 * f).epsilon(1e-9));
  CHECK(w.std_accel.y() == Approx(0.03 * f).epsilon(1e-9));
  // The same samples 1000 s later: the window is relative to the first sample's stamp.
  auto later = imu;
  for (auto& m : later) m.t_ns += from_seconds(1000.0);
  const InitWindow wl = init_window(later, 0.2);
  CHECK(wl.samples == 41);
  CHECK(wl.duration_s == Approx(0.2).epsilon(1e-12));
  CHECK((wl.mean_gyro - w.mean_gyro).norm() == 0.0);
  // A zero window still holds the first sample (σ 0).
  const InitWindow one = init_window(imu, 0.0);
  CHECK(one.samples == 1);
  CHECK(one.std_gyro.isZero());
  CHECK_THROWS(init_window({}, 0.2));
}

TEST_CASE("gyro bias at rest: taken from the window only when asked for and at rest", "[ekf][init]") {
  const Vec3 b_g(0.01, -0.02, 0.08);
  FilterOptions opt;
  opt.init_gyro_bias = Vec3(1e-3, 2e-3, 3e-3);
  std::string why;

  SECTION("off (the paper, roe's default): the configured bias") {
    const InitWindow w = init_window(imu_stream(b_g, 1.0), 0.2);
    CHECK(initial_gyro_bias(w, opt, &why) == opt.init_gyro_bias);
    CHECK(why.empty());
  }
  opt.init_gyro_bias_from_rest = true;
  SECTION("at rest: the window's gyro mean") {
    const InitWindow w = init_window(imu_stream(b_g, 1.0), 0.2);
    CHECK(initial_gyro_bias(w, opt, &why) == w.mean_gyro);
    CHECK(why.empty());
  }
  SECTION("rotating in the window: the configured bias, and why") {
    const InitWindow w = init_window(imu_stream(b_g, 1.0, 0.1), 0.2);
    CHECK(initial_gyro_bias(w, opt, &why) == opt.init_gyro_bias);
    CHECK(why.find("gyro moves") != std::string::npos);
    CHECK(why.find("init_rest_max_gyro_std") != std::string::npos);
  }
  SECTION("a shaking accelerometer: the configured bias, and why") {
    auto imu = imu_stream(b_g, 1.0);
    for (std::size_t k = 0; k < imu.size(); ++k) imu[k].accel.x() += (k % 4 < 2) ? 0.3 : -0.3;
    const InitWindow w = init_window(imu, 0.2);
    CHECK(initial_gyro_bias(w, opt, &why) == opt.init_gyro_bias);
    CHECK(why.find("accelerometer moves") != std::string::npos);
  }
  SECTION("one sample: no σ, no rest estimate") {
    const InitWindow w = init_window(imu_stream(b_g, 1.0), 0.0);
    CHECK(initial_gyro_bias(w, opt, &why) == opt.init_gyro_bias);
    CHECK(why.find("1 IMU sample") != std::string::npos);
  }
  SECTION("the thresholds decide") {
    const InitWindow w = init_window(imu_stream(b_g, 1.0), 0.2);
    opt.init_rest_max_gyro_std = 1e-3;  // below the ±2e-3 rad/s of the stream
    CHECK(initial_gyro_bias(w, opt, &why) == opt.init_gyro_bias);
    CHECK_FALSE(why.empty());
  }
}

TEST_CASE("run_filter: a gyro bias of 4.6 deg/s at rest, from the window instead of 0", "[ekf][init]") {
  // 10 s standing still, no detections: with the bias from the window the yaw stays put; with the
  // configured 0 it runs off at the bias rate (the EuRoC V1_02 ADIS16448 has 0.076 rad/s about z).
  const Vec3 b_g(0.002, -0.02, 0.08);
  const auto imu = imu_stream(b_g, 10.0);
  const ImuNoiseParams noise{1.7e-4, 2e-5, 2e-3, 3e-3};
  FilterOptions opt;
  opt.init_gyro_bias_from_rest = true;
  Last rest;
  const FilterRunSummary s = run_filter(imu, {}, opt, noise, Pose(), rest);
  CHECK(s.gyro_bias_from_rest);
  CHECK(s.gyro_bias_rest_refused.empty());
  CHECK((s.init_gyro_bias - b_g).norm() < 1e-4);
  CHECK((rest.first.b_g - s.init_gyro_bias).norm() == 0.0);
  CHECK(std::abs(yaw_deg(rest.last.q_W_I)) < 0.05);

  opt.init_gyro_bias_from_rest = false;
  Last zero;
  const FilterRunSummary s0 = run_filter(imu, {}, opt, noise, Pose(), zero);
  CHECK_FALSE(s0.gyro_bias_from_rest);
  CHECK(s0.init_gyro_bias.isZero());
  CHECK(std::abs(yaw_deg(zero.last.q_W_I)) > 40.0);  // 0.08 rad/s for 10 s = 46 deg

  // Moving from the first sample: refused, the configured bias, and the reason in the summary.
  opt.init_gyro_bias_from_rest = true;
  Last moving;
  const FilterRunSummary s1 = run_filter(imu_stream(b_g, 2.0, 0.05), {}, opt, noise, Pose(), moving);
  CHECK_FALSE(s1.gyro_bias_from_rest);
  CHECK(s1.init_gyro_bias.isZero());
  CHECK(s1.gyro_bias_rest_refused.find("gyro moves") != std::string::npos);
}

TEST_CASE("initialize: roll and pitch from the mean accelerometer less the configured accelerometer bias",
          "[ekf][init]") {
  // A tilted IMU at rest whose accelerometer reads R_W_Iᵀ g + b_a; with init_accel_bias = b_a the initial
  // attitude is the true roll and pitch (yaw 0), and the bias state starts at b_a.
  const Vec3 rpy(0.2, -0.1, 0.0);
  const Mat3 R_W_I = math::from_euler_zyx(rpy);
  const Vec3 b_a(0.3, -0.2, 0.15);
  const Vec3 f = R_W_I.transpose() * Vec3(0.0, 0.0, 9.81) + b_a;
  FilterOptions opt;
  opt.init_accel_bias = b_a;
  Filter filter(opt, ImuNoiseParams{1e-3, 1e-4, 1e-2, 1e-3}, Pose());
  filter.initialize(0, Vec3::Zero(), f, f);
  const Vec3 est = math::euler_zyx(filter.core().q_W_I.toRotationMatrix());
  CHECK((est - rpy).norm() < 1e-12);  // 1.6 deg off if the bias were added instead
  CHECK((filter.core().b_a - b_a).norm() == 0.0);
}

// run_filter's schedule: an image between two IMU samples is processed after propagating to its stamp
// with the IMU sample linearly interpolated there, an image on an IMU stamp after that sample, and images
// outside the IMU span are rejected. Checked against a filter stepped by hand on a stream whose gyro and
// accelerometer change from sample to sample (an interpolation error of one sample's change shows at
// 1e-7 rad over the second; the comparison is to 1e-13).
TEST_CASE("run_filter: images between IMU samples see the IMU linearly interpolated at their stamp",
          "[ekf][init]") {
  std::vector<ImuSample> imu;
  const Timestamp t0 = from_seconds(5.0);
  for (int k = 0; k <= 200; ++k) {
    const double t = k / 200.0;
    ImuSample m;
    m.t_ns = t0 + from_seconds(t);
    m.gyro = Vec3(0.3 * std::sin(7.0 * t), 0.8 * t, -0.4 + 0.6 * std::cos(5.0 * t));
    m.accel = Vec3(0.5 * t, -0.3 + std::sin(9.0 * t), 9.81 + 0.4 * std::cos(6.0 * t));
    imu.push_back(m);
  }
  // 30 Hz images, 1.7 ms after an IMU stamp mostly, one exactly on a stamp, one before and one after the
  // IMU span.
  std::vector<ImageDetections> images;
  images.push_back({t0 - from_seconds(0.01), {}});
  for (int j = 0; j < 30; ++j) images.push_back({t0 + from_seconds(j / 30.0 + 0.0017), {}});
  images.push_back({t0 + from_seconds(1.0), {}});  // the last IMU stamp
  images.push_back({t0 + from_seconds(1.002), {}});
  std::sort(images.begin(), images.end(), [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });

  struct Trace : FilterObserver {
    std::vector<std::pair<Timestamp, CoreState>> imu, image;
    void on_imu(const Filter& f) override { imu.emplace_back(f.time(), f.core()); }
    void on_image(Filter& f, const FrameResult& r) override { image.emplace_back(r.t_ns, f.core()); }
  } run;
  const ImuNoiseParams noise{1.7e-4, 2e-5, 2e-3, 3e-3};
  FilterOptions opt;
  const FilterRunSummary s = run_filter(imu, images, opt, noise, Pose(), run);
  CHECK(s.images == images.size() - 2);  // all but the two outside the IMU span

  // By hand.
  const InitWindow w = init_window(imu, opt.init_window_s);
  Vec3 b_g0 = initial_gyro_bias(w, opt, nullptr);
  Filter f(opt, noise, Pose());
  f.initialize(imu[0].t_ns, imu[0].gyro, imu[0].accel, w.mean_accel, &b_g0);
  std::vector<std::pair<Timestamp, CoreState>> imu_ref{{f.time(), f.core()}}, image_ref;
  for (std::size_t k = 1; k < imu.size(); ++k) {
    const ImuSample& a = imu[k - 1];
    const ImuSample& b = imu[k];
    for (const auto& im : images)
      if (im.t_ns > a.t_ns && im.t_ns < b.t_ns) {
        const double u = to_seconds(im.t_ns - a.t_ns) / to_seconds(b.t_ns - a.t_ns);
        f.propagate(im.t_ns, (1.0 - u) * a.gyro + u * b.gyro, (1.0 - u) * a.accel + u * b.accel);
        f.update({});
        image_ref.emplace_back(im.t_ns, f.core());
      }
    f.propagate(b.t_ns, b.gyro, b.accel);
    imu_ref.emplace_back(f.time(), f.core());
    for (const auto& im : images)
      if (im.t_ns == b.t_ns) {
        f.update({});
        image_ref.emplace_back(im.t_ns, f.core());
      }
  }
  // run's image trace also holds the two rejected images (before and after the IMU span).
  REQUIRE(run.image.size() == image_ref.size() + 2);
  CHECK(run.image.front().first == images.front().t_ns);
  CHECK(run.image.back().first == images.back().t_ns);
  const auto same = [](const CoreState& x, const CoreState& y) {
    return (x.p_W_I - y.p_W_I).norm() < 1e-13 && (x.v_W_I - y.v_W_I).norm() < 1e-13 &&
           x.q_W_I.angularDistance(y.q_W_I) < 1e-13;
  };
  for (std::size_t i = 0; i < image_ref.size(); ++i) {
    INFO("image " << i);
    CHECK(run.image[i + 1].first == image_ref[i].first);
    CHECK(same(run.image[i + 1].second, image_ref[i].second));
  }
  REQUIRE(run.imu.size() == imu_ref.size());
  for (std::size_t i = 0; i < imu_ref.size(); ++i) {
    INFO("IMU sample " << i);
    CHECK(run.imu[i].first == imu_ref[i].first);
    CHECK(same(run.imu[i].second, imu_ref[i].second));
  }
}
