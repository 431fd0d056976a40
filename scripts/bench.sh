#!/usr/bin/env bash
# Runs every benchmark executable (tests/bench/*.cpp) built in the given build folder.
# Results are printed; record them with machine and date in docs/BENCHMARKS.md.
set -euo pipefail
BUILD=${1:-build}
cd "$(dirname "$0")/.."
echo "machine: $(lscpu | sed -n 's/^Model name: *//p' | head -1), $(nproc) cores; date: $(date -u +%F)"
status=0
for src in tests/bench/*.cpp; do
  [ -e "$src" ] || continue
  exe="$BUILD/$(basename "${src%.cpp}")"
  echo "== $(basename "$exe")"
  if [ -x "$exe" ]; then "$exe" || status=1; else echo "not built: $exe"; status=1; fi
done
echo "== whole process (scripts/bench-process.sh)"
scripts/bench-process.sh "$BUILD/roe" || status=1
exit $status
