#!/usr/bin/env bash
# Reproduces the table of docs/RESULTS.md: for paper-seq1 … paper-seq8 (seed 1), simulate the
# sequence, run the filter with configs/paper.json (and configs/default.json), compute the metrics
# (scripts/run_metrics.py) and print a Markdown table.
# usage: scripts/reproduce-tables.sh [ROE_BINARY] [WORK_DIR]
#
# The paper's Tables I-III (docs/REPRODUCTION.md): one sweep, configs/sweeps/paper-tables.json (26 runs of
# 60 s), run with JOBS parallel shards (default 2), aggregated, then printed next to the paper's numbers
# (read from ../shared/paper.tex, or $PAPER_TEX):
# usage: scripts/reproduce-tables.sh --paper [ROE_BINARY] [WORK_DIR]
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
if [[ "${1:-}" == "--paper" ]]; then
  shift
  roe="${1:-$here/build/roe}"
  work="${2:-$(mktemp -d)}"
  jobs="${JOBS:-2}"
  start=$(date +%s.%N)
  "$roe" sweep plan "$here/configs/sweeps/paper-tables.json" --out "$work/sweep" -q
  pids=()
  for ((i = 0; i < jobs; i++)); do
    "$roe" sweep run "$work/sweep" --shard "$i/$jobs" -q & pids+=($!)
  done
  for p in "${pids[@]}"; do wait "$p" || true; done   # a failed job is reported by status and the tables
  end=$(date +%s.%N)
  "$roe" sweep status "$work/sweep" >&2
  "$roe" sweep aggregate "$work/sweep" --out "$work/aggregate" --group-by dataset --force -q
  echo "sweep of $("$roe" sweep status "$work/sweep" --json | /usr/bin/python3 -c 'import json,sys; print(json.load(sys.stdin)["total"])') jobs with $jobs shards: $(/usr/bin/python3 -c "print('%.1f' % ($end - $start))") s (plan + run); aggregate in $work/aggregate" >&2
  /usr/bin/python3 "$here/scripts/paper_tables.py" "$work/aggregate" "${PAPER_TEX:-$here/../shared/paper.tex}"
  exit 0
fi
roe="${1:-$here/build/roe}"
work="${2:-$(mktemp -d)}"
seed="${SEED:-1}"
mkdir -p "$work"
for config in paper default; do
  echo
  echo "### configs/$config.json (seed $seed)"
  echo
  echo "| sequence | objects | fused RMSE x, y, z [m] | fused RMSE roll, pitch, yaw [deg] | raw per-object RMSE x, y, z [m] (median) | fused <= median raw / 2 |"
  echo "|---|---|---|---|---|---|"
  for i in 1 2 3 4 5 6 7 8; do
    ds="$work/paper-seq$i"
    [ -d "$ds" ] || "$roe" simulate --preset "paper-seq$i" --seed "$seed" --out "$ds" -q
    run="$work/run-$config-seq$i"
    if ! "$roe" run "$ds" --config "$here/configs/$config.json" --out "$run" --force -q 2> "$work/err-$config-$i.txt"; then
      echo "| $i | - | run failed: $(tail -1 "$work/err-$config-$i.txt") | | | |"
      continue
    fi
    /usr/bin/python3 "$here/scripts/run_metrics.py" "$run" "$ds" > "$work/metrics-$config-$i.json"
    /usr/bin/python3 - "$work/metrics-$config-$i.json" "$i" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
f = ", ".join("%.3f" % v for v in m["fused_pos_rmse_m"])
e = ", ".join("%.2f" % v for v in m["fused_euler_rmse_deg"])
r = ", ".join("%.3f" % v for v in m["raw_median_m"])
print("| %s | %d | %s | %s | %s | %s |" % (sys.argv[2], m["objects"], f, e, r, "yes" if m["criterion_fused_le_half_median_raw"] else "**no**"))
PY
  done
done
