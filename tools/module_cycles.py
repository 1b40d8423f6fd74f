#!/usr/bin/env python3
"""Reports import cycles between the top-level modules of a Rust crate.

Each top-level module (`src/foo.rs`, `src/foo/`, or both) is one node;
an edge foo -> bar means code in foo names `crate::bar` (in a `use` or
inline path) or reaches bar through `super::`. Sub-modules of the same
top-level module are one node, so cycles inside a module do not count.
Comments, strings and `$crate` paths are skipped. Code inside
`#[cfg(test)]` items is reported apart: a cycle made only by test code is
listed but does not fail the check.

Usage: tools/module_cycles.py [SRC_DIR]   (default: crates/fluidtex/src)
Exit status 1 when a cycle exists outside test code, else 0.
"""

import os
import re
import sys

IDENT = r"[A-Za-z_][A-Za-z0-9_]*"


def strip(src):
    """The source with comments, strings and char literals blanked
    (newlines kept, so offsets and line numbers still match)."""
    out = []
    i, n = 0, len(src)
    while i < n:
        c = src[i]
        if src.startswith("//", i):
            j = src.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif src.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if src.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif src.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            out.append(re.sub(r"[^\n]", " ", src[i:j]))
            i = j
        elif c == "r" and re.match(r'r#*"', src[i:]) and not re.match(r"\w", src[i - 1 : i] or " "):
            hashes = re.match(r"r(#*)\"", src[i:]).group(1)
            end = src.find('"' + hashes, i + 2 + len(hashes))
            j = n if end < 0 else end + 1 + len(hashes)
            out.append(re.sub(r"[^\n]", " ", src[i:j]))
            i = j
        elif c == '"':
            j = i + 1
            while j < n and src[j] != '"':
                j += 2 if src[j] == "\\" else 1
            out.append(re.sub(r"[^\n]", " ", src[i : j + 1]))
            i = j + 1
        elif c == "'":
            m = re.match(r"'(\\u\{[0-9a-fA-F]+\}|\\.|[^\\'])'", src[i:])
            if m:
                out.append(" " * len(m.group(0)))
                i += len(m.group(0))
            else:  # a lifetime
                out.append(c)
                i += 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def file_module(src_dir, path):
    """The module path of a file: `a/b.rs` -> [a, b], `a/mod.rs` -> [a]."""
    rel = os.path.relpath(path, src_dir)[: -len(".rs")].split(os.sep)
    if rel[-1] == "mod":
        rel = rel[:-1]
    if rel == ["lib"] or rel == ["main"]:
        rel = []
    return rel


def closing_brace(code, j):
    """The offset of the brace that closes the one at `j` (or the end)."""
    depth = 0
    while j < len(code):
        if code[j] == "{":
            depth += 1
        elif code[j] == "}":
            depth -= 1
            if depth == 0:
                break
        j += 1
    return j


def inline_modules(code):
    """(start, end, name, is_test) for each inline `mod name { ... }`."""
    found = []
    for m in re.finditer(r"\bmod\s+(" + IDENT + r")\s*\{", code):
        j = closing_brace(code, m.end() - 1)
        before = code[max(0, m.start() - 80) : m.start()]
        is_test = bool(re.search(r"#\[cfg\(test\)\]\s*(pub(\([^)]*\))?\s*)?$", before))
        found.append((m.start(), j, m.group(1), is_test))
    return found


def test_spans(code):
    """Spans of items under `#[cfg(test)]` (functions, impls, mods, uses)."""
    spans = []
    for m in re.finditer(r"#\[cfg\(test\)\]", code):
        j = m.end()
        while j < len(code) and code[j] not in "{;":
            j += 1
        if j < len(code) and code[j] == ";":
            spans.append((m.start(), j))
            continue
        spans.append((m.start(), closing_brace(code, j)))
    return spans


def edges_of_file(src_dir, path, top_modules):
    src = open(path, encoding="utf-8").read()
    code = strip(src)
    base = file_module(src_dir, path)
    inner = inline_modules(code)
    tests = test_spans(code)
    out = []

    def module_at(pos):
        names = [name for (s, e, name, _) in inner if s < pos < e]
        return base + names

    def in_test(pos):
        return any(s <= pos <= e for (s, e) in tests)

    def add(target, pos):
        if target in top_modules:
            line = code.count("\n", 0, pos) + 1
            out.append((target, line, in_test(pos)))

    for m in re.finditer(r"(?<![\w$])crate\s*::\s*(\{|" + IDENT + ")", code):
        if m.group(1) == "{":
            # `crate::{a::x, b}`: each item's head at the group's top level.
            depth, j, item = 1, m.end(), ""
            heads = []
            while j < len(code) and depth:
                ch = code[j]
                if ch == "{":
                    depth += 1
                elif ch == "}":
                    depth -= 1
                if depth == 1 and ch == ",":
                    heads.append(item)
                    item = ""
                elif depth >= 1:
                    item += ch
                j += 1
            heads.append(item)
            for h in heads:
                hm = re.match(r"\s*(" + IDENT + ")", h)
                if hm:
                    add(hm.group(1), m.start())
        else:
            add(m.group(1), m.start())
    for m in re.finditer(r"(?<![\w:])((?:super\s*::\s*)+)(\{|" + IDENT + ")", code):
        ups = m.group(1).count("super")
        here = module_at(m.start())
        if ups > len(here):
            continue
        resolved = here[: len(here) - ups]
        if resolved:
            add(resolved[0], m.start())
        elif m.group(2) != "{":
            add(m.group(2), m.start())
    return base, out


def top_level_modules(src_dir):
    """`foo.rs` and `foo/` below the crate root, as module names."""
    found = set()
    for entry in os.listdir(src_dir):
        full = os.path.join(src_dir, entry)
        if os.path.isdir(full):
            found.add(entry)
        elif entry.endswith(".rs") and entry not in ("lib.rs", "main.rs"):
            found.add(entry[:-3])
    return found


def test_module_files(src_dir):
    """Files that are whole test modules: declared `#[cfg(test)] mod x;`
    by their parent (`mod.rs`, `dir.rs` beside the folder, or `lib.rs`)."""
    found = set()
    for dirpath, _, files in os.walk(src_dir):
        for f in files:
            if not f.endswith(".rs"):
                continue
            full = os.path.join(dirpath, f)
            stem = f[:-3]
            parents = (os.path.join(dirpath, "mod.rs"), dirpath + ".rs", os.path.join(dirpath, "lib.rs"))
            for decl in parents:
                if os.path.isfile(decl) and decl != full:
                    code = strip(open(decl, encoding="utf-8").read())
                    declared = (
                        r"#\[cfg\(test\)\]\s*(#\[[^\]]*\]\s*)*(pub(\([^)]*\))?\s*)?mod\s+"
                        + stem
                        + r"\s*;"
                    )
                    if re.search(declared, code):
                        found.add(full)
    return found


def collect_edges(src_dir, top_modules):
    """(from, to) -> [(file, line, in test code)] between top-level modules."""
    test_files = test_module_files(src_dir)
    edges = {}
    for dirpath, _, files in os.walk(src_dir):
        for f in sorted(files):
            if not f.endswith(".rs"):
                continue
            full = os.path.join(dirpath, f)
            base, found = edges_of_file(src_dir, full, top_modules)
            if not base:
                continue
            for target, line, test in found:
                if target == base[0]:
                    continue
                test = test or full in test_files
                edges.setdefault((base[0], target), []).append(
                    (os.path.relpath(full, src_dir), line, test)
                )
    return edges


def graph(edges, top_modules, include_tests):
    g = {m: set() for m in top_modules}
    for (a, b), uses in edges.items():
        if include_tests or any(not t for (_, _, t) in uses):
            g[a].add(b)
    return g


def strongly_connected(g):
    """Tarjan's components of more than one node: the cycles."""
    index, low, stack, on, comps = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(g[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                comps.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(g):
        if v not in index:
            visit(v)
    return comps


def report(edges, comps, include_tests):
    """Each cycle and its edges. With `include_tests` only the edges made
    by test code alone are listed (the others close library paths)."""
    for comp in comps:
        print("cycle among: " + " <-> ".join(comp))
        for a in comp:
            for b in comp:
                uses = edges.get((a, b), [])
                library = [u for u in uses if not u[2]]
                if include_tests and library:
                    continue
                uses = uses if include_tests else library
                if uses:
                    where = ", ".join(f"{f}:{l}" for (f, l, _) in uses[:4])
                    more = f" (+{len(uses) - 4} more)" if len(uses) > 4 else ""
                    print(f"  {a} -> {b}: {where}{more}")


def main():
    src_dir = sys.argv[1] if len(sys.argv) > 1 else "crates/fluidtex/src"
    top_modules = top_level_modules(src_dir)
    edges = collect_edges(src_dir, top_modules)
    library_graph = graph(edges, top_modules, False)
    n_edges = sum(len(v) for v in library_graph.values())
    print(f"{len(top_modules)} top-level modules, {n_edges} dependencies outside tests")
    library = strongly_connected(library_graph)
    if library:
        report(edges, library, False)
    else:
        print("no cycle outside tests")
    with_tests = [c for c in strongly_connected(graph(edges, top_modules, True)) if c not in library]
    if with_tests:
        print("cycles closed only by test code (not counted; test-only edges listed):")
        report(edges, with_tests, True)
    return 1 if library else 0


if __name__ == "__main__":
    sys.exit(main())
