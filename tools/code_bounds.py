#!/usr/bin/env python3
"""Checks the size bounds of the Rust sources (docs/architecture.md, "Bounds").

- A file holds at most MAX_FILE_LINES lines of non-test code: its lines
  before an inline `#[cfg(test)] mod name { ... }` module. A file that a
  parent declares `#[cfg(test)] mod name;` (or a `tests.rs`) is test code
  and not counted; a file that declares its tests in another file counts
  whole, because all of it is non-test code.
- A function outside test code spans at most MAX_FN_LINES lines, from its
  `fn` line to its closing brace.

Comments and string literals are skipped when braces are matched (with
the reader of tools/module_cycles.py).

Usage: tools/code_bounds.py [DIR ...]   (default: every crates/*/src)
Exit status 1 when a bound is broken (each one listed), else 0.
"""

import glob
import os
import re
import sys

# Comments and literals blanked, newlines kept (the cycle check's reader).
from module_cycles import strip as code_only

MAX_FILE_LINES = 1000
MAX_FN_LINES = 100

TEST_MOD = re.compile(r"^\s*#\[cfg\(test\)\]\s*$")
MOD_DECL = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+([A-Za-z_][A-Za-z0-9_]*)\s*;")
MOD_INLINE = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+[A-Za-z_][A-Za-z0-9_]*\s*\{")
FN = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?(?:const\s+)?(?:async\s+)?(?:unsafe\s+)?fn\s+([A-Za-z_][A-Za-z0-9_]*)")


def test_files(src):
    """Files declared `#[cfg(test)] mod x;` by their parent, and tests.rs files."""
    found = set()
    for path in glob.glob(os.path.join(src, "**", "*.rs"), recursive=True):
        lines = open(path, encoding="utf-8").read().split("\n")
        name = os.path.basename(path)
        base = os.path.dirname(path) if name in ("mod.rs", "lib.rs", "main.rs") else path[:-3]
        for k, line in enumerate(lines[:-1]):
            m = MOD_DECL.match(lines[k + 1])
            if TEST_MOD.match(line) and m:
                for child in (os.path.join(base, m.group(1) + ".rs"), os.path.join(base, m.group(1), "mod.rs")):
                    found.add(os.path.normpath(child))
        if name == "tests.rs":
            found.add(os.path.normpath(path))
    return found


def production_end(lines):
    """Index of the first line of the inline test module, or len(lines)."""
    for k, line in enumerate(lines[:-1]):
        if TEST_MOD.match(line) and MOD_INLINE.match(lines[k + 1]):
            return k
    return len(lines)


def long_functions(code_lines, end):
    """(name, first line, span) of every fn longer than MAX_FN_LINES before `end`,
    skipping items under `#[cfg(test)]`."""
    found = []
    k = 0
    skip_next_item = False
    while k < end:
        line = code_lines[k]
        if TEST_MOD.match(line):
            skip_next_item = True
            k += 1
            continue
        m = FN.match(line)
        if m:
            depth, opened, j = 0, False, k
            while j < len(code_lines):
                for ch in code_lines[j]:
                    if ch == "{":
                        depth, opened = depth + 1, True
                    elif ch == "}":
                        depth -= 1
                    elif ch == ";" and not opened and depth == 0:
                        # A declaration without a body (trait item).
                        opened = None
                        break
                if opened is None or (opened and depth == 0):
                    break
                j += 1
            span = j - k + 1
            if opened and span > MAX_FN_LINES and not skip_next_item:
                found.append((m.group(1), k + 1, span))
            skip_next_item = False
            # Nested fns are counted inside their outer one.
            k = j + 1 if opened else k + 1
            continue
        if line.strip() and not line.strip().startswith("#"):
            skip_next_item = False
        k += 1
    return found


def check(src):
    problems = []
    tests = test_files(src)
    for path in sorted(glob.glob(os.path.join(src, "**", "*.rs"), recursive=True)):
        if os.path.normpath(path) in tests:
            continue
        text = open(path, encoding="utf-8").read()
        lines = text.split("\n")
        if lines and lines[-1] == "":
            lines.pop()
        end = production_end(lines)
        if end > MAX_FILE_LINES:
            problems.append(f"{path}: {end} lines of non-test code (at most {MAX_FILE_LINES})")
        code_lines = code_only(text).split("\n")
        for name, line, span in long_functions(code_lines, end):
            problems.append(f"{path}:{line}: fn {name} spans {span} lines (at most {MAX_FN_LINES})")
    return problems


def main(argv):
    dirs = argv[1:] or sorted(glob.glob("crates/*/src"))
    problems = [p for d in dirs for p in check(d)]
    for p in problems:
        print(p)
    if problems:
        return 1
    print(f"code bounds: {len(dirs)} source folders, every file and function within bounds")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
