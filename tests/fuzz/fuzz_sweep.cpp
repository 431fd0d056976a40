// libFuzzer target: the files of a sweep the user may edit (issue 40): a sweep spec (plan_sweep, with a job
// limit so that a large product is refused, not expanded) and a sweep folder's jobs.jsonl (read_sweep). A
// job id or detection set that read_sweep accepts can never make a path outside the sweep folder.
#include <fstream>

#include "fuzz_support.hpp"
#include "roe/app/sweep.hpp"
#include "roe/io/input.hpp"
#include "roe/io/json.hpp"

namespace {

const std::filesystem::path& folder() {
  static const std::filesystem::path d = [] {
    const std::uint8_t none = 0;
    auto p = roe::fuzz::input_file(&none, 0, "spec-dir-marker").parent_path() / "sweep";
    std::filesystem::create_directories(p);
    return p;
  }();
  return d;
}

void fuzz_spec(const std::string& text) {
  roe::fuzz::expect_clean([&] {
    const auto spec = roe::io::parse_json_text(text, "spec.json");
    (void)roe::app::plan_sweep(spec, folder(), "spec.json", 1000);
  });
}

void fuzz_jobs(const std::string& text) {
  std::size_t n = 0;
  for (std::size_t start = 0; start < text.size(); ++n) {
    const std::size_t end = text.find('\n', start);
    start = end == std::string::npos ? text.size() : end + 1;
  }
  std::ofstream(folder() / "sweep.json", std::ios::trunc)
      << R"({"format": "roe-sweep/1", "roe_version": "0", "spec_file": "spec.json", "spec": {},)"
      << R"( "axes": ["dataset", "seed", "config"], "n_jobs": )" << n << "}";
  std::ofstream(folder() / "jobs.jsonl", std::ios::binary | std::ios::trunc) << text;
  roe::fuzz::expect_clean([&] {
    const auto s = roe::app::read_sweep(folder());
    for (const auto& j : s.jobs) {
      if (!roe::store::is_sweep_job_id(j.id)) __builtin_trap();
      const std::string& det = j.content.detections;
      if (!det.empty() && !roe::io::is_plain_name(det)) __builtin_trap();
    }
  });
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // The first byte picks the file: even a spec, odd a jobs.jsonl (one corpus seeds both).
  if (size == 0) return 0;
  const std::string t = roe::fuzz::text(data + 1, size - 1);
  if (data[0] % 2 == 0) fuzz_spec(t);
  else fuzz_jobs(t);
  return 0;
}
