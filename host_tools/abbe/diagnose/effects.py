"""Catalogue of the effects ``abbe diagnose`` can name (docs/effects.md).

Each candidate effect is a set of **extra parameters of the model**: either a
change of the :class:`abbe.model.table.Table` (squareness, backlash, scale, cyclic
block, tool offset, straightness bow, thermal coefficients) or a parameter of
the *prediction model* that the table cannot hold (servo lag, a time-driven
drift). :meth:`EffectSpec.apply` returns the modified (table, prediction
parameters); the diagnosis computes an effect's signature on a test by
re-predicting the test through the model with the parameter perturbed, never
from a hand-drawn shape, so a new test geometry needs no new code.

Sign conventions follow docs/table-format.md and notes.md §1: an axis' own
positioning term (d_x of X, d_y of Y, d_z of Z) enters the spatial error with
the sign ``OWN_SIGN`` (-1, -1, +1); backlash is the table's ISO 230-2 reversal B
(mean(+ approach) - mean(- approach) of the own term), applied as s B / 2.

Units: positions mm, linear values um, angles urad, lags ms, scale ppm.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from abbe.diagnose.backlash_pair import is_pair, table_takeup_mm
from abbe.model.geometry import PLANE_AXES, PLANES
from abbe.model.table import AXES, OWN_TERM, AxisTable, FourierBlock, Table, basis_matrix

#: Order of the servo-mismatch parameters (one per plane).
SERVO_PLANES: tuple[str, ...] = PLANES
#: Highest degree of the position-dependent reversal series (the table's Chebyshev limit).
REVERSAL_MAX_DEGREE = 7
#: Most targets a per-target reversal takes (parameters: targets - 1).
REVERSAL_MAX_TARGETS = 41


def reversal_series(travel_mm: tuple[float, float], coef: np.ndarray, pos_mm: np.ndarray) -> np.ndarray:
    """Position-dependent part of the reversal (um) at axis positions (mm): Chebyshev
    series of the normalised travel, the position clamped to the travel (end value
    held, as for every table term). float64."""
    lo, hi = float(travel_mm[0]), float(travel_mm[1])
    p = np.clip(np.asarray(pos_mm, dtype=np.float64), lo, hi)
    u = (2.0 * p - lo - hi) / (hi - lo)
    return np.polynomial.chebyshev.chebval(u, np.asarray(coef, dtype=np.float64))


class NotRepresentable(Exception):
    """The effect cannot be put into this table (e.g. no free Fourier block)."""


@dataclass
class PredParams:
    """Parameters of the prediction model that the table does not hold.

    servo_lag_ms: (3,) position-loop lag of each axis (ms): the actual position
        is the commanded one ``lag`` earlier along the path (only differences
        within a plane change a circle's radius).
    servo_mismatch_ms: (3,) lag difference tau_b - tau_a (ms) of the planes XY, YZ,
        ZX (a, b as in the plane name), acting only on circles in that plane.
    drift_offset: (3,) own-positioning-term offset per unit of the drift
        variable (um per h, per run, or per K; see ``Check.drift_unit``).
    drift_scale_ppm: (3,) own-positioning-term scale per unit of the drift
        variable (ppm per h / run / K), about the reference point.
    drift_tau: time constant of a time-driven drift (same unit as the drift
        variable; inf = linear in time): the drift follows a first-order warm-up,
        tau (1 - exp(-t / tau)), whose initial rate is the offset / scale above.
    servo_gain_ms2: (3,) per plane XY, YZ, ZX, q = kappa x tau_mean x (tau_b - tau_a)
        (ms^2): the oval along the plane axes (R w^2 q cos 2 theta, the same in CW and
        CCW, growing with the feed squared) that unequal loops give beyond the phase
        mismatch: the common lag tau_mean rotates the mismatch oval (kappa = 1 for pure
        delays) and first-order loops add an amplitude mismatch (kappa = 1.5). Modelled
        as amplitudes 1 + w^2 q and 1 - w^2 q of the plane's first and second axis.
    reversal_cheb_um: (3, REVERSAL_MAX_DEGREE + 1) per axis, the position-dependent part
        of the reversal (um) as Chebyshev T0..TD of the normalised travel: the total
        reversal at p is the table's backlash_um + this series, applied with the
        backlash direction state (own term + s R(p) / 2); evaluated in float64
        (:func:`reversal_series`) while the effects are searched and fitted, then moved
        into the table's reversal block (format 1.1, :func:`fold_reversal`).
    """

    servo_lag_ms: np.ndarray = field(default_factory=lambda: np.zeros(3))
    servo_mismatch_ms: np.ndarray = field(default_factory=lambda: np.zeros(3))
    drift_offset: np.ndarray = field(default_factory=lambda: np.zeros(3))
    drift_scale_ppm: np.ndarray = field(default_factory=lambda: np.zeros(3))
    drift_tau: float = math.inf
    servo_gain_ms2: np.ndarray = field(default_factory=lambda: np.zeros(3))
    reversal_cheb_um: np.ndarray = field(
        default_factory=lambda: np.zeros((3, REVERSAL_MAX_DEGREE + 1)))
    reversal_knots_mm: list = field(default_factory=lambda: [None, None, None])
    reversal_knot_um: list = field(default_factory=lambda: [None, None, None])
    drift_bow_um: np.ndarray = field(default_factory=lambda: np.zeros(3))
    #: per axis (take-up after a reversal to + motion, to - motion) mm, or zeros: the
    #: table's one take-up (abbe.diagnose.backlash_pair; the table holds their mean)
    backlash_takeup_pair_mm: np.ndarray = field(default_factory=lambda: np.zeros((3, 2)))

    def copy(self) -> "PredParams":
        return PredParams(self.servo_lag_ms.copy(), self.servo_mismatch_ms.copy(),
                          self.drift_offset.copy(), self.drift_scale_ppm.copy(), self.drift_tau,
                          self.servo_gain_ms2.copy(), self.reversal_cheb_um.copy(),
                          list(self.reversal_knots_mm),
                          [None if v is None else v.copy() for v in self.reversal_knot_um],
                          self.drift_bow_um.copy(), self.backlash_takeup_pair_mm.copy())

    def has_reversal(self, j: int) -> bool:
        k = self.reversal_knot_um[j]
        return bool(np.any(self.reversal_cheb_um[j]) or (k is not None and np.any(k)))

    def reversal_at(self, j: int, travel_mm: tuple[float, float], pos_mm: np.ndarray) -> np.ndarray:
        """Position-dependent part of the reversal of axis j (um) at positions (mm): the
        Chebyshev series plus the per-target values (linear between the targets, held
        beyond the end targets)."""
        v = reversal_series(travel_mm, self.reversal_cheb_um[j], pos_mm)
        k = self.reversal_knot_um[j]
        if k is not None and np.any(k):
            v = v + np.interp(np.asarray(pos_mm, dtype=np.float64), self.reversal_knots_mm[j], k)
        return v

    def drift_shape(self, v: np.ndarray) -> np.ndarray:
        """The drift variable through the warm-up shape tau (1 - exp(-v / tau))."""
        if not math.isfinite(self.drift_tau):
            return v
        return -self.drift_tau * np.expm1(-v / self.drift_tau)

    def is_zero(self) -> bool:
        return not (np.any(self.servo_lag_ms) or np.any(self.servo_mismatch_ms)
                    or np.any(self.drift_offset) or np.any(self.drift_scale_ppm)
                    or np.any(self.drift_bow_um)
                    or np.any(self.servo_gain_ms2) or np.any(self.reversal_cheb_um))

    def plane_lags_ms(self, plane: str) -> tuple[float, float]:
        """Lags (ms) of the plane's first and second axis on a circle in ``plane``."""
        a, b = PLANE_AXES[plane]
        d = float(self.servo_mismatch_ms[SERVO_PLANES.index(plane)])
        return float(self.servo_lag_ms[a]) - 0.5 * d, float(self.servo_lag_ms[b]) + 0.5 * d

    def plane_gains(self, plane: str, omega_rad_s: float) -> tuple[float, float]:
        """Relative amplitudes (1 + h, 1 - h) of the plane's first and second axis on a
        circle at ``omega_rad_s`` (h = w^2 q, q in ms^2; see ``servo_gain_ms2``)."""
        h = omega_rad_s ** 2 * float(self.servo_gain_ms2[SERVO_PLANES.index(plane)]) * 1e-6
        return 1.0 + h, 1.0 - h


def fold_reversal(table: Table, pp: PredParams, takeup_mm: float) -> tuple[Table, PredParams]:
    """The position-dependent reversal of ``pp`` moved into the table's reversal blocks
    (table format 1.1), so that ``model.bin`` carries it: the Chebyshev part exactly; a
    per-target form as its least-squares Chebyshev series of degree <= min(7, targets - 1)
    at the targets, what that series leaves at the targets staying in ``pp`` (the
    prediction model only, linear between the targets). An axis without a backlash
    take-up gets ``takeup_mm`` (mm), the one its prediction assumed. The total
    predicted reversal is unchanged at the targets."""
    t, p = copy_table(table), pp.copy()
    for j, a in enumerate(AXES):
        if not p.has_reversal(j):
            continue
        ax = t.axes[a]
        series = np.asarray(p.reversal_cheb_um[j], dtype=np.float64).copy()
        knots, vals = p.reversal_knots_mm[j], p.reversal_knot_um[j]
        if knots is not None and vals is not None and np.any(vals):
            k = np.asarray(knots, dtype=np.float64)
            lo, hi = float(ax.travel_mm[0]), float(ax.travel_mm[1])
            u = (2.0 * np.clip(k, lo, hi) - lo - hi) / (hi - lo)
            deg = min(REVERSAL_MAX_DEGREE, k.size - 1)
            c = np.polynomial.chebyshev.chebfit(u, vals, deg)
            series[:c.size] += c
            left = vals - np.polynomial.chebyshev.chebval(u, c)
            p.reversal_knot_um[j] = left if np.max(np.abs(left)) > 1e-4 else None
        old = np.zeros(0) if ax.reversal_cheb_um is None else np.asarray(ax.reversal_cheb_um)
        n = max(old.size, series.size)
        total = np.zeros(n)
        total[:old.size] += old
        total[:series.size] += series
        nz = np.flatnonzero(np.abs(total) > 1e-9)
        ax.reversal_cheb_um = tuple(float(v) for v in total[:nz[-1] + 1]) if nz.size else None
        if ax.backlash_takeup_mm <= 0 and ax.reversal_cheb_um is not None:
            ax.backlash_takeup_mm = float(takeup_mm)
        p.reversal_cheb_um[j] = 0.0
    return t, p


def copy_table(t: Table) -> Table:
    """Deep copy of a table (coefficient arrays copied)."""
    return copy.deepcopy(t)


def _nb0(ax: AxisTable) -> int:
    return ax.n_trend() + (0 if ax.blocks[0] is None else 2 * int(ax.blocks[0].harmonics))


def ensure_term(ax: AxisTable, term: str) -> None:
    """Add ``term`` with zero coefficients if absent."""
    if term not in ax.coef:
        ax.coef[term] = np.zeros(ax.n_basis())


def ensure_trend(ax: AxisTable, degree: int) -> None:
    """Raise the axis' trend degree to at least ``degree`` (new rows zero)."""
    cur = -1 if ax.trend_degree is None else int(ax.trend_degree)
    if cur >= degree:
        return
    add = degree - cur
    n_old = ax.n_trend()
    for t, c in list(ax.coef.items()):
        c = np.asarray(c, dtype=np.float64)
        ax.coef[t] = np.concatenate([c[:n_old], np.zeros(add), c[n_old:]])
    ax.trend_degree = degree


def add_block(ax: AxisTable, period_mm: float, origin_mm: float, harmonics: int = 1) -> int:
    """Make a Fourier block with this period available; returns its index.

    Reuses a block with the same period and origin (raising its harmonics if
    needed), else takes a free slot (block 1 first: the short-period block).
    Raises NotRepresentable if both blocks are in use with other periods.
    """
    for b, blk in enumerate(ax.blocks):
        if (blk is not None and math.isclose(blk.period_mm, period_mm, rel_tol=1e-12)
                and math.isclose(blk.origin_mm, origin_mm, abs_tol=1e-9)):
            if blk.harmonics < harmonics:
                _set_block(ax, b, FourierBlock(blk.period_mm, blk.origin_mm, harmonics))
            return b
    for b in (1, 0):
        if ax.blocks[b] is None:
            _set_block(ax, b, FourierBlock(float(period_mm), float(origin_mm), int(harmonics)))
            return b
    raise NotRepresentable("both Fourier blocks of the axis are in use")


def _set_block(ax: AxisTable, b: int, blk: FourierBlock) -> None:
    """Replace block ``b`` (rows of a shrinking block are dropped, new rows zero)."""
    old = ax.blocks[b]
    h_old = 0 if old is None else int(old.harmonics)
    start = ax.n_trend() + (0 if b == 0 else (0 if ax.blocks[0] is None
                                              else 2 * int(ax.blocks[0].harmonics)))
    for t, c in list(ax.coef.items()):
        c = np.asarray(c, dtype=np.float64)
        keep = c[start:start + 2 * min(h_old, blk.harmonics)]
        new = np.zeros(2 * blk.harmonics)
        new[:keep.size] = keep
        ax.coef[t] = np.concatenate([c[:start], new, c[start + 2 * h_old:]])
    blocks = list(ax.blocks)
    blocks[b] = blk
    ax.blocks = (blocks[0], blocks[1])


def block_row(ax: AxisTable, b: int) -> int:
    """Index of the sin1 row of block ``b``."""
    return ax.n_trend() + (0 if b == 0 else (0 if ax.blocks[0] is None
                                             else 2 * int(ax.blocks[0].harmonics)))


def _value_at(ax: AxisTable, coef: np.ndarray, p: float) -> float:
    return float((basis_matrix(ax, np.array([p])) @ coef)[0])


def add_shape(t: Table, axis: str, term: str, fn_coef: Callable[[AxisTable], np.ndarray],
              zero_at_reference: bool = True) -> None:
    """Add coefficients (computed by ``fn_coef`` on the prepared axis) to a term, then
    shift T0 so the added part is 0 at the reference point."""
    ax = t.axes[axis]
    ensure_term(ax, term)
    add = np.asarray(fn_coef(ax), dtype=np.float64)
    if zero_at_reference:
        ref = float(t.reference_mm[AXES.index(axis)])
        if ax.trend_degree is None:
            ensure_trend(ax, 0)
            add = np.concatenate([[0.0], add])
        add[0] -= _value_at(ax, add, ref)
    ax.coef[term] = np.asarray(ax.coef[term], dtype=np.float64) + add


@dataclass(frozen=True)
class ParamSpec:
    """One parameter of an effect: name, unit, a typical magnitude (notes.md §7) used
    for observability and the finite-difference step."""

    name: str
    unit: str
    typical: float
    limit: float = math.inf  # largest plausible |value|; beyond it the fit is not believed
    optional: bool = False   # the candidate is also tried without this parameter


@dataclass(frozen=True)
class EffectSpec:
    """A catalogue entry.

    family: the id reported (``squareness_xy``, ``backlash_x``, ``thermal_drift``,
    ``servo_mismatch``, ``tool_offset``, ``straightness`` ...); key: unique name
    of this candidate (``thermal_drift_x``, ``servo_mismatch_xy``,
    ``straightness_xy``); axis / plane: where it acts; params: linear
    parameters; scan: name, unit and grid of a nonlinear parameter searched on
    a grid (cyclic period, backlash take-up) or None; compensable: the C
    library can evaluate it as a table term; kind: how it is applied.
    """

    family: str
    key: str
    params: tuple[ParamSpec, ...]
    compensable: bool
    kind: str
    axis: str | None = None
    plane: str | None = None
    term: str | None = None
    scan: str | None = None
    scan_unit: str = ""
    physics: str = ""
    remedy: str = ""

    def apply(self, table: Table, pp: PredParams, theta: np.ndarray,
              scan_value: float | tuple[float, float] | None = None, drift_on_table: bool = False,
              tref_c: float = 20.0) -> tuple[Table, PredParams]:
        """Return copies of (table, pp) with this effect's parameters ``theta`` added.

        ``scan_value``: the nonlinear parameter (cyclic period mm, backlash take-up
        mm, or a backlash's per-direction pair: abbe.diagnose.backlash_pair). ``drift_on_table``: thermal drift driven by temperature goes into the
        table's thermal fields (reference temperature ``tref_c``) instead of the
        prediction parameters. Raises NotRepresentable if the table cannot hold it.
        """
        th = np.asarray(theta, dtype=np.float64).reshape(-1)
        t = copy_table(table)
        p = pp.copy()
        k = self.kind
        j = None if self.axis is None else AXES.index(self.axis)
        if k == "squareness":
            sq = list(t.squareness_urad)
            sq[{"XY": 0, "XZ": 1, "YZ": 2}[self.plane]] += th[0]  # type: ignore[index]
            t.squareness_urad = tuple(float(v) for v in sq)  # type: ignore[assignment]
        elif k == "backlash":
            ax = t.axes[self.axis]  # type: ignore[index]
            ax.backlash_um = float(ax.backlash_um + th[0])
            if scan_value is not None:
                # a per-direction pair: the prediction's, the table keeps their mean
                ax.backlash_takeup_mm = table_takeup_mm(scan_value)
                p.backlash_takeup_pair_mm[j] = scan_value if is_pair(scan_value) else 0.0
            elif ax.backlash_takeup_mm <= 0:
                ax.backlash_takeup_mm = 1.0
        elif k == "scale":
            a = self.axis
            ref = float(t.reference_mm[j])  # type: ignore[index]

            def scale_coef(ax: AxisTable) -> np.ndarray:
                bow = float(th[1]) if th.size > 1 else 0.0
                ensure_trend(ax, 2 if bow else 1)
                ensure_term(ax, OWN_TERM[a])  # type: ignore[index]
                lo, hi = ax.travel_mm
                c = np.zeros(ax.n_basis())
                c[0] = th[0] * 1e-3 * (0.5 * (lo + hi) - ref)
                c[1] = th[0] * 1e-3 * 0.5 * (hi - lo)
                if bow:
                    # bow (1 - u^2) = bow (T0 - (T0 + T2) / 2): sag at mid-travel
                    c[0] += 0.5 * bow
                    c[2] -= 0.5 * bow
                return c
            add_shape(t, a, OWN_TERM[a], scale_coef)  # type: ignore[index]
        elif k == "cyclic":
            a = self.axis
            period = float(scan_value)  # type: ignore[arg-type]

            h2 = th.size > 3 and bool(th[2] or th[3])

            def cyc_coef(ax: AxisTable) -> np.ndarray:
                b = add_block(ax, period, float(ax.travel_mm[0]), 2 if h2 else 1)
                ensure_term(ax, OWN_TERM[a])  # type: ignore[index]
                c = np.zeros(ax.n_basis())
                r = block_row(ax, b)
                c[r], c[r + 1] = th[0], th[1]
                if h2:     # rows sin1, cos1, sin2, cos2 (abbe.model.table.basis_matrix)
                    c[r + 2], c[r + 3] = th[2], th[3]
                return c
            add_shape(t, a, OWN_TERM[a], cyc_coef)  # type: ignore[index]
        elif k == "straightness":
            a, term = self.axis, self.term
            ref = float(t.reference_mm[j])  # type: ignore[index]

            def bow_coef(ax: AxisTable) -> np.ndarray:
                ensure_trend(ax, 2)
                ensure_term(ax, term)  # type: ignore[arg-type]
                lo, hi = ax.travel_mm
                c = np.zeros(ax.n_basis())
                # bow * (1 - u^2) = bow * (T0 - (T0 + T2) / 2)
                c[0] = 0.5 * th[0]
                c[2] = -0.5 * th[0]
                return c
            add_shape(t, a, term, bow_coef)  # type: ignore[arg-type]
        elif k == "reversal":
            n = min(th.size, REVERSAL_MAX_DEGREE)
            p.reversal_cheb_um[j, 1:1 + n] += th[:n]  # type: ignore[index]
            pt = th[REVERSAL_MAX_DEGREE:]
            knots = p.reversal_knots_mm[j]  # type: ignore[index]
            if pt.size and np.any(pt) and knots is not None:
                T = len(knots)
                vals = np.concatenate([pt[:T - 1], [-float(np.sum(pt[:T - 1]))]])
                old = p.reversal_knot_um[j]  # type: ignore[index]
                p.reversal_knot_um[j] = vals if old is None else old + vals  # type: ignore[index]
        elif k == "tool_offset":
            to = np.asarray(t.tool_offset_mm, dtype=np.float64) + th[:3]
            t.tool_offset_mm = tuple(float(v) for v in to)  # type: ignore[assignment]
        elif k == "servo":
            i = SERVO_PLANES.index(self.plane)  # type: ignore[arg-type]
            p.servo_mismatch_ms[i] += th[0]
            if th.size > 1:
                p.servo_gain_ms2[i] += th[1]
        elif k == "thermal":
            if drift_on_table:
                ax = t.axes[self.axis]  # type: ignore[index]
                ax.thermal_offset_um_per_k = float(ax.thermal_offset_um_per_k + th[0])
                ax.thermal_expansion_ppm_per_k = float(ax.thermal_expansion_ppm_per_k + th[1])
                if ax.thermal_tref_c == 0.0:
                    ax.thermal_tref_c = float(tref_c)
            else:
                p.drift_offset[j] += th[0]  # type: ignore[index]
                p.drift_scale_ppm[j] += th[1]  # type: ignore[index]
                if th.size > 2:
                    p.drift_bow_um[j] += th[2]  # type: ignore[index]
                if scan_value is not None:
                    p.drift_tau = float(scan_value)
        else:  # pragma: no cover - catalogue is closed
            raise ValueError(f"unknown effect kind {k!r}")
        return t, p


def _axis_l(a: str) -> str:
    return a.lower()


def catalogue() -> list[EffectSpec]:
    """All candidate effects, in report order."""
    out: list[EffectSpec] = []
    for plane, key in (("XY", "squareness_xy"), ("XZ", "squareness_xz"), ("YZ", "squareness_yz")):
        out.append(EffectSpec(
            family=key, key=key, kind="squareness", plane=plane, compensable=True,
            params=(ParamSpec("S", "urad", 20.0, 1000.0),),
            physics=f"the {plane[1]} axis is not square to {plane[0]} (S_{plane.lower()}, notes.md §1)",
            remedy="table squareness term (SQUARENESS feature)"))
    for a in AXES:
        out.append(EffectSpec(
            family=f"backlash_{_axis_l(a)}", key=f"backlash_{_axis_l(a)}", kind="backlash", axis=a,
            compensable=True, params=(ParamSpec("B", "um", 5.0, 300.0),),
            scan="takeup_mm", scan_unit="mm",
            physics=f"lost motion of the {a} drive: the own positioning term differs by the "
                    "reversal B between + and - approach",
            remedy="table backlash term (BACKLASH feature; direction state from the compensator)"))
    for a in AXES:
        out.append(EffectSpec(
            family=f"reversal_{_axis_l(a)}", key=f"reversal_{_axis_l(a)}", kind="reversal", axis=a,
            compensable=True, scan="degree", scan_unit="",
            params=tuple(ParamSpec(f"r{k}", "um", 3.0, 300.0) for k in range(1, REVERSAL_MAX_DEGREE + 1))
            + tuple(ParamSpec(f"t{k}", "um", 3.0, 300.0, optional=True)
                    for k in range(1, REVERSAL_MAX_TARGETS)),
            physics=f"position-dependent reversal of {a}: the lost motion changes along the travel "
                    "(wear, pitch of the screw, preload), a smooth series over the travel on top "
                    "of the constant backlash",
            remedy="table reversal block (direction-dependent part of the own positioning term, "
                   "Chebyshev over the travel, applied with the backlash direction state)"))
    for a in AXES:
        out.append(EffectSpec(
            family=f"scale_{_axis_l(a)}", key=f"scale_{_axis_l(a)}", kind="scale", axis=a,
            compensable=True, params=(ParamSpec("k", "ppm", 10.0, 1000.0),
                                      ParamSpec("bow", "um", 2.0, 200.0, optional=True)),
            physics=f"linear positioning (scale) error of {a} about the reference point, "
                    "optionally with a bow of the positioning error (a lead error growing "
                    "along the screw: sag at mid-travel relative to the ends)",
            remedy="added to the own positioning term's Chebyshev trend (T0, T1; T2 for the bow)"))
    for a in AXES:
        out.append(EffectSpec(
            family=f"cyclic_{_axis_l(a)}", key=f"cyclic_{_axis_l(a)}", kind="cyclic", axis=a,
            compensable=True, params=(ParamSpec("a_sin", "um", 1.0, 50.0), ParamSpec("a_cos", "um", 1.0, 50.0),
                                      # the second harmonic (period / 2) of a screw's lead error,
                                      # kept when the evidence ratio prefers it (selection.py)
                                      ParamSpec("a2_sin", "um", 0.5, 50.0, optional=True),
                                      ParamSpec("a2_cos", "um", 0.5, 50.0, optional=True)),
            scan="period_mm", scan_unit="mm",
            physics=f"cyclic (screw lead) error of {a}: a sine of the position with an unknown "
                    "period, possibly shorter than the laser target spacing",
            remedy="Fourier block (short-period block 1 if free) on the own positioning term"))
    for a in AXES:
        out.append(EffectSpec(
            family="thermal_drift", key=f"thermal_drift_{_axis_l(a)}", kind="thermal", axis=a,
            compensable=True, scan="tau",
            params=(ParamSpec("offset", "um", 3.0, 500.0), ParamSpec("scale", "ppm", 10.0, 2000.0, optional=True),
                    ParamSpec("bow", "um", 3.0, 500.0, optional=True)),
            physics=f"thermal drift of {a}: own positioning offset, scale and bow along the travel "
                    "(a screw warming where the nut runs most) changing with time (or "
                    "temperature) between and during runs",
            remedy="table thermal terms when a temperature is measured; otherwise warm the "
                   "machine up / log temperature (time drift cannot be compensated by a table)"))
    for plane in ("XY", "YZ", "ZX"):
        out.append(EffectSpec(
            family="servo_mismatch", key=f"servo_mismatch_{plane.lower()}", kind="servo",
            plane=plane, compensable=False,
            params=(ParamSpec("dtau", "ms", 0.5, 30.0),
                    ParamSpec("q", "ms^2", 20.0, 3000.0, optional=True)),
            physics=f"unequal position-loop lag of {plane[1]} and {plane[0]} (tau_{plane[1]} - "
                    f"tau_{plane[0]}): an oval on circles that flips with the direction, and "
                    "q = kappa tau_mean dtau, an oval along the axes growing with the feed "
                    "squared (kappa = 1 pure delays, 1.5 first-order loops)",
            remedy=f"match the position-loop gains (Kv) / feed-forward of {plane[0]} and "
                   f"{plane[1]}; the table cannot compensate a dynamic error"))
    out.append(EffectSpec(
        family="tool_offset", key="tool_offset", kind="tool_offset", compensable=True,
        params=(ParamSpec("t_x", "mm", 50.0, 400.0, optional=True),
                ParamSpec("t_y", "mm", 50.0, 400.0, optional=True),
                ParamSpec("t_z", "mm", 100.0, 600.0)),
        physics="Abbe arm missing from the model: the tool tip is offset from the spindle "
                "reference, angular errors times the offset",
        remedy="table tool offset (TOOL_OFFSET feature)"))
    for a in AXES:
        for term in ("dx", "dy", "dz"):
            if term == OWN_TERM[a]:
                continue
            key = f"straightness_{_axis_l(a)}{term[1]}"
            out.append(EffectSpec(
                family="straightness", key=key, kind="straightness", axis=a, term=term,
                compensable=True, params=(ParamSpec("bow", "um", 2.0, 200.0),),
                physics=f"unmodelled bow of the {a} axis straightness in {term[1].upper()} "
                        f"(d_{term[1]}({_axis_l(a)})): value at mid-travel relative to the ends",
                remedy=f"Chebyshev T0/T2 rows of d_{term[1]} of {a}"))
    return out


def by_key() -> dict[str, EffectSpec]:
    """Catalogue indexed by key."""
    return {e.key: e for e in catalogue()}
#: Nonlinear scan grids.
#: Take-up distances searched (mm): from a sharp step (a play of a few um taken up over
#: its own size) to a soft, preloaded drive; refined continuously after selection.
BACKLASH_TAKEUP_GRID_MM: tuple[float, ...] = (0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 4.0)
