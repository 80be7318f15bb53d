"""``fanuc-pitch``: Fanuc pitch error compensation as a parameter tape and a listing.

Parameters (FANUC parameter manuals, e.g. Series 0i-PB B-63980EN §4 "pitch error
compensation"; 16i/18i bidirectional pitch error compensation A-77810E):
3620 number of the compensation point of the reference position, 3621 / 3622 the
farthest point on the - / + side, 3623 magnification, 3624 interval, 3605#0 BDP
bidirectional, 3626 the farthest - side point of the negative-direction data,
3627 the absolute compensation at the reference position when it is reached from
the opposite direction. Data: one increment per point, "output at the
compensation position corresponding to each section": the value of point n is
the change of the compensation over the section from point n - 1 to point n
(coordinate of point n = reference + (n - n_ref) x interval); the absolute
compensation is 0 at the reference position. Point numbers of point n on the
tape: N10000 + n.

Reconstruction (our reading of "output at the compensation position"): the
compensation is a staircase; a section's increment is output when the axis
reaches the section's end point moving away from the reference (truncation
toward the reference). Each step's value is the mean correction over the step,
rounded to magnification x detection unit; the magnification is the smallest
that keeps every increment within the data range.

Sign: the data are corrections (added to the position: the negative of the
error), as pitch error data are "compensation amounts".
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from abbe.errors import AbbeInputError
from abbe.exports.grids import nice_spacings
from abbe.exports.target import Context, Export, Option, TABLE_MAX_POINTS, Unheld, not_held
from abbe.exports.terms import Item, has_reversal, own_error
from abbe.model.table import AXES

NAME = "fanuc-pitch"
SUMMARY = "Fanuc pitch error compensation: parameters 3620-3627 and point data (tape format)"
OPTIONS = {
    "points": Option("int", 128, "compensation points per axis and direction", lo=2,
                     hi=TABLE_MAX_POINTS),
    "total_points": Option("int", 1024, "pitch error data numbers of the control (0 .. n - 1)",
                           lo=2, hi=6 * TABLE_MAX_POINTS),
    "unit_um": Option("float", 1.0, "detection unit, um (IS-B metric: 1)", lo=1e-4, hi=1000.0),
    "max_value": Option("int", 127, "largest |increment| per point (data range)", lo=1,
                        hi=32767),
    "max_magnification": Option("int", 100, "largest magnification 3623", lo=1, hi=100),
    "rapid_mm_min": Option("float", 15000.0, "rapid traverse rate (minimum interval = rate / "
                           "7500), mm/min", lo=0.0, hi=1e6),
    "reference": Option("axes", {"X": "0", "Y": "0", "Z": "0"},
                        "machine coordinate of each axis' reference position, mm", item="float",
                        lo=-2147.0, hi=2147.0),
    "ref_return": Option("axes", {"X": "+", "Y": "+", "Z": "+"},
                         "direction of the reference position return (+ or -)",
                         choices=("+", "-")),
}
SOURCES = ["FANUC Series 0i-PB parameter manual B-63980EN/01, pitch error compensation "
           "parameters 3620-3624 and the compensation value example",
           "FANUC Series 16i/18i-MA/TA bidirectional pitch error compensation A-77810E "
           "(3605#0, 3621, 3622, 3626, 3627)"]


def regions(n_ref: int, n_min: int, n_max: int) -> list[int]:
    """Point numbers n whose absolute value Q(n) applies somewhere: n_min - 1 .. n_max."""
    return list(range(n_min - 1, n_max + 1))


def staircase(p: np.ndarray, r: float, h: float, n_ref: int, n_min: int, n_max: int,
              Q: dict[int, float]) -> np.ndarray:
    """The absolute compensation at positions p (module docstring): for p >= r the point
    n = n_ref + floor((p - r) / h), for p < r the point n_ref - floor((r - p) / h)... as
    truncation toward the reference; held beyond the farthest points."""
    k = (np.asarray(p, dtype=np.float64) - r) / h
    kk = np.where(k >= 0, np.floor(k + 1e-9), np.ceil(k - 1e-9))
    n = np.clip(n_ref + kk.astype(int), n_min - 1, n_max)
    lut = np.array([Q[i] for i in range(n_min - 1, n_max + 1)])
    return lut[n - (n_min - 1)]


def _layout(lo: float, hi: float, r: float, h: float) -> tuple[int, int]:
    """(sections on the - side, sections on the + side) covering [lo, hi]."""
    return (int(math.ceil((r - lo) / h - 1e-9)), int(math.ceil((hi - r) / h - 1e-9)))


def region(r: float, h: float, n_ref: int, n: int, lo: float, hi: float) -> tuple[float, float]:
    """The positions where Q(n) applies, clipped to the travel [lo, hi]."""
    c = r + (n - n_ref) * h
    a, b = (c, c + h) if n > n_ref else ((c - h, c) if n < n_ref else (c - h, c + h))
    return max(a, lo), min(b, hi)


def _values(qf: np.ndarray, cum: np.ndarray, r: float, h: float, n_ref: int, n_min: int,
            n_max: int, unit: float, m: int, fixed_ref: float | None,
            offset: float) -> dict[int, float]:
    """Q(n) for every region: the mean correction over the region (within the travel
    [qf[0], qf[-1]]; ``cum`` the running integral of the correction on ``qf``) minus
    ``offset`` (the correction at the reference position: Fanuc's is zero there), in
    units of m * unit (um); Q(n_ref) = ``fixed_ref`` when given."""
    lo, hi = float(qf[0]), float(qf[-1])
    Q: dict[int, float] = {}
    for n in regions(n_ref, n_min, n_max):
        a, b = region(r, h, n_ref, n, lo, hi)
        if n == n_ref and fixed_ref is not None:
            Q[n] = fixed_ref
        elif b <= a:
            Q[n] = math.nan  # beyond the travel: takes its inner neighbour below
        else:
            mean = (np.interp(b, qf, cum) - np.interp(a, qf, cum)) / (b - a) - offset
            Q[n] = float(np.round(mean / (m * unit)) * m * unit)
    for n in sorted(Q, key=lambda n: abs(n - n_ref)):
        if math.isnan(Q[n]):
            Q[n] = Q.get(n + 1 if n < n_ref else n - 1, 0.0)
    return Q


def build(ctx: Context) -> Export:
    o = ctx.options
    unit, limit, vmax = float(o["unit_um"]), int(o["points"]), int(o["max_value"])
    hmin = float(o["rapid_mm_min"]) / 7500.0
    params: dict[int, dict[str, str]] = {n: {} for n in (3605, 3620, 3621, 3622, 3623, 3624,
                                                         3626, 3627)}
    data: dict[int, int] = {}
    listing = ["abbe export fanuc-pitch: pitch error compensation (corrections, detection "
               f"unit {unit:g} um)"]
    tabs: dict[str, Any] = {}
    tables: list[dict[str, Any]] = []
    next_no = 0
    for i, a in enumerate(AXES):
        lo, hi = ctx.volume.travel_mm[a]
        try:
            r = float(o["reference"][a])
        except ValueError:
            raise AbbeInputError("a number (mm)", field=f"--set reference {a}") from None
        if not lo - 1e-9 <= r <= hi + 1e-9:
            raise AbbeInputError(f"reference position {r:g} mm of {a} outside its travel "
                                 f"[{lo:g}, {hi:g}] mm", field=f"--set reference {a}")
        rd = 1 if str(o["ref_return"][a]).strip() != "-" else -1
        bidir = has_reversal(ctx.table, a)
        up = lambda q, a=a: -own_error(ctx.table, a, q, 1.0)  # noqa: E731  corrections, um
        dn = lambda q, a=a: -own_error(ctx.table, a, q, -1.0)  # noqa: E731
        mean = lambda q, a=a: -own_error(ctx.table, a, q, 0.0)  # noqa: E731
        dirs = [(+1, up), (-1, dn)] if bidir else [(0, mean)]
        qf = np.linspace(lo, hi, 20001)
        fv = {d: f(qf) for d, f in dirs}
        cums = {d: np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(qf))])
                for d, v in fv.items()}
        best = None
        for hh in sorted(set(nice_spacings(lo, hi) + [(hi - lo) / limit])):
            h = max(math.ceil(hh * 1000.0 / unit - 1e-9) * unit / 1000.0, hmin)
            h = math.ceil(h * 1000.0 / unit - 1e-9) * unit / 1000.0
            nn, npos = _layout(lo, hi, r, h)
            nn = max(nn, 1)  # the reference point is always a compensation point
            if nn + npos > limit:
                continue
            n_ref, n_min, n_max = nn, 1, nn + npos
            d0 = 0 if not bidir else rd
            a0, b0 = region(r, h, n_ref, n_ref, lo, hi)
            K = float((np.interp(b0, qf, cums[d0]) - np.interp(a0, qf, cums[d0])) / (b0 - a0))
            for m in range(1, int(o["max_magnification"]) + 1):
                Qs, ok, err = [], True, 0.0
                for d, _ in dirs:
                    fixed = 0.0 if d in (0, rd) else None
                    Q = _values(qf, cums[d], r, h, n_ref, n_min, n_max, unit, m, fixed, K)
                    inc = [Q[n] - Q[n - 1] for n in range(n_min, n_max + 1)]
                    if max(abs(v) for v in inc) / (m * unit) > vmax + 1e-9:
                        ok = False
                        break
                    err = max(err, float(np.max(np.abs(
                        staircase(qf, r, h, n_ref, n_min, n_max, Q) + K - fv[d]))))
                    Qs.append(Q)
                if ok:
                    tie = max(1e-3, 0.01 * best[0]) if best else 0.0
                    if best is None or err < best[0] - tie or (abs(err - best[0]) <= tie
                                                                and h > best[1]):
                        best = (err, h, m, n_ref, n_min, n_max, Qs)
                    break
        if best is None:
            raise AbbeInputError(
                f"axis {a}: no interval >= {hmin:g} mm within {limit} points keeps every "
                f"increment within +/-{vmax} x magnification <= {o['max_magnification']} "
                f"(travel {hi - lo:g} mm)", field="--set points")
        err, h, m, n_ref, n_min, n_max, Qs = best
        npts = n_max - n_min + 1
        base = next_no - n_min  # shift this axis' numbers into the control's range
        blocks = []
        for bi, ((d, f), Q) in enumerate(zip(dirs, Qs)):
            shift = base + bi * npts
            for n in range(n_min, n_max + 1):
                data[n + shift] = int(round((Q[n] - Q[n - 1]) / (m * unit)))
            blocks.append((d, shift, Q))
        next_no += npts * len(dirs)
        if next_no > int(o["total_points"]):
            raise AbbeInputError(f"{next_no} pitch error data points needed, the control has "
                                 f"{o['total_points']}", field="--set total_points")
        A = f"A{i + 1}"
        params[3605][A] = "00000001" if bidir else "00000000"
        params[3620][A] = str(n_ref + base)
        params[3621][A] = str(n_min + base)
        params[3622][A] = str(n_max + base)
        params[3623][A] = str(m)
        params[3624][A] = str(int(round(h * 1000.0 / unit)))
        if bidir:
            other = next(Q for d, _, Q in blocks if d != rd)
            params[3626][A] = str(n_min + base + npts)
            params[3627][A] = str(int(round(other[n_ref] / unit)))
        tabs[a] = (r, h, n_ref, n_min, n_max, {d: Q for d, _, Q in blocks}, rd)
        tables.append({"name": f"axis {a} ({'bidirectional' if bidir else 'one table'})",
                       "points": npts, "limit": limit, "start_mm": r - (n_ref - n_min + 1) * h,
                       "end_mm": r + (n_max - n_ref) * h, "spacing_mm": h, "magnification": m,
                       "staircase_residual_um": round(err, 4),
                       "limit_is_cause": bool(h <= max(hmin, (hi - lo) / limit) * 1.0001
                                              and err > 0.05)})
        listing.append(f"axis {a}: 3620 = {n_ref + base} (reference at {r:g} mm), 3621 = "
                       f"{n_min + base}, 3622 = {n_max + base}, 3623 = {m}, 3624 = "
                       f"{params[3624][A]} ({h:g} mm)"
                       + (f", 3605#0 = 1, 3626 = {params[3626][A]}, 3627 = {params[3627][A]}"
                          if bidir else ""))
        for d, shift, Q in blocks:
            tag = {0: "both directions", 1: "moving +", -1: "moving -"}[d]
            listing.append(f"  {tag}: point, position mm, increment, absolute um")
            for n in range(n_min, n_max + 1):
                listing.append(f"    {n + shift:5d} {r + (n - n_ref) * h:10.3f} "
                               f"{data[n + shift]:5d} {Q[n]:9.3f}")
    tape = ["%"]
    for no, vals in params.items():
        if vals:
            tape.append(f"N{no}" + "".join(f"{k}P{v}" for k, v in vals.items()))
    tape += [f"N{10000 + n}P{v}" for n, v in sorted(data.items())]
    tape.append("%")

    def correction(pos: np.ndarray, state: np.ndarray) -> np.ndarray:
        out = np.zeros_like(pos, dtype=np.float64)
        for j, a in enumerate(AXES):
            r, h, n_ref, n_min, n_max, Qd, rd = tabs[a]
            if 0 in Qd:
                out[:, j] = staircase(pos[:, j], r, h, n_ref, n_min, n_max, Qd[0])
                continue
            u = staircase(pos[:, j], r, h, n_ref, n_min, n_max, Qd[1])
            d = staircase(pos[:, j], r, h, n_ref, n_min, n_max, Qd[-1])
            out[:, j] = np.where(state[:, j] < 0, d, u)
        return out

    def cannot(item: Item) -> Unheld | None:
        if item.kind == "term" and item.part == "single":
            return Unheld("pitch compensation corrects an axis from its own position only",
                          "".join(b for b in AXES if b != item.axis))
        if item.kind == "term":
            return Unheld("products with other axes' positions need more than one input")
        if item.kind == "squareness":
            return Unheld("cross-axis (the 30i's 3D error compensation is another function)")
        if item.kind == "thermal":
            return Unheld("no temperature input")
        return None

    return Export(
        target=NAME, files={"fanuc_pitch.prm": ("\n".join(tape) + "\n").encode(),
                            "fanuc_pitch.txt": ("\n".join(listing) + "\n").encode()},
        correction=correction,
        expressed=[f"{a} positioning along its own line" + (", bidirectional" if 0 not in tabs[a][5]
                                                             else "") for a in AXES],
        not_held=not_held(ctx, cannot), tables=tables, direction="sign",
        notes=["3605 is written with only bit 0 (BDP): merge it with the machine's other bits",
               "3624 in detection units; newer controls take it in mm: check the parameter manual"],
        assumptions=["data are corrections (negative of the error)",
                     "a section's increment is output on reaching its end point moving away from "
                     "the reference (staircase, truncation toward the reference)",
                     "the reference position return direction per --set ref_return (default +)"],
        sources=SOURCES)
