"""Reader of Beckhoff TF5280 ISG CSV error files (and their ``.lis`` list file).

Format (Beckhoff TF5280 "ISG CSV format", "Units of measure"): blocks separated by a
line ``#``; each block a header of argument names (X, Y, Z, mm) and parameter names,
then one record per line; ``//`` starts a comment; values in mm and rad. A block with
one argument and component errors of that argument's axis (``X EXX EYX ...``) gives
curves; a block without arguments gives location errors (one record). Blocks with
several arguments (a map over X, Y, Z) are not a component model and are refused.
Cells are separated by ASCII spaces, tabs, commas or semicolons; every number goes
through the strict parser with the range of its column
(:func:`abbe.formats.components.value_range`).

A ``.lis`` file (TF5280 "General configuration", P-VOLC parameters) is ``KEY VALUE``
lines, ``#`` or ``//`` comments, keys in any case; it names the error files
(``file[j]`` with its ``file_format[j]``: ISG_CSV or ETALON_EXCHANGE, j = 0..9) and
:func:`read_list` reads them all. Unknown keys are refused with a suggestion; so are
settings that change what the values mean (``negate``, ``set_to_zero``,
``alternative_model`` TRUE) and a kinematic chain other than abbe's model (``chain
XYZ``, ``workpiece_axes 2``), rather than misread.

Both are read by the bounded text reader (size and line limits of
:mod:`abbe.formats.limits`, BOM, CRLF / CR, UTF-8); every problem raises
AbbeInputError with file, line and field.
"""

from __future__ import annotations

import re
from pathlib import Path, PureWindowsPath

import numpy as np

from abbe.errors import AbbeInputError, parse_int, parse_number_column
from abbe.formats.components import (
    LOCATION,
    ComponentData,
    argument_range,
    check_name,
    value_range,
)
from abbe.formats.limits import (
    COMPONENT_FILE_MAX_BYTES,
    COMPONENT_FILE_MAX_RECORDS,
    LIS_MAX_BYTES,
    LIS_MAX_FILES,
)
from abbe.formats.structured import unknown_key
from abbe.formats.text import read_text

ARGUMENTS = ("X", "Y", "Z", "A", "B", "C")
_SEP = re.compile(r"[ \t,;]+")


def split_cells(line: str) -> list[str]:
    """The cells of an ISG CSV line (ASCII separators only: a no-break space is not one)."""
    return [c for c in _SEP.split(line) if c]


def read_isg_csv(path: str | Path, data: ComponentData | None = None) -> ComponentData:
    """Curves and location errors of an ISG CSV file (module docstring)."""
    tf = read_text(path, what="ISG CSV file", max_bytes=COMPONENT_FILE_MAX_BYTES)
    src = tf.name
    short = Path(src).name
    out = data or ComponentData(file=src)
    if not out.sha256:
        out.sha256 = tf.sha256
    header: list[str] | None = None
    hline = 0
    rows: list[list[str]] = []
    lines: list[int] = []
    records = 0

    def flush() -> None:
        if header is None:
            return
        args = [h for h in header if h in ARGUMENTS]
        names = [h for h in header if h not in ARGUMENTS]
        if header[:len(args)] != args:
            raise AbbeInputError("arguments (X, Y, Z, ...) must come first in the header",
                                 file=src, line=hline, field=header[0])
        if not names:
            raise AbbeInputError("a header of arguments only: expected error parameters after "
                                 "them", file=src, line=hline, field=header[-1])
        if not rows:
            raise AbbeInputError("a header without records", file=src, line=hline,
                                 field=header[0])
        ln = np.array(lines, dtype=np.int64)
        cols = list(zip(*rows))
        vals = {}
        for i, h in enumerate(header):
            if h in ARGUMENTS:
                lo, hi, unit = argument_range(h)
                scale = 1.0
            else:
                lo, hi, unit, scale = value_range(h)
            vals[h] = parse_number_column(cols[i], ln, file=src, field=h, lo=lo, hi=hi,
                                          unit=unit, scale=scale)
        if not args:
            if len(rows) != 1:
                raise AbbeInputError("location errors take one record", file=src,
                                     line=int(ln[1]), field=names[0])
            for n in names:
                out.add_location(n, float(vals[n][0]), f"{short}:{hline}", hline, src)
            return
        if len(args) > 1:
            raise AbbeInputError(f"a block over {' '.join(args)}: a multi-dimensional map is not "
                                 "a component model (export it with layout=components)",
                                 file=src, line=hline, field=" ".join(args))
        arg = args[0]
        for n in names:
            if n in LOCATION:
                raise AbbeInputError(f"the location error {n} over {arg}: expected it in a block "
                                     "without arguments (one record)", file=src, line=hline,
                                     field=n)
        if arg not in ("X", "Y", "Z"):
            for n in names:
                out.ignored.append(f"{n} over {arg} ({short}:{hline})")
            return
        pos = vals[arg]
        for n in names:
            if n[0] == "E" and n[2] != arg and n[2] in "XYZ":
                raise AbbeInputError(f"{n} is an error of axis {n[2]} in a block over {arg}",
                                     file=src, line=hline, field=n)
            out.add_curve(n, pos, vals[n], f"{short}:{hline}", hline, src)

    for no, raw in tf.lines():
        line = raw.split("//", 1)[0].strip(" \t")
        if not line:
            continue
        if line == "#":
            flush()
            header, rows, lines = None, [], []
            continue
        cells = split_cells(line)
        if not cells:
            continue
        if header is None:
            for c in cells:
                if c not in ARGUMENTS:
                    check_name(c, src, no)
            if len(set(cells)) != len(cells):
                dup = next(c for c in cells if cells.count(c) > 1)
                raise AbbeInputError("a column named twice", file=src, line=no, field=dup)
            header, hline = cells, no
            continue
        if len(cells) != len(header):
            raise AbbeInputError(f"{len(cells)} values for {len(header)} columns", file=src,
                                 line=no, field=header[min(len(cells), len(header) - 1)])
        records += 1
        if records > COMPONENT_FILE_MAX_RECORDS:
            raise AbbeInputError(f"more than {COMPONENT_FILE_MAX_RECORDS} records: the limit for "
                                 "an error file (docs/formats.md, \"Limits\")", file=src, line=no)
        rows.append(cells)
        lines.append(no)
    flush()
    return out


# --------------------------------------------------------------------------- .lis

FILE_FORMATS = ("ISG_CSV", "ETALON_EXCHANGE")
INTERPOLATIONS = ("GRID", "SCATTER", "AUTO", "PATH", "PATH_XY")
_BOOLS = {"TRUE": True, "FALSE": False, "1": True, "0": False}
#: TF5280 compensation list keys (P-VOLC-00001 ..): lower case -> kind.
LIST_KEYS = {
    "x": "axis", "y": "axis", "z": "axis", "a": "axis", "b": "axis", "c": "axis",
    "chain": "text", "workpiece_axes": "count", "negate": "off", "set_to_zero": "off",
    "alternative_model": "off", "file[j]": "file", "file_format[j]": "format",
    "interpolation": "interpolation", "enable_splicing": "bool", "diagnosis_file": "text",
    "manual_activation": "bool", "filter_steps": "count", "associate_to_channel": "bool",
    "use_axis_offsets": "bool",
}
#: The machine of abbe's model (docs/concepts.md): X and Y carry the workpiece, Z the tool.
MODEL_CHAIN = "XYZ"
MODEL_WORKPIECE_AXES = 2
_MODEL_CHAIN = (f"abbe's model is the chain {MODEL_CHAIN} with {MODEL_WORKPIECE_AXES} workpiece "
                "axes (X, Y carry the workpiece, Z the tool); a list for another machine cannot "
                "be read into it")
_INDEXED = re.compile(r"^(file|file_format)\[([0-9]+)\]$")
_OFF_WHY = {"negate": "the controller negates the file's values",
            "set_to_zero": "the controller applies zero instead of the file's values",
            "alternative_model": "the controller uses another calculation rule"}


def _list_key(key: str, src: str, no: int) -> tuple[str, int | None]:
    """(kind key of LIST_KEYS, index j or None) of a list file key."""
    low = key.lower()
    m = _INDEXED.match(low)
    if m:
        j = parse_int(m.group(2), file=src, line=no, field=key, lo=0, hi=LIS_MAX_FILES - 1)
        return f"{m.group(1)}[j]", j
    if low in LIST_KEYS:
        return low, None
    msg = unknown_key(low, [k for k in LIST_KEYS], "key")
    if low.startswith("vol_comp["):
        msg = "a start-up list entry (hochlauf.lis), not a compensation list key; " + msg
    raise AbbeInputError(msg, file=src, line=no, field=key if len(key) <= 40 else key[:30] + "...")


def _resolve(list_path: Path, name: str, out: ComponentData, src: str, no: int) -> Path:
    """The path of ``file[j]``: relative to the list file; a Windows absolute path (the
    controller's ``C:\\...``) is looked for beside the list file by its name."""
    win = PureWindowsPath(name)
    if win.drive or name.startswith("\\"):
        local = list_path.parent / win.name
        out.notes.append(f"{Path(src).name}:{no}: {name} (a path on the controller) read as "
                         f"{win.name} beside the list file")
        return local
    p = Path(name.replace("\\", "/"))
    return p if p.is_absolute() else list_path.parent / p


def read_list(path: str | Path) -> ComponentData:
    """All error files named by a TF5280 ``.lis`` file (module docstring)."""
    from abbe.formats.etalon import read_etalon

    tf = read_text(path, what="TF5280 list file", max_bytes=LIS_MAX_BYTES)
    src = tf.name
    p = Path(src)
    files: dict[int, tuple[str, int]] = {}
    fmts: dict[int, tuple[str, int]] = {}
    seen: dict[str, int] = {}
    logical: dict[int, str] = {}
    for no, raw in tf.lines():
        line = raw.split("//", 1)[0].split("#", 1)[0].strip(" \t")
        if not line:
            continue
        parts = line.split(None, 1) if line.isascii() else re.split(r"[ \t]+", line, maxsplit=1)
        key = parts[0]
        val = parts[1].strip(" \t") if len(parts) > 1 else ""
        kind, j = _list_key(key, src, no)
        canon = kind.replace("[j]", f"[{j}]")
        if canon in seen:
            raise AbbeInputError(f"given twice (first on line {seen[canon]})", file=src, line=no,
                                 field=key)
        seen[canon] = no
        if not val:
            raise AbbeInputError("expected KEY VALUE, got no value", file=src, line=no, field=key)
        how = LIST_KEYS[kind]
        if how == "axis":
            n = parse_int(val, file=src, line=no, field=key, lo=1, hi=65535)
            if n in logical:
                raise AbbeInputError(f"logical axis {n} is already axis {logical[n]}", file=src,
                                     line=no, field=key)
            logical[n] = kind.upper()
        elif how == "count":
            n = parse_int(val, file=src, line=no, field=key, lo=0, hi=65535)
            if kind == "workpiece_axes" and n != MODEL_WORKPIECE_AXES:
                raise AbbeInputError(f"workpiece_axes {n}: {_MODEL_CHAIN}", file=src, line=no,
                                     field=key)
        elif kind == "chain":
            if val.upper() != MODEL_CHAIN:
                raise AbbeInputError(f"chain {val[:40]!r}: {_MODEL_CHAIN}", file=src, line=no,
                                     field=key)
        elif how in ("bool", "off"):
            b = _BOOLS.get(val.upper())
            if b is None:
                raise AbbeInputError(f"expected TRUE or FALSE, got {val!r}", file=src, line=no,
                                     field=key)
            if how == "off" and b:
                raise AbbeInputError(f"{key} TRUE is not read: {_OFF_WHY[kind]} (abbe import "
                                     "reads the values as written; set it FALSE)", file=src,
                                     line=no, field=key)
        elif how == "interpolation":
            if val.upper() not in INTERPOLATIONS:
                raise AbbeInputError(f"expected one of {', '.join(INTERPOLATIONS)}, got {val!r}",
                                     file=src, line=no, field=key)
        elif how == "format":
            if val.upper() not in FILE_FORMATS:
                raise AbbeInputError(unknown_key(val.upper(), FILE_FORMATS, "file format"),
                                     file=src, line=no, field=key)
            assert j is not None
            fmts[j] = (val.upper(), no)
        elif how == "file":
            assert j is not None
            files[j] = (val, no)
    if not files:
        raise AbbeInputError("no file[j] entries", file=src, field="file[0]")
    for j, (_f, no) in fmts.items():
        if j not in files:
            raise AbbeInputError(f"file_format[{j}] without file[{j}]", file=src, line=no,
                                 field=f"file_format[{j}]")
    for j, (_f, no) in files.items():
        if j not in fmts:
            raise AbbeInputError(f"file[{j}] without file_format[{j}] (ISG_CSV or "
                                 "ETALON_EXCHANGE): every parameter file names its format",
                                 file=src, line=no, field=f"file_format[{j}]")
    out = ComponentData(file=src, sha256=tf.sha256)
    for j, (name, no) in sorted(files.items()):
        f = _resolve(p, name, out, src, no)
        fmt = fmts[j][0]
        try:
            if fmt == "ISG_CSV":
                read_isg_csv(f, out)
            else:
                read_etalon(f, out)
        except AbbeInputError as exc:
            if exc.file == str(f) and exc.line is None and "cannot read" in exc.message:
                raise AbbeInputError(f"{exc.message} ({f})", file=src, line=no,
                                     field=f"file[{j}]") from None
            raise
    return out
