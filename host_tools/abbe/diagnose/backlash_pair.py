"""A backlash whose take-up differs with the direction of the reversal: the optional
per-direction take-up of the diagnosis' backlash entry (docs/effects.md §3, "A
per-direction take-up").

The compensator and the table hold one take-up per axis (``backlash_takeup_mm``,
model/backlash.py): the direction state runs from -1 to +1 over it after every reversal.
A drive can take up its lost motion over a shorter distance after a reversal to + motion
than after one to - motion (preload, the screw's end); one take-up then leaves a mirrored
residual after each reversal (issue 36, team suite seed 1356483448 ``backlash_asym``).
The diagnosis offers a pair (take-up after a reversal to + motion, after one to - motion)
as an alternative of the backlash candidate, searched on a grid of pairs with its own
look-elsewhere cost and one more shape parameter in the BIC, refined continuously, and
chosen only by the evidence the selection already uses. The pair is carried in the
prediction parameters (``PredParams.backlash_takeup_pair_mm``); the table written keeps
one take-up, the mean of the pair (docs/effects.md catalogue, backlash).

Units: positions and take-ups mm.
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np

#: a candidate's scan value that is a per-direction pair: (take-up to + motion, to - motion)
Pair = tuple[float, float]


#: the pairs searched: two take-ups of the single take-up's grid at most this many grid
#: steps apart (a ratio of 2 to 5 on 0.005 ... 4 mm); the refinement moves each within its
#: grid neighbours, so a refined pair reaches larger ratios. The whole grid's 90 pairs gave
#: the same answers on the team's suites and draws (docs/diagnose-validation.md) at about
#: 2.6 times as many predictions (each pair is one prediction of every check).
PAIR_MAX_GRID_STEPS = 2


def pair_grid(grid_mm: tuple[float, ...]) -> list[Pair]:
    """The ordered pairs (to + motion, to - motion) of two different take-ups of the single
    take-up's grid (mm, ascending) at most PAIR_MAX_GRID_STEPS grid steps apart."""
    return [(float(grid_mm[i]), float(grid_mm[j]))
            for i, j in itertools.permutations(range(len(grid_mm)), 2)
            if abs(i - j) <= PAIR_MAX_GRID_STEPS]


def is_pair(v: Any) -> bool:
    """True if a scan value is a per-direction take-up pair."""
    return isinstance(v, tuple)


def table_takeup_mm(v: Any) -> float:
    """The one take-up the table holds for a scan value (mm): a pair's mean (the compensator
    has one take-up; the mean keeps the total distance over which a reversal cycle's two
    take-ups happen), a single take-up as it is."""
    if is_pair(v):
        return 0.5 * (float(v[0]) + float(v[1]))
    return float(v)


def scan_entries(v: Any, name: str) -> dict[str, float]:
    """The reported shape values of a scan value: ``name`` (the table's take-up) and, for a
    pair, ``takeup_plus_mm`` / ``takeup_minus_mm`` (after a reversal to + / - motion)."""
    if not is_pair(v):
        return {name: float(v)}
    return {name: table_takeup_mm(v), "takeup_plus_mm": float(v[0]),
            "takeup_minus_mm": float(v[1])}


def pair_state(pos_mm: np.ndarray, up_mm: float, down_mm: float,
               s0: float | None = None) -> np.ndarray:
    """Direction state s in [-1, 1] along a polyline path (N,) mm with a per-direction
    take-up: s rises by 2 dp / ``up_mm`` while the axis moves in +, falls by 2 |dp| /
    ``down_mm`` while it moves in -, clipped; standstill keeps it. ``s0`` defaults to the
    sign of the first motion (as model.backlash.direction_state)."""
    p = np.asarray(pos_mm, dtype=np.float64).reshape(-1)
    out = np.zeros(p.size)
    if p.size < 2:
        return out
    dp = np.diff(p)
    if s0 is None:
        nz = np.flatnonzero(np.abs(dp) > 1e-12)
        s0 = float(np.sign(dp[nz[0]])) if nz.size else 0.0
    out[0] = s = float(np.clip(s0, -1.0, 1.0))
    sgn = np.sign(dp)
    n = dp.size
    i = 0
    while i < n:
        j = i
        while j + 1 < n and sgn[j + 1] == sgn[i]:
            j += 1
        k = 2.0 / float(up_mm if sgn[i] > 0 else down_mm)
        seg = p[i + 1: j + 2] - p[i]
        out[i + 1: j + 2] = np.clip(s + k * seg, -1.0, 1.0)
        s = float(out[j + 1])
        i = j + 1
    return out
