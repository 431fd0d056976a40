#!/usr/bin/env bash
# Benchmark of the figures and of `roe report` on a 60 s run (docs/report.md, docs/benchmarks/report.md):
#   scripts/bench-report.sh [BUILD_DIR] [DURATION_S]
# Simulates `matched-calib` (seed 7) for DURATION_S (default 60), runs the filter, then times, each
# three times (wall and CPU): the figure set alone (scripts/plot_run.py, PNG + PDF, one python process) and the whole
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
# Wall and CPU (user + sys of the process and the children it waited for): on a shared machine the wall
# time follows the load, the CPU time much less.
for what in figures report; do
  walls=(); cpus=()
  for i in 1 2 3; do
    rm -rf "$W/figs" "$W/r.html"
    if [ "$what" = figures ]; then
      cmd=("$PY" scripts/plot_run.py --eval "$W/eval" --run "$W/run" --dataset "$W/ds" --out "$W/figs" --objects all)
    else
      cmd=("$ROE" -q report "$W/run" --gt "$W/ds" --out "$W/r.html" --objects all)
    fi
    /usr/bin/time -f "%e %U %S" -o "$W/time" "${cmd[@]}" >/dev/null
    read -r e u s < "$W/time"
    walls+=("$e"); cpus+=("$(awk "BEGIN{print $u + $s}")")
  done
  [ "$what" = figures ] && echo "figures: $(ls "$W/figs" | grep -c '\.png$') PNG + $(ls "$W/figs" | grep -c '\.pdf$') PDF"
  printf "%-8s wall median %s s (%s), CPU median %s s (%s); %s s run\n" "$what" \
    "$(printf '%s\n' "${walls[@]}" | median)" "${walls[*]}" "$(printf '%s\n' "${cpus[@]}" | median)" "${cpus[*]}" "$DUR"
done
echo "report: $(stat -c %s "$W/r.html") bytes; load after: $(cut -d' ' -f1-3 /proc/loadavg)"
