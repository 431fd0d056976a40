#!/usr/bin/env bash
# The filter and the RTS smoother (issue 41), old and new binaries interleaved in one session:
#   scripts/bench-filter-pair.sh BUILD OLD_DIR      e.g. build /work/base-d95e457
# OLD_DIR holds the old bench_filter and roe. ROUNDS rounds (default 3) of `bench_filter REPS` (default 9)
# new, old, new, old ... on CPUS (default 1: one core, so the smoother runs on one thread; CPUS=0,1 lets
# it use two), then RUNS (default 7) whole-process `roe run` of paper-seq4 per binary and config, new and
# old alternating: the default config (RTS smoother, states at the IMU rate) and the same with
# "output": {"rate": "images"} (the smoother forms the covariance at the image rows only since issue 41), and
# the same two configs on the 142 s, 200 Hz handheld-size case (paper-seq2, 3 objects, --duration 142;
# HANDHELD=0 skips it), with the run folder's size; and (LEVELS=1, the default) the new binary's
# `--output standard` and `--output minimal` on both.
# Prints the machine, the load before and after, every bench_filter line of every round, and the medians:
# bench_filter's filter CPU and backward-pass times per rate, roe run's wall and CPU (user + system).
# On a loaded machine compare the CPU times and the ratios, not the wall times.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=$(readlink -f "${1:-build}")
OLD=$(readlink -f "${2:?OLD_DIR with the old bench_filter and roe}")
ROUNDS=${ROUNDS:-3}
REPS=${REPS:-9}
RUNS=${RUNS:-7}
CPUS=${CPUS:-1}
PY=/usr/bin/python3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "machine: $(lscpu | sed -n 's/^Model name: *//p' | head -1), $(nproc) cores; load $(cut -d' ' -f1-3 /proc/loadavg); date: $(date -u +%FT%TZ); taskset -c $CPUS"
for ((r = 1; r <= ROUNDS; r++)); do
  for tag in new old; do
    dir=$BUILD
    [ "$tag" = old ] && dir=$OLD
    taskset -c "$CPUS" "$dir/bench_filter" "$REPS" >"$work/bench-$tag-$r.txt"
    sed "s/^/$tag $r | /" "$work/bench-$tag-$r.txt"
  done
done
$PY - "$work" "$ROUNDS" <<'PY'
import re, statistics, sys
work, rounds = sys.argv[1], int(sys.argv[2])
num = r"([0-9.]+)"
for tag in ("new", "old"):
    rows = {}
    for r in range(1, rounds + 1):
        for line in open(f"{work}/bench-{tag}-{r}.txt"):
            m = re.match(r"\s+(200|400)\s+\d+\s+\d+\s+" + num + r" \(\s*" + num + r"\)\s+" + num, line)
            if m:
                rows.setdefault((m[1], "filter CPU"), []).append(float(m[4]))
            m = re.search(r"^\s+(200|400) RTS smoother: filter while recording " + num + r" .*backward pass " + num +
                          r" .*of all threads " + num + r" .*one thread " + num, line)
            if m:
                rows.setdefault((m[1], "backward pass wall"), []).append(float(m[3]))
                rows.setdefault((m[1], "backward pass CPU, all threads"), []).append(float(m[4]))
                rows.setdefault((m[1], "backward pass CPU, one thread"), []).append(float(m[5]))
            m = re.search(r"^\s+(200|400) RTS smoother, covariance at the images only: backward pass " + num +
                          r" .*of all threads " + num, line)
            if m:
                rows.setdefault((m[1], "backward pass, covariance at images: wall"), []).append(float(m[2]))
                rows.setdefault((m[1], "backward pass, covariance at images: CPU"), []).append(float(m[3]))
            m = re.search(r"^\s+(200|400) RTS smoother, covariance after each image \(--output standard\): backward "
                          r"pass " + num + r" .*of all threads " + num, line)
            if m:
                rows.setdefault((m[1], "backward pass, covariance after each image (standard): wall"), []).append(float(m[2]))
                rows.setdefault((m[1], "backward pass, covariance after each image (standard): CPU"), []).append(float(m[3]))
    for (rate, what), v in sorted(rows.items()):
        print(f"median {tag} {rate} Hz {what}: {statistics.median(v):.2f} ms (rounds: {', '.join(f'{x:.1f}' for x in v)})")
PY
# Whole process: one dataset, then roe run per binary and config, alternating.
"$BUILD/roe" -q simulate --preset paper-seq4 --seed 1 --out "$work/seq4" >/dev/null
HANDHELD=${HANDHELD:-1}
LEVELS=${LEVELS:-1}
[ "$HANDHELD" = 1 ] && "$BUILD/roe" -q simulate --preset paper-seq2 --seed 1 --duration 142 --out "$work/handheld" >/dev/null
echo '{"output": {"rate": "images"}}' >"$work/images.json"
one() {  # one ROE TAG DATASET CONFIG_NAME [--config FILE]
  local roe=$1 tag=$2 ds=$3 name=$4
  shift 4
  rm -rf "$work/run-$tag"
  /usr/bin/time -f '%e %U %S %M' -o "$work/t" taskset -c "$CPUS" "$roe" -q run "$work/$ds" "$@" --out "$work/run-$tag" --force >/dev/null 2>&1
  local mb
  mb=$(du -sm "$work/run-$tag" | cut -f1)
  tail -n 1 "$work/t" | awk -v mb="$mb" '{printf "%.3f %.3f %.0f %s\n", $1, $2 + $3, $4 / 1024, mb}' >>"$work/run-$tag-$ds-$name"
}
datasets=seq4
[ "$HANDHELD" = 1 ] && datasets="seq4 handheld"
for ((i = 0; i < RUNS; i++)); do
  for ds in $datasets; do
    one "$BUILD/roe" new "$ds" default
    one "$OLD/roe" old "$ds" default
    one "$BUILD/roe" new "$ds" images --config "$work/images.json"
    one "$OLD/roe" old "$ds" images --config "$work/images.json"
    if [ "$LEVELS" = 1 ]; then  # roe run --output (new only: the old binary has no levels)
      one "$BUILD/roe" new "$ds" standard --output standard
      one "$BUILD/roe" new "$ds" minimal --output minimal
    fi
  done
done
median() {  # median COLUMN FILE
  sort -n -k"$1" "$2" | awk -v c="$1" '{a[NR]=$c} END {print a[int((NR+1)/2)]}'
}
for ds in $datasets; do
  label=paper-seq4
  [ "$ds" = handheld ] && label="handheld-size (paper-seq2 142 s, 200 Hz)"
  for name in default images standard minimal; do
    for tag in new old; do
      f=$work/run-$tag-$ds-$name
      [ -f "$f" ] || continue
      echo "median $tag roe run $label ($name): $(median 1 "$f") s wall, $(median 2 "$f") s CPU, $(median 3 "$f") MB max RSS, run folder $(median 4 "$f") MB ($RUNS runs)"
    done
  done
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
