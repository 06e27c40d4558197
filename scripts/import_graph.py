#!/usr/bin/env python3
"""The module import graph of one crate, and its circles.

    python3 scripts/import_graph.py crates/tetloc-core/src [DEPTH]

An edge a -> b means that non-test code of module a names module b through `crate::` or
`super::` (DEPTH 1: top-level modules; 2: their submodules too). Test code (`tests.rs`,
`*_tests.rs`, `test_support/`, `#[cfg(test)]` modules) and comments are left out. A name the
crate root re-exports (`pub use locate::BatchLocator`) counts as its module. Prints the edges,
then each circle (strongly connected component) and its two-way pairs. A quick reading of the
source, not a compiler: a path built by a macro is not seen.
"""

import itertools
import re
import sys
from pathlib import Path

CFG_TEST_MOD = re.compile(r"#\[cfg\(test\)\]\s*\n\s*(?:pub(?:\(crate\))? )?mod (\w+);")
INLINE_TESTS = re.compile(r"^#\[cfg\(test\)\]\s*\n\s*mod tests\s*\{", re.M)
CRATE_PATH = re.compile(r"\bcrate::(\w+)(?:::(\w+))?")
SUPER_PATH = re.compile(r"\b((?:super::)+)(\w+)(?:::(\w+))?")


def module_path(src: Path, file: Path) -> list[str]:
    return [p for p in file.relative_to(src).with_suffix("").parts if p != "mod"]


def is_module(src: Path, parts: list[str]) -> bool:
    base = src.joinpath(*parts)
    return base.is_dir() or base.with_suffix(".rs").is_file()


def test_files(src: Path) -> set[Path]:
    out = set()
    for f in src.rglob("*.rs"):
        for m in CFG_TEST_MOD.finditer(f.read_text()):
            out |= {f.parent / f"{m.group(1)}.rs", f.parent / m.group(1) / "mod.rs"}
    return out


def edges_of(src: Path, depth: int) -> dict[str, set[str]]:
    root = src / "lib.rs" if (src / "lib.rs").exists() else src / "main.rs"
    reexported = {}
    for m in re.finditer(r"pub use (\w+)::(\{[^}]*\}|\w+)", root.read_text()):
        reexported.update((name, m.group(1)) for name in re.findall(r"\w+", m.group(2)))
    skip = test_files(src)
    edges: dict[str, set[str]] = {}
    for f in src.rglob("*.rs"):
        if f in skip or f.name == "tests.rs" or f.name.endswith("_tests.rs") or "test_support" in f.parts:
            continue
        text = f.read_text()
        if cut := INLINE_TESTS.search(text):
            text = text[: cut.start()]
        text = "\n".join(line.split("//")[0] for line in text.splitlines())
        here = module_path(src, f)
        me = "::".join(here[:depth]) or "lib"
        paths = [[m.group(1)] + ([m.group(2)] if m.group(2) else []) for m in CRATE_PATH.finditer(text)]
        for m in SUPER_PATH.finditer(text):
            up = m.group(1).count("super::")
            paths.append(here[: len(here) - up] + [g for g in m.groups()[1:] if g])
        for path in paths:
            first = reexported.get(path[0], path[0])
            if not is_module(src, [first]):
                continue  # an item of the crate root
            target = first
            if depth > 1 and first == path[0] and len(path) > 1 and is_module(src, path[:2]):
                target = "::".join(path[:2])
            if target != me:
                edges.setdefault(me, set()).add(target)
    return edges


def circles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in list(edges):
        if v not in index:
            visit(v)
    return out


def main() -> None:
    src = Path(sys.argv[1])
    depth = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    edges = edges_of(src, depth)
    for a in sorted(edges):
        print(f"{a} -> {', '.join(sorted(edges[a]))}")
    found = circles(edges)
    print("circles:", found or "none")
    for comp in found:
        for a, b in itertools.combinations(comp, 2):
            if b in edges.get(a, ()) and a in edges.get(b, ()):
                print(f"  {a} <-> {b}")


if __name__ == "__main__":
    main()
