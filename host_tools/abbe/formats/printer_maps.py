"""Printer measurements as the firmware stores them: Klipper's bed mesh and axis twist
values, RepRapFirmware's height map, skew artefact diagonals.

* Klipper ``printer.cfg`` (or any file holding its ``SAVE_CONFIG`` block): the
  ``#*# [bed_mesh NAME]`` sections (``points`` = y_count rows of x_count values,
  mm, the first row at min_y; ``x_count``, ``y_count``, ``min_x`` .. ``max_y``;
  klippy/extras/bed_mesh.py ``ProfileManager`` writes them) and
  ``#*# [axis_twist_compensation]`` (``z_compensations``, ``compensation_start_x``,
  ``compensation_end_x``).
* RepRapFirmware ``heightmap.csv`` (Grid.cpp ``HeightMap::SaveToFile``): a first
  line ``RepRapFirmware height map file v2 ...``; a label line, one of Grid.cpp's
  ``HeightMapLabelLines``: ``xmin,xmax,ymin,ymax,radius,spacing,xnum,ynum`` (the oldest,
  one spacing), ``xmin,xmax,ymin,ymax,radius,xspacing,yspacing,xnum,ynum`` (until 3.3-beta1)
  or ``axis0,axis1,min0,max0,min1,max1,radius,spacing0,spacing1,num0,num1`` (3.3-beta2 on);
  the values of that header; then one line per row of the second axis (from its
  minimum), num0 values each, mm. A point that was not probed is written as a bare
  ``0`` (no decimal point): it is kept as "not measured", never as a height of 0.
* Skew artefacts: a CSV ``plane,ac_mm,bd_mm,ad_mm`` (one row per plane XY / XZ /
  YZ: the two diagonals and one side of a printed or probed square, Klipper's
  ``SET_SKEW XY=AC,BD,AD``, Marlin's ``XY_DIAG_AC / XY_DIAG_BD / XY_SIDE_AD``).

Every refusal names the file, the line and the field (AbbeInputError, exit 2); no
value is NaN or infinite; nothing is silently dropped.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from abbe.errors import AbbeInputError
from abbe.errors.numbers import parse_int, parse_number
from abbe.formats.text import read_text

MAX_BYTES = 4 << 20
#: Largest mesh accepted (points per axis).
MAX_POINTS = 100
#: Largest height a printer map may hold, mm (Klipper refuses meshes beyond its fade range).
MAX_HEIGHT_MM = 50.0
MAX_COORD_MM = 10000.0
#: What separates cells: spaces and tabs only (a no-break space or another Unicode space
#: next to a number is refused by the number parser, as in every abbe reader).
_WS = " \t"


@dataclass
class HeightMap:
    """Z heights on a grid: ``z_mm[j, i]`` at (x_mm[i], y_mm[j]); NaN = not probed.

    ``source``: the file; ``kind``: ``"klipper-bed-mesh"`` or ``"rrf-heightmap"``;
    ``name``: the profile (Klipper) or ``""``.
    """

    x_mm: np.ndarray
    y_mm: np.ndarray
    z_mm: np.ndarray
    source: str
    kind: str
    name: str = ""
    notes: list[str] = field(default_factory=list)

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """The measured points: ((N, 2) x, y mm; (N,) z mm), not-probed points left out."""
        X, Y = np.meshgrid(self.x_mm, self.y_mm)
        m = np.isfinite(self.z_mm)
        return np.column_stack([X[m], Y[m]]), self.z_mm[m]


@dataclass
class TwistTable:
    """Klipper's ``[axis_twist_compensation]``: z_compensations (mm) evenly spaced from
    start_x to end_x (mm)."""

    z_mm: np.ndarray
    start_x_mm: float
    end_x_mm: float
    source: str


@dataclass
class SkewArtefact:
    """One plane's square: diagonals AC, BD and side AD, mm."""

    plane: str
    ac_mm: float
    bd_mm: float
    ad_mm: float
    line: int

    def tangent(self) -> float:
        """The skew factor Klipper's ``calc_skew_factor`` and Marlin derive from the
        three lengths: tan(pi/2 - angle DAB)."""
        side = math.sqrt(2 * self.ac_mm ** 2 + 2 * self.bd_mm ** 2 - 4 * self.ad_mm ** 2) / 2.0
        return math.tan(math.pi / 2 - math.acos(
            (self.ac_mm ** 2 - side ** 2 - self.ad_mm ** 2) / (2 * side * self.ad_mm)))


# -- Klipper ---------------------------------------------------------------------------

_SECTION = re.compile(r"^#\*#\s*\[(?P<name>[^\]]+)\]\s*$")
_OPTION = re.compile(r"^#\*#\s*(?P<key>[A-Za-z_0-9]+)\s*[=:]\s*(?P<value>.*)$")
_CONT = re.compile(r"^#\*#\s+(?P<value>\S.*)$")


def _autosave_sections(path: str | Path) -> dict[str, dict[str, tuple[str, int]]]:
    """The ``#*#`` sections: name -> key -> (value text, line). Continuation lines
    (the mesh rows) are joined to their key with newlines."""
    tf = read_text(path, what="Klipper config", max_bytes=MAX_BYTES)
    sections: dict[str, dict[str, tuple[str, int]]] = {}
    cur: dict[str, tuple[str, int]] | None = None
    key = None
    for no, line in tf.lines():
        s = line.rstrip()
        if not s.startswith("#*#"):
            cur, key = None, None if not s.strip() else key
            continue
        body = s[3:]
        if not body.strip() or "SAVE_CONFIG" in body or "DO NOT EDIT" in body:
            key = None
            continue
        m = _SECTION.match(s)
        if m:
            name = m.group("name").strip()
            if name in sections:
                raise AbbeInputError(f"section [{name}] twice in the SAVE_CONFIG block",
                                     file=str(path), line=no, field=name)
            cur = sections[name] = {}
            key = None
            continue
        if cur is None:
            raise AbbeInputError("a #*# line outside a section", file=str(path), line=no)
        m = _OPTION.match(s)
        if m and not body.startswith(("\t", "   ")):
            key = m.group("key").lower()
            if key in cur:
                raise AbbeInputError(f"option {key} twice", file=str(path), line=no, field=key)
            cur[key] = (m.group("value").strip(_WS), no)
            continue
        m = _CONT.match(s)
        if m and key is not None:
            v, first = cur[key]
            cur[key] = ((v + "\n" + m.group("value").strip(_WS)).strip(_WS + "\n"), first)
            continue
        raise AbbeInputError(f"cannot read {s!r}: expected '#*# key = value' or a mesh row",
                             file=str(path), line=no)
    return sections


def _num(opts, key, path, section, lo=-MAX_COORD_MM, hi=MAX_COORD_MM) -> float:
    if key not in opts:
        raise AbbeInputError(f"[{section}] has no {key}", file=str(path), field=key)
    text, no = opts[key]
    return parse_number(text, file=str(path), line=no, field=f"{section}.{key}", lo=lo, hi=hi)


def _int(opts, key, path, section, lo=2, hi=MAX_POINTS) -> int:
    if key not in opts:
        raise AbbeInputError(f"[{section}] has no {key}", file=str(path), field=key)
    text, no = opts[key]
    return parse_int(text, file=str(path), line=no, field=f"{section}.{key}", lo=lo, hi=hi)


def read_klipper_meshes(path: str | Path) -> list[HeightMap]:
    """Every ``#*# [bed_mesh NAME]`` of a Klipper config, in file order."""
    out = []
    for name, opts in _autosave_sections(path).items():
        if not name.startswith("bed_mesh "):
            continue
        prof = name.split(" ", 1)[1].strip()
        nx, ny = _int(opts, "x_count", path, name), _int(opts, "y_count", path, name)
        x0, x1 = _num(opts, "min_x", path, name), _num(opts, "max_x", path, name)
        y0, y1 = _num(opts, "min_y", path, name), _num(opts, "max_y", path, name)
        if not (x0 < x1 and y0 < y1):
            raise AbbeInputError(f"min_x {x0} / max_x {x1}, min_y {y0} / max_y {y1}: expected min < max",
                                 file=str(path), line=opts["min_x"][1], field=f"{name}.min_x")
        if "points" not in opts:
            raise AbbeInputError(f"[{name}] has no points", file=str(path), field="points")
        text, first = opts["points"]
        rows = [r for r in text.split("\n") if r.strip()]
        if len(rows) != ny:
            raise AbbeInputError(f"{len(rows)} rows of points, y_count = {ny}",
                                 file=str(path), line=first, field=f"{name}.points")
        z = np.empty((ny, nx))
        for j, r in enumerate(rows):
            cells = [c.strip(_WS) for c in r.split(",") if c.strip(_WS) != ""]
            if len(cells) != nx:
                raise AbbeInputError(f"row {j + 1} has {len(cells)} values, x_count = {nx}",
                                     file=str(path), line=first + 1 + j, field=f"{name}.points")
            for i, c in enumerate(cells):
                z[j, i] = parse_number(c, file=str(path), line=first + 1 + j,
                                       field=f"{name}.points[{j}][{i}] (mm)",
                                       lo=-MAX_HEIGHT_MM, hi=MAX_HEIGHT_MM)
        out.append(HeightMap(np.linspace(x0, x1, nx), np.linspace(y0, y1, ny), z,
                             source=str(path), kind="klipper-bed-mesh", name=prof))
    if not out:
        raise AbbeInputError("no #*# [bed_mesh NAME] section (Klipper writes it with SAVE_CONFIG)",
                             file=str(path), field="bed_mesh")
    return out


def read_klipper_twist(path: str | Path) -> TwistTable | None:
    """``#*# [axis_twist_compensation]`` of a Klipper config, or None if it has none."""
    secs = _autosave_sections(path)
    opts = secs.get("axis_twist_compensation")
    if opts is None:
        return None
    name = "axis_twist_compensation"
    if "z_compensations" not in opts:
        raise AbbeInputError("[axis_twist_compensation] has no z_compensations",
                             file=str(path), field="z_compensations")
    text, no = opts["z_compensations"]
    vals = np.array([parse_number(c.strip(_WS), file=str(path), line=no, field=f"{name}.z_compensations",
                                  lo=-MAX_HEIGHT_MM, hi=MAX_HEIGHT_MM)
                     for c in text.replace("\n", ",").split(",") if c.strip(_WS)])
    if vals.size < 2:
        raise AbbeInputError(f"{vals.size} z_compensations: expected at least 2",
                             file=str(path), line=no, field=f"{name}.z_compensations")
    x0 = _num(opts, "compensation_start_x", path, name)
    x1 = _num(opts, "compensation_end_x", path, name)
    if not x0 < x1:
        raise AbbeInputError("compensation_start_x must be < compensation_end_x", file=str(path),
                             line=opts["compensation_start_x"][1], field=f"{name}.compensation_start_x")
    return TwistTable(vals, x0, x1, str(path))


# -- RepRapFirmware ----------------------------------------------------------------------

_RRF_HEADERS = {
    "xmin,xmax,ymin,ymax,radius,spacing,xnum,ynum": "v1",
    "xmin,xmax,ymin,ymax,radius,xspacing,yspacing,xnum,ynum": "v2-old",
    "axis0,axis1,min0,max0,min1,max1,radius,spacing0,spacing1,num0,num1": "v2-axes",
}


def read_rrf_heightmap(path: str | Path) -> HeightMap:
    """A RepRapFirmware ``heightmap.csv`` (module docstring)."""
    tf = read_text(path, what="RepRapFirmware height map", max_bytes=MAX_BYTES)
    lines = [(no, ln.strip(_WS)) for no, ln in tf.lines()]
    lines = [(no, ln) for no, ln in lines if ln]
    p = str(path)
    if not lines or not lines[0][1].startswith("RepRapFirmware height map file"):
        raise AbbeInputError("expected a first line 'RepRapFirmware height map file v2 ...'",
                             file=p, line=lines[0][0] if lines else 1, field="header")
    if len(lines) < 4:
        raise AbbeInputError("expected a header line, its values and the rows", file=p,
                             line=lines[-1][0], field="header")
    hno, head = lines[1]
    kind = _RRF_HEADERS.get(head.replace(" ", "").lower())
    if kind is None:
        raise AbbeInputError(f"header {head!r}: expected one of {list(_RRF_HEADERS)}",
                             file=p, line=hno, field="header")
    vno, vals_text = lines[2]
    vals = [v.strip(_WS) for v in vals_text.split(",")]
    want = {"v1": 8, "v2-old": 9, "v2-axes": 11}[kind]
    if len(vals) != want:
        raise AbbeInputError(f"{len(vals)} values under the header: expected {want}",
                             file=p, line=vno, field="header values")
    if kind == "v2-axes":
        if [v.upper() for v in vals[:2]] != ["X", "Y"]:
            raise AbbeInputError(f"axes {vals[0]},{vals[1]}: only X,Y maps are read",
                                 file=p, line=vno, field="axis0,axis1")
        vals = vals[2:]
    if kind == "v1":  # one spacing for both axes (RRF's oldest label line)
        vals = vals[:5] + [vals[5]] + vals[5:]
    names = ["min0", "max0", "min1", "max1", "radius", "spacing0", "spacing1"]
    f = {n: parse_number(v, file=p, line=vno, field=n, lo=-MAX_COORD_MM, hi=MAX_COORD_MM)
         for n, v in zip(names, vals[:7])}
    n0 = parse_int(vals[7], file=p, line=vno, field="num0", lo=2, hi=MAX_POINTS)
    n1 = parse_int(vals[8], file=p, line=vno, field="num1", lo=2, hi=MAX_POINTS)
    if f["radius"] > 0:
        raise AbbeInputError("a circular (delta) height map: only rectangular grids are read",
                             file=p, line=vno, field="radius")
    if f["spacing0"] <= 0 or f["spacing1"] <= 0:
        raise AbbeInputError("spacing must be > 0", file=p, line=vno, field="spacing")
    rows = lines[3:]
    if len(rows) != n1:
        raise AbbeInputError(f"{len(rows)} rows: num1 = {n1}", file=p, line=rows[-1][0], field="rows")
    z = np.empty((n1, n0))
    unprobed = 0
    for j, (no, r) in enumerate(rows):
        cells = [c.strip(_WS) for c in r.split(",")]
        if len(cells) != n0:
            raise AbbeInputError(f"{len(cells)} values: num0 = {n0}", file=p, line=no,
                                 field=f"row {j + 1}")
        for i, c in enumerate(cells):
            if c == "0":  # RRF writes an unprobed point as a bare 0 (Grid.cpp)
                z[j, i] = np.nan
                unprobed += 1
            else:
                z[j, i] = parse_number(c, file=p, line=no, field=f"row {j + 1} value {i + 1} (mm)",
                                       lo=-MAX_HEIGHT_MM, hi=MAX_HEIGHT_MM)
    x = f["min0"] + f["spacing0"] * np.arange(n0)
    y = f["min1"] + f["spacing1"] * np.arange(n1)
    notes = [f"{unprobed} points not probed (written as a bare 0), left out"] if unprobed else []
    if np.isfinite(z).sum() < 4:
        raise AbbeInputError("fewer than 4 probed points", file=p, field="rows")
    return HeightMap(x, y, z, source=p, kind="rrf-heightmap", notes=notes)


def read_height_map(path: str | Path) -> list[HeightMap]:
    """A Klipper config (its bed meshes) or a RepRapFirmware height map, by content."""
    tf = read_text(path, what="printer height map", max_bytes=MAX_BYTES)
    first = next((ln for _, ln in tf.lines() if ln.strip()), "")
    if first.startswith("RepRapFirmware height map file"):
        return [read_rrf_heightmap(path)]
    return read_klipper_meshes(path)


# -- skew artefacts ------------------------------------------------------------------------

def read_skew_csv(path: str | Path) -> list[SkewArtefact]:
    """``plane,ac_mm,bd_mm,ad_mm`` rows (module docstring)."""
    tf = read_text(path, what="skew artefact CSV", max_bytes=1 << 16)
    p = str(path)
    out: list[SkewArtefact] = []
    header_seen = False
    for no, line in tf.lines():
        s = line.split("#", 1)[0].strip(_WS)
        if not s:
            continue
        cells = [c.strip(_WS) for c in s.split(",")]
        if not header_seen:
            if [c.lower() for c in cells] != ["plane", "ac_mm", "bd_mm", "ad_mm"]:
                raise AbbeInputError(f"header {s!r}: expected plane,ac_mm,bd_mm,ad_mm",
                                     file=p, line=no, field="header")
            header_seen = True
            continue
        if len(cells) != 4:
            raise AbbeInputError(f"{len(cells)} fields: expected plane,ac_mm,bd_mm,ad_mm",
                                 file=p, line=no)
        plane = cells[0].upper()
        if plane not in ("XY", "XZ", "YZ"):
            raise AbbeInputError(f"plane {cells[0]!r}: expected XY, XZ or YZ", file=p, line=no,
                                 field="plane")
        if any(a.plane == plane for a in out):
            raise AbbeInputError(f"plane {plane} twice", file=p, line=no, field="plane")
        ac, bd, ad = (parse_number(c, file=p, line=no, field=n, lo=1e-3, hi=MAX_COORD_MM)
                      for c, n in zip(cells[1:], ("ac_mm", "bd_mm", "ad_mm")))
        art = SkewArtefact(plane, ac, bd, ad, no)
        arg = 2 * ac ** 2 + 2 * bd ** 2 - 4 * ad ** 2
        if arg <= 0:
            raise AbbeInputError("these lengths are not a square's diagonals and side", file=p,
                                 line=no, field="ac_mm,bd_mm,ad_mm")
        side = math.sqrt(arg) / 2.0
        cosv = (ac ** 2 - side ** 2 - ad ** 2) / (2 * side * ad)
        if not -1.0 < cosv < 1.0 or abs(art.tangent()) > 0.1:
            raise AbbeInputError(f"these lengths give a skew of {math.degrees(math.acos(max(-1, min(1, cosv)))) - 90:.2f} deg: "
                                 "expected a square within a few degrees", file=p, line=no,
                                 field="ac_mm,bd_mm,ad_mm")
        out.append(art)
    if not out:
        raise AbbeInputError("no plane measured", file=p, field="rows")
    return out
