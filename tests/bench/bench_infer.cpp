// Per-frame time of the PoET pipeline parts on this machine: OpenCV Darknet detector (+ NMS) and
// the LibTorch pose head, for a bundle (default: the committed tiny one).
//   bench_infer [BUNDLE_DIR] [FRAMES]
// The PoET-sized bundle: /usr/bin/python3 tests/models/gen_tiny_poet.py --full /tmp/poet_full
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "roe/infer/bundle.hpp"
#include "roe/infer/model.hpp"
#include "roe/infer/pose_head.hpp"
#include "roe/io/output.hpp"

namespace {
double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
void report(const char* what, std::vector<double> v) {
  std::sort(v.begin(), v.end());
  double sum = 0;
  for (double x : v) sum += x;
  std::printf("  %-22s median %9.2f ms  mean %9.2f ms  min %9.2f ms  (n=%zu)\n", what, v[v.size() / 2], sum / v.size(), v.front(),
              v.size());
}
}  // namespace

int main(int argc, char** argv) {
  using namespace roe::infer;
  const std::filesystem::path dir = argc > 1 ? argv[1] : std::filesystem::path(ROE_SOURCE_DIR) / "tests/models/tiny_poet";
  const int frames = argc > 2 ? std::atoi(argv[2]) : 20;
  if (!PoseHead::available()) {
    std::printf("roe was built without LibTorch: nothing to benchmark\n");
    return 0;
  }
  try {
    const double t0 = now_ms();
    PoetModel model(read_bundle(dir));
    const double load_ms = now_ms() - t0;
    const auto& b = model.bundle();
    std::printf("bundle %s (%s): %dx%d, %d queries, LibTorch %s on %s\n", b.model_id.c_str(), dir.string().c_str(),
                b.image.width, b.image.height, b.num_queries, PoseHead::runtime_version().c_str(), "cpu");
    std::printf("  load + self-test       %9.2f ms\n", load_ms);
    const std::string png = roe::io::read_file(b.darknet.selftest_image);
    const HostTensor blob = model.preprocess(png);
    std::vector<HostTensor> head_in;
    for (const auto& f : b.selftest.inputs) head_in.push_back(read_npy(f));
    std::vector<double> det, head, total;
    for (int i = 0; i < frames + 1; ++i) {  // the first run warms up caches and allocators
      double a = now_ms();
      auto r = model.run_detector(blob);
      double d = now_ms() - a;
      a = now_ms();
      model.run_pose_head(head_in);
      double h = now_ms() - a;
      a = now_ms();
      model.infer(png);
      double t = now_ms() - a;
      if (i == 0) continue;
      det.push_back(d);
      head.push_back(h);
      total.push_back(t);
    }
    report("detector (+NMS)", det);
    report("pose head", head);
    report("whole frame (infer)", total);
    // The pose head alone under each CPU setting, old and new side by side (docs/BENCHMARKS.md).
    struct Variant {
      const char* name;
      PoseHeadTuning tuning;
    };
    const Variant variants[] = {{"plain, 1 thread", {false, 1, true}},
                                {"plain, all threads", {false, 0, true}},
                                {"optimized, 1 thread", {true, 1, true}},
                                {"optimized, all threads", {true, 0, true}}};
    for (const auto& v : variants) {
      PoseHead h(b.pose.file, "cpu", v.tuning);
      std::vector<double> ms;
      double worst = 0;
      for (int i = 0; i < frames + 1; ++i) {
        const double a = now_ms();
        const auto out = h.forward(head_in);
        if (i > 0) ms.push_back(now_ms() - a);
        for (std::size_t k = 0; k < out.size() && k < b.selftest.outputs.size(); ++k)
          worst = std::max(worst, max_abs_diff(out[k], read_npy(b.selftest.outputs[k])));
      }
      char label[96];
      std::snprintf(label, sizeof label, "head: %s (%d)%s", v.name, PoseHead::threads(), h.optimized() || !v.tuning.optimize ? "" : " [passes failed]");
      report(label, ms);
      std::printf("    max |output - reference| %.3g\n", worst);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_infer: %s\n", e.what());
    return 1;
  }
  return 0;
}
