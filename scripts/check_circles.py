#!/usr/bin/env python3
"""Find circles of files: Python modules that import each other (host_tools/abbe, the
benchmark report bench/report, scripts/) and C files in lib/ and port/ that include
each other, or a header whose code (inline functions, macros) calls a function defined
in a .c file that includes it (eval_f32.c <-> eval_f32_linear.h was one: issue 41).

import-linter (host_tools/pyproject.toml) keeps the package's floors one way; it does
not look inside a floor, nor at C. This does, by reading the sources (no build):

    python3 scripts/check_circles.py     # prints each circle; exit 1 if there is one

host_tools/tests/scripts/test_architecture_doc.py runs it. Standard library only.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: (folder on sys.path, top-level package or None for loose scripts) of each Python tree
PYTHON_TREES = ((REPO / "host_tools", "abbe"), (REPO / "bench", "report"), (REPO / "scripts", None))
C_TREES = (REPO / "lib", REPO / "port")
_DEFINITION = re.compile(r"^[A-Za-z_][\w \t\*]*?\b(\w+)\s*\([^;{)]*\)\s*\{", re.M)
_KEYWORDS = {"if", "for", "while", "switch", "return", "sizeof", "defined"}


def _rel(p: Path) -> str:
    try:
        return str(p.relative_to(REPO))
    except ValueError:
        return str(p)


def _python_modules(base: Path, package: str | None) -> dict[str, Path]:
    files = (base / package).rglob("*.py") if package else base.glob("*.py")
    mods = {}
    for p in files:
        rel = p.relative_to(base).with_suffix("")
        mods[".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)] = p
    return mods


def python_edges(mods: dict[str, Path]) -> dict[str, set[str]]:
    """module -> the modules of the same tree it imports (anywhere in the file: a
    function-level import is still an arrow between the two files)."""
    edges: dict[str, set[str]] = {m: set() for m in mods}
    for m, path in mods.items():
        is_pkg = path.name == "__init__.py"
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = m.split(".") if is_pkg else m.split(".")[:-1]
                    base = base[:len(base) - (node.level - 1)]
                    module = ".".join(base + ([node.module] if node.module else []))
                else:
                    module = node.module or ""
                # "from pkg import sub" imports the submodule; "from pkg import name" the package
                subs = [f"{module}.{a.name}" for a in node.names if f"{module}.{a.name}" in mods]
                targets = subs if len(subs) == len(node.names) else [module, *subs]
            else:
                continue
            edges[m].update(t for t in targets if t in mods and t != m)
    return edges


def _strip_comments(text: str) -> str:
    return re.sub(r"/\*.*?\*/|//[^\n]*", " ", text, flags=re.S)


def _code_calls(header: str) -> set[str]:
    """Names called inside the header's function bodies and macros (not its prototypes,
    not an extern "C" block's)."""
    text = _strip_comments(header).replace('extern "C" {', " ")
    depth, body = 0, []
    for ch in text:
        if ch == "{":
            depth += 1
        elif ch == "}":
            depth -= 1
        elif depth > 0:
            body.append(ch)
    macros = " ".join(re.findall(r"^\s*#\s*define\s+\w+(?:\([^)]*\))?(.*(?:\\\n.*)*)", text, re.M))
    return set(re.findall(r"\b(\w+)\s*\(", "".join(body) + " " + macros)) - _KEYWORDS


def c_edges(root: Path) -> tuple[dict[Path, set[Path]], list[str]]:
    """file -> the files it includes (quoted includes resolved in the tree), and the
    call-backs: a header whose code calls a function defined in a .c that includes it."""
    files = [p for p in root.rglob("*") if p.suffix in (".c", ".h")]
    by_name: dict[str, list[Path]] = {}
    for p in files:
        by_name.setdefault(p.name, []).append(p)
    edges: dict[Path, set[Path]] = {p: set() for p in files}
    texts = {p: p.read_text(encoding="utf-8", errors="replace") for p in files}
    for p in files:
        for inc in re.findall(r'^\s*#\s*include\s+"([^"]+)"', texts[p], re.M):
            cands = [q for q in by_name.get(Path(inc).name, []) if str(q).endswith(inc)]
            near = [q for q in cands if q.parent == p.parent]
            edges[p].update((near or cands)[:1])
    callbacks = []
    for c in (p for p in files if p.suffix == ".c"):
        defined = set(_DEFINITION.findall(_strip_comments(texts[c])))
        for h in (q for q in edges[c] if q.suffix == ".h"):
            own = set(_DEFINITION.findall(_strip_comments(texts[h])))
            hit = sorted((_code_calls(texts[h]) & defined) - own)
            if hit:
                callbacks.append(f"{_rel(h)} calls {', '.join(hit)}, defined in {_rel(c)}, which includes it")
    return edges, callbacks


def cycles(edges: dict) -> list[list]:
    """The strongly connected components of more than one node (Tarjan)."""
    index: dict = {}
    low: dict = {}
    stack: list = []
    on: set = set()
    out: list[list] = []

    def visit(v) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges[v]:
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
                out.append(sorted(comp, key=str))

    sys.setrecursionlimit(max(10_000, sys.getrecursionlimit()))
    for v in list(edges):
        if v not in index:
            visit(v)
    return out


def circles() -> list[str]:
    """Every circle found, one line each (empty: none)."""
    found = []
    for base, package in PYTHON_TREES:
        for comp in cycles(python_edges(_python_modules(base, package))):
            found.append(f"Python, {_rel(base)}: " + " <-> ".join(comp))
    for root in C_TREES:
        edges, callbacks = c_edges(root)
        for comp in cycles(edges):
            found.append("C includes: " + " <-> ".join(_rel(p) for p in comp))
        found += [f"C call-back: {line}" for line in callbacks]
    return found


def main() -> int:
    found = circles()
    for line in found:
        print(line)
    print(f"check_circles: {len(found)} circle(s) in host_tools/abbe, bench/report, scripts, lib, port")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
