#!/usr/bin/env python3
"""Reports import cycles in a Rust crate, at two levels.

Top-level modules: each top-level module (`src/foo.rs`, `src/foo/`, or
both) is one node; an edge foo -> bar means code in foo names
`crate::bar` (in a `use` or inline path) or reaches bar through
`super::`. Sub-modules of the same top-level module are one node, so
cycles inside a module do not count here.

Files: each `.rs` file is one node (an inline `mod x { ... }` belongs to
its file); an edge a.rs -> b.rs means code in a.rs names a path
(`crate::x::y`, `super::y`, `self::y`, a child module `y::...`, or a
module a `use` brought in) whose deepest module is defined by b.rs. A
re-export is not followed: `use super::fill::X` is an edge to fill.rs even
when fill.rs only re-exports X. Declaring a module (`mod y;`) is no edge,
and neither is a path between a module's file and the file of one of its
own sub-modules (either way): a parent declares, re-exports and calls its
children, which see its items through `super::`, by design. So a
file-level cycle runs through files none of which is inside another, e.g.
two siblings that import each other.

Comments, strings and `$crate` paths are skipped. Code inside
`#[cfg(test)]` items, and whole test files (declared `#[cfg(test)] mod x;`,
or named `tests.rs`), is reported apart: a cycle made only by test code is
listed but does not fail the check.

Usage: tools/module_cycles.py [SRC_DIR]   (default: crates/fluidtex/src)
Exit status 1 when a cycle exists outside test code (file-level cycles
closed only by an edge of KNOWN_FILE_CYCLE_EDGES excepted), else 0.
"""

import os
import re
import sys

IDENT = r"[A-Za-z_][A-Za-z0-9_]*"

# Known file-level cycles, each excused by one edge (from, to), paths
# relative to SRC_DIR. The check ignores these edges; delete an entry once
# its cycle is broken (the script says when an entry no longer closes one).
KNOWN_FILE_CYCLE_EDGES = [
]


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


def rust_files(src_dir):
    """Every .rs file under `src_dir`, in a fixed order."""
    for dirpath, dirs, files in os.walk(src_dir):
        dirs.sort()
        for f in sorted(files):
            if f.endswith(".rs"):
                yield os.path.join(dirpath, f)


def collect_edges(src_dir, top_modules):
    """(from, to) -> [(file, line, in test code)] between top-level modules."""
    test_files = test_module_files(src_dir)
    edges = {}
    for full in rust_files(src_dir):
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


def report(edges, comps, include_tests, kind="cycle", where=None, known=()):
    """Each cycle and its edges. With `include_tests` only the edges made
    by test code alone are listed (the others close library paths).
    `where(uses)` formats a list of uses and tells which are test code
    (module edges: (file, line, test); file edges: (line, test))."""
    where = where or (lambda uses: (", ".join(f"{f}:{l}" for (f, l, _) in uses[:4]), [u[2] for u in uses]))
    for comp in comps:
        print(f"{kind} among: " + " <-> ".join(comp))
        for a in comp:
            for b in comp:
                uses = edges.get((a, b), [])
                library = [u for u, test in zip(uses, where(uses)[1]) if not test]
                if include_tests and library:
                    continue
                uses = uses if include_tests else library
                if uses:
                    text, _ = where(uses)
                    more = f" (+{len(uses) - 4} more)" if len(uses) > 4 else ""
                    tag = " [known exception]" if (a, b) in known else ""
                    print(f"  {a} -> {b}: {text}{more}{tag}")


# ---- File level ----------------------------------------------------------

TOKEN = re.compile(r"\s*(::|\{|\}|,|\*|" + IDENT + ")")


def parse_tree(code, j):
    """The paths of the use tree (or inline path) starting at offset `j`,
    as segment lists (`a::{b, c::d}` -> [a, b], [a, c, d]), and the offset
    after it, with the alias of each (`as x`) or None."""
    segs = []
    while True:
        m = TOKEN.match(code, j)
        if not m:
            return [(segs, None)], j
        tok = m.group(1)
        if tok == "{":
            j, out = m.end(), []
            while True:
                m2 = TOKEN.match(code, j)
                if not m2 or m2.group(1) == "}":
                    j = m2.end() if m2 else j
                    break
                sub, j2 = parse_tree(code, j)
                if j2 == j:
                    break
                j = j2
                out += [(segs + p, alias) for (p, alias) in sub]
                m2 = TOKEN.match(code, j)
                if m2 and m2.group(1) == ",":
                    j = m2.end()
            return (out or [(segs, None)]), j
        if tok == "*":
            return [(segs, None)], m.end()
        if not re.fullmatch(IDENT, tok):
            return [(segs, None)], j
        segs.append(tok)
        j = m.end()
        m2 = TOKEN.match(code, j)
        if m2 and m2.group(1) == "::":
            j = m2.end()
            continue
        alias = re.match(r"\s+as\s+(" + IDENT + ")", code[j:])
        if alias:
            return [(segs, alias.group(1))], j + alias.end()
        return [(segs, None)], j


def module_files(src_dir):
    """Module path (a tuple) -> its file relative to `src_dir`, for every
    file and every inline `mod x { ... }` (which belongs to its file)."""
    mods = {}
    for dirpath, _, files in os.walk(src_dir):
        for f in files:
            if not f.endswith(".rs"):
                continue
            full = os.path.join(dirpath, f)
            rel = os.path.relpath(full, src_dir)
            base = tuple(file_module(src_dir, full))
            mods.setdefault(base, rel)
            inner = inline_modules(strip(open(full, encoding="utf-8").read()))
            for s, _, name, _ in inner:
                names = [n for (s2, e2, n, _) in inner if s2 < s < e2]
                mods[base + tuple(names) + (name,)] = rel
    return mods


def resolve(path, here, mods, aliases):
    """The module a path names (its deepest module prefix), or None."""
    head, rest = path[0], path[1:]
    if head == "crate":
        cur = ()
    elif head in ("super", "self"):
        cur, rest = here, path
        while rest and rest[0] in ("super", "self"):
            if rest[0] == "super":
                if not cur:
                    return None
                cur = cur[:-1]
            rest = rest[1:]
    elif here + (head,) in mods:
        cur = here + (head,)
    elif head in aliases:
        cur = aliases[head]
    else:
        return None
    for seg in rest:
        if seg == "self":
            continue
        if cur + (seg,) not in mods:
            break
        cur = cur + (seg,)
    return cur


def file_edges_of(src_dir, path, mods):
    """[(target file, line, in test code)] for the paths in one file."""
    src = open(path, encoding="utf-8").read()
    code = strip(src)
    rel = os.path.relpath(path, src_dir)
    base = tuple(file_module(src_dir, path))
    inner = inline_modules(code)
    tests = test_spans(code)

    def module_at(pos):
        return base + tuple(name for (s, e, name, _) in inner if s < pos < e)

    def in_test(pos):
        return any(s <= pos <= e for (s, e) in tests)

    # Modules that `use` brings in under a name (`use super::sph;`,
    # `use crate::io::{self as io}`), per enclosing module.
    aliases = {}
    uses = []
    parsed_to = 0
    for m in re.finditer(r"(?<![\w:$.])(" + IDENT + r")(?=\s*::)", code):
        if m.start() < parsed_to:
            continue  # inside a use tree already read (`crate::{a::x, b}`)
        here = module_at(m.start())
        paths, parsed_to = parse_tree(code, m.start())
        uses.append((m.start(), here, paths))
        if not re.search(r"\buse\s+$", code[max(0, m.start() - 40) : m.start()]):
            continue
        for segs, alias in paths:
            key = segs[-2] if len(segs) > 1 and segs[-1] == "self" else segs[-1]
            target = resolve(segs, here, mods, {})
            if target and target[-1] == key:
                aliases.setdefault(here, {})[alias or key] = target
    out = []
    for pos, here, paths in uses:
        for segs, _ in paths:
            target = resolve(segs, here, mods, aliases.get(here, {}))
            if target is None:
                continue
            f = mods.get(target)
            if f is not None and f != rel:
                out.append((f, code.count("\n", 0, pos) + 1, in_test(pos)))
    return out


def collect_file_edges(src_dir):
    """(from file, to file) -> [(line, in test code)], leaving out the
    paths between a module's file and its sub-modules' files."""
    mods = module_files(src_dir)
    test_files = {os.path.relpath(f, src_dir) for f in test_module_files(src_dir)}
    module_of = {f: m for (m, f) in mods.items() if m == tuple(file_module(src_dir, os.path.join(src_dir, f)))}

    def is_test_file(rel):
        if os.path.basename(rel) == "tests.rs":
            return True
        m = module_of.get(rel, ())
        return any(mods.get(m[:k]) in test_files for k in range(1, len(m) + 1))

    edges = {}
    for full in rust_files(src_dir):
        rel = os.path.relpath(full, src_dir)
        whole_test = is_test_file(rel)
        here = module_of[rel]
        for target, line, test in file_edges_of(src_dir, full, mods):
            there = module_of[target]
            if here[: len(there)] == there or there[: len(here)] == here:
                continue  # a module and its own sub-modules
            uses = edges.setdefault((rel, target), [])
            if (line, test or whole_test) not in uses:
                uses.append((line, test or whole_test))
    return sorted(set(mods.values())), edges


def file_graph(files, edges, include_tests, skip=()):
    g = {f: set() for f in files}
    for (a, b), uses in edges.items():
        if (a, b) in skip:
            continue
        if include_tests or any(not t for (_, t) in uses):
            g[a].add(b)
    return g


def report_files(edges, comps, include_tests, known=()):
    """[`report`] for file cycles, whose uses are (line, test)."""
    def where(uses):
        return "line " + ", ".join(str(l) for (l, _) in uses[:4]), [u[1] for u in uses]

    report(edges, comps, include_tests, "file cycle", where, known)


def check_graph(nodes, kind, library_graph, test_graph, show):
    """Prints the counts of a graph of `nodes` (a label with their count),
    its cycles outside tests and those closed only by test code (`show`
    lists a cycle's edges, all or test-only); returns the cycles outside
    tests. The known exceptions are reported by the caller."""
    n_edges = sum(len(v) for v in library_graph.values())
    print(f"{nodes}, {n_edges} {kind} dependencies outside tests".replace("  ", " "))
    library = strongly_connected(library_graph)
    if library:
        show(library, False)
    else:
        print(f"no {kind} cycle outside tests".replace("  ", " "))
    with_tests = [c for c in strongly_connected(test_graph) if c not in library]
    if with_tests:
        print(f"{kind} cycles closed only by test code (not counted; test-only edges listed):".lstrip())
        show(with_tests, True)
    return library


def check_files(src_dir):
    """The file-level check; True when it passes."""
    files, edges = collect_file_edges(src_dir)
    known = set(KNOWN_FILE_CYCLE_EDGES)
    library = check_graph(
        f"{len(files)} files",
        "file",
        file_graph(files, edges, False, known),
        file_graph(files, edges, True, known),
        lambda comps, tests: report_files(edges, comps, tests),
    )
    # The known exceptions: each still an edge of a cycle, or stale.
    full = strongly_connected(file_graph(files, edges, False))
    for a, b in KNOWN_FILE_CYCLE_EDGES:
        if any(a in c and b in c for c in full):
            print(f"known exception (KNOWN_FILE_CYCLE_EDGES): {a} -> {b}")
        else:
            print(
                f"note: KNOWN_FILE_CYCLE_EDGES entry {a} -> {b} closes no cycle "
                "any more; delete it"
            )
    return not library


def main():
    src_dir = sys.argv[1] if len(sys.argv) > 1 else "crates/fluidtex/src"
    top_modules = top_level_modules(src_dir)
    edges = collect_edges(src_dir, top_modules)
    library = check_graph(
        f"{len(top_modules)} top-level modules",
        "",
        graph(edges, top_modules, False),
        graph(edges, top_modules, True),
        lambda comps, tests: report(edges, comps, tests),
    )
    files_ok = check_files(src_dir)
    return 1 if library or not files_ok else 0


if __name__ == "__main__":
    sys.exit(main())
