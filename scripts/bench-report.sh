#!/usr/bin/env bash
# Benchmark of the figures and of `roe report` on a 60 s run (docs/report.md, docs/benchmarks/report.md):
#   scripts/bench-report.sh [BUILD_DIR] [DURATION_S]
# Simulates `matched-calib` (seed 7) for DURATION_S (default 60), runs the filter, then times, each
# three times: the figure set alone (scripts/plot_run.py, PNG + PDF, one python process) and the whole
# `roe report` (in-process eval + calib-check + figures + HTML). Prints the median and the HTML size.
set -euo pipefail
BUILD=${1:-build}
DUR=${2:-60}
cd "$(dirname "$0")/.."
ROE=$BUILD/roe
PY=${ROE_PYTHON:-/usr/bin/python3}
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
echo "machine: $(lscpu | sed -n 's/^Model name: *//p' | head -1), $(nproc) cores; date: $(date -u +%F); load: $(cut -d' ' -f1-3 /proc/loadavg)"
"$ROE" -q simulate --preset matched-calib --seed 7 --duration "$DUR" --out "$W/ds"
"$ROE" -q run "$W/ds" --out "$W/run"
"$ROE" -q eval "$W/run" --gt "$W/ds" --out "$W/eval"
median() { sort -n | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
now() { date +%s.%N; }
for what in figures report; do
  times=()
  for i in 1 2 3; do
    rm -rf "$W/figs" "$W/r.html"
    t0=$(now)
    if [ "$what" = figures ]; then
      "$PY" scripts/plot_run.py --eval "$W/eval" --run "$W/run" --dataset "$W/ds" --out "$W/figs" --objects all >/dev/null
    else
      "$ROE" -q report "$W/run" --gt "$W/ds" --out "$W/r.html" --objects all
    fi
    t1=$(now)
    times+=("$(awk "BEGIN{print $t1 - $t0}")")
  done
  printf '%s\n' "${times[@]}" | median | xargs printf "%-8s median of 3: %.2f s (${DUR} s run; runs: ${times[*]})\n" "$what"
done
echo "figures: $(ls "$W/figs" | grep -c '\.png$') PNG + $(ls "$W/figs" | grep -c '\.pdf$') PDF"
echo "report: $(stat -c %s "$W/r.html") bytes"
