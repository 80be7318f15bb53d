"""The in-memory error model of a 3-axis machine: :class:`Table`, its axes and basis.

A :class:`Table` holds, per axis, the fitted error terms (Chebyshev trend + up to
two Fourier blocks, paper Eq. 3's 18 position-dependent errors), plus the
squareness, tool offset, backlash (a constant reversal and, format 1.1, a
position-dependent one) and thermal parameters. :func:`basis_matrix` is the
library's basis, so a term's value is ``basis_matrix(axis, p) @ coef``;
:func:`reversal_matrix` that of the reversal block.

Units: positions, travels, periods in mm; linear coefficients in um; angular
coefficients and squareness in urad; backlash and reversal coefficients in um;
thermal expansion in ppm/K, thermal offset in um/K, reference temperature in deg C.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from abbe.errors import AbbeInputError

AXES: tuple[str, str, str] = ("X", "Y", "Z")

TERMS: tuple[str, ...] = ("dx", "dy", "dz", "ex", "ey", "ez")

LINEAR_TERMS: tuple[str, ...] = ("dx", "dy", "dz")

ANGULAR_TERMS: tuple[str, ...] = ("ex", "ey", "ez")
#: Each axis' own positioning term ...
OWN_TERM: dict[str, str] = {"X": "dx", "Y": "dy", "Z": "dz"}
#: ... and the sign with which it enters its own error component in Eq. 3.
OWN_SIGN: dict[str, int] = {"X": -1, "Y": -1, "Z": +1}

# Feature bits of the header.
FEATURE_SQUARENESS = 0x1

FEATURE_TOOL_OFFSET = 0x2

FEATURE_BACKLASH = 0x4

FEATURE_THERMAL = 0x8

#: Format 1.1: an axis' reversal depends on its position (reversal blocks); needs BACKLASH.
FEATURE_REVERSAL = 0x10

FEATURE_ALL = 0x1F

#: The feature bits a format 1.0 table may set.
FEATURES_1_0 = 0xF

FEATURE_NAMES: dict[int, str] = {
    FEATURE_SQUARENESS: "SQUARENESS",
    FEATURE_TOOL_OFFSET: "TOOL_OFFSET",
    FEATURE_BACKLASH: "BACKLASH",
    FEATURE_THERMAL: "THERMAL",
    FEATURE_REVERSAL: "REVERSAL",
}

MAX_DEGREE = 7

#: Coefficients of a reversal block: Chebyshev T_0 .. T_7 (degree <= 7).
MAX_REVERSAL_ROWS = 8

NO_TREND = 255

MAX_HARMONICS = 8


class TableError(AbbeInputError):
    """A table that cannot be written or read.

    ``status`` is the name of the C status the library returns for the same
    problem (``"ABBE_E_CRC"``, ``"ABBE_E_RANGE"``, ...).
    """

    def __init__(self, message: str, *, status: str, file: str | None = None,
                 line: int | None = None, field: str | None = None) -> None:
        self.status = status
        super().__init__(f"{message} ({status})", file=file, line=line, field=field)


@dataclass
class FourierBlock:
    """One Fourier block: ``harmonics`` sin/cos pairs of period ``period_mm``,
    phase 0 at position ``origin_mm`` (both mm, machine coordinates)."""

    period_mm: float
    origin_mm: float
    harmonics: int  # 1..8


@dataclass
class AxisTable:
    """The fitted error terms of one axis.

    ``coef[term]`` holds the ``n_basis()`` coefficients of a present term in the
    table's row order (:meth:`row_names`): um for dx/dy/dz, urad for ex/ey/ez.
    A term absent from ``coef`` is not in the table (evaluates to 0).

    The reversal of the axis' own positioning term (ISO 230-2: the mean
    approaching from + minus the mean approaching from -) is
    ``R(p) = backlash_um + sum_k reversal_cheb_um[k] * T_k(u)``, um, with u the
    trend's normalised travel at p clamped to the travel; the term gets
    ``s * R(p) / 2`` with the backlash direction state s (+1 moving +), which
    ramps over ``backlash_takeup_mm``. ``reversal_cheb_um`` (1..8 coefficients,
    um; None = no block) is the position-dependent part (format 1.1); a block of
    one coefficient c is the same as ``backlash_um + c``.
    """

    travel_mm: tuple[float, float]
    trend_degree: int | None = None
    blocks: tuple[FourierBlock | None, FourierBlock | None] = (None, None)
    coef: dict[str, np.ndarray] = field(default_factory=dict)
    backlash_um: float = 0.0
    backlash_takeup_mm: float = 0.0
    thermal_expansion_ppm_per_k: float = 0.0
    thermal_offset_um_per_k: float = 0.0
    thermal_tref_c: float = 0.0
    reversal_cheb_um: tuple[float, ...] | None = None

    def n_trend(self) -> int:
        """Rows of the trend block (degree + 1, or 0 without trend)."""
        return 0 if self.trend_degree is None else int(self.trend_degree) + 1

    def n_basis(self) -> int:
        """Number of basis functions (rows of the coefficient matrix)."""
        n = self.n_trend()
        for blk in self.blocks:
            if blk is not None:
                n += 2 * int(blk.harmonics)
        return n

    def row_names(self) -> list[str]:
        """Row names in table order: ``T0..TD``, ``sin1(b0)``, ``cos1(b0)``, ..."""
        names = [f"T{k}" for k in range(self.n_trend())]
        for b, blk in enumerate(self.blocks):
            if blk is None:
                continue
            for h in range(1, int(blk.harmonics) + 1):
                names += [f"sin{h}(b{b})", f"cos{h}(b{b})"]
        return names

    def present_terms(self) -> list[str]:
        """Terms in the table, in TERMS order."""
        return [t for t in TERMS if t in self.coef]

    def has_reversal(self) -> bool:
        """True if the axis has a reversal (non-zero backlash_um or reversal block)."""
        return bool(self.backlash_um != 0 or (
            self.reversal_cheb_um is not None and any(c != 0 for c in self.reversal_cheb_um)))

    def reversal_um(self, pos_mm: np.ndarray) -> np.ndarray:
        """The total reversal R(p) (class docstring) at positions ``pos_mm`` (mm), um."""
        p = np.asarray(pos_mm, dtype=np.float64).reshape(-1)
        out = np.full(p.shape, float(self.backlash_um))
        if self.reversal_cheb_um is not None:
            out += reversal_matrix(self, p) @ np.asarray(self.reversal_cheb_um, dtype=np.float64)
        return out


@dataclass
class Table:
    """The geometric error model of one 3-axis machine (all three axes present).

    ``reference_mm``: the reference point (machine coordinates, mm);
    ``tool_offset_mm``: tool tip relative to the spindle reference point (mm);
    ``squareness_urad``: S_xy, S_xz, S_yz (urad).
    """

    axes: dict[str, AxisTable]
    reference_mm: tuple[float, float, float]
    tool_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    squareness_urad: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def features(self) -> int:
        """Feature bits implied by the non-zero fields (as given; write_blob
        derives them from the quantized values)."""
        f = 0
        if any(v != 0 for v in self.squareness_urad):
            f |= FEATURE_SQUARENESS
        if any(v != 0 for v in self.tool_offset_mm):
            f |= FEATURE_TOOL_OFFSET
        for ax in self.axes.values():
            if ax.backlash_um != 0 or ax.backlash_takeup_mm != 0 or ax.reversal_cheb_um is not None:
                f |= FEATURE_BACKLASH
            if ax.reversal_cheb_um is not None:
                f |= FEATURE_REVERSAL
            if (ax.thermal_expansion_ppm_per_k != 0 or ax.thermal_offset_um_per_k != 0
                    or ax.thermal_tref_c != 0):
                f |= FEATURE_THERMAL
        return f


def feature_names(features: int) -> list[str]:
    """Names of the set feature bits."""
    return [name for bit, name in FEATURE_NAMES.items() if features & bit]


def basis_matrix(axis: AxisTable, pos_mm: np.ndarray) -> np.ndarray:
    """Basis functions of ``axis`` at positions ``pos_mm`` (mm), shape (N, n_basis).

    Positions are clamped to the travel first (end value held), then the rows
    follow the table: Chebyshev T_0..T_D of the normalised travel
    u = (2p - min - max) / (max - min), then sin(k phi_b), cos(k phi_b) for
    each block, phi_b = 2 pi (p - origin_b) / period_b. The fit uses this as
    its design matrix, so a term's value is ``basis_matrix(...) @ coef``.
    """
    p = np.asarray(pos_mm, dtype=np.float64).reshape(-1)
    lo, hi = float(axis.travel_mm[0]), float(axis.travel_mm[1])
    p = np.clip(p, lo, hi)
    cols: list[np.ndarray] = []
    if axis.trend_degree is not None:
        u = (2.0 * p - lo - hi) / (hi - lo)
        cols.append(np.polynomial.chebyshev.chebvander(u, int(axis.trend_degree)))
    for blk in axis.blocks:
        if blk is None or blk.harmonics == 0:
            continue
        phi = 2.0 * np.pi * (p - float(blk.origin_mm)) / float(blk.period_mm)
        k = np.arange(1, int(blk.harmonics) + 1, dtype=np.float64)
        arg = phi[:, None] * k[None, :]
        sc = np.empty((p.size, 2 * k.size))
        sc[:, 0::2] = np.sin(arg)
        sc[:, 1::2] = np.cos(arg)
        cols.append(sc)
    if not cols:
        return np.zeros((p.size, 0))
    return np.hstack(cols)


def reversal_matrix(axis: AxisTable, pos_mm: np.ndarray) -> np.ndarray:
    """Rows of the reversal block of ``axis`` at positions ``pos_mm`` (mm), shape (N, rows).

    Chebyshev T_0..T_(rows-1) of the trend's normalised travel u at the
    position clamped to the travel (rows = len(reversal_cheb_um), 0 without a
    block), so the block's value is ``reversal_matrix(...) @ reversal_cheb_um``
    and a fit of a reversal curve can use it as its design matrix.
    """
    p = np.asarray(pos_mm, dtype=np.float64).reshape(-1)
    rows = 0 if axis.reversal_cheb_um is None else len(axis.reversal_cheb_um)
    if rows == 0:
        return np.zeros((p.size, 0))
    lo, hi = float(axis.travel_mm[0]), float(axis.travel_mm[1])
    u = (2.0 * np.clip(p, lo, hi) - lo - hi) / (hi - lo)
    return np.polynomial.chebyshev.chebvander(u, rows - 1)
