#!/usr/bin/env bash
# Regenerates the embedded default dataset datasets/sample (called by `make sample`):
# a 30 s paper-seq4 sequence (4 objects), seed 1. The output is deterministic: running this twice
# gives byte-identical files, so `git status` shows no change unless the simulator changed.
# Usage: scripts/make-sample.sh [path/to/roe]
set -euo pipefail
ROE=${1:-build/roe}
cd "$(dirname "$0")/.."
ROE=$(cd "$(dirname "$ROE")" && pwd)/$(basename "$ROE")
[ -x "$ROE" ] || { echo "make-sample: roe binary not found: $ROE (build first)" >&2; exit 2; }
TMP=$(mktemp -d datasets/.sample.XXXXXX)
trap 'rm -rf "$TMP"' EXIT
"$ROE" -q simulate --preset paper-seq4 --seed 1 --duration 30 --out "$TMP/sample"
# Keep the hand-written README; everything else is generated.
[ -f datasets/sample/README.md ] && cp datasets/sample/README.md "$TMP/sample/README.md"
rm -rf datasets/sample
mv "$TMP/sample" datasets/sample
echo "datasets/sample regenerated ($(du -sh datasets/sample | cut -f1)):"
"$ROE" simulate --preset paper-seq4 --seed 1 --duration 30 --out "$TMP/check" | sed -n '2,5p'
