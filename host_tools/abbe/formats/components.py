"""ISO 230-1 component errors as sampled curves: the plain data of ``abbe import``.

Readers of controller / instrument files (:mod:`abbe.formats.isg_csv`,
:mod:`abbe.formats.etalon`) return :class:`ComponentData`: per axis and abbe term
the positions (mm) and values (um for d_x/d_y/d_z, urad for eps), and the
squareness from the location errors (urad). Name mapping (docs/exports.md,
``isg-csv``): E<D><J> is abbe's term of axis J in direction D (D = X, Y, Z
translations d_x, d_y, d_z; A, B, C rotations eps_jx, eps_jy, eps_jz); C0Y = S_xy,
B0Z = -S_xz, A0Z = S_yz. Files carry mm and rad.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from abbe.errors import AbbeInputError
from abbe.model.table import AXES

DIRECTION_TERM = {"X": "dx", "Y": "dy", "Z": "dz", "A": "ex", "B": "ey", "C": "ez"}
LOCATION = {"C0Y": (0, 1.0), "B0Z": (1, -1.0), "A0Z": (2, 1.0)}
#: any ISO 230-1 / ISG parameter name (linear or rotary axes)
ISO_NAME = re.compile(r"^(E[XYZABC][XYZABC]|[XYZABC]0[XYZABC]|[PNV][0XYZ][XYZABC])$")
COMPONENT = re.compile(r"^E([XYZABC])([XYZ])$")


@dataclass
class Curve:
    """Samples of one term: positions (mm, ascending), values (um / urad), where."""

    pos_mm: np.ndarray
    values: np.ndarray
    source: str


@dataclass
class ComponentData:
    """What an ISO 230-1 error file says about a 3-axis machine (module docstring).

    curves[(axis, term)]; squareness_urad (S_xy, S_xz, S_yz) or None if the file has
    no location errors; ignored: names of parameters that are not part of a 3-axis
    model (rotary axes, tool parameters), with where they were.
    """

    file: str
    curves: dict[tuple[str, str], Curve] = field(default_factory=dict)
    squareness_urad: list[float] | None = None
    ignored: list[str] = field(default_factory=list)

    def add_curve(self, name: str, pos: np.ndarray, values_file_units: np.ndarray, where: str,
                  line: int | None, file: str | None = None) -> None:
        """Add the samples of a component error ``name`` (mm or rad in the file)."""
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
        scale = 1e3 if term.startswith("d") else 1e6  # mm -> um, rad -> urad
        self.curves[key] = Curve(p, np.asarray(values_file_units, dtype=np.float64) * scale, where)

    def add_location(self, name: str, value_file_units: float, where: str,
                     line: int | None) -> None:
        if name not in LOCATION:
            self.ignored.append(f"{name} ({where})")
            return
        if self.squareness_urad is None:
            self.squareness_urad = [0.0, 0.0, 0.0]
        k, sign = LOCATION[name]
        self.squareness_urad[k] = sign * value_file_units * 1e6

    def check(self) -> None:
        """At least one component error of one of X, Y, Z."""
        if not self.curves:
            raise AbbeInputError("no component error of the X, Y or Z axis (E<d><axis>) found",
                                 file=self.file)

    def axes(self) -> list[str]:
        return [a for a in AXES if any(k[0] == a for k in self.curves)]


def check_name(name: str, file: str, line: int | None) -> None:
    """An ISO 230-1 / ISG parameter name, or an AbbeInputError naming it."""
    if not ISO_NAME.match(name):
        raise AbbeInputError(f"unknown parameter {name!r}: expected an ISO 230-1 name "
                             "(EXX .. ECZ, location errors like C0Y)", file=file, line=line,
                             field=name)
