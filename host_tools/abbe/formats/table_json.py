"""Table JSON (``model.json`` and ``--model X.json``): the table in um / urad / mm.

:func:`table_to_json` writes the documented object (docs/formats.md, "Table
JSON"); :func:`table_from_json` reads it back, naming the field of anything
missing or malformed.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from abbe.errors import AbbeInputError
from abbe.formats.blob import FORMAT_MAJOR, FORMAT_MINOR
from abbe.model.table import (
    AXES,
    LINEAR_TERMS,
    MAX_DEGREE,
    MAX_HARMONICS,
    TERMS,
    AxisTable,
    FourierBlock,
    Table,
)

JSON_FORMAT = "abbe-table"


def table_to_json(table: Table) -> dict:
    """A JSON-ready dict of ``table``: units in the key names, row names listed.

    Floats are written as Python floats, so ``table_from_json(table_to_json(t))``
    gives back exactly ``t``.
    """
    axes: dict[str, Any] = {}
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
    return {
        "format": JSON_FORMAT,
        "version": f"{FORMAT_MAJOR}.{FORMAT_MINOR}",
        "reference_mm": [float(v) for v in table.reference_mm],
        "tool_offset_mm": [float(v) for v in table.tool_offset_mm],
        "squareness_urad": {"S_xy": float(table.squareness_urad[0]),
                            "S_xz": float(table.squareness_urad[1]),
                            "S_yz": float(table.squareness_urad[2])},
        "axes": axes,
    }


def _jget(d: dict, key: str, where: str, source: str, default: Any = ...) -> Any:
    if not isinstance(d, dict):
        raise AbbeInputError("expected an object", file=source, field=where)
    if key not in d:
        if default is ...:
            raise AbbeInputError("missing", file=source, field=f"{where}.{key}".lstrip("."))
        return default
    return d[key]


def _jnum(v: Any, where: str, source: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise AbbeInputError(f"expected a number, got {v!r}", file=source, field=where)
    f = float(v)
    if not math.isfinite(f):
        raise AbbeInputError(f"not finite: {v!r}", file=source, field=where)
    return f


def _jvec(v: Any, n: int, where: str, source: str) -> tuple[float, ...]:
    if not isinstance(v, list) or len(v) != n:
        raise AbbeInputError(f"expected a list of {n} numbers", file=source, field=where)
    return tuple(_jnum(x, f"{where}[{i}]", source) for i, x in enumerate(v))


def _jint(v: Any, where: str, source: str) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise AbbeInputError(f"expected an integer, got {v!r}", file=source, field=where)
    return v


def table_from_json(d: dict, source: str = "<json>") -> Table:
    """Build a Table from the dict of :func:`table_to_json`.

    Raises AbbeInputError naming ``source`` and the field for anything missing or
    malformed (the binary checks happen when the table is written).
    """
    if not isinstance(d, dict):
        raise AbbeInputError("expected a JSON object", file=source)
    fmt = d.get("format")
    if fmt != JSON_FORMAT:
        raise AbbeInputError(f"expected '{JSON_FORMAT}', got {fmt!r}", file=source,
                             field="format")
    ver = d.get("version")
    if not isinstance(ver, str) or not ver.startswith(f"{FORMAT_MAJOR}."):
        raise AbbeInputError(f"expected table format {FORMAT_MAJOR}.x, got {ver!r}",
                             file=source, field="version")
    ref = _jvec(_jget(d, "reference_mm", "", source), 3, "reference_mm", source)
    tool = _jvec(_jget(d, "tool_offset_mm", "", source, [0.0, 0.0, 0.0]), 3,
                 "tool_offset_mm", source)
    sqd = _jget(d, "squareness_urad", "", source, {"S_xy": 0.0, "S_xz": 0.0, "S_yz": 0.0})
    if not isinstance(sqd, dict):
        raise AbbeInputError("expected an object with S_xy, S_xz, S_yz", file=source,
                             field="squareness_urad")
    extra = set(sqd) - {"S_xy", "S_xz", "S_yz"}
    if extra:
        raise AbbeInputError(f"unknown key(s) {sorted(extra)}", file=source,
                             field="squareness_urad")
    sq = tuple(_jnum(sqd.get(k, 0.0), f"squareness_urad.{k}", source)
               for k in ("S_xy", "S_xz", "S_yz"))
    axes_d = _jget(d, "axes", "", source)
    if not isinstance(axes_d, dict) or set(axes_d) != set(AXES):
        raise AbbeInputError(f"expected an object with exactly the axes {list(AXES)}",
                             file=source, field="axes")
    axes: dict[str, AxisTable] = {}
    for a in AXES:
        ad = axes_d[a]
        pre = f"axes.{a}"
        if not isinstance(ad, dict):
            raise AbbeInputError("expected an object", file=source, field=pre)
        travel = _jvec(_jget(ad, "travel_mm", pre, source), 2, f"{pre}.travel_mm", source)
        deg = _jget(ad, "trend_degree", pre, source, None)
        if deg is not None:
            deg = _jint(deg, f"{pre}.trend_degree", source)
            if not 0 <= deg <= MAX_DEGREE:
                raise AbbeInputError(f"trend degree {deg} not in 0..{MAX_DEGREE} (or null)",
                                     file=source, field=f"{pre}.trend_degree")
        blocks_d = _jget(ad, "blocks", pre, source, [None, None])
        if not isinstance(blocks_d, list) or len(blocks_d) != 2:
            raise AbbeInputError("expected a list of 2 blocks (object or null)", file=source,
                                 field=f"{pre}.blocks")
        blocks: list[FourierBlock | None] = []
        for b, bd in enumerate(blocks_d):
            bw = f"{pre}.blocks[{b}]"
            if bd is None:
                blocks.append(None)
                continue
            h = _jint(_jget(bd, "harmonics", bw, source), f"{bw}.harmonics", source)
            if not 1 <= h <= MAX_HARMONICS:
                raise AbbeInputError(f"harmonics {h} not in 1..{MAX_HARMONICS}", file=source,
                                     field=f"{bw}.harmonics")
            per = _jnum(_jget(bd, "period_mm", bw, source), f"{bw}.period_mm", source)
            if per <= 0:
                raise AbbeInputError(f"period {per} mm must be > 0", file=source,
                                     field=f"{bw}.period_mm")
            org = _jnum(_jget(bd, "origin_mm", bw, source, 0.0), f"{bw}.origin_mm", source)
            blocks.append(FourierBlock(per, org, h))
        ax = AxisTable(travel_mm=(travel[0], travel[1]), trend_degree=deg,
                       blocks=(blocks[0], blocks[1]))
        rows = _jget(ad, "rows", pre, source, None)
        if rows is not None and rows != ax.row_names():
            raise AbbeInputError(f"rows {rows} do not match the basis {ax.row_names()}",
                                 file=source, field=f"{pre}.rows")
        terms_d = _jget(ad, "terms", pre, source, {})
        if not isinstance(terms_d, dict):
            raise AbbeInputError("expected an object", file=source, field=f"{pre}.terms")
        nb = ax.n_basis()
        for key, vals in terms_d.items():
            tw = f"{pre}.terms.{key}"
            t, _, unit = key.partition("_")
            want = "um" if t in LINEAR_TERMS else "urad"
            if t not in TERMS or unit != want:
                raise AbbeInputError(
                    "unknown term key; use dx_um, dy_um, dz_um, ex_urad, ey_urad, ez_urad",
                    file=source, field=tw)
            if not isinstance(vals, list) or len(vals) != nb:
                raise AbbeInputError(f"expected a list of {nb} coefficients (one per row)",
                                     file=source, field=tw)
            ax.coef[t] = np.array([_jnum(v, f"{tw}[{i}]", source) for i, v in enumerate(vals)])
        for name in ("backlash_um", "backlash_takeup_mm", "thermal_expansion_ppm_per_k",
                     "thermal_offset_um_per_k", "thermal_tref_c"):
            setattr(ax, name, _jnum(_jget(ad, name, pre, source, 0.0), f"{pre}.{name}", source))
        axes[a] = ax
    return Table(axes=axes, reference_mm=ref, tool_offset_mm=tool,  # type: ignore[arg-type]
                 squareness_urad=sq)  # type: ignore[arg-type]
