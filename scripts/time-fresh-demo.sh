#!/usr/bin/env bash
# Times `make demo` on a fresh Debian bookworm (issue 38: target <= 4 min on 2 cores), end to end: a
# minimal bookworm made by debootstrap (what the debian:bookworm image holds: the required packages and
# apt), a clean clone of a commit of this repository, then `make demo` in a chroot pinned to 2 CPUs.
# Reports each recipe line of `make demo` (install-deps: apt update, download and install; configure;
# build; demo) with its wall and CPU time (user+sys of its processes), the packages apt added, the load
# average before and after, and then checks the refusals of the commands whose libraries the demo build
# does not have (roe refine, roe import realsense, roe infer: exit 2 naming the Debian package).
#   sudo scripts/time-fresh-demo.sh [--rev REV] [--cpus LIST] [--work DIR] [--mirror URL] [--keep]
#     --rev REV      the commit to clone (default HEAD; committed work only)
#     --cpus LIST    taskset CPU list the chroot runs on (default 0,1: 2 cores)
#     --work DIR     scratch folder (default /var/tmp/roe-fresh-demo); the bootstrapped base is cached in
#                    DIR/base (not timed; delete it for a new one), each run gets a copy in DIR/run
#     --mirror URL   Debian mirror (default: the host's, else http://deb.debian.org/debian)
#     --keep         keep DIR/run afterwards (default: removed)
# Needs root, debootstrap (apt-get install debootstrap) and the mirror; writes DIR/report.txt.
set -euo pipefail

rev=HEAD
cpus=0,1
work=/var/tmp/roe-fresh-demo
mirror=""
keep=0
while [[ $# -gt 0 ]]; do
  case "$1" in
    --rev) rev=$2; shift 2 ;;
    --cpus) cpus=$2; shift 2 ;;
    --work) work=$2; shift 2 ;;
    --mirror) mirror=$2; shift 2 ;;
    --keep) keep=1; shift ;;
    -h | --help) sed -n '2,17p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "time-fresh-demo: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
[[ $(id -u) -eq 0 ]] || { echo "time-fresh-demo: needs root (debootstrap, chroot, mounts)" >&2; exit 2; }
command -v debootstrap >/dev/null || { echo "time-fresh-demo: needs debootstrap (apt-get install debootstrap)" >&2; exit 2; }
repo=$(cd "$(dirname "$0")/.." && pwd)
commit=$(git -C "$repo" rev-parse --verify "$rev^{commit}") || { echo "time-fresh-demo: no commit '$rev'" >&2; exit 2; }
if [[ -z $mirror ]]; then
  mirror=$(sed -n 's/^URIs: *\(http[^ ]*debian\)$/\1/p' /etc/apt/sources.list.d/debian.sources 2>/dev/null | head -1)
  mirror=${mirror:-http://deb.debian.org/debian}
fi

mkdir -p "$work"
base=$work/base
run=$work/run
report=$work/report.txt
if [[ ! -x $base/usr/bin/apt-get ]]; then
  echo "time-fresh-demo: bootstrapping a minimal bookworm into $base (once, not timed)" >&2
  rm -rf "$base"
  debootstrap --variant=minbase bookworm "$base" "$mirror" >"$work/debootstrap.log" 2>&1 ||
    { echo "time-fresh-demo: debootstrap failed, see $work/debootstrap.log" >&2; exit 1; }
fi

mounted=()
cleanup() {
  for ((i = ${#mounted[@]} - 1; i >= 0; i--)); do umount -l "${mounted[i]}" 2>/dev/null || true; done
  [[ $keep -eq 1 ]] || rm -rf "$run"
}
trap cleanup EXIT
rm -rf "$run"
cp -a "$base" "$run"
for m in proc sys dev dev/pts; do
  mount --bind "/$m" "$run/$m"
  mounted+=("$run/$m")
done
cp /etc/resolv.conf "$run/etc/resolv.conf"
git clone -q --no-local "$repo" "$run/root/roe"
git -C "$run/root/roe" checkout -q "$commit"
# ../shared beside the clone is not needed: the demo reads the embedded datasets/sample.

# One line of timing per recipe line: make runs each through $SHELL (sub-makes and CMake's makefiles
# too); this one records the make level, wall, user+sys of everything the line ran (bash's `times`,
# children; called in this shell, not in a subshell) and the line itself.
cat >"$run/root/timed-sh" <<'EOF'
#!/bin/bash
start=$(date +%s.%N)
/bin/sh "$@"
rc=$?
end=$(date +%s.%N)
times >/tmp/timed-sh.$$
read -r _ _ cu cs < <(tr '\n' ' ' </tmp/timed-sh.$$)
rm -f /tmp/timed-sh.$$
to_s() { local m=${1%%m*} s=${1#*m}; s=${s%s}; echo "$m*60+$s" | bc -l; }
printf '%s\t%s\t%s\t%s\t%s\t%s\n' "${MAKELEVEL:-0}" "$(date -u +%T)" "$(echo "$end-$start" | bc -l | xargs printf '%.1f')" \
  "$(to_s "$cu")" "$(to_s "$cs")" "${!#}" >>/root/steps.tsv
exit $rc
EOF
chmod +x "$run/root/timed-sh"

in_chroot() { taskset -c "$cpus" chroot "$run" /usr/bin/env -i HOME=/root PATH=/usr/sbin:/usr/bin:/sbin:/bin \
  LANG=C.UTF-8 "$@"; }
# Before the clock starts: make (the one command a user must have to type `make demo`; build-essential
# would bring it) and bc for the step timer.
in_chroot apt-get update -qq >/dev/null && in_chroot apt-get install -y -qq --no-install-recommends make bc >/dev/null
packages_before=$(in_chroot dpkg-query -W -f='${Status}\n' | grep -c "install ok installed")
load_before=$(cut -d' ' -f1-3 /proc/loadavg)
start=$(date +%s.%N)
set +e
in_chroot bash -c "cd /root/roe && rm -rf /var/lib/apt/lists/* && \
  TIMEFORMAT='%R %U %S' && time (make demo SHELL=/root/timed-sh >/root/demo.log 2>&1)" 2>"$work/total.txt"
rc=$?
set -e
end=$(date +%s.%N)
load_after=$(cut -d' ' -f1-3 /proc/loadavg)
packages_after=$(in_chroot dpkg-query -W -f='${Status}\n' | grep -c "install ok installed")
cp "$run/root/demo.log" "$work/demo.log"

{
  echo "make demo on a fresh Debian bookworm (debootstrap --variant=minbase, $mirror)"
  echo "commit $(git -C "$repo" log -1 --format='%h %s' "$commit")"
  echo "date $(date -u '+%F %T') UTC; host $(nproc) CPUs ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)),"
  echo "chroot pinned to CPUs $cpus; load average before $load_before, after $load_after"
  echo "exit code of make demo: $rc; packages: $packages_before before, $packages_after after (+$((packages_after - packages_before)))"
  read -r wall user sys <"$work/total.txt" || true
  printf 'total: wall %.0f s, CPU %.0f s (user %.0f + sys %.0f)\n' "$(echo "$end - $start" | bc -l)" \
    "$(echo "${user:-0} + ${sys:-0}" | bc -l)" "${user:-0}" "${sys:-0}"
  echo "each recipe line of make demo (a \$(MAKE) line includes its sub-make):"
  printf '  %-8s %8s %9s %8s  %s\n' "end" "wall s" "user s" "sys s" "line"
  # The recipe lines' level (the Makefile's own $(shell nproc) and $(shell command -v ccache) run one level up).
  top=$(awk -F'\t' '$6 != "nproc" && $6 !~ /^command -v / {print $1}' "$run/root/steps.tsv" | sort -n | head -1)
  while IFS=$'\t' read -r level t w u s line; do
    [[ $level == "$top" && $line != nproc && $line != "command -v "* ]] || continue
    printf '  %-8s %8s %9.1f %8.1f  %s\n' "$t" "$w" "$u" "$s" "${line:0:90}"
  done <"$run/root/steps.tsv"
} | tee "$report"

# The demo build lacks OpenCV and Ceres: their commands must refuse, naming the package (exit 2).
check() {
  local want_code=$1 want_text=$2
  shift 2
  local out code
  out=$(in_chroot bash -c 'cd /root/roe && build/roe "$@" 2>&1' _ "$@") && code=0 || code=$?
  if [[ $code -eq $want_code && $out == *"$want_text"* ]]; then
    echo "ok    roe $* -> exit $code, names '$want_text'"
  else
    echo "FAIL  roe $* -> exit $code (want $want_code and '$want_text'): ${out:0:300}"
    return 1
  fi
}
{
  echo "refusals of the demo build:"
  in_chroot /root/roe/build/roe --version | sed 's/^/  /'
  fails=0
  check 2 "libceres-dev" refine out/demo/run-default --out /tmp/refined || fails=1
  check 2 "libopencv-dev" import realsense /tmp/x.bag --out /tmp/ds || fails=1
  check 2 "libopencv-dev" infer datasets/sample --model /tmp/m || fails=1
  check 0 "libopencv-dev" infer --help || fails=1
} | tee -a "$report"
[[ $rc -eq 0 ]] || { echo "time-fresh-demo: make demo failed (exit $rc), see $work/demo.log" >&2; exit 1; }
! grep -q '^FAIL' "$report" || exit 1
echo "report: $report"
