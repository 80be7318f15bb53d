"""Table JSON (``model.json`` and ``--model X.json``): the table in um / urad / mm.

:func:`table_to_json` writes the documented object (docs/formats.md, "Table
JSON"); :func:`table_from_json` reads it back, naming the field of anything
missing or malformed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from abbe.errors import AbbeInputError, check_number
from abbe.errors.numbers import show_value
from abbe.formats.blob import FORMAT_MAJOR, FORMAT_MINOR
from abbe.formats.limits import BLOB_MAX_BYTES, TABLE_JSON_MAX_BYTES
from abbe.formats.structured import JsonLocator, json_from_bytes, load_json, unknown_key
from abbe.formats.text import read_bytes
from abbe.model.table import (
    AXES,
    LINEAR_TERMS,
    MAX_DEGREE,
    MAX_HARMONICS,
    MAX_REVERSAL_ROWS,
    TERMS,
    AxisTable,
    FourierBlock,
    Table,
)

JSON_FORMAT = "abbe-table"


def table_to_json(table: Table) -> dict:
    """A JSON-ready dict of ``table``: units in the key names, row names listed.

    Floats are written as Python floats, so ``table_from_json(table_to_json(t))``
    gives back exactly ``t``. ``version`` is the table format the blob of ``t``
    has: 1.1 if an axis has a reversal block (key ``reversal_cheb_um``, written
    only then), else 1.0.
    """
    axes: dict[str, Any] = {}
    minor = 0
    for a in AXES:
        ax = table.axes[a]
        terms: dict[str, list[float]] = {}
        for t in ax.present_terms():
            unit = "um" if t in LINEAR_TERMS else "urad"
            terms[f"{t}_{unit}"] = [float(v) for v in np.asarray(ax.coef[t]).reshape(-1)]
        axes[a] = {
            "travel_mm": [float(ax.travel_mm[0]), float(ax.travel_mm[1])],
            "trend_degree": None if ax.trend_degree is None else int(ax.trend_degree),
            "blocks": [None if b is None else {"period_mm": float(b.period_mm),
                                               "origin_mm": float(b.origin_mm),
                                               "harmonics": int(b.harmonics)}
                       for b in ax.blocks],
            "rows": ax.row_names(),
            "terms": terms,
            "backlash_um": float(ax.backlash_um),
            "backlash_takeup_mm": float(ax.backlash_takeup_mm),
            "thermal_expansion_ppm_per_k": float(ax.thermal_expansion_ppm_per_k),
            "thermal_offset_um_per_k": float(ax.thermal_offset_um_per_k),
            "thermal_tref_c": float(ax.thermal_tref_c),
        }
        if ax.reversal_cheb_um is not None:
            axes[a]["reversal_cheb_um"] = [float(v) for v in ax.reversal_cheb_um]
            minor = 1
    return {
        "format": JSON_FORMAT,
        "version": f"{FORMAT_MAJOR}.{minor}",
        "reference_mm": [float(v) for v in table.reference_mm],
        "tool_offset_mm": [float(v) for v in table.tool_offset_mm],
        "squareness_urad": {"S_xy": float(table.squareness_urad[0]),
                            "S_xz": float(table.squareness_urad[1]),
                            "S_yz": float(table.squareness_urad[2])},
        "axes": axes,
    }


_TOP_KEYS = ("format", "version", "reference_mm", "tool_offset_mm", "squareness_urad", "axes")
_AXIS_KEYS = ("travel_mm", "trend_degree", "blocks", "rows", "terms", "backlash_um",
              "backlash_takeup_mm", "thermal_expansion_ppm_per_k", "thermal_offset_um_per_k",
              "thermal_tref_c", "reversal_cheb_um")
_BLOCK_KEYS = ("period_mm", "origin_mm", "harmonics")
#: Ranges of the numbers of a table JSON (unit); the blob encoder checks the finer limits.
_RANGES = {"mm": 2147.0, "um": 1e7, "urad": 1e7, "ppm_per_k": 1e4, "um_per_k": 1e6, "c": 1e4}
_SHOW_UNIT = {"mm": "mm", "um": "um", "urad": "urad", "ppm_per_k": "ppm/K", "um_per_k": "um/K",
              "c": "deg C"}


class _Src:
    """Where a table JSON came from: file name and a field -> line locator."""

    def __init__(self, source: str, locator: JsonLocator | None) -> None:
        self.source = source
        self.loc = locator

    def err(self, msg: str, field: str | None = None) -> AbbeInputError:
        line = self.loc.line(field) if (self.loc is not None and field) else None
        return AbbeInputError(msg, file=self.source, line=line, field=field or None)

    def obj(self, v: Any, where: str, keys: tuple[str, ...]) -> dict:
        if not isinstance(v, dict):
            raise self.err(f"expected an object, got {show_value(v)}", where)
        for k in v:
            if k not in keys:
                raise self.err(unknown_key(k, keys), f"{where}.{k}" if where else k)
        return v

    def num(self, v: Any, where: str, unit: str) -> float:
        lim = _RANGES[unit]
        line = self.loc.line(where) if self.loc is not None else None
        return check_number(v, file=self.source, line=line, field=where, lo=-lim, hi=lim,
                            unit=_SHOW_UNIT[unit])

    def vec(self, v: Any, n: int, where: str, unit: str) -> tuple[float, ...]:
        if not isinstance(v, list) or len(v) != n:
            raise self.err(f"expected a list of {n} numbers ({unit}), got {show_value(v)}", where)
        return tuple(self.num(x, f"{where}[{i}]", unit) for i, x in enumerate(v))

    def int_(self, v: Any, where: str, lo: int, hi: int, what: str) -> int:
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise self.err(f"{what}: expected an integer in {lo}..{hi}, got {show_value(v)}", where)
        return v


def table_from_json(d: Any, source: str = "<json>", locator: JsonLocator | None = None) -> Table:
    """Build a Table from the dict of :func:`table_to_json`.

    Raises AbbeInputError naming ``source``, the field and (with ``locator``) its
    line for anything missing, malformed, out of range or unknown (a misspelt key
    is refused with a suggestion, never ignored). The blob's own limits are
    checked when the table is written.
    """
    src = _Src(source, locator)
    d = src.obj(d, "", _TOP_KEYS)
    fmt = d.get("format")
    if fmt != JSON_FORMAT:
        raise src.err(f"expected '{JSON_FORMAT}', got {show_value(fmt)}", "format")
    ver = d.get("version")
    if not isinstance(ver, str) or not ver.startswith(f"{FORMAT_MAJOR}."):
        raise src.err(f"expected table format {FORMAT_MAJOR}.x, got {show_value(ver)}", "version")
    minor = ver[len(f"{FORMAT_MAJOR}."):]
    if minor.isdigit() and int(minor) > FORMAT_MINOR:
        raise src.err(f"table format {ver} is newer than {FORMAT_MAJOR}.{FORMAT_MINOR}, the "
                      "newest this abbe reads", "version")
    if "reference_mm" not in d:
        raise src.err("missing", "reference_mm")
    ref = src.vec(d["reference_mm"], 3, "reference_mm", "mm")
    tool = src.vec(d.get("tool_offset_mm", [0.0, 0.0, 0.0]), 3, "tool_offset_mm", "mm")
    sqd = src.obj(d.get("squareness_urad", {}), "squareness_urad", ("S_xy", "S_xz", "S_yz"))
    sq = tuple(src.num(sqd.get(k, 0.0), f"squareness_urad.{k}", "urad")
               for k in ("S_xy", "S_xz", "S_yz"))
    if "axes" not in d:
        raise src.err("missing", "axes")
    axes_d = src.obj(d["axes"], "axes", AXES)
    axes: dict[str, AxisTable] = {}
    for a in AXES:
        pre = f"axes.{a}"
        if a not in axes_d:
            raise src.err(f"missing axis {a}: expected exactly the axes {list(AXES)}", "axes")
        ad = src.obj(axes_d[a], pre, _AXIS_KEYS)
        if "travel_mm" not in ad:
            raise src.err("missing", f"{pre}.travel_mm")
        travel = src.vec(ad["travel_mm"], 2, f"{pre}.travel_mm", "mm")
        deg = ad.get("trend_degree")
        if deg is not None:
            deg = src.int_(deg, f"{pre}.trend_degree", 0, MAX_DEGREE, "trend degree (or null)")
        blocks_d = ad.get("blocks", [None, None])
        if not isinstance(blocks_d, list) or len(blocks_d) != 2:
            raise src.err("expected a list of 2 blocks (object or null)", f"{pre}.blocks")
        blocks: list[FourierBlock | None] = []
        for b, bd in enumerate(blocks_d):
            bw = f"{pre}.blocks[{b}]"
            if bd is None:
                blocks.append(None)
                continue
            bd = src.obj(bd, bw, _BLOCK_KEYS)
            for k in ("harmonics", "period_mm"):
                if k not in bd:
                    raise src.err("missing", f"{bw}.{k}")
            h = src.int_(bd["harmonics"], f"{bw}.harmonics", 1, MAX_HARMONICS, "harmonics")
            per = src.num(bd["period_mm"], f"{bw}.period_mm", "mm")
            if per <= 0:
                raise src.err(f"period {per:g} mm must be > 0", f"{bw}.period_mm")
            org = src.num(bd.get("origin_mm", 0.0), f"{bw}.origin_mm", "mm")
            blocks.append(FourierBlock(per, org, h))
        ax = AxisTable(travel_mm=(travel[0], travel[1]), trend_degree=deg,
                       blocks=(blocks[0], blocks[1]))
        rows = ad.get("rows")
        if rows is not None and rows != ax.row_names():
            raise src.err(f"rows {show_value(rows)} do not match the basis {ax.row_names()}",
                          f"{pre}.rows")
        terms_d = ad.get("terms", {})
        if not isinstance(terms_d, dict):
            raise src.err(f"expected an object, got {show_value(terms_d)}", f"{pre}.terms")
        nb = ax.n_basis()
        keys = tuple(f"{t}_{'um' if t in LINEAR_TERMS else 'urad'}" for t in TERMS)
        for key, vals in terms_d.items():
            tw = f"{pre}.terms.{key}"
            if key not in keys:
                raise src.err(unknown_key(key, keys, "term key"), tw)
            t, _, unit = key.partition("_")
            if not isinstance(vals, list) or len(vals) != nb:
                raise src.err(f"expected a list of {nb} coefficients (one per row), got "
                              f"{show_value(vals)}", tw)
            ax.coef[t] = np.array([src.num(v, f"{tw}[{i}]", unit) for i, v in enumerate(vals)])
        for name, unit in (("backlash_um", "um"), ("backlash_takeup_mm", "mm"),
                           ("thermal_expansion_ppm_per_k", "ppm_per_k"),
                           ("thermal_offset_um_per_k", "um_per_k"), ("thermal_tref_c", "c")):
            setattr(ax, name, src.num(ad.get(name, 0.0), f"{pre}.{name}", unit))
        rev = ad.get("reversal_cheb_um")
        if rev is not None:
            rw = f"{pre}.reversal_cheb_um"
            if not isinstance(rev, list) or not 1 <= len(rev) <= MAX_REVERSAL_ROWS:
                raise src.err(f"expected a list of 1..{MAX_REVERSAL_ROWS} Chebyshev coefficients "
                              f"(um; degree 0..7) or null, got {show_value(rev)}", rw)
            ax.reversal_cheb_um = tuple(src.num(v, f"{rw}[{i}]", "um") for i, v in enumerate(rev))
        axes[a] = ax
    return Table(axes=axes, reference_mm=ref, tool_offset_mm=tool,  # type: ignore[arg-type]
                 squareness_urad=sq)  # type: ignore[arg-type]


def load_table_json(path: str | Path) -> Table:
    """A table from a table JSON file: bounded, strict JSON, every error located."""
    d, tf = load_json(path, what="table JSON", max_bytes=TABLE_JSON_MAX_BYTES)
    return table_from_json(d, tf.name, JsonLocator(tf.text))


def load_table_file(path: str | Path, what: str = "model") -> tuple[bytes | None, Table]:
    """A table from a blob (``model.bin``, magic ABBE) or a table JSON, chosen by content.

    Returns (blob bytes or None for JSON, Table); AbbeInputError naming the file.
    """
    from abbe.formats.blob import MAGIC, read_blob
    name = str(path)
    raw = read_bytes(path, what=what, max_bytes=TABLE_JSON_MAX_BYTES)
    if raw[:4] == MAGIC:
        if len(raw) > BLOB_MAX_BYTES:
            raise AbbeInputError(f"a table blob is at most {BLOB_MAX_BYTES} bytes", file=name)
        return raw, read_blob(raw, source=name)
    head = raw.lstrip(b"\xef\xbb\xbf \t\r\n")[:1]
    if head not in (b"{", b"[") and not raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise AbbeInputError("not an abbe table: neither a blob (magic ABBE) nor table JSON",
                             file=name)
    d, tf = json_from_bytes(raw, name=name, what="table JSON")
    return None, table_from_json(d, name, JsonLocator(tf.text))
