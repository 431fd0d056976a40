#!/usr/bin/env bash
# Whole-process figures of the commands users call thousands of times in batch scripts (issue 24):
# wall time (median of repeated runs, hyperfine when Debian's package is installed, else a timed loop)
# and peak RSS (/usr/bin/time), and with hyperfine the mean CPU time (user + system) per run, the steadier
# figure on a loaded machine. With two binaries it measures both side by side and prints old/new ratios.
#   scripts/bench-process.sh NEW_ROE [OLD_ROE]       e.g. build/roe /tmp/roe-before
# Needs ../shared/data (the V102 pair) beside the repository. Record results in docs/BENCHMARKS.md.
# "run paper-seq4" runs each binary's own defaults (since 2026-12-02 with the RTS smoother); "run
# paper-seq4, plain" the same causal filter in both.
set -euo pipefail
cd "$(dirname "$0")/.."
NEW=$(readlink -f "${1:-build/roe}")
OLD=${2:+$(readlink -f "$2")}
RUNS=${RUNS:-15}
DATA=../shared/data/eval
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "machine: $(lscpu | sed -n 's/^Model name: *//p' | head -1), $(nproc) cores; load $(cut -d' ' -f1-3 /proc/loadavg); date: $(date -u +%FT%TZ)"

# One dataset and one run per binary, made once, so that each timed command reads the same inputs.
prepare() {  # prepare ROE TAG
  "$1" -q simulate --preset paper-seq4 --seed 1 --out "$work/$2-seq4" >/dev/null 2>&1
  "$1" -q run "$work/$2-seq4" --out "$work/$2-run" >/dev/null 2>&1
}

median_ms() {  # median_ms CMD... : "median wall ms, mean CPU ms" over $RUNS runs (after one warm-up)
  if command -v hyperfine >/dev/null; then
    hyperfine -N -i --style none --warmup 1 --runs "$RUNS" --export-json "$work/h.json" -- "$*" >/dev/null 2>&1
    /usr/bin/python3 -c 'import json,sys; r = json.load(open(sys.argv[1]))["results"][0]; print("%.1f %.1f" % (1000 * r["median"], 1000 * (r["user"] + r["system"])))' "$work/h.json"
  else
    "$@" >/dev/null 2>&1 || true
    local ts=()
    for ((i = 0; i < RUNS; i++)); do
      local t0=$(date +%s%N)
      "$@" >/dev/null 2>&1 || true
      ts+=($(( ($(date +%s%N) - t0) / 1000 )))
    done
    printf '%s\n' "${ts[@]}" | sort -n | awk '{a[NR]=$1} END {printf "%.1f -\n", a[int((NR+1)/2)]/1000}'
  fi
}

peak_mb() {  # peak RSS in MB of one run
  /usr/bin/time -f '%M' -o "$work/rss" "$@" >/dev/null 2>&1 || true
  tail -n 1 "$work/rss" | awk '{printf "%.1f\n", $1/1024}'  # after "Command exited with non-zero status"
}

# The filter as roe run's defaults were before 2026-12-02 (FilterOptions' plain defaults, causal): the same
# work for binaries before and after the default changed (docs/filter.md §12), keys both understand.
cat >"$work/plain.json" <<'JSON'
{"smoother": "none", "filter": {"require_anchor": true, "meas_sigma_p_m": 0.1, "meas_sigma_p_per_depth": 0,
 "meas_sigma_ray_m": -1, "meas_sigma_ray_per_depth": 0, "init_gyro_bias_from_rest": false, "imu_noise_scale": 1}}
JSON

# The commands: name | arguments (TAG stands for the binary's own prepared files, OUT for a fresh output).
commands=(
  "--version|--version"
  "eval V102 pair|-q eval $DATA/V102.txt --gt $DATA/V102_groundtruth.csv --out OUT --force"
  "simulate paper-seq4|-q simulate --preset paper-seq4 --seed 2 --out OUT --force"
  "run paper-seq4|-q run TAG-seq4 --out OUT --force"
  "run paper-seq4, plain|-q run TAG-seq4 --config $work/plain.json --out OUT --force"
  "calib-check|-q calib-check TAG-run"
)

bench() {  # bench ROE TAG NAME ARGS -> "ms cpu_ms mb"
  local args=${4//TAG-/$work/$2-}
  args=${args//OUT/$work/$2-out}
  # shellcheck disable=SC2086
  echo "$(median_ms "$1" $args) $(peak_mb "$1" $args)"
}

prepare "$NEW" new
[ -n "$OLD" ] && prepare "$OLD" old
printf '%-22s %12s %12s %10s' command "new ms" "new CPU ms" "new MB"
[ -n "$OLD" ] && printf ' %12s %12s %10s %8s' "old ms" "old CPU ms" "old MB" "old/new"
echo
for c in "${commands[@]}"; do
  name=${c%%|*}
  args=${c#*|}
  read -r nms ncpu nmb < <(bench "$NEW" new "$name" "$args")
  printf '%-22s %12s %12s %10s' "$name" "$nms" "$ncpu" "$nmb"
  if [ -n "$OLD" ]; then
    read -r oms ocpu omb < <(bench "$OLD" old "$name" "$args")
    printf ' %12s %12s %10s %8s' "$oms" "$ocpu" "$omb" "$(awk -v o="$oms" -v n="$nms" 'BEGIN {printf "%.1fx", o / n}')"
  fi
  echo
done
