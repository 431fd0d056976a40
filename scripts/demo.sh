#!/usr/bin/env bash
# The main job on the embedded default data: run the filter on datasets/sample, evaluate it against
# the dataset's ground truth and print the paper-style table. Outputs go to out/demo/.
set -euo pipefail
ROE=${1:-build/roe}
cd "$(dirname "$0")/.."
OUT=out/demo
mkdir -p "$OUT"
echo "== roe run datasets/sample (configs/default.json)"
"$ROE" run datasets/sample --config configs/default.json --out "$OUT/run" --force
echo
echo "== roe eval $OUT/run --gt datasets/sample"
"$ROE" eval "$OUT/run" --gt datasets/sample --out "$OUT/eval" --force
if /usr/bin/python3 -c "import matplotlib" 2>/dev/null; then
  "$ROE" eval "$OUT/run" --gt datasets/sample --out "$OUT/eval" --force --plot -q
  echo
  echo "Plots: $(ls "$OUT"/eval/plots/*.png 2>/dev/null | tr '\n' ' ')"
fi
echo "Run folder: $OUT/run   Evaluation: $OUT/eval"
