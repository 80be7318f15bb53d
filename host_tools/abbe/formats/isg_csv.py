"""Reader of Beckhoff TF5280 ISG CSV error files (and their ``.lis`` list file).

Format (Beckhoff TF5280 "ISG CSV format", "Units of measure"): blocks separated by a
line ``#``; each block a header of argument names (X, Y, Z, mm) and parameter names,
then one record per line; ``//`` starts a comment; values in mm and rad. A block with
one argument and component errors of that argument's axis (``X EXX EYX ...``) gives
curves; a block without arguments gives location errors (one record). Blocks with
several arguments (a map over X, Y, Z) are not a component model and are refused.
A ``.lis`` file names the error files (``file[j]``, ``file_format[j]``: ISG_CSV or
ETALON_EXCHANGE); :func:`read_list` reads them all.

Every problem raises AbbeInputError with file, line and field.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from abbe.errors import AbbeInputError, parse_finite
from abbe.formats.components import ComponentData, check_name

ARGUMENTS = ("X", "Y", "Z", "A", "B", "C")
MAX_BYTES = 64 * 1024 * 1024


def read_text(path: Path) -> str:
    try:
        if path.stat().st_size > MAX_BYTES:
            raise AbbeInputError(f"larger than {MAX_BYTES >> 20} MiB", file=str(path))
        return path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise AbbeInputError(f"cannot read: {exc.strerror}", file=str(path)) from None
    except UnicodeDecodeError:
        raise AbbeInputError("not UTF-8 text", file=str(path)) from None


def read_isg_csv(path: str | Path, data: ComponentData | None = None) -> ComponentData:
    """Curves and location errors of an ISG CSV file (module docstring)."""
    p = Path(path)
    src = str(p)
    out = data or ComponentData(file=src)
    header: list[str] | None = None
    hline = 0
    rows: list[tuple[int, list[float]]] = []

    def flush() -> None:
        if header is None:
            return
        args = [h for h in header if h in ARGUMENTS]
        names = [h for h in header if h not in ARGUMENTS]
        if header[:len(args)] != args:
            raise AbbeInputError("arguments (X, Y, Z, ...) must come first in the header",
                                 file=src, line=hline, field=header[0])
        if not rows:
            raise AbbeInputError("a header without records", file=src, line=hline,
                                 field=header[0])
        vals = np.array([r for _, r in rows])
        if not args:
            if len(rows) != 1:
                raise AbbeInputError("location errors take one record", file=src,
                                     line=rows[1][0], field=names[0])
            for i, n in enumerate(names):
                out.add_location(n, float(vals[0, i]), f"{p.name}:{hline}", hline)
            return
        if len(args) > 1:
            raise AbbeInputError(f"a block over {' '.join(args)}: a multi-dimensional map is not "
                                 "a component model (export it with layout=components)",
                                 file=src, line=hline, field=" ".join(args))
        if args[0] not in ("X", "Y", "Z"):
            for n in names:
                out.ignored.append(f"{n} over {args[0]} ({p.name}:{hline})")
            return
        pos = vals[:, 0]
        for i, n in enumerate(names, start=1):
            if n[0] == "E" and n[2:] != args[0] and n[2] in "XYZ":
                raise AbbeInputError(f"{n} is an error of axis {n[2]} in a block over {args[0]}",
                                     file=src, line=hline, field=n)
            out.add_curve(n, pos, vals[:, i], f"{p.name}:{hline}", hline, src)

    for no, raw in enumerate(read_text(p).splitlines(), start=1):
        line = raw.split("//", 1)[0].strip()
        if not line:
            continue
        if line == "#":
            flush()
            header, rows = None, []
            continue
        cells = line.replace(",", " ").replace(";", " ").split()
        if not cells:
            continue
        if header is None:
            for c in cells:
                if c not in ARGUMENTS:
                    check_name(c, src, no)
            if len(set(cells)) != len(cells):
                raise AbbeInputError("a column named twice", file=src, line=no, field=line)
            header, hline = cells, no
            continue
        if len(cells) != len(header):
            raise AbbeInputError(f"{len(cells)} values for {len(header)} columns", file=src,
                                 line=no, field=header[min(len(cells), len(header) - 1)])
        rows.append((no, [parse_finite(c, file=src, line=no, field=header[i])
                          for i, c in enumerate(cells)]))
    flush()
    return out


def read_list(path: str | Path) -> ComponentData:
    """All error files named by a TF5280 ``.lis`` file (``file[j]`` / ``file_format[j]``)."""
    from abbe.formats.etalon import read_etalon

    p = Path(path)
    files: dict[str, tuple[str, int]] = {}
    fmts: dict[str, str] = {}
    for no, raw in enumerate(read_text(p).splitlines(), start=1):
        line = raw.split("#", 1)[0].split("//", 1)[0].strip()
        if not line:
            continue
        key, _, val = line.partition(" ")
        key, val = key.strip(), val.strip()
        if key.startswith("file[") and key.endswith("]"):
            files[key[5:-1]] = (val, no)
        elif key.startswith("file_format[") and key.endswith("]"):
            fmts[key[12:-1]] = val
    if not files:
        raise AbbeInputError("no file[j] entries", file=str(p), field="file[0]")
    out = ComponentData(file=str(p))
    for j, (name, no) in sorted(files.items()):
        f = (p.parent / name.replace("\\", "/")) if not Path(name).is_absolute() else Path(name)
        fmt = fmts.get(j, "ISG_CSV")
        if fmt == "ISG_CSV":
            read_isg_csv(f, out)
        elif fmt == "ETALON_EXCHANGE":
            read_etalon(f, out)
        else:
            raise AbbeInputError(f"unknown file format {fmt!r} (ISG_CSV, ETALON_EXCHANGE)",
                                 file=str(p), line=no, field=f"file_format[{j}]")
    return out
