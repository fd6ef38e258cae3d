#!/usr/bin/env python3
"""Finds import circles between the modules of each crate of the workspace.

A module is a file: `foo.rs` is module `foo`, `foo/mod.rs` (or `foo.rs`
beside a folder `foo/`) is the folder's module. Every `crate::`, `super::`
and `self::` path in the code, and every path that starts with the name of
one of the module's own child modules, (in `use` lines, including grouped
`use a::{b, c::d}`, and inline paths in expressions and types) is resolved to
the deepest file module it names; that gives an edge from the file to that
module. Edges from inside a `#[cfg(test)] mod tests { ... }` block are
ignored. Tarjan's algorithm then finds the strongly-connected components;
every component of more than one module is printed, and the exit status is 1
if there is any.

Usage: python3 docs/tools/import_circles.py [WORKSPACE_ROOT]
(stdlib only; the root defaults to two folders above this script).
"""

import os
import re
import sys


def strip_comments_and_strings(text):
    """Removes comments, string and char literals (keeping line structure)."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            depth, i = 1, i + 2
            while i < n and depth:
                if text.startswith("/*", i):
                    depth, i = depth + 1, i + 2
                elif text.startswith("*/", i):
                    depth, i = depth - 1, i + 2
                else:
                    if text[i] == "\n":
                        out.append("\n")
                    i += 1
        elif c == "r" and re.match(r'r#*"', text[i:i + 10]) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            m = re.match(r'r(#*)"', text[i:])
            end = '"' + m.group(1)
            j = text.find(end, i + m.end())
            j = n if j < 0 else j + len(end)
            out.append('""' + "\n" * text[i:j].count("\n"))
            i = j
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            out.append('""' + "\n" * text[i:j].count("\n"))
            i = j + 1
        elif c == "'":
            m = re.match(r"'(\\.[^']*|[^\\'])'", text[i:])
            if m:
                out.append("' '")
                i += m.end()
            else:  # a lifetime
                out.append(c)
                i += 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def remove_test_modules(text):
    """Drops `#[cfg(test)] mod NAME { ... }` blocks (brace-matched)."""
    pat = re.compile(r"#\[cfg\(test\)\]\s*(pub(\([^)]*\))?\s+)?mod\s+\w+\s*\{")
    while True:
        m = pat.search(text)
        if not m:
            return text
        depth, j = 1, m.end()
        while j < len(text) and depth:
            if text[j] == "{":
                depth += 1
            elif text[j] == "}":
                depth -= 1
            j += 1
        text = text[:m.start()] + "\n" * text[m.start():j].count("\n") + text[j:]


def crate_modules(src):
    """Maps module path tuples to files for one crate's src folder."""
    mods = {}
    for root, _dirs, files in os.walk(src):
        for f in files:
            if not f.endswith(".rs"):
                continue
            rel = os.path.relpath(os.path.join(root, f), src)
            parts = rel[:-3].split(os.sep)
            if parts in (["lib"], ["main"]):
                parts = []
            elif parts[-1] == "mod":
                parts = parts[:-1]
            mods[tuple(parts)] = os.path.join(root, f)
    return mods


def expand_use(tree):
    """Expands a use tree `a::{b, c::{d, e}}` into flat paths."""
    tree = re.sub(r"\s+", "", tree)
    if "{" not in tree:
        return [tree]
    i = tree.index("{")
    prefix = tree[:i]
    depth, parts, start = 0, [], i + 1
    for j in range(i, len(tree)):
        ch = tree[j]
        if ch == "{":
            depth += 1
        elif ch == "}":
            depth -= 1
            if depth == 0:
                parts.append(tree[start:j])
                break
        elif ch == "," and depth == 1:
            parts.append(tree[start:j])
            start = j + 1
    out = []
    for p in parts:
        if p:
            for e in expand_use(p):
                out.append(prefix + e)
    return out


def resolve(path, here, mods):
    """Resolves a `crate::`/`super::`/`self::` path used in module `here`."""
    segs = [s for s in path.split("::") if s]
    segs = [re.sub(r"\s+as\s+\w+$", "", s) for s in segs]
    if not segs:
        return None
    if segs[0] == "crate":
        base, rest = [], segs[1:]
    elif segs[0] in ("super", "self"):
        base = list(here)
        rest = segs
        while rest and rest[0] in ("super", "self"):
            if rest[0] == "super":
                if not base:
                    return None
                base.pop()
            rest = rest[1:]
    elif tuple(here) + (segs[0],) in mods:
        # A path relative to this module, through one of its children.
        base, rest = list(here), segs
    else:
        return None
    best = tuple(base)
    cur = list(base)
    for s in rest:
        s = s.split(" as ")[0].strip()
        cur.append(s)
        if tuple(cur) in mods:
            best = tuple(cur)
        else:
            break
    return best


USE_RE = re.compile(r"\buse\s+(::)?([^;]*);")
INLINE_RE = re.compile(r"(?<![\w:])([A-Za-z_]\w*(?:\s*::\s*\w+)+)")


def edges_of(file, here, mods):
    text = remove_test_modules(strip_comments_and_strings(open(file, encoding="utf-8").read()))
    targets = set()
    for m in USE_RE.finditer(text):
        if m.group(1):  # `use ::name`: an external crate
            continue
        for p in expand_use(m.group(2)):
            t = resolve(p, here, mods)
            if t is not None:
                targets.add(t)
    text_wo_use = USE_RE.sub(";", text)
    for m in INLINE_RE.finditer(text_wo_use):
        t = resolve(re.sub(r"\s+", "", m.group(1)), here, mods)
        if t is not None:
            targets.add(t)
    targets.discard(here)
    return targets


def tarjan(graph):
    index, low, on, stack, sccs, counter = {}, {}, set(), [], [], [0]
    sys.setrecursionlimit(10000)

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
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
            sccs.append(comp)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sccs


def crate_sources(root):
    srcs = []
    cdir = os.path.join(root, "crates")
    if os.path.isdir(cdir):
        for c in sorted(os.listdir(cdir)):
            s = os.path.join(cdir, c, "src")
            if os.path.isdir(s):
                srcs.append((c, s))
    if os.path.isdir(os.path.join(root, "src")):
        srcs.append((os.path.basename(os.path.abspath(root)), os.path.join(root, "src")))
    return srcs


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
    found = 0
    for name, src in crate_sources(root):
        mods = crate_modules(src)
        graph = {m: sorted(edges_of(f, m, mods)) for m, f in mods.items()}
        for comp in tarjan(graph):
            if len(comp) > 1:
                found += 1
                names = sorted("::".join(m) or "(crate root)" for m in comp)
                print(f"{name}: circle of {len(comp)} modules: {', '.join(names)}")
    if found == 0:
        print("no import circles")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
