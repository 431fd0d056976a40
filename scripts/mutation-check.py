#!/usr/bin/python3
"""Mutation check: would the tests catch a wrong sign, a missing transpose or a wrong factor?

Applies one small change at a time to the given C++ sources (a flipped binary + or -, a swapped += / -=,
a dropped unary minus, a dropped .transpose() / .conjugate() / .inverse(), 0.5 or 2.0 replaced by 1.0),
rebuilds the test binaries and runs them. A mutant is *killed* when a test fails (or the run times out or
crashes), *survived* when every test passes, and *invalid* when it does not compile. Survivors are either
holes in the tests or changes that cannot matter (e.g. a term of a Taylor branch below the tests' precision);
docs/TESTING.md lists them with the reason.

Usage (in a clean checkout with a configured build folder; it edits the sources and restores them):
  scripts/mutation-check.py --build build src/ekf/measurement.cpp src/ekf/imu.cpp:40-98 ...
  scripts/mutation-check.py --list src/ekf/measurement.cpp        # print the mutants, run nothing

Each FILE may carry a line range (FILE:FROM-TO). --test adds a test command, run in the build folder in the
given order (default: ./test_math, then ./test_ekf); --target names the build targets (default: the test
commands' first words). The report (--report, Markdown) lists every mutant and its fate.
"""
import argparse
import os
import re
import signal
import subprocess
import sys
import time

SKIP_LINE = re.compile(r'"|ROE_CHECK|throw |fmt::|^\s*#|static_assert')


def code_part(line):
    """The line without its // comment (the sources do not put // inside strings on mutated lines)."""
    i = line.find("//")
    return line if i < 0 else line[:i]


def unary_minus_positions(code):
    """Offsets of unary minus signs in front of an operand: after ( , = << ? : or return."""
    out = []
    for m in re.finditer(r"-", code):
        i = m.start()
        nxt = code[i + 1:i + 2]
        if not (nxt.isalpha() or nxt in "_("):
            continue
        prev = code[:i].rstrip()
        if prev.endswith(("(", ",", "=", "<<", "?", ":", "return")) and not prev.endswith(("==", "<=", ">=")):
            out.append(i)
    return out


def mutants_of_line(code):
    """(description, mutated code) for one line of code."""
    out = []
    for m in re.finditer(r" ([+-]) ", code):
        flip = "-" if m.group(1) == "+" else "+"
        out.append((f"binary {m.group(1)} -> {flip}", code[:m.start(1)] + flip + code[m.end(1):]))
    for m in re.finditer(r"([+-])=", code):
        flip = "-" if m.group(1) == "+" else "+"
        out.append((f"{m.group(1)}= -> {flip}=", code[:m.start(1)] + flip + code[m.end(1):]))
    for i in unary_minus_positions(code):
        out.append(("drop unary -", code[:i] + code[i + 1:]))
    for fn in ("transpose", "conjugate", "inverse"):
        for m in re.finditer(r"\." + fn + r"\(\)", code):
            out.append((f"drop .{fn}()", code[:m.start()] + code[m.end():]))
    for m in re.finditer(r"(?<![\w.])(0\.5|2\.0)(?![\w.])", code):
        out.append((f"{m.group(1)} -> 1.0", code[:m.start()] + "1.0" + code[m.end():]))
    return out


def collect(spec):
    path, _, rng = spec.partition(":")
    lines = open(path, encoding="utf-8").read().split("\n")
    lo, hi = 1, len(lines)
    if rng:
        lo, hi = (int(x) for x in rng.split("-"))
    found = []
    for n in range(lo, min(hi, len(lines)) + 1):
        line = lines[n - 1]
        code = code_part(line)
        if not code.strip() or SKIP_LINE.search(code):
            continue
        for desc, mutated in mutants_of_line(code):
            found.append((path, n, desc, line, mutated + line[len(code):]))
    return found


def run(cmd, cwd, timeout):
    """Runs a shell command in its own process group; on timeout the whole group is killed (a mutant that
    makes a test loop forever must not keep running behind the shell)."""
    p = subprocess.Popen(cmd, cwd=cwd, shell=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         start_new_session=True)
    try:
        out, _ = p.communicate(timeout=timeout)
        return p.returncode, out.decode(errors="replace")
    except (subprocess.TimeoutExpired, KeyboardInterrupt) as e:
        os.killpg(p.pid, signal.SIGKILL)
        p.wait()
        if isinstance(e, KeyboardInterrupt):
            raise
        return None, "timeout"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("files", nargs="+", help="FILE or FILE:FROM-TO")
    ap.add_argument("--build", default="build")
    ap.add_argument("--test", action="append", help="test command run in the build folder")
    ap.add_argument("--target", action="append", help="build target")
    ap.add_argument("--timeout", type=int, default=300, help="seconds per test command")
    ap.add_argument("--report", help="write a Markdown report here")
    ap.add_argument("--list", action="store_true", help="only print the mutants")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    a = ap.parse_args()
    tests = a.test or ["./test_math", "./test_ekf"]
    targets = a.target or sorted({os.path.basename(t.split()[0]) for t in tests})

    mutants = [m for spec in a.files for m in collect(spec)]
    if a.list:
        for i, (path, n, desc, old, new) in enumerate(mutants, 1):
            print(f"{i:4d} {path}:{n} {desc}\n       {old.strip()}\n    -> {new.strip()}")
        print(f"{len(mutants)} mutants")
        return 0

    paths = sorted({m[0] for m in mutants})
    dirty = subprocess.run(["git", "status", "--porcelain", "--"] + paths, stdout=subprocess.PIPE).stdout
    if dirty.strip():
        print("mutation-check: the sources to mutate have local changes; commit or stash them first",
              file=sys.stderr)
        return 2
    originals = {p: open(p, encoding="utf-8").read() for p in paths}
    build = ["cmake", "--build", a.build, "-j", str(a.jobs), "--target"] + targets
    rc, log = run(" ".join(build), ".", 3600)
    if rc != 0:
        print(log[-3000:], file=sys.stderr)
        print("mutation-check: the unmutated tree does not build", file=sys.stderr)
        return 2
    for t in tests:
        rc, log = run(t, a.build, a.timeout)
        if rc != 0:
            print(log[-3000:], file=sys.stderr)
            print(f"mutation-check: `{t}` fails without any mutation", file=sys.stderr)
            return 2

    results = []
    t_start = time.time()

    def stop(signum, frame):  # restore the sources (finally below) on kill / Ctrl-C
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, stop)
    try:
        for i, (path, n, desc, old, new) in enumerate(mutants, 1):
            lines = originals[path].split("\n")
            lines[n - 1] = new
            with open(path, "w", encoding="utf-8") as f:
                f.write("\n".join(lines))
            rc, log = run(" ".join(build), ".", 3600)
            if rc != 0:
                fate, by = "invalid", "does not compile"
            else:
                fate, by = "survived", ""
                for t in tests:
                    rc, log = run(t, a.build, a.timeout)
                    if rc != 0:
                        fate = "killed"
                        by = t + (" (timeout)" if rc is None else "")
                        fails = re.findall(r"^(?:[^\n]*\n)?-{70,}\n([^\n]+)\n", log, re.M)
                        if fails:
                            by += ": " + fails[0].strip()
                        break
            with open(path, "w", encoding="utf-8") as f:
                f.write(originals[path])
            results.append((path, n, desc, old.strip(), new.strip(), fate, by))
            print(f"[{i}/{len(mutants)} {time.time() - t_start:6.0f} s] {fate:8s} {path}:{n} {desc}", flush=True)
            write_report(a.report, tests, results, len(mutants))
    except KeyboardInterrupt:
        print("mutation-check: interrupted; the report covers the mutants run so far", file=sys.stderr)
    finally:
        for p, text in originals.items():
            with open(p, "w", encoding="utf-8") as f:
                f.write(text)
        run(" ".join(build), ".", 3600)
    print(summary_line(results, len(mutants)))
    return 0


def summary_line(results, total):
    counts = {k: sum(1 for r in results if r[5] == k) for k in ("killed", "survived", "invalid")}
    valid = counts["killed"] + counts["survived"]
    return (f"{len(results)} of {total} mutants run: {counts['killed']} killed, {counts['survived']} survived, "
            f"{counts['invalid']} invalid (do not compile); kill rate {counts['killed']}/{valid}")


def write_report(report, tests, results, total):
    """Markdown report, rewritten (temporary file + rename) after every mutant."""
    if not report:
        return
    with open(report + ".tmp", "w", encoding="utf-8") as f:
        f.write(f"# Mutation check\n\nTests: {', '.join('`' + t + '`' for t in tests)}\n\n")
        f.write(summary_line(results, total) + "\n\n")
        f.write("| file:line | mutation | fate | caught by |\n|---|---|---|---|\n")
        for path, n, desc, old, new, fate, by in results:
            f.write(f"| {path}:{n} | {desc}: `{new.replace('|', '∣')}` | {fate} | {by.replace('|', '∣')} |\n")
    os.replace(report + ".tmp", report)


if __name__ == "__main__":
    sys.exit(main())
