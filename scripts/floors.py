#!/usr/bin/env python3
"""Print the floors of the `abbe` package from its import-linter contracts.

The contracts in host_tools/pyproject.toml are the one source of the package's
dependency rule (`lint-imports` enforces them); docs/architecture.md shows the
picture this prints, between its "floors" markers, and
host_tools/tests/scripts/test_architecture_doc.py fails when the two differ.

    python3 scripts/floors.py            # print the picture
    python3 scripts/floors.py --write    # rewrite it in docs/architecture.md

Only the Python standard library (tomllib: Python 3.11).
"""

from __future__ import annotations

import argparse
import sys
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PYPROJECT = REPO / "host_tools" / "pyproject.toml"
DOC = REPO / "docs" / "architecture.md"
BEGIN = "<!-- floors: written by scripts/floors.py from host_tools/pyproject.toml; do not edit -->"
END = "<!-- /floors -->"


def _short(module: str) -> str:
    return module.removeprefix("abbe.")


def picture(pyproject: Path = PYPROJECT) -> list[str]:
    """The floors (top = imports everything below it) and the other contracts, as
    markdown lines: a fenced block of floors, then one bullet per extra contract."""
    contracts = tomllib.loads(pyproject.read_text(encoding="utf-8"))["tool"]["importlinter"]["contracts"]
    layered = [c for c in contracts if c["type"] == "layers"]
    if len(layered) != 1:
        raise SystemExit(f"{pyproject}: expected one 'layers' contract, found {len(layered)}")
    floors = layered[0]["layers"]
    out = ["```"]
    for i, floor in enumerate(floors):
        names = [_short(m.strip()) for m in floor.split("|")]
        note = "  (siblings: never import each other)" if len(names) > 1 else ""
        out.append(f"floor {len(floors) - i}  " + " | ".join(names) + note)
    out.append("```")
    out.append("")
    out.append("Each floor may import only the floors below it (never above, never a sibling).")
    for c in contracts:
        if c["type"] == "forbidden":
            src = ", ".join(_short(m) for m in c["source_modules"])
            bad = ", ".join(_short(m) for m in c["forbidden_modules"])
            out.append(f"Forbidden as well: {src} must not import {bad} ({c['name']}).")
        elif c["type"] != "layers":
            out.append(f"Contract ({c['type']}): {c['name']}.")
    return out


def documented(doc: Path = DOC) -> list[str]:
    """The lines between the markers of docs/architecture.md."""
    lines = doc.read_text(encoding="utf-8").splitlines()
    try:
        i, j = lines.index(BEGIN), lines.index(END)
    except ValueError:
        raise SystemExit(f"{doc}: the markers {BEGIN!r} / {END!r} are missing") from None
    return lines[i + 1:j]


def write(doc: Path = DOC) -> None:
    lines = doc.read_text(encoding="utf-8").splitlines()
    i, j = lines.index(BEGIN), lines.index(END)
    doc.write_text("\n".join(lines[:i + 1] + picture() + lines[j:]) + "\n", encoding="utf-8")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help=f"rewrite the picture in {DOC.relative_to(REPO)}")
    args = ap.parse_args()
    if args.write:
        write()
    else:
        print("\n".join(picture()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
