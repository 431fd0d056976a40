#!/usr/bin/env bash
# Fuzzing roe's readers (docs/TESTING.md, "Fuzzing"). One libFuzzer target per tests/fuzz/fuzz_*.cpp.
#   scripts/fuzz.sh build            configure and build build-fuzz/ (clang, ASan + UBSan, libFuzzer)
#   scripts/fuzz.sh run SECONDS [T]  run every target (or only T) SECONDS each, niced, on its corpus
#                                    (build-fuzz/corpus/<target>, seeded from real files and test data);
#                                    findings land in build-fuzz/findings/, a summary line per target
#   scripts/fuzz.sh run-cpu SECONDS [T]  the same, but SECONDS of CPU time (user + system, read from /proc)
#                                    instead of wall time: on a shared machine a niced target gets a
#                                    fraction of a core, and the CPU time is what was fuzzed
#   scripts/fuzz.sh smoke            build, then run every target ROE_FUZZ_SMOKE_S seconds (default 10);
#                                    exit 77 when clang or libFuzzer is missing (by hand: not a CTest test)
#   scripts/fuzz.sh replay T [EXE]   replay target T's seed corpus (the files `run` starts from) through
#                                    the normal build's fuzz_replay (EXE, default build/fuzz_replay): CTest's
#                                    `fuzz/replay/T` (cmake/extra-fuzz.cmake); exit 1 on a finding. With
#                                    EXE = build-fuzz/T, the clang build's libFuzzer binary (ASan, UBSan)
#   scripts/fuzz.sh seeds T          list target T's seed files
# Environment: FUZZ_BUILD (default build-fuzz), JOBS (build jobs, default nproc), FUZZ_TIMEOUT (seconds one
# input may take before it counts as a hang, default 30: generous, for a loaded machine).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
B=${FUZZ_BUILD:-build-fuzz}
JOBS=${JOBS:-$(nproc)}
SHARED=$ROOT/../shared/data

have_toolchain() {
  command -v clang++ >/dev/null 2>&1 || return 1
  local d
  d=$(mktemp -d)
  printf '#include <cstdint>\n#include <cstddef>\nextern "C" int LLVMFuzzerTestOneInput(const uint8_t*, size_t) { return 0; }\n' >"$d/t.cpp"
  clang++ -fsanitize=fuzzer,address,undefined "$d/t.cpp" -o "$d/t" >/dev/null 2>&1
  local ok=$?
  rm -rf "$d"
  return $ok
}

build() {
  local launcher=()
  command -v ccache >/dev/null 2>&1 && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
  if [ ! -f "$B/CMakeCache.txt" ]; then
    CC=clang CXX=clang++ cmake -S . -B "$B" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DROE_FUZZ=ON \
      -DROE_BUILD_TESTS=OFF -DROE_BUILD_BENCH=OFF -DROE_WITH_TORCH=OFF "${launcher[@]}" >/dev/null
  fi
  cmake --build "$B" -j "$JOBS" --target fuzz_all
}

targets() { for f in tests/fuzz/fuzz_*.cpp; do basename "$f" .cpp; done; }

# Seed files of a target: the real files (../shared/data, when present) and the project's own data.
seeds() {
  local pats
  case "$1" in
    fuzz_csv|fuzz_dataset|fuzz_trajectory) pats='*.csv *.txt' ;;
    fuzz_json) pats='*.json' ;;
    fuzz_poet) pats='*results*.json' ;;
    fuzz_kalibr) pats='*.yaml' ;;
    fuzz_rosbag) pats='*.bag' ;;
    fuzz_mcap) pats='*.mcap' ;;
    fuzz_cdr) pats='*.mcap *.db3' ;;
    fuzz_rosbag2_metadata) pats='metadata.yaml' ;;
    fuzz_sweep) pats='*.sweep-seed' ;;
    *) pats='*' ;;
  esac
  local dirs=(tests/data tests/fuzz/seeds datasets configs)
  [ -d "$SHARED" ] && dirs+=("$SHARED")
  for p in $pats; do find "${dirs[@]}" -type f -name "$p" -size -8M 2>/dev/null; done | sort -u
}

run_one() {  # target seconds
  local t=$1 s=$2 corpus=$B/corpus/$1 log=$B/logs/${LOG_PREFIX:-}$1.log
  mkdir -p "$corpus" "$B/findings" "$B/logs"
  seeds "$t" | while read -r f; do cp -n "$f" "$corpus/seed-$(sha1sum "$f" | cut -c1-16)"; done
  # Inputs long enough for every structure of the format, short enough for many executions a second.
  local max_len=65536
  case "$t" in
    fuzz_rosbag|fuzz_mcap|fuzz_cdr) max_len=1048576 ;;
    fuzz_csv|fuzz_trajectory) max_len=8192 ;;
  esac
  local rc=0 wall=$s started=$SECONDS
  # With a CPU budget the wall limit is only a backstop; a watcher interrupts the target (SIGINT: libFuzzer
  # prints its final statistics and exits 72) once it has used the budget.
  [ -n "${CPU_BUDGET:-}" ] && wall=$((s * 20))
  nice -n "${FUZZ_NICE:-10}" "$B/$t" "$corpus" -max_total_time="$wall" -timeout="${FUZZ_TIMEOUT:-30}" -rss_limit_mb=2048 \
    -max_len=$max_len -print_final_stats=1 -artifact_prefix="$B/findings/$t-" >"$log" 2>&1 &
  local pid=$! cpu=0
  if [ -n "${CPU_BUDGET:-}" ]; then
    local tck
    tck=$(getconf CLK_TCK)
    while kill -0 "$pid" 2>/dev/null; do
      cpu=$(awk -v t="$tck" '{print int(($14 + $15) / t)}' "/proc/$pid/stat" 2>/dev/null || echo "$cpu")
      [ "$cpu" -ge "$s" ] && { kill -INT "$pid" 2>/dev/null; break; }
      sleep 5
    done
  fi
  wait "$pid" || rc=$?
  [ -n "${CPU_BUDGET:-}" ] && [ $rc -eq 72 ] && rc=0  # interrupted at the budget, as intended
  local execs
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  local what="${s} s"
  [ -n "${CPU_BUDGET:-}" ] && what="${cpu} s CPU in $((SECONDS - started)) s wall"
  echo "$t: $what, ${execs:-?} executions, corpus $(ls "$corpus" | wc -l) files, exit $rc"
  if [ $rc -ne 0 ]; then
    grep -E 'ERROR|SUMMARY|uncaught|Test unit written' "$log" | head -5
    return 1
  fi
}

run_all() {  # seconds [target]
  local s=$1 only=${2:-} failed=0
  for t in $(targets); do
    [ -n "$only" ] && [ "$t" != "$only" ] && continue
    [ -x "$B/$t" ] || { echo "$t: not built (scripts/fuzz.sh build)"; failed=1; continue; }
    run_one "$t" "$s" || failed=1
  done
  return $failed
}

case "${1:-}" in
  build) build ;;
  seeds) seeds "${2:?target}" ;;
  replay)
    t=${2:?target}
    exe=${3:-$ROOT/build/fuzz_replay}
    [ -f "tests/fuzz/$t.cpp" ] || { echo "fuzz replay: no target $t (tests/fuzz/$t.cpp)"; exit 2; }
    mapfile -t files < <(seeds "$t")
    # A libFuzzer binary of the clang build (build-fuzz/T, ASan + UBSan) runs the files it is given once.
    if [ "$(basename "$exe")" = "$t" ]; then
      exec "$exe" -timeout="${FUZZ_TIMEOUT:-30}" -rss_limit_mb=2048 "${files[@]}"
    fi
    # Each input's hang limit as in `run` (FUZZ_TIMEOUT); an input's memory as libFuzzer's -rss_limit_mb.
    exec "$exe" "$t" --timeout "${FUZZ_TIMEOUT:-30}" --memory-mb 2048 "${files[@]}"
    ;;
  run) run_all "${2:?seconds}" "${3:-}" ;;
  run-cpu) CPU_BUDGET=1 run_all "${2:?CPU seconds}" "${3:-}" ;;
  smoke)
    if ! have_toolchain; then
      echo "fuzz smoke: skipped (no clang++ with libFuzzer; Debian: apt-get install clang libclang-rt-14-dev)"
      exit 77
    fi
    build >"${TMPDIR:-/tmp}/roe-fuzz-build.log" 2>&1 || { cat "${TMPDIR:-/tmp}/roe-fuzz-build.log"; exit 1; }
    LOG_PREFIX=smoke- run_all "${ROE_FUZZ_SMOKE_S:-10}"
    ;;
  *) sed -n '2,15p' "$0"; exit 2 ;;
esac
