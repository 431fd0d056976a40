#!/usr/bin/env bash
# Whole-process `roe eval` of the 1,000,000-pose pair of bench_eval (issue 24: parse, associate, align,
# metrics, write <= 0.5 s), old and new binaries interleaved in one session, median of RUNS runs each:
# wall time and CPU time (user + system; on a loaded machine the CPU time is the steadier figure).
#   scripts/bench-eval-pair.sh BUILD [OLD_ROE] [N=1000000]     e.g. build /tmp/roe-before
# The pair is written once by BUILD/bench_eval (kept in $DIR, default /tmp/roe_bench_eval_pair).
# Without output files (--no-out) and with them (--out: the six matched/aligned/error tables + JSON).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${1:-build}
NEW=$(readlink -f "$BUILD/roe")
OLD=${2:+$(readlink -f "$2")}
N=${3:-1000000}
RUNS=${RUNS:-7}
DIR=${DIR:-/tmp/roe_bench_eval_pair}
"$BUILD/bench_eval" "$N" "$DIR" keep >/dev/null
echo "machine: $(lscpu | sed -n 's/^Model name: *//p' | head -1), $(nproc) cores; load $(cut -d' ' -f1-3 /proc/loadavg); date: $(date -u +%FT%TZ); $N poses"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
one() {  # one ROE TAG MODE -> appends "wall cpu rss" to $work/TAG-MODE
  local out=(--no-out)
  [ "$3" = out ] && out=(--out "$work/$2-out" --force)
  /usr/bin/time -f '%e %U %S %M' -o "$work/t" "$1" -q eval "$DIR/est.tum" --gt "$DIR/gt.csv" "${out[@]}" >/dev/null
  tail -n 1 "$work/t" | awk '{printf "%.3f %.3f %.0f\n", $1, $2 + $3, $4 / 1024}' >>"$work/times-$2-$3"
}
median() {  # median COLUMN FILE
  sort -n -k"$1" "$2" | awk -v c="$1" '{a[NR]=$c} END {print a[int((NR+1)/2)]}'
}
for mode in no-out out; do
  runs=$RUNS
  [ "$mode" = out ] && runs=$(( (RUNS + 1) / 2 ))
  for ((i = 0; i < runs; i++)); do
    one "$NEW" new "$mode"
    [ -n "$OLD" ] && one "$OLD" old "$mode"
  done
  printf '%-8s new: %s s wall, %s s CPU, %s MB' "$mode" "$(median 1 "$work/times-new-$mode")" "$(median 2 "$work/times-new-$mode")" "$(median 3 "$work/times-new-$mode")"
  [ -n "$OLD" ] && printf ' | old: %s s wall, %s s CPU, %s MB' "$(median 1 "$work/times-old-$mode")" "$(median 2 "$work/times-old-$mode")" "$(median 3 "$work/times-old-$mode")"
  echo " ($runs runs each)"
done
if [ -n "$OLD" ]; then  # the same results, byte for byte (report.json names its own folder)
  one "$NEW" new out && one "$OLD" old out
  for f in "$work/new-out"/*; do
    b=$(basename "$f")
    [ "$b" = report.json ] && continue
    cmp -s "$f" "$work/old-out/$b" || echo "DIFFERENT: $b"
  done
  diff <(grep -v '"dir"' "$work/new-out/report.json") <(grep -v '"dir"' "$work/old-out/report.json") >/dev/null ||
    echo "DIFFERENT: report.json"
  echo "outputs compared with the old binary's"
fi
