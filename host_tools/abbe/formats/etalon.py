"""Reader of the Etalon exchange format (LaserTRACER results, "Vendor" variant).

Format (Beckhoff TF5280 "Etalon Exchange Format"): INI-like blocks, each starting
with the parameter's name in brackets; ``//`` starts a comment. A position error has
``VALUE = v``; a component error a lookup table ``Gridpoints = { ... }`` of records
``argument value`` (the argument in mm), closed by ``}``; records may share a line
and may follow the ``{``. Values in mm and rad, names ISO 230-1 (docs/exports.md).

Strict: the keys are VALUE and Gridpoints (any case), one of them per block, each
once; any other key is refused with a suggestion (a misspelt ``Gridpionts`` would
otherwise drop a curve). Parameters of rotary axes and tool parameters are listed as
ignored. Read by the bounded text reader; numbers by the strict parser with the
range of the parameter (:func:`abbe.formats.components.value_range`); every
problem raises AbbeInputError with file, line and field.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from abbe.errors import AbbeInputError, parse_number, parse_number_column
from abbe.formats.components import (
    COMPONENT,
    LOCATION,
    ComponentData,
    argument_range,
    check_name,
    value_range,
)
from abbe.formats.limits import COMPONENT_FILE_MAX_BYTES, COMPONENT_FILE_MAX_RECORDS
from abbe.formats.structured import unknown_key
from abbe.formats.text import read_text

SECTION = re.compile(r"^\[[ \t]*([A-Za-z0-9]+)[ \t]*\]$")
KEYS = ("VALUE", "Gridpoints")


class _Block:
    def __init__(self, name: str, line: int) -> None:
        self.name, self.line = name, line
        self.key: str | None = None
        self.args: list[str] = []
        self.vals: list[str] = []
        self.lines: list[int] = []


def read_etalon(path: str | Path, data: ComponentData | None = None) -> ComponentData:
    """Curves and location errors of an Etalon exchange file (module docstring)."""
    tf = read_text(path, what="Etalon exchange file", max_bytes=COMPONENT_FILE_MAX_BYTES)
    src = tf.name
    short = Path(src).name
    out = data or ComponentData(file=src)
    if not out.sha256:
        out.sha256 = tf.sha256
    blk: _Block | None = None
    in_grid = False
    seen: set[str] = set()
    records = 0

    def close_block() -> None:
        if blk is None:
            return
        if blk.key is None:
            raise AbbeInputError("block without VALUE or Gridpoints", file=src, line=blk.line,
                                 field=blk.name)

    def close_grid(b: _Block) -> None:
        name = b.name
        if not b.args:
            raise AbbeInputError("Gridpoints without records", file=src, line=b.line,
                                 field=name)
        m = COMPONENT.match(name)
        lo, hi, unit = argument_range(m.group(2) if m else "X")
        ln = np.array(b.lines, dtype=np.int64)
        pos = parse_number_column(b.args, ln, file=src, field=f"{name} argument", lo=lo, hi=hi,
                                  unit=unit)
        vlo, vhi, vunit, scale = value_range(name)
        vals = parse_number_column(b.vals, ln, file=src, field=f"{name} value", lo=vlo, hi=vhi,
                                   unit=vunit, scale=scale)
        out.add_curve(name, pos, vals, f"{short}:{b.line}", b.line, src)

    def grid_body(text: str, no: int) -> bool:
        """Records of a Gridpoints line; True when it closes the table."""
        nonlocal records
        assert blk is not None
        closed = "}" in text
        if closed:
            text, rest = text.split("}", 1)
            if rest.strip(" \t"):
                raise AbbeInputError("text after '}'", file=src, line=no, field=blk.name)
        cells = [c for c in re.split(r"[ \t]+", text) if c]
        if len(cells) % 2:
            raise AbbeInputError("expected records 'argument value'", file=src, line=no,
                                 field=blk.name)
        for i in range(0, len(cells), 2):
            records += 1
            if records > COMPONENT_FILE_MAX_RECORDS:
                raise AbbeInputError(f"more than {COMPONENT_FILE_MAX_RECORDS} records: the limit "
                                     "for an error file (docs/formats.md, \"Limits\")", file=src,
                                     line=no, field=blk.name)
            blk.args.append(cells[i])
            blk.vals.append(cells[i + 1])
            blk.lines.append(no)
        return closed

    for no, raw in tf.lines():
        line = raw.split("//", 1)[0].strip(" \t")
        if not line:
            continue
        if in_grid:
            assert blk is not None
            if grid_body(line, no):
                close_grid(blk)
                in_grid = False
            continue
        if line.startswith("["):
            m = SECTION.match(line)
            if not m:
                raise AbbeInputError("expected a block name [NAME]", file=src, line=no,
                                     field=line[:40])
            close_block()
            name = m.group(1)
            check_name(name, src, no)
            if name in seen:
                raise AbbeInputError(f"block [{name}] given twice", file=src, line=no, field=name)
            seen.add(name)
            blk = _Block(name, no)
            continue
        key, eq, val = line.partition("=")
        key, val = key.strip(" \t"), val.strip(" \t")
        if blk is None:
            raise AbbeInputError("a line before the first [NAME] block", file=src, line=no,
                                 field=key[:40] or None)
        if not eq:
            raise AbbeInputError("expected KEY = VALUE", file=src, line=no, field=blk.name)
        canon = next((k for k in KEYS if k.lower() == key.lower()), None)
        if canon is None:
            raise AbbeInputError(unknown_key(key, KEYS, f"key in [{blk.name}]"), file=src,
                                 line=no, field=f"{blk.name}.{key[:40]}")
        if blk.key is not None:
            raise AbbeInputError(f"a second key in [{blk.name}]: a block holds one VALUE or one "
                                 "Gridpoints", file=src, line=no, field=f"{blk.name}.{canon}")
        blk.key = canon
        if canon == "VALUE":
            if COMPONENT.match(blk.name):
                raise AbbeInputError(f"{blk.name} is a component error: expected Gridpoints = "
                                     "{ ... }", file=src, line=no, field=blk.name)
            lo, hi, unit, scale = value_range(blk.name)
            v = parse_number(val, file=src, line=no, field=blk.name, lo=lo, hi=hi, unit=unit,
                             scale=scale)
            out.add_location(blk.name, v, f"{short}:{no}", no, src)
        else:
            if blk.name in LOCATION:
                raise AbbeInputError(f"{blk.name} is a location error: expected VALUE = v",
                                     file=src, line=no, field=blk.name)
            if not val.startswith("{"):
                raise AbbeInputError("expected Gridpoints = {", file=src, line=no, field=blk.name)
            blk.line = no
            if grid_body(val[1:], no):
                close_grid(blk)
            else:
                in_grid = True
    if in_grid:
        assert blk is not None
        raise AbbeInputError("Gridpoints not closed by '}'", file=src, line=blk.line,
                             field=blk.name)
    close_block()
    return out
