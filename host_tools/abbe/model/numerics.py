"""A-priori error bounds of the C library's two numeric variants.

The derivation is in docs/numerics.md; this module evaluates it for a given
table so the bound is a number, not a claim. Each bound is the worst case over
the whole travel of |C result - float64 reference| for one of dX, dY, dZ, in nm.
The reference is the exact arithmetic on the table's stored (quantised)
values, so table quantisation is not part of these bounds (abbe.formats.blob reports
it separately).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from abbe.model.table import AXES, Table

U_F32 = 2.0 ** -24            # unit roundoff of IEEE single precision
SINCOS_Q30 = 2.1e-9           # measured max |error| of the Q30 sin/cos kernel (tests/unit/test_eval.c: 2.04e-9)
SINCOS_F32 = 1.2e-7           # measured max |error| of the float sin/cos kernel, with margin
PHASE_Q32 = 2 * math.pi * 1.5 * 2.0 ** -32   # phase reduction: <= 1.5 LSB of a Q32 turn, in rad
POS_F32_NM = 0.56             # float mm -> integer nm conversion (docs/numerics.md)
Q30 = 2.0 ** -30


@dataclass(frozen=True)
class Bound:
    """Worst-case error bounds in nm, per output component."""

    f32_nm: tuple[float, float, float]
    q_nm: tuple[float, float, float]


def _basis_errors(n_trend: int, harmonics: tuple[int, int], variant: str) -> np.ndarray:
    """Bound of |computed - exact| for each basis row (unitless)."""
    errs: list[float] = []
    if variant == "q":
        for k in range(n_trend):
            # argument error (1 LSB) amplified by |T_k'| <= k^2, plus one rounding per recurrence step
            errs.append((k * k + k) * Q30)
        for h in harmonics:
            for n in range(1, h + 1):
                e = n * (SINCOS_Q30 + PHASE_Q32 + Q30)
                errs += [e, e]
    else:
        for k in range(n_trend):
            errs.append((k * k) * (Q30 + 2 * U_F32) + k * 2 * U_F32)
        for h in harmonics:
            for n in range(1, h + 1):
                e = n * (SINCOS_F32 + PHASE_Q32 + 3 * U_F32)
                errs += [e, e]
    return np.asarray(errs, dtype=float)


def _slope(axis, coef: np.ndarray) -> float:
    """Upper bound of |d term / d position| per nm (term units per nm)."""
    lo, hi = axis.travel_mm
    span_nm = (hi - lo) * 1e6
    n_trend = 0 if axis.trend_degree is None else axis.trend_degree + 1
    s = 0.0
    for k in range(n_trend):
        s += abs(coef[k]) * k * k * 2.0 / span_nm
    row = n_trend
    for block in axis.blocks:
        if block is None:
            continue
        for n in range(1, block.harmonics + 1):
            s += (abs(coef[row]) + abs(coef[row + 1])) * 2 * math.pi * n / (block.period_mm * 1e6)
            row += 2
    return s


def _term_error(axis, coef: np.ndarray, variant: str) -> float:
    """Bound of the error of one fitted term, in its unit (um or urad)."""
    n_trend = 0 if axis.trend_degree is None else axis.trend_degree + 1
    harm = tuple(b.harmonics if b is not None else 0 for b in axis.blocks)
    eb = _basis_errors(n_trend, harm, variant)
    mag = np.abs(coef)
    if variant == "q":
        return float(mag @ eb)  # exact int64 dot product; its rounding is counted in unit LSBs below
    rows = len(coef)
    # stored float32 coefficient (u), basis error, dot-product accumulation (rows * u)
    return float(mag @ (eb + (rows + 1) * U_F32 * (1.0 + eb))) + _slope(axis, coef) * POS_F32_NM


def _reversal_error(axis, variant: str) -> float:
    """Bound of the error of an axis' reversal block R(p) (format 1.1), um, before
    the backlash's s / 2: the trend's Chebyshev rows and dot product (the same
    recurrence and roundings); ``_q`` adds R's one rounding to 2^-8 nm."""
    if axis.reversal_cheb_um is None:
        return 0.0
    c = np.abs(np.asarray(axis.reversal_cheb_um, dtype=float))
    rows = c.size
    eb = _basis_errors(rows, (0, 0), variant)
    if variant == "q":
        return float(c @ eb) + 0.5 * 2.0 ** -8 * 1e-3
    span_nm = (axis.travel_mm[1] - axis.travel_mm[0]) * 1e6
    slope = float(sum(c[k] * k * k * 2.0 / span_nm for k in range(rows)))
    return float(c @ (eb + (rows + 1) * U_F32 * (1.0 + eb))) + slope * POS_F32_NM


# Eq. 3 + Abbe terms: for each output component, the arms (lever "x"/"y"/"z" from the
# reference point, tool offset "tx"/"ty"/"tz") and the angular terms (axis, about) and
# squareness (index into squareness_urad) each arm multiplies (docs/table-format.md).
_ARMS: dict[int, list[tuple[str, list[tuple[str, str]], list[int]]]] = {
    0: [("y", [("X", "ez"), ("Y", "ez")], [0]), ("z", [("X", "ey"), ("Y", "ey")], [1]),
        ("ty", [("X", "ez"), ("Y", "ez"), ("Z", "ez")], []), ("tz", [("Z", "ey"), ("X", "ey"), ("Y", "ey")], [])],
    1: [("x", [("X", "ez")], []), ("z", [("X", "ex"), ("Y", "ex")], [2]),
        ("tx", [("Z", "ez"), ("X", "ez"), ("Y", "ez")], []), ("tz", [("X", "ex"), ("Y", "ex"), ("Z", "ex")], [])],
    2: [("x", [("X", "ey")], []), ("y", [("X", "ex"), ("Y", "ex")], []),
        ("tx", [("X", "ey"), ("Y", "ey"), ("Z", "ey")], []), ("ty", [("Z", "ex"), ("X", "ex"), ("Y", "ex")], [])],
}


def error_bound(table: Table) -> Bound:
    """Worst-case error of abbe_error_eval_f32 / _q against the float64 reference, in nm.

    Positions range over the travel of each axis; levers are measured from the
    reference point, so the largest lever is the farther travel end.
    """
    ref = np.asarray(table.reference_mm, dtype=float)
    arm_mm = {}
    for i, a in enumerate(AXES):
        lo, hi = table.axes[a].travel_mm
        arm_mm["xyz"[i]] = max(abs(lo - ref[i]), abs(hi - ref[i]))
        arm_mm["t" + "xyz"[i]] = abs(float(table.tool_offset_mm[i]))
    err = {"f32": {}, "q": {}}   # (axis, term) -> bound, um or urad
    mag = {}                     # (axis, term) -> bound of |value|, um or urad
    for a in AXES:
        axis = table.axes[a]
        for t, coef in axis.coef.items():
            coef = np.asarray(coef, dtype=float)
            for v in ("f32", "q"):
                err[v][(a, t)] = _term_error(axis, coef, v)
            mag[(a, t)] = float(np.abs(coef).sum())
        own = "d" + "xyz"[AXES.index(a)]
        lever = arm_mm["xyz"[AXES.index(a)]]
        rev = 0.0 if axis.reversal_cheb_um is None else float(np.abs(axis.reversal_cheb_um).sum())
        extra = (abs(axis.backlash_um) + rev) / 2 + abs(axis.thermal_offset_um_per_k) * 50.0 \
            + abs(axis.thermal_expansion_ppm_per_k) * 1e-6 * 50.0 * lever * 1e3   # |dT| <= 50 K
        mag[(a, own)] = mag.get((a, own), 0.0) + extra
        for v in ("f32", "q"):   # the reversal block, times |s| / 2 <= 1 / 2
            err[v][(a, own)] = err[v].get((a, own), 0.0) + 0.5 * _reversal_error(axis, v)
    sq = [abs(float(s)) for s in table.squareness_urad]

    out: dict[str, list[float]] = {"f32": [], "q": []}
    for i in range(3):
        lin_terms = [(a, "d" + "xyz"[i]) for a in AXES]
        lin_mag_nm = sum(mag.get(k, 0.0) for k in lin_terms) * 1e3
        ang_mag_nm = sum(arm_mm[arm] * (sum(mag.get(k, 0.0) for k in terms) + sum(sq[s] for s in sqs))
                         for arm, terms, sqs in _ARMS[i])
        for v in ("f32", "q"):
            lin = sum(err[v].get(k, 0.0) for k in lin_terms) * 1e3                          # nm
            ang = sum(arm_mm[arm] * sum(err[v].get(k, 0.0) for k in terms) for arm, terms, _ in _ARMS[i])
            if v == "q":
                n_ang_terms = sum(len(terms) for _, terms, _ in _ARMS[i])
                worst_arm = max(arm_mm[arm] for arm, _, _ in _ARMS[i])
                # term values rounded once from their exact int64 sums: linear to 2^-6 nm,
                # angular to 2^-35 rad; the lever products and their sum are exact int64
                # (docs/numerics.md), the squareness sum is halved (floor, 2^-35 nm), the
                # extras round in 2^-8 nm as before and E >> 27 floors (1 x 2^-8 nm)
                rounding = (3 * 0.5 * 2.0 ** -6                       # linear term values
                            + n_ang_terms * 0.5 * 2.0 ** -35 * worst_arm * 1e6  # angle values x arm
                            + 2.0 ** -35                             # squareness halving
                            + 4 * 0.5 * 2.0 ** -8 + 2.0 ** -8        # extras, E >> 27
                            + 0.5)                                   # final rounding to whole nm
                out[v].append(lin + ang + rounding)
            else:
                # arms carry 4u relative (float conversion, the scale to um per angle LSB
                # and its own rounding, the arm differences such as t_y - y) + 1 nm absolute
                # error; about 12 roundings act on each component in the assembly
                arm_err = sum((4 * U_F32 * arm_mm[arm] + 1e-6) * (sum(mag.get(k, 0.0) for k in terms)
                                                               + sum(sq[s] for s in sqs))
                              for arm, terms, sqs in _ARMS[i])
                out[v].append(lin + ang + arm_err + 12 * U_F32 * (lin_mag_nm + ang_mag_nm))
    return Bound(f32_nm=tuple(out["f32"]), q_nm=tuple(out["q"]))
