"""ISO 230-1 component errors as sampled curves: the plain data of ``abbe import``.

Readers of controller / instrument files (:mod:`abbe.formats.isg_csv`,
:mod:`abbe.formats.etalon`) return :class:`ComponentData`: per axis and abbe term
the positions (mm) and values (um for d_x/d_y/d_z, urad for eps), and the
squareness from the location errors (urad). Name mapping (docs/exports.md,
``isg-csv``): E<D><J> is abbe's term of axis J in direction D (D = X, Y, Z
translations d_x, d_y, d_z; A, B, C rotations eps_jx, eps_jy, eps_jz); C0Y = S_xy,
B0Z = -S_xz, A0Z = S_yz. Files carry mm and rad; :func:`value_range` says how a
parameter's numbers are read (the strict parser's range and the scale to abbe's
units), :func:`argument_range` the same for an argument column.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass, field

import numpy as np

from abbe.errors import AbbeInputError
from abbe.formats.blob import SQUARENESS_CAP
from abbe.model.table import AXES

DIRECTION_TERM = {"X": "dx", "Y": "dy", "Z": "dz", "A": "ex", "B": "ey", "C": "ez"}
LOCATION = {"C0Y": (0, 1.0), "B0Z": (1, -1.0), "A0Z": (2, 1.0)}
#: any ISO 230-1 / ISG parameter name (linear or rotary axes)
ISO_NAME = re.compile(r"^(E[XYZABC][XYZABC]|[XYZABC]0[XYZABC]|[PNV][0XYZ][XYZABC])$")
COMPONENT = re.compile(r"^E([XYZABC])([XYZ])$")
#: the names of a 3-axis model (for suggestions)
MODEL_NAMES = tuple(f"E{d}{j}" for j in "XYZ" for d in "XYZABC") + tuple(LOCATION)

#: Ranges of the numbers of an error file, in abbe's units (docs/formats.md, "Numbers").
POSITION_MAX_MM = 2147.0       # a table holds int32 nm
ROTARY_MAX_DEG = 1e4
LINEAR_MAX_UM = 1e5
ANGULAR_MAX_URAD = 1e5
#: |squareness| a table holds: 2^28 x 2^-36 rad
SQUARENESS_MAX_URAD = SQUARENESS_CAP * 2.0 ** -36 * 1e6


def value_range(name: str) -> tuple[float, float, str, float]:
    """(lo, hi, unit, scale) of a parameter's values: abbe unit, file unit x scale."""
    if name in LOCATION:
        return -SQUARENESS_MAX_URAD, SQUARENESS_MAX_URAD, "urad", 1e6
    letter = name[1] if name[0] == "E" else name[0]
    if name[0] in "EXYZABC" and letter in "XYZ":
        return -LINEAR_MAX_UM, LINEAR_MAX_UM, "um", 1e3  # mm -> um
    if name[0] in "EXYZABC":
        return -ANGULAR_MAX_URAD, ANGULAR_MAX_URAD, "urad", 1e6  # rad -> urad
    return -1e5, 1e5, "", 1.0  # tool parameters (P, N, V): listed as ignored


def argument_range(axis: str) -> tuple[float, float, str]:
    """(lo, hi, unit) of an argument column (a linear axis in mm, a rotary one in deg)."""
    if axis in "XYZ":
        return -POSITION_MAX_MM, POSITION_MAX_MM, "mm"
    return -ROTARY_MAX_DEG, ROTARY_MAX_DEG, "deg"


@dataclass
class Curve:
    """Samples of one term: positions (mm, ascending), values (um / urad), where."""

    pos_mm: np.ndarray
    values: np.ndarray
    source: str
    file: str = ""
    line: int | None = None


@dataclass
class ComponentData:
    """What an ISO 230-1 error file says about a 3-axis machine (module docstring).

    curves[(axis, term)]; squareness_urad (S_xy, S_xz, S_yz) or None if the file has
    no location errors; ignored: names of parameters that are not part of a 3-axis
    model (rotary axes, tool parameters), with where they were; sha256 of the file
    read first (the list file for a ``.lis``); notes: what the reader decided.
    """

    file: str
    curves: dict[tuple[str, str], Curve] = field(default_factory=dict)
    squareness_urad: list[float] | None = None
    ignored: list[str] = field(default_factory=list)
    sha256: str = ""
    notes: list[str] = field(default_factory=list)
    _location_seen: dict[str, str] = field(default_factory=dict)

    def add_curve(self, name: str, pos: np.ndarray, values: np.ndarray, where: str,
                  line: int | None, file: str | None = None) -> None:
        """Add the samples of a component error ``name`` (values in um / urad)."""
        file = file or self.file
        m = COMPONENT.match(name)
        if not m:
            self.ignored.append(f"{name} ({where})")
            return
        term = DIRECTION_TERM[m.group(1)]
        key = (m.group(2), term)
        if key in self.curves:
            raise AbbeInputError(f"{name} given twice (first in {self.curves[key].source})",
                                 file=file, line=line, field=name)
        p = np.asarray(pos, dtype=np.float64)
        if p.size < 2 or np.any(np.diff(p) <= 0):
            raise AbbeInputError("positions must be at least 2 and strictly ascending",
                                 file=file, line=line, field=name)
        self.curves[key] = Curve(p, np.asarray(values, dtype=np.float64), where, file, line)

    def add_location(self, name: str, value: float, where: str, line: int | None,
                     file: str | None = None) -> None:
        """Add a location error (value in urad for the squareness names)."""
        if name not in LOCATION:
            self.ignored.append(f"{name} ({where})")
            return
        if name in self._location_seen:
            raise AbbeInputError(f"{name} given twice (first in {self._location_seen[name]})",
                                 file=file or self.file, line=line, field=name)
        self._location_seen[name] = where
        if self.squareness_urad is None:
            self.squareness_urad = [0.0, 0.0, 0.0]
        k, sign = LOCATION[name]
        self.squareness_urad[k] = sign * value

    def check(self) -> None:
        """At least one component error of one of X, Y, Z."""
        if not self.curves:
            raise AbbeInputError("no component error of the X, Y or Z axis (E<d><axis>) found",
                                 file=self.file)

    def axes(self) -> list[str]:
        return [a for a in AXES if any(k[0] == a for k in self.curves)]


def check_name(name: str, file: str, line: int | None) -> None:
    """An ISO 230-1 / ISG parameter name, or an AbbeInputError naming it (with a suggestion)."""
    if ISO_NAME.match(name):
        return
    if ISO_NAME.match(name.upper()):
        hint = f" (did you mean {name.upper()!r}? names are upper case)"
    else:
        close = difflib.get_close_matches(name.upper(), MODEL_NAMES, n=1, cutoff=0.6)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
    shown = name if len(name) <= 40 else name[:30] + f"... ({len(name)} characters)"
    raise AbbeInputError(f"unknown parameter{hint}: expected an ISO 230-1 name (EXX .. ECZ, "
                         "location errors like C0Y)", file=file, line=line, field=shown)
