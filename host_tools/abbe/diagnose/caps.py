"""The table's caps on the terms ``abbe diagnose`` adds (issue 24).

The effects diagnose writes into the table (scale, bow, cyclic, straightness,
reversal) change the coefficients of a term that ``abbe fit`` chose within the
table's fixed-point cap and its conditioning guard
(:func:`abbe.analysis.fit.select.well_conditioned`: sum |c| at most 10 x the largest
|value| over the travel and at most half the cap). The same guard holds here, so that
the updated model.bin can always be written: a change that takes a term out of it
is rejected by the selection (``selection.py``), which names the term and the amount.

Units: linear terms um, angular terms urad, positions mm.
"""

from __future__ import annotations

import numpy as np

from abbe.analysis.fit.select import CAP_FRACTION, well_conditioned
from abbe.formats.blob import coef_sum_cap
from abbe.model.table import AxisTable, Table, basis_matrix

#: samples over the travel on which a term's values are taken (its largest |value|)
_GRID_POINTS = 201


def _values(ax: AxisTable, c: np.ndarray) -> np.ndarray:
    """The term's values (um or urad) over the axis' travel."""
    lo, hi = ax.travel_mm
    return basis_matrix(ax, np.linspace(lo, hi, _GRID_POINTS)) @ np.asarray(c, dtype=float)


def cap_violations(base: Table, new: Table) -> list[tuple[str, str, str]]:
    """The terms of ``new`` that the changes from ``base`` take out of the guard:
    (axis, term, statement). A term that already failed the guard in ``base`` (a machine
    error larger than the format holds, reported by ``abbe fit``) is held only to not
    growing in sum |c| and to the hard cap."""
    out: list[tuple[str, str, str]] = []
    for a, ax in new.axes.items():
        bax = base.axes.get(a)
        for term, c in ax.coef.items():
            c = np.asarray(c, dtype=float)
            b = None if bax is None else bax.coef.get(term)
            if b is not None and b.shape == c.shape and np.array_equal(b, c):
                continue
            cap = coef_sum_cap(term)
            unit = "um" if term.startswith("d") else "urad"
            total = float(np.abs(c).sum())
            if total > cap:
                out.append((a, term, f"sum |coefficients| {total:.6g} {unit} over the "
                                      f"table's cap {cap:.0f} {unit} by {total - cap:.6g} {unit}"))
                continue
            if well_conditioned(c, _values(ax, c), cap):
                continue
            before = float(np.abs(b).sum()) if b is not None else 0.0
            was_ok = b is None or well_conditioned(np.asarray(b, float), _values(bax, b), cap)  # type: ignore[arg-type]
            if was_ok or total > before:
                out.append((a, term, f"sum |coefficients| {total:.6g} {unit} fails the "
                                      f"conditioning guard of abbe fit (<= 10 x its largest "
                                      f"value and <= {CAP_FRACTION:g} x the cap {cap:.0f} {unit})"))
    return out
