#!/usr/bin/env bash
# Old vs new figures, interleaved in one session (docs/BENCHMARKS.md, issue 37):
#   scripts/bench-figures.sh NEW_ROE OLD_ROE [ROUNDS=3]
# Simulates paper-seq4 for 300 s and 60 s (seed 1) and runs the filter once with NEW_ROE, then times,
# round by round and old/new alternating: `roe report --objects all` of both runs and `roe eval --plot` of
# the V102 pair (../shared/data/eval). Prints wall and CPU (user + sys, children included) per command,
# and the medians.
set -euo pipefail
NEW=$(readlink -f "$1"); OLD=$(readlink -f "$2"); ROUNDS=${3:-3}
cd "$(dirname "$0")/.."
DATA=$(readlink -f ../shared/data/eval)
W=${W:-$(mktemp -d)}
echo "machine: $(lscpu | sed -n 's/^Model name: *//p' | head -1), $(nproc) cores; $(date -u +%FT%TZ); load $(cut -d' ' -f1-3 /proc/loadavg)"
for d in 300 60; do
  [ -d "$W/run$d" ] && continue
  "$NEW" -q simulate --preset paper-seq4 --duration "$d" --seed 1 --out "$W/ds$d" --force
  "$NEW" -q run "$W/ds$d" --out "$W/run$d" --force 2>/dev/null
done
one() {  # one TAG CASE ROE
  local out=$W/out-$1-$2
  rm -rf "$out" "$out.html"
  case $2 in
    r300|r60) set -- "$1" "$2" "$3" report "$W/run${2#r}" --out "$out.html" --objects all ;;
    v102) set -- "$1" "$2" "$3" eval "$DATA/V102.txt" --gt "$DATA/V102_groundtruth.csv" --out "$out" --plot ;;
  esac
  /usr/bin/time -f '%e %U %S' -o "$W/t" "$3" -q "${@:4}" >/dev/null 2>&1
  read -r e u s < "$W/t"
  echo "$e $(awk "BEGIN{print $u + $s}")" >> "$W/times-$1-$2"
  printf '%-4s %-5s %6.2f s wall %6.2f s CPU (load %s)\n' "$1" "$2" "$e" "$(awk "BEGIN{print $u + $s}")" "$(cut -d' ' -f1 /proc/loadavg)"
}
median() { sort -n -k"$1" "$2" | awk -v c="$1" '{a[NR]=$c} END {print a[int((NR+1)/2)]}'; }
rm -f "$W"/times-*
for ((i = 0; i < ROUNDS; i++)); do
  for c in r300 r60 v102; do
    one new "$c" "$NEW"
    one old "$c" "$OLD"
  done
done
for c in r300 r60 v102; do
  echo "$c median: new $(median 1 "$W/times-new-$c") s wall, $(median 2 "$W/times-new-$c") s CPU | old $(median 1 "$W/times-old-$c") s wall, $(median 2 "$W/times-old-$c") s CPU"
done
echo "HTML: new $(stat -c %s "$W/out-new-r300.html") / old $(stat -c %s "$W/out-old-r300.html") bytes (300 s)," \
     "new $(stat -c %s "$W/out-new-r60.html") / old $(stat -c %s "$W/out-old-r60.html") bytes (60 s)"
