#!/usr/bin/env python3
"""Checks that ctest runs every Catch2 test case under its own full name (issue 42).

catch_discover_tests turns each line of `test_AREA --list-test-names-only` into one ctest entry
"AREA/NAME". A name that CMake splits (a ';' is a list separator), drops or rewrites gives entries
whose filter matches no test case; this compares the two lists for every test binary and also
refuses test-case names with characters that the registration cannot carry.

usage: check-test-registration.py BUILD_DIR     exit 0: the lists agree; 1: they differ (listed)
"""
import pathlib
import re
import subprocess
import sys


def ctest_names(build):
    out = subprocess.run(["ctest", "-N"], cwd=build, capture_output=True, text=True, check=True).stdout
    names = set()
    for line in out.splitlines():
        m = re.match(r"\s*Test\s+#\d+: (.*)$", line)
        if m:
            names.add(m.group(1))
    return names


def explicit_names(build):
    """Entries added by add_test() in CMake itself (not discovered from a Catch2 binary)."""
    text = (build / "CTestTestfile.cmake").read_text()
    return {m.group(2) or m.group(3)
            for m in re.finditer(r'^add_test\((\[=*\[(.*?)\]=*\]|"?([^\s"]+)"?)', text, re.M)}


def catch_names(binary):
    out = subprocess.run([str(binary), "--list-test-names-only"], capture_output=True, text=True).stdout
    return [n for n in out.splitlines() if n.strip()]


def main():
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    build = pathlib.Path(sys.argv[1]).resolve()
    registered = ctest_names(build)
    explicit = explicit_names(build)
    problems = []
    binaries = sorted(b for b in build.glob("test_*") if b.is_file() and b.stat().st_mode & 0o111)
    if not binaries:
        print(f"no test_* binaries in {build}", file=sys.stderr)
        return 1
    expected = set()
    for b in binaries:
        area = b.name[len("test_"):]
        for name in catch_names(b):
            full = f"{area}/{name}"
            expected.add(full)
            # ';' splits the CMake list; a backslash is an escape in Catch2's filter, so the entry's
            # filter would not match the name it carries; a leading '-' makes the filter an option, a
            # leading '~' or '#' an exclusion or a file-name filter.
            if ";" in name or "\\" in name or name != name.strip() or name[:1] in ("-", "~", "#"):
                problems.append(f"{b.name}: test case name cannot be registered as written: {name!r}")
            if full not in registered:
                problems.append(f"{b.name}: test case not registered with ctest: {name!r}")
    areas = {b.name[len("test_"):] for b in binaries}
    for full in sorted(registered):
        area = full.split("/", 1)[0]
        if area in areas and full not in expected and full not in explicit:
            problems.append(f"ctest entry that matches no test case: {full!r}")
    for p in problems:
        print(p)
    n = len(expected)
    print(f"{n} test cases in {len(binaries)} binaries; {len(problems)} registration problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
