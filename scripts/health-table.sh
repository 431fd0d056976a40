#!/usr/bin/env bash
# The measurements behind the default health limits (docs/filter.md §11) and the anchor rule (§4):
# every shipped simulator preset, datasets/sample and the EuRoC V1_02 snippet with 4 objects, each run
# with a config (default: configs/default.json), one TSV row per run: the anchor, the health figures of
# run.json and the worst-axis position and Euler RMSE (scripts/run_metrics.py, needs numpy and scipy).
# usage: scripts/health-table.sh [ROE_BINARY] [WORK_DIR] [CONFIG]     (SEEDS="1 2 3" by default)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
roe="${1:-$here/build/roe}"
work="${2:-$(mktemp -d)}"
config="${3:-$here/configs/default.json}"
seeds="${SEEDS:-1 2 3}"
snippet="$here/../shared/data/euroc_v102_snippet/mav0"
mkdir -p "$work"
printf 'dataset\tseed\texit\tanchor\tupdates\tsupported\tlongest_dr_s\tnis_median\tnis_median_ratio\tworst_axis_m\tworst_euler_deg\n'
row() {  # dataset-name seed dataset-dir
  local run="$work/run-$1-$2"
  local code=0
  nice -n 10 timeout 300 "$roe" run "$3" --config "$config" --out "$run" --force -q 2>"$run.err" || code=$?
  if [ ! -f "$run/run.json" ]; then printf '%s\t%s\t%s\t(no run.json: %s)\n' "$1" "$2" "$code" "$(tail -1 "$run.err")"; return; fi
  local worst="-	-"
  if [ -f "$3/mav0/state_groundtruth_estimate0/data.csv" ]; then
    worst=$(/usr/bin/python3 "$here/scripts/run_metrics.py" "$run" "$3" | /usr/bin/python3 -c \
      'import json,sys; j = json.load(sys.stdin); print("%.3f\t%.2f" % (max(j["fused_pos_rmse_m"]), max(j["fused_euler_rmse_deg"])))')
  fi
  /usr/bin/python3 - "$run/run.json" "$1" "$2" "$code" "$worst" <<'PY'
import json, sys
j = json.load(open(sys.argv[1])); h = j["health"]; n = j["nis"]
print("\t".join([sys.argv[2], sys.argv[3], sys.argv[4], str(j["anchor_id"]), str(j["counts"]["updates"]),
                 "%.3f" % h["supported_fraction"], "%.2f" % h["longest_dead_reckoning_s"],
                 "%.2f" % n.get("median", float("nan")), "%.2f" % h["nis_median_ratio"], sys.argv[5]]))
PY
}
for s in $seeds; do
  for p in "$here"/configs/sim/*.json; do
    name="$(basename "$p" .json)"
    ds="$work/$name-$s"
    [ -d "$ds" ] || nice -n 10 "$roe" simulate --preset "$name" --seed "$s" --out "$ds" -q
    row "$name" "$s" "$ds"
  done
  if [ -d "$snippet" ]; then
    ds="$work/euroc-$s"
    [ -d "$ds" ] || nice -n 10 "$roe" simulate --from-groundtruth "$snippet" --objects 4 --seed "$s" --out "$ds" -q
    row euroc-snippet "$s" "$ds"
  fi
done
row sample 1 "$here/datasets/sample"
