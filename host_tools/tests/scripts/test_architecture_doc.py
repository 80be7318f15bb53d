"""docs/architecture.md draws the floors the import contracts hold (scripts/floors.py),
and no two files of host_tools/abbe, bench/report, scripts, lib or port lean on each
other (scripts/check_circles.py). Issue 41."""

from __future__ import annotations

import importlib.util
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]


def _script(name: str):
    spec = importlib.util.spec_from_file_location(f"_abbe_script_{name}", REPO / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_documented_floors_are_the_contracts() -> None:
    floors = _script("floors")
    picture = floors.picture()
    assert floors.documented() == picture, "run: python3 scripts/floors.py --write"
    # the picture names every floor of the layers contract, top first
    assert picture[1].startswith("floor 7  cli") and "exports | programs" in "\n".join(picture)


def test_a_changed_contract_changes_the_picture(tmp_path: Path) -> None:
    floors = _script("floors")
    text = (REPO / "host_tools" / "pyproject.toml").read_text(encoding="utf-8")
    moved = text.replace('    "abbe.exports | abbe.programs",\n', '    "abbe.exports",\n    "abbe.programs",\n')
    assert moved != text
    (tmp_path / "pyproject.toml").write_text(moved, encoding="utf-8")
    changed = floors.picture(tmp_path / "pyproject.toml")
    assert changed != floors.documented()
    assert "floor 5  exports" in changed and "floor 4  programs" in changed


def test_no_circle_of_files() -> None:
    assert _script("check_circles").circles() == []


def test_circles_are_found(tmp_path: Path) -> None:
    check = _script("check_circles")
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from pkg.b import g\n")
    (pkg / "b.py").write_text("def g():\n    from pkg import a\n")
    (pkg / "c.py").write_text("from pkg import a\n")
    assert check.cycles(check.python_edges(check._python_modules(tmp_path, "pkg"))) == [["pkg.a", "pkg.b"]]

    src = tmp_path / "src"
    src.mkdir()
    (src / "shared.h").write_text("int helper(int x);\nstatic inline int twice(int x) { return helper(x) * 2; }\n")
    (src / "user.c").write_text('#include "shared.h"\nint helper(int x)\n{\n    return x + 1;\n}\n')
    (src / "x.h").write_text('#include "y.h"\n')
    (src / "y.h").write_text('#include "x.h"\n')
    edges, callbacks = check.c_edges(tmp_path)
    assert [[p.name for p in comp] for comp in check.cycles(edges)] == [["x.h", "y.h"]]
    assert len(callbacks) == 1 and "shared.h calls helper" in callbacks[0] and "user.c" in callbacks[0]


#: Issue 41: no source file over this many lines outside tests (and the carried
#: third-party sources): a file that grows past it is split by concern.
MAX_LINES = 700
SOURCE_SUFFIXES = (".c", ".h", ".py", ".sh", ".comp")


def _source_files() -> list[Path]:
    out = []
    for top in ("lib", "port", "host_tools", "bench", "scripts", "cases"):
        for p in (REPO / top).rglob("*"):
            rel = p.relative_to(REPO).parts
            if (p.suffix in SOURCE_SUFFIXES and p.is_file() and "tests" not in rel
                    and "fuzz" not in rel and ".venv" not in rel and "build" not in rel[0]):
                out.append(p)
    return out


def test_no_source_file_is_over_700_lines() -> None:
    files = _source_files()
    assert len(files) > 100  # the walk sees the tree, not an empty folder
    long = sorted((sum(1 for _ in p.open(encoding="utf-8", errors="replace")), str(p.relative_to(REPO)))
                  for p in files)
    over = [f"{path}: {n} lines" for n, path in long if n > MAX_LINES]
    assert not over, "split by concern (docs/architecture.md): " + "; ".join(over)
