"""Reader of the Etalon exchange format (LaserTRACER results, "Vendor" variant).

Format (Beckhoff TF5280 "Etalon Exchange Format"): INI-like blocks, each starting
with the parameter's name in brackets; ``//`` starts a comment. A position error has
``VALUE = v``; a component error a lookup table ``Gridpoints = { ... }`` of records
``argument value`` (one per line, the argument in mm), closed by ``}``. Values in mm
and rad, names ISO 230-1 (docs/exports.md). Keys other than VALUE and Gridpoints are
listed as ignored, never dropped silently.

Every problem raises AbbeInputError with file, line and field.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from abbe.errors import AbbeInputError, parse_finite
from abbe.formats.components import ComponentData, check_name
from abbe.formats.isg_csv import read_text

SECTION = re.compile(r"^\[\s*([A-Za-z0-9]+)\s*\]$")


def read_etalon(path: str | Path, data: ComponentData | None = None) -> ComponentData:
    """Curves and location errors of an Etalon exchange file."""
    p = Path(path)
    src = str(p)
    out = data or ComponentData(file=src)
    name: str | None = None
    grid: list[tuple[float, float]] | None = None
    gline = 0
    seen: set[str] = set()

    def close_grid() -> None:
        pts = np.array(grid, dtype=np.float64).reshape(-1, 2)
        out.add_curve(name, pts[:, 0], pts[:, 1], f"{p.name}:{gline}", gline, src)

    for no, raw in enumerate(read_text(p).splitlines(), start=1):
        line = raw.split("//", 1)[0].strip()
        if not line:
            continue
        if grid is not None:
            body, closed = line, False
            if "}" in line:
                body, rest = line.split("}", 1)
                if rest.strip():
                    raise AbbeInputError("text after '}'", file=src, line=no, field=name)
                closed = True
            cells = body.split()
            if len(cells) % 2:
                raise AbbeInputError("expected records 'argument value'", file=src, line=no,
                                     field=name)
            for i in range(0, len(cells), 2):
                grid.append((parse_finite(cells[i], file=src, line=no, field=f"{name} argument"),
                             parse_finite(cells[i + 1], file=src, line=no, field=f"{name} value")))
            if closed:
                close_grid()
                grid = None
            continue
        m = SECTION.match(line)
        if m:
            name = m.group(1)
            check_name(name, src, no)
            if name in seen:
                raise AbbeInputError(f"block [{name}] given twice", file=src, line=no, field=name)
            seen.add(name)
            continue
        if name is None:
            raise AbbeInputError("a line before the first [NAME] block", file=src, line=no,
                                 field=line.split("=")[0].strip())
        key, eq, val = line.partition("=")
        key, val = key.strip(), val.strip()
        if not eq:
            raise AbbeInputError("expected KEY = VALUE", file=src, line=no, field=name)
        if key.upper() == "VALUE":
            out.add_location(name, parse_finite(val, file=src, line=no, field=name),
                             f"{p.name}:{no}", no)
        elif key.lower() == "gridpoints":
            if not val.startswith("{"):
                raise AbbeInputError("expected Gridpoints = {", file=src, line=no, field=name)
            grid, gline = [], no
            inner = val[1:].strip()
            if inner:  # records on the same line
                if "}" in inner:
                    body = inner.split("}", 1)[0].split()
                    if len(body) % 2:
                        raise AbbeInputError("expected records 'argument value'", file=src,
                                             line=no, field=name)
                    for i in range(0, len(body), 2):
                        grid.append((parse_finite(body[i], file=src, line=no, field=name),
                                     parse_finite(body[i + 1], file=src, line=no, field=name)))
                    close_grid()
                    grid = None
                else:
                    raise AbbeInputError("records start on the line after 'Gridpoints = {'",
                                         file=src, line=no, field=name)
        else:
            out.ignored.append(f"{name}.{key} ({p.name}:{no})")
    if grid is not None:
        raise AbbeInputError("Gridpoints not closed by '}'", file=src, line=gline, field=name)
    return out
