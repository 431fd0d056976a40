// fuzz_replay: the fuzz targets' corpora as ordinary tests of the normal build (issue 53; docs/TESTING.md,
// "Fuzzing"). One executable holds every harness tests/fuzz/fuzz_*.cpp, each compiled with its
// LLVMFuzzerTestOneInput renamed (cmake/extra-fuzz.cmake; the generated fuzz_replay_targets.hpp lists
// them), and feeds it inputs as libFuzzer would replay a corpus: the empty input first, then every file
// named, each in a buffer of exactly its size. libFuzzer itself runs in the separate clang build
// (`make fuzz`, scripts/fuzz.sh).
//
//   fuzz_replay TARGET [--timeout S] [--memory-mb N] PATH...   PATH: a file, or a folder (its files, sorted)
//   fuzz_replay --list                                          the targets, one a line
//
// A finding is what libFuzzer would report: an exception other than roe::InputError / DataError leaving
// the harness (reported with the input's path, exit 1, the other inputs still replayed), a crash (the
// process dies of its signal; the line naming the input was printed before it ran), an input that runs
// longer than --timeout (default 30 s: exit 1) or an allocation beyond --memory-mb (default 2048, the
// address space; not under AddressSanitizer, which reserves its own). Bad usage: exit 2.
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <cxxabi.h>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <typeinfo>
#include <vector>

#include "fuzz_replay_targets.hpp"

#if defined(__SANITIZE_ADDRESS__)
#define ROE_REPLAY_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define ROE_REPLAY_ASAN 1
#endif
#endif

namespace fs = std::filesystem;

namespace {

struct Args {
  const roe::fuzz::ReplayTarget* target = nullptr;
  unsigned timeout_s = 30;
  unsigned long memory_mb = 2048;
  std::vector<fs::path> inputs;
};

[[noreturn]] void usage(const std::string& why) {
  std::fprintf(stderr,
               "fuzz_replay: %s\nusage: fuzz_replay TARGET [--timeout S] [--memory-mb N] PATH...\n"
               "       fuzz_replay --list\n",
               why.c_str());
  std::exit(2);
}

unsigned long positive(const std::string& option, const char* value) {
  if (value == nullptr) usage(option + " needs a value");
  char* end = nullptr;
  const unsigned long v = std::strtoul(value, &end, 10);
  if (*value < '0' || *value > '9' || *end != '\0' || v == 0 || v > 1000000) {
    usage(option + ": expected an integer in [1, 1000000], got '" + value + "'");
  }
  return v;
}

/// The files a PATH names: itself, or a folder's regular files sorted by name (libFuzzer's corpus layout).
void add_inputs(const fs::path& p, std::vector<fs::path>& out) {
  std::error_code ec;
  if (fs::is_directory(p, ec)) {
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(p, ec))
      if (e.is_regular_file(ec)) files.push_back(e.path());
    if (ec) usage("cannot list " + p.string() + ": " + ec.message());
    std::sort(files.begin(), files.end());
    out.insert(out.end(), files.begin(), files.end());
  } else if (fs::is_regular_file(p, ec)) {
    out.push_back(p);
  } else {
    usage("no such file or folder: " + p.string());
  }
}

Args parse(int argc, char** argv) {
  if (argc >= 2 && std::string(argv[1]) == "--list") {
    for (const auto& t : roe::fuzz::kReplayTargets) std::printf("%s\n", t.name);
    std::exit(0);
  }
  if (argc < 2) usage("no target given");
  Args a;
  for (const auto& t : roe::fuzz::kReplayTargets)
    if (std::string(argv[1]) == t.name) a.target = &t;
  if (a.target == nullptr) usage(std::string("unknown target '") + argv[1] + "' (fuzz_replay --list)");
  for (int i = 2; i < argc; ++i) {
    const std::string s = argv[i];
    if (s == "--timeout") {
      a.timeout_s = static_cast<unsigned>(positive(s, i + 1 < argc ? argv[++i] : nullptr));
    } else if (s == "--memory-mb") {
      a.memory_mb = positive(s, i + 1 < argc ? argv[++i] : nullptr);
    } else if (!s.empty() && s[0] == '-') {
      usage("unknown option " + s);
    } else {
      add_inputs(s, a.inputs);
    }
  }
  return a;
}

char g_timeout_message[256];

void on_alarm(int) {
  // async-signal-safe: write(2) and _exit(2) only.
  const ssize_t n = ::write(STDERR_FILENO, g_timeout_message, std::strlen(g_timeout_message));
  (void)n;
  ::_exit(1);
}

std::string type_name(const std::type_info& t) {
  int status = 0;
  std::unique_ptr<char, void (*)(void*)> d(abi::__cxa_demangle(t.name(), nullptr, nullptr, &status), std::free);
  return status == 0 && d ? d.get() : t.name();
}

/// Runs the harness on one input; returns the finding's description, empty when the input was clean.
std::string replay_one(const Args& a, const std::string& label, const std::vector<char>& bytes) {
  std::printf("  %s (%zu bytes)\n", label.c_str(), bytes.size());
  std::fflush(stdout);  // before the input runs: a crash leaves this line as the last one
  std::snprintf(g_timeout_message, sizeof g_timeout_message,
                "fuzz_replay: FINDING: %s on %s: still running after %u s (--timeout)\n", a.target->name,
                label.c_str(), a.timeout_s);
  // Exactly the input's size on the heap, as libFuzzer passes it: a read past its end is a sanitizer report.
  std::unique_ptr<std::uint8_t[]> data(new std::uint8_t[bytes.size()]);
  std::copy(bytes.begin(), bytes.end(), data.get());
  ::alarm(a.timeout_s);
  std::string finding;
  try {
    a.target->run(data.get(), bytes.size());
  } catch (const std::exception& e) {
    finding = "uncaught " + type_name(typeid(e)) + ": " + e.what();
  } catch (...) {
    finding = "uncaught exception of an unknown type";
  }
  ::alarm(0);
  return finding;
}

std::vector<char> read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) usage("cannot read " + p.string());
  return std::vector<char>(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

}  // namespace

int main(int argc, char** argv) {
  const Args a = parse(argc, argv);
#ifndef ROE_REPLAY_ASAN
  // libFuzzer's -rss_limit_mb / -malloc_limit_mb, as a limit of the address space: an allocation beyond it
  // throws std::bad_alloc, which no reader may let escape.
  const rlim_t bytes = static_cast<rlim_t>(a.memory_mb) << 20;
  const struct rlimit lim = {bytes, bytes};
  if (::setrlimit(RLIMIT_AS, &lim) != 0) std::perror("fuzz_replay: setrlimit");
#endif
  struct sigaction sa = {};
  sa.sa_handler = on_alarm;
  ::sigaction(SIGALRM, &sa, nullptr);
  std::printf("fuzz_replay %s: the empty input and %zu files\n", a.target->name, a.inputs.size());
  int findings = 0;
  const auto report = [&](const std::string& label, const std::string& finding) {
    if (finding.empty()) return;
    ++findings;
    std::fprintf(stderr, "fuzz_replay: FINDING: %s on %s: %s\n", a.target->name, label.c_str(), finding.c_str());
  };
  report("the empty input", replay_one(a, "the empty input", {}));
  for (const fs::path& p : a.inputs) report(p.string(), replay_one(a, p.string(), read_file(p)));
  std::printf("fuzz_replay %s: %zu inputs, %d findings\n", a.target->name, a.inputs.size() + 1, findings);
  return findings == 0 ? 0 : 1;
}
