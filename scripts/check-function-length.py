#!/usr/bin/env python3
"""Checks that no function in src/ is longer than a reader holds in their head (issue 39).

A function's length is counted from the line of its opening brace to the line of its closing brace.
Functions are found by a small scanner, not a compiler: comments, string, character and raw-string
literals are blanked out, then every '{' whose text before it ends like a function head (a ')' with
optional const/noexcept/override, a trailing return type or a constructor's initialiser list, and not an
if/for/while/switch/catch or a lambda) opens a function; the outermost one counts (lambdas and local
classes inside it are part of it).

usage: check-function-length.py SRC_DIR [--max N] [--allow FILE:NAME_PREFIX ...]
       check-function-length.py --self-test
exit 0: none longer than N (default 120) apart from the allowed ones; 1: the long ones are listed.
"""
import argparse
import os
import re
import sys

HEAD_END = re.compile(r'\)\s*(const)?\s*(noexcept)?\s*(override|final)?\s*(->\s*[\w:<>,&* ]+)?\s*(:[^;{}]*)?$')
CONTROL = re.compile(r'\b(if|for|while|switch|catch|return)\b[^;{}]*$')
LAMBDA = re.compile(r'[=\[(,]\s*\[[^\]]*\]\s*\([^;{}]*\)[^;{}]*$|[=\[]\s*[^;{}]*\)\s*$')


def blank_literals(src):
    """The source with comments and literals replaced by spaces (newlines kept, so lines still count)."""
    out, i, n = [], 0, len(src)
    keep_lines = lambda t: re.sub(r'[^\n]', ' ', t)
    while i < n:
        if src.startswith('//', i):
            j = src.find('\n', i)
            j = n if j < 0 else j
        elif src.startswith('/*', i):
            j = src.find('*/', i)
            j = n if j < 0 else j + 2
        elif src.startswith('R"', i) and (i == 0 or not (src[i - 1].isalnum() or src[i - 1] == '_')):
            m = re.match(r'R"([^(\s]*)\(', src[i:])
            if not m:
                out.append(src[i]); i += 1; continue
            end = ')' + m.group(1) + '"'
            j = src.find(end, i)
            j = n if j < 0 else j + len(end)
        elif src[i] == '"' or (src[i] == "'" and not (i > 0 and src[i - 1].isalnum())):
            q, j = src[i], i + 1
            while j < n and src[j] != q and src[j] != '\n':
                j += 2 if src[j] == '\\' else 1
            j += 1
        else:
            out.append(src[i]); i += 1; continue
        out.append(keep_lines(src[i:j]))
        i = j
    return ''.join(out)


def functions(src):
    """(first line, length in lines, head) of every outermost function body in the C++ text."""
    lines = blank_literals(src).split('\n')
    stack, found = [], []
    for ln, line in enumerate(lines, 1):
        for k, ch in enumerate(line):
            if ch == '{':
                before = '\n'.join(lines[max(0, ln - 6):ln - 1] + [line[:k]])
                stmt = re.split(r'[;{}]', before)[-1]
                is_fn = bool(HEAD_END.search(before)) and not CONTROL.search(stmt) and not LAMBDA.search(stmt)
                stack.append((ln, is_fn, ' '.join(stmt.split())[:100]))
            elif ch == '}' and stack:
                start, is_fn, head = stack.pop()
                if is_fn and not any(f for _, f, _ in stack):
                    found.append((start, ln - start + 1, head))
    return found


def self_test():
    body = '\n'.join('  x += %d;  // "{" and \'}\' in text' % i for i in range(130))
    src = ('namespace a {\nint long_one(int x) {\n%s\n  auto f = [](int y) {\n    return y;\n  };\n  if (x) {\n  }\n'
           '  return x;\n}\nint short_one() const noexcept { return R"x({)x"[0]; }\n}  // namespace a\n') % body
    got = functions(src)
    assert len(got) == 2, got
    assert got[0][1] == 138 and 'long_one' in got[0][2], got[0]
    assert got[1][1] == 1, got[1]
    print('self-test: ok (a 138-line function found, literals and lambdas ignored)')


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('src', nargs='?')
    ap.add_argument('--max', type=int, default=120)
    ap.add_argument('--allow', action='append', default=[], help='FILE:NAME_PREFIX (relative to SRC_DIR)')
    ap.add_argument('--self-test', action='store_true')
    a = ap.parse_args()
    if a.self_test:
        self_test()
        return 0
    if not a.src:
        ap.error('SRC_DIR is required')
    allowed = [tuple(x.split(':', 1)) for x in a.allow]
    long_ones = []
    for root, _, files in os.walk(a.src):
        for f in sorted(files):
            if not f.endswith(('.cpp', '.hpp')):
                continue
            path = os.path.join(root, f)
            rel = os.path.relpath(path, a.src)
            with open(path, encoding='utf-8', errors='replace') as fh:
                for start, length, head in functions(fh.read()):
                    if length <= a.max:
                        continue
                    name = head.split('(')[0].split()[-1] if '(' in head else head
                    if any(rel == af and name.startswith(ap_) for af, ap_ in allowed):
                        print(f'allowed: {rel}:{start} {name} ({length} lines)')
                        continue
                    long_ones.append((length, rel, start, head))
    for length, rel, start, head in sorted(long_ones, reverse=True):
        print(f'{rel}:{start}: {length} lines (at most {a.max}): {head}')
    if long_ones:
        print(f'{len(long_ones)} function(s) longer than {a.max} lines: give their parts names')
        return 1
    print(f'no function in {a.src} is longer than {a.max} lines')
    return 0


if __name__ == '__main__':
    sys.exit(main())
