#!/usr/bin/env bash
# CTest fuzz/replay-driver (cmake/extra-fuzz.cmake): fuzz_replay reports every kind of finding, naming the
# input, and fails; clean inputs pass. The harness is tests/fuzz/replay_selftest.cpp, whose inputs name the
# finding they stand for.   usage: tests/fuzz/check_replay.sh BUILD/fuzz_replay
set -uo pipefail
exe=${1:?usage: check_replay.sh FUZZ_REPLAY}
d=$(mktemp -d "${TMPDIR:-/tmp}/roe-replay-check.XXXXXX")
trap 'rm -rf "$d"' EXIT
failed=0

# expect NAME CODE TEXT ARGS...: runs fuzz_replay replay_selftest ARGS; the exit status must be CODE and
# the output (stdout and stderr) must contain TEXT.
expect() {
  local name=$1 code=$2 text=$3
  shift 3
  local out rc
  out=$("$exe" replay_selftest "$@" 2>&1)
  rc=$?
  if [ "$rc" != "$code" ] || [[ "$out" != *"$text"* ]]; then
    echo "FAIL $name: exit $rc (expected $code), output lacks or has: $text"
    echo "$out" | sed 's/^/    /'
    failed=1
  else
    echo "ok   $name"
  fi
}

mkdir -p "$d/clean"
printf 'input-error' >"$d/clean/a"
printf 'anything' >"$d/clean/b"
for k in runtime-error trap abort hang allocate; do printf '%s' "$k" >"$d/$k"; done

expect "clean files and a folder pass" 0 "3 inputs, 0 findings" "$d/clean"
expect "an exception that is no reader's error fails, naming it and the input" 1 \
  "FINDING: replay_selftest on $d/runtime-error: uncaught std::runtime_error: not a reader's error type" \
  "$d/clean/a" "$d/runtime-error" "$d/clean/b"
expect "the inputs after a finding are still replayed" 1 "4 inputs, 1 findings" \
  "$d/clean/a" "$d/runtime-error" "$d/clean/b"
# A crash ends the process by its signal (CTest: failed); the last line printed names the input.
expect "a trap (SIGILL) fails, the input named last" 132 "  $d/trap (4 bytes)" "$d/trap"
expect "an abort (SIGABRT) fails, the input named last" 134 "  $d/abort (5 bytes)" "$d/abort"
expect "a hang fails at --timeout, naming the input" 1 \
  "FINDING: replay_selftest on $d/hang: still running after 1 s (--timeout)" --timeout 1 "$d/hang"
expect "an allocation beyond --memory-mb fails as std::bad_alloc" 1 \
  "FINDING: replay_selftest on $d/allocate: uncaught std::bad_alloc" --memory-mb 512 "$d/allocate"
expect "a missing input is bad usage" 2 "no such file or folder: $d/none" "$d/none"
out=$("$exe" no_such_target 2>&1)
rc=$?
if [ $rc != 2 ] || [[ "$out" != *"unknown target 'no_such_target'"* ]]; then
  echo "FAIL an unknown target is bad usage: exit $rc: $out"
  failed=1
else
  echo "ok   an unknown target is bad usage"
fi
exit $failed
