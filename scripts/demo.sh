#!/usr/bin/env bash
# The main job on the embedded default data (datasets/sample: 30 s, 4 objects, simulated PoET-like
# detections): run the filter with roe's defaults and with the paper's exact settings, evaluate both
# against the dataset's ground truth, and print the paper-style table. Outputs go to out/demo/.
set -euo pipefail
ROE=${1:-build/roe}
cd "$(dirname "$0")/.."
OUT=out/demo
mkdir -p "$OUT"
for cfg in default paper; do
  echo "== roe run datasets/sample --config configs/$cfg.json"
  "$ROE" run datasets/sample --config "configs/$cfg.json" --out "$OUT/run-$cfg" --force
  echo
  echo "== roe eval $OUT/run-$cfg --gt datasets/sample"
  plot=()
  if /usr/bin/python3 -c "import matplotlib" 2>/dev/null; then plot=(--plot); fi
  "$ROE" eval "$OUT/run-$cfg" --gt datasets/sample --out "$OUT/eval-$cfg" --label "$cfg" --force "${plot[@]}"
  echo
done
echo "== roe eval --summary (the paper's Table I layout; RMSE after SE(3) alignment)"
"$ROE" eval --summary "$OUT/eval-default" "$OUT/eval-paper" --out "$OUT/table.md" --force
echo
echo "Run folders: $OUT/run-default $OUT/run-paper   Evaluations (report.json, CSVs, plots/): $OUT/eval-*"
