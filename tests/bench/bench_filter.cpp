// bench_filter: wall time of the multi-object EKF on paper-seq4 (60 s, 4 objects) at 200 Hz and 400 Hz
// IMU, single-threaded. Reports the filter alone (run_filter with an observer that records nothing),
// propagation alone (no images), and the whole in-memory run (run_dataset: recording every state).
// Wall time and thread CPU time (CLOCK_THREAD_CPUTIME_ID) are both reported: on a shared, loaded
// machine the CPU time is the better measure of what the filter costs.
// With the RTS smoother ("smoother": "rts"): the filter while recording, the backward pass (wall, CPU of
// the calling thread and of all threads: it smooths the IMU steps on a second thread where the process may
// use two CPUs), the same pass on one thread, the recording's size, and the pass with the covariance at the
// image times only (the IMU steps' means from the segments' ends, issue 41).
// A second line per rate ("default") times the filter with roe run's built-in defaults (configs/default.json:
// camera-frame residual, split gate, detection sigmas with the learned scale, relock, IMU noise x 4), causal,
// with an observer that records nothing: what users run, without roe run's per-sample output rows.
// usage: bench_filter [repetitions=15] [--each] [--filter-only] [--rate HZ] [--time-offset]
//   --each: also print every repetition's filter wall time; --filter-only: only the filter lines (no
//   run_dataset, no smoother; for profiling the filter with perf); --rate HZ: only that IMU rate (200 or 400;
//   default both); --time-offset: both filters with the online camera-IMU time offset state (issue 49).
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <ctime>
#include <new>
#include <string>
#include <vector>

#include "roe/app/run.hpp"
#include "roe/app/simulate.hpp"
#include "roe/ekf/driver.hpp"
#include "roe/ekf/smoother.hpp"
#include "roe/sim/simulator.hpp"

using namespace roe;
using Clock = std::chrono::steady_clock;

// Heap allocations of this (single-threaded) benchmark, counted by the replaced global operator new: the
// filter's allocations per image are (with images − propagation only) / images.
static std::size_t g_allocations = 0;
void* operator new(std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace {

struct Null : ekf::FilterObserver {
  std::size_t n = 0;
  void on_imu(const ekf::Filter& f) override { n += f.time() & 1; }
};

std::vector<ekf::ImageDetections> images_of(const Dataset& d) { return ekf::group_images(d.detections.at("sim")); }

double cpu_ms() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

double process_cpu_ms() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

double min_of(const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); }

}  // namespace

int main(int argc, char** argv) {
  const int reps = argc > 1 ? std::atoi(argv[1]) : 15;
  bool each = false, filter_only = false, time_offset = false;
  std::vector<double> rates = {200.0, 400.0};
  for (int a = 2; a < argc; ++a) {
    each |= std::string(argv[a]) == "--each";
    filter_only |= std::string(argv[a]) == "--filter-only";
    if (std::string(argv[a]) == "--rate" && a + 1 < argc) rates = {std::atof(argv[++a])};
    time_offset |= std::string(argv[a]) == "--time-offset";
  }
  fmt::print("bench_filter: paper-seq4, 60 s, seed 1, FilterOptions' plain defaults; {} repetitions, median (min) [ms]\n",
             reps);
  fmt::print("{:>8} {:>7} {:>8} {:>20} {:>14} {:>20} {:>20} {:>12}\n", "IMU Hz", "images", "updates",
             "filter wall", "filter CPU (min)", "propagation only", "run_dataset", "x real time");
  for (double rate : rates) {
    sim::SimConfig c = app::sim_config_from_preset("paper-seq4");
    c.imu.rate_hz = rate;
    c.duration_s = 60.0;
    const Dataset d = sim::simulate(c, 1);
    const auto images = images_of(d);
    // FilterOptions' plain defaults, causal (as every earlier figure in docs/BENCHMARKS.md): roe run's
    // built-in defaults changed on 2026-12-02 (docs/filter.md §12) and would make the figures incomparable.
    app::RunConfig cfg;
    cfg.filter = ekf::FilterOptions{};
    cfg.estimator = store::Estimator::kFilter;
    const ekf::ImuNoiseParams noise{
        d.manifest.imu->noise.gyro_noise_density, d.manifest.imu->noise.gyro_random_walk,
        d.manifest.imu->noise.accel_noise_density, d.manifest.imu->noise.accel_random_walk};
    // run_filter picks the anchor as roe run does (ekf::choose_anchor).
    ekf::FilterOptions opt = cfg.filter;
    opt.estimate_time_offset = time_offset;
    // roe run's built-in defaults (app::RunConfig's filter, = configs/default.json), causal; the IMU noise
    // scaled as roe run scales it.
    ekf::FilterOptions dopt = app::RunConfig{}.filter;
    dopt.estimate_time_offset = time_offset;
    ekf::ImuNoiseParams dnoise = noise;
    for (double* v : {&dnoise.gyro_noise_density, &dnoise.gyro_random_walk, &dnoise.accel_noise_density,
                      &dnoise.accel_random_walk})
      *v *= dopt.imu_noise_scale;
    std::vector<double> t_filter, t_cpu, t_prop, t_run, t_rec, t_smooth, t_smooth_cpu, t_smooth_all, t_smooth_1,
        t_smooth_img, t_smooth_img_cpu, t_smooth_std, t_smooth_std_cpu, d_filter, d_cpu, d_prop;
    double rec_mb = 0.0;
    std::size_t updates = 0, d_updates = 0;
    double allocs = 0.0, d_allocs = 0.0;  // heap allocations per image (filter with images − propagation only)
    for (int r = 0; r < reps; ++r) {
      Null obs;
      std::size_t a0 = g_allocations;
      auto t0 = Clock::now();
      double c0 = cpu_ms();
      const auto s = ekf::run_filter(d.imu, images, opt, noise, d.manifest.camera->T_I_C, obs);
      t_cpu.push_back(cpu_ms() - c0);
      t_filter.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
      updates = s.updates;
      std::size_t a1 = g_allocations;
      t0 = Clock::now();
      ekf::run_filter(d.imu, {}, opt, noise, d.manifest.camera->T_I_C, obs);
      t_prop.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
      allocs = (static_cast<double>(a1 - a0) - static_cast<double>(g_allocations - a1)) / images.size();
      a0 = g_allocations;
      t0 = Clock::now();
      c0 = cpu_ms();
      const auto sd = ekf::run_filter(d.imu, images, dopt, dnoise, d.manifest.camera->T_I_C, obs);
      d_cpu.push_back(cpu_ms() - c0);
      d_filter.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
      d_updates = sd.updates;
      a1 = g_allocations;
      c0 = cpu_ms();
      ekf::run_filter(d.imu, {}, dopt, dnoise, d.manifest.camera->T_I_C, obs);
      d_prop.push_back(cpu_ms() - c0);
      d_allocs = (static_cast<double>(a1 - a0) - static_cast<double>(g_allocations - a1)) / images.size();
      if (filter_only) continue;
      t0 = Clock::now();
      const auto out = app::run_dataset(d, "sim", cfg);
      t_run.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
      ekf::FilterRecording rec;
      t0 = Clock::now();
      ekf::run_filter(d.imu, images, opt, noise, d.manifest.camera->T_I_C, obs, &rec);
      t_rec.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
      t0 = Clock::now();
      const double s0 = cpu_ms(), p0 = process_cpu_ms();
      const auto sm = ekf::smooth(rec, noise);
      t_smooth_cpu.push_back(cpu_ms() - s0);
      t_smooth_all.push_back(process_cpu_ms() - p0);
      t_smooth.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
      const double s1 = cpu_ms();
      obs.n += ekf::smooth(rec, noise, {1}).states.size() & 1;
      t_smooth_1.push_back(cpu_ms() - s1);
      // The covariance only at the image times (roe run with "output": {"rate": "images"}): the means of
      // the IMU steps from the segments' ends.
      std::vector<Timestamp> image_times;
      for (const auto& im : images) image_times.push_back(im.t_ns);
      t0 = Clock::now();
      const double s2 = cpu_ms(), p2 = process_cpu_ms();
      obs.n += ekf::smooth(rec, noise, {0, &image_times}).states.size() & 1;
      t_smooth_img_cpu.push_back(process_cpu_ms() - p2);
      t_smooth_img.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
      obs.n += static_cast<std::size_t>(cpu_ms() - s2) & 1;
      // The covariance at the first IMU step and the first after each image (roe run --output standard).
      std::vector<Timestamp> after_images{d.imu.front().t_ns};
      for (const auto& im : images) {
        const auto it = std::upper_bound(d.imu.begin(), d.imu.end(), im.t_ns,
                                         [](Timestamp t, const ImuSample& s) { return t < s.t_ns; });
        if (it != d.imu.end() && it->t_ns > after_images.back()) after_images.push_back(it->t_ns);
      }
      t0 = Clock::now();
      const double p3 = process_cpu_ms();
      obs.n += ekf::smooth(rec, noise, {0, &after_images}).states.size() & 1;
      t_smooth_std_cpu.push_back(process_cpu_ms() - p3);
      t_smooth_std.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
      obs.n += sm.states.size() & 1;
      std::size_t bytes = rec.steps.size() * sizeof(ekf::RecordedStep);
      for (const auto& nd : rec.nodes) bytes += sizeof(nd) + 8 * (nd.P.size() + nd.B.size());
      rec_mb = bytes / 1e6;
    }
    if (each) {
      fmt::print("  {:.0f} Hz, filter wall per repetition [ms]:", rate);
      for (double t : t_filter) fmt::print(" {:.1f}", t);
      fmt::print("\n");
    }
    const double mf = median(t_filter);
    if (filter_only) {
      t_run.push_back(0.0);
    }
    fmt::print(
        "{:>8.0f} {:>7} {:>8} {:>12.2f} ({:>5.2f}) {:>6.2f} ({:>5.2f}) {:>12.2f} ({:>5.2f}) {:>12.2f} ({:>5.2f}) "
        "{:>12.0f}\n",
        rate, images.size(), updates, mf, min_of(t_filter), median(t_cpu), min_of(t_cpu), median(t_prop),
        min_of(t_prop), median(t_run), min_of(t_run), 60000.0 / median(t_cpu));
    fmt::print("{:>8.0f} default: roe run's built-in filter options, causal, {} updates: filter {:.2f} ({:.2f}), "
               "CPU {:.2f} ({:.2f}), propagation only CPU {:.2f} ({:.2f}); heap allocations per image: {:.1f} "
               "(plain options {:.1f})\n",
               rate, d_updates, median(d_filter), min_of(d_filter), median(d_cpu), min_of(d_cpu), median(d_prop),
               min_of(d_prop), d_allocs, allocs);
    if (filter_only) continue;
    fmt::print("{:>8.0f} RTS smoother: filter while recording {:.2f} ({:.2f}), backward pass {:.2f} ({:.2f}), "
               "CPU of the calling thread {:.2f} ({:.2f}), of all threads {:.2f} ({:.2f}); one thread {:.2f} "
               "({:.2f}) CPU; recording {:.1f} MB\n",
               rate, median(t_rec), min_of(t_rec), median(t_smooth), min_of(t_smooth), median(t_smooth_cpu),
               min_of(t_smooth_cpu), median(t_smooth_all), min_of(t_smooth_all), median(t_smooth_1),
               min_of(t_smooth_1), rec_mb);
    fmt::print("{:>8.0f} RTS smoother, covariance at the images only: backward pass {:.2f} ({:.2f}), CPU of all "
               "threads {:.2f} ({:.2f}); ratio to the filter's CPU {:.2f}\n",
               rate, median(t_smooth_img), min_of(t_smooth_img), median(t_smooth_img_cpu), min_of(t_smooth_img_cpu),
               median(t_smooth_img_cpu) / median(t_cpu));
    fmt::print("{:>8.0f} RTS smoother, covariance after each image (--output standard): backward pass {:.2f} ({:.2f}), "
               "CPU of all threads {:.2f} ({:.2f}); ratio to the filter's CPU {:.2f}\n",
               rate, median(t_smooth_std), min_of(t_smooth_std), median(t_smooth_std_cpu), min_of(t_smooth_std_cpu),
               median(t_smooth_std_cpu) / median(t_cpu));
  }
  return 0;
}
