"""Uncertainty of a fitted table (ISO/TR 230-9, GUM): the coefficients' covariance and the
error it predicts at any position, with U (k = 2); the compensated machine's residual.

Given the selected structure (trend degree, harmonics, period: held fixed), every step of
``abbe fit`` from the bidirectional means at the targets to the stored coefficients is
linear: straightness detrending (paper Eq. 1), values relative to the reference point, the
least squares on the term's columns, the exact shift to zero at the reference. Its matrix
G (n_basis x T) is built by running those very steps (:mod:`abbe.analysis.fit.prep`,
:func:`numpy.linalg.lstsq` on the term's columns) on the unit vectors, so the
coefficients' covariance is C = G S G^T with S the covariance of the means:

* per target, independent: u_y^2 = max(u_rep^2, u_fit^2) with u_rep = s / sqrt(2 n) (the
  run-to-run spread s of n bidirectional runs) and u_fit^2 = SSE / (T - p) (the least
  squares' own residual variance, p parameters, the period counted): the larger of the
  two, so a model that leaves a shape unexplained is not credited with the repeatability;
  plus the instrument's linearity (rectangular) and resolution (rectangular) per target;
* the own positioning term only, fully correlated along the line: the instrument's scale
  errors (:func:`abbe.analysis.uncertainty.scale_inputs`: laser accuracy, air sensors,
  material temperature and expansion or the whole temperature effect when not normalised,
  cosine misalignment) as delta x p.

The predicted term at position p is b(p) . c (b the library's basis), so u(p)^2 =
b(p) C b(p)^T; it is 0 at the reference point, where the table is 0 by definition (every
value is relative to it). At a machine point the terms combine by Eq. 3, linear in the term
values: u of dX, dY, dZ from the lever arms and every term's u (the lines are independent
measurements). The selection of the structure itself is not propagated (held fixed): the
Monte Carlo can re-select on each draw to show what that would add.

The independent check (:func:`monte_carlo`, GUM Supplement 1) draws new means (normal
repeatability, rectangular instrument terms, each scale input from its own distribution),
re-runs the pipeline's steps on them (``prep``'s detrending and reference functions, the
selection's :func:`abbe.analysis.fit.select.fit_structure` or, with ``reselect``, the whole
automatic selection), builds the table and evaluates it with the float64 reference
(:mod:`abbe.model.reference`); it shares no formula with G S G^T.

Units: positions mm; linear terms um, angular terms urad; scale ppm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from abbe.analysis.fit.prep import detrend_line, relative_to_reference
from abbe.analysis.fit.select import columns, fit_structure, select_auto
from abbe.analysis.fit.scan import make_design
from abbe.analysis.uncertainty import _delta_density, scale_inputs
from abbe.formats.uncertainty_spec import Budget, default_budget
from abbe.model.reference import combine_eq3, spatial_error
from abbe.model.table import AXES, LINEAR_TERMS, OWN_TERM, AxisTable, Table, basis_matrix

if TYPE_CHECKING:  # pragma: no cover
    from abbe.analysis.fit.results import AxisResult, FitResult

K = 2.0
#: Positions along each axis where the JSON states the predicted term and its U.
GRID_POINTS = 21
METHOD = ("GUM first order: coefficient covariance C = G S G^T (G: the fit's linear map from "
          "the targets' means to the stored coefficients, structure held fixed), "
          "u(p)^2 = b(p) C b(p)^T, U = k u, k = 2")


@dataclass
class TermUncertainty:
    """One fitted term's coefficient covariance and the inputs it comes from.

    ``cov``: (n_basis, n_basis) of the stored coefficients, table row order, unit^2.
    ``parts``: the same split by input (name -> covariance). ``inputs``: the per-target
    figures (unit) and the scale's standard uncertainty (ppm)."""

    axis: str
    term: str
    unit: str
    cov: np.ndarray
    parts: dict[str, np.ndarray]
    inputs: dict[str, float]

    def u_at(self, table: AxisTable, pos_mm: np.ndarray) -> np.ndarray:
        """Standard uncertainty of the predicted term at axis positions (mm)."""
        B = basis_matrix(table, np.asarray(pos_mm, dtype=float).reshape(-1))
        return np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", B, self.cov, B), 0.0))


def fit_operator(pos_mm: np.ndarray, ref_mm: float, table: AxisTable, order: tuple[int, int],
                 detrend: bool) -> np.ndarray:
    """G (n_basis, T): the stored coefficients of a term as a linear map of its
    bidirectional means at the targets, for the fixed structure of ``table`` and the
    term's (degree, harmonics). Built by running the fit's own steps on unit vectors."""
    p = np.asarray(pos_mm, dtype=float)
    T = p.size
    B = basis_matrix(table, p)
    d, h = order
    cols = columns(table, d, h if table.blocks[0] is not None else 0)
    bref = basis_matrix(table, np.array([ref_mm]))[0]
    Y = np.eye(T)
    if detrend:
        Y = np.column_stack([detrend_line(p, Y[:, i])[0] for i in range(T)])
    Y = np.column_stack([relative_to_reference(p, Y[:, i], ref_mm)[0] for i in range(T)])
    G = np.zeros((table.n_basis(), T))
    G[cols], *_ = np.linalg.lstsq(B[:, cols], Y, rcond=None)
    G[0] -= bref @ G  # the exact shift to zero at the reference (row T_0 == 1)
    return G


def _n_params(order: tuple[int, int]) -> int:
    d, h = order
    return d + 1 + 2 * h + (1 if h else 0)


def laser_budget(machine: Any) -> Budget:
    """The machine file's ``[uncertainty.laser]`` budget, else the laser interferometer
    class defaults (a 6D laser line)."""
    spec = machine.extra.get("uncertainty")
    if spec is not None and spec.laser is not None:
        return spec.laser
    return default_budget("laser_interferometer")


def scale_u_ppm(budget: Budget, norm: Any) -> float:
    """Combined standard uncertainty of the scale inputs, ppm."""
    return math.sqrt(sum(s.u_ppm ** 2 for s in scale_inputs(budget, norm)))


def term_uncertainty(ar: "AxisResult", term: str, budget: Budget) -> TermUncertainty:
    """Covariance of one fitted term of axis result ``ar`` (module docstring)."""
    tr = ar.terms[term]
    p = ar.targets_mm
    T = p.size
    ref = float(ar.ref_mm)
    tab = ar.table
    G = fit_operator(p, ref, tab, tr.order, detrend=term in LINEAR_TERMS and term != OWN_TERM[ar.axis])
    n = tr.stats.n_runs
    u_rep = float(tr.stats.noise) / math.sqrt(2.0 * n) if n > 1 and np.isfinite(tr.stats.noise) \
        else float("nan")
    resid = tr.stats.mean - basis_matrix(tab, p) @ tr.coef
    dof = T - _n_params(tr.order)
    u_fit = float(math.sqrt(float(resid @ resid) / dof)) if dof > 0 else float("nan")
    cands = [v for v in (u_rep, u_fit) if np.isfinite(v)]
    u_y = max(cands) if cands else 0.0
    f = budget.figures
    linear_channel = tr.unit == "um"
    u_inst = math.sqrt(f["linearity_um"] ** 2 / 3.0 + f["resolution_um"] ** 2 / 12.0) \
        if linear_channel else 0.0
    parts = {"repeatability / lack of fit": u_y ** 2 * (G @ G.T)}
    if u_inst > 0:
        parts["instrument linearity and resolution"] = u_inst ** 2 * (G @ G.T)
    u_ppm = 0.0
    if term == OWN_TERM[ar.axis]:
        u_ppm = scale_u_ppm(budget, ar.data.normalisation)
        g = G @ (p * 1e-3)  # ppm x mm = 1e-3 um
        parts["instrument scale"] = u_ppm ** 2 * np.outer(g, g)
    cov = sum(parts.values())
    return TermUncertainty(ar.axis, term, tr.unit, cov, parts,
                           {"u_repeatability": u_rep, "u_lack_of_fit": u_fit, "u_per_target": u_y,
                            "u_instrument": u_inst, "scale_u_ppm": u_ppm, "dof": float(dof),
                            "linearity_half_width": f["linearity_um"] if linear_channel else 0.0,
                            "u_resolution": f["resolution_um"] / math.sqrt(12.0)
                            if linear_channel else 0.0,
                            "n_runs": float(n)})


@dataclass
class FitUncertainty:
    """Every fitted term's covariance, per axis; the budget; the Monte Carlo (if run)."""

    terms: dict[str, dict[str, TermUncertainty]]
    budget: Budget
    table: Table
    monte_carlo: dict[str, Any] | None = None
    compensated: dict[str, Any] = field(default_factory=dict)

    def point_u(self, pos_mm: np.ndarray) -> np.ndarray:
        """(N, 3) standard uncertainty of dX, dY, dZ at machine points (N, 3), um."""
        return point_u(self.table, self.terms, pos_mm)


def point_u(table: Table, terms: dict[str, dict[str, TermUncertainty]],
            pos_mm: np.ndarray) -> np.ndarray:
    """(N, 3) standard uncertainty of the spatial error dX, dY, dZ (um) at machine points
    ``pos_mm`` (N, 3): Eq. 3 is linear in the term values, so each term's u is carried by
    its lever arm (Eq. 3 evaluated with that term at 1); terms are independent."""
    pos = np.asarray(pos_mm, dtype=float).reshape(-1, 3)
    var = np.zeros((pos.shape[0], 3))
    for j, a in enumerate(AXES):
        ax = table.axes[a]
        pa = np.clip(pos[:, j], *ax.travel_mm)  # the table holds its end values outside
        for t, tu in terms.get(a, {}).items():
            u = tu.u_at(ax, pa)
            lever = combine_eq3({(a, t): np.ones(pos.shape[0])}, pos, table.reference_mm,
                                table.tool_offset_mm, (0.0, 0.0, 0.0))
            var += (lever * u[:, None]) ** 2
    return np.sqrt(var)


def fit_uncertainty(res: "FitResult", budget: Budget | None = None) -> FitUncertainty:
    """The covariance of every fitted term of ``res``; the compensated residual."""
    budget = budget or laser_budget(res.machine)
    terms = {a: {t: term_uncertainty(ar, t, budget) for t in ar.terms}
             for a, ar in res.axes.items()}
    fu = FitUncertainty(terms=terms, budget=budget, table=res.table)
    fu.compensated = compensated_residual(res, fu)
    return fu


def compensated_residual(res: "FitResult", fu: FitUncertainty) -> dict[str, Any]:
    """The compensated machine at the targets, per axis and term: residual r_i = measured
    mean - the stored table, the machine's error after the table is applied. The table is
    known exactly once written, so r is uncertain by the measurement of the means only:
    independent per target (normal repeatability and resolution, the instrument's
    rectangular linearity) plus, for the own positioning term, the scale error delta x p_i
    shared by every target. Per target u(r_i); max |r| from its exact distribution given
    delta (the product of the targets' CDFs: they compete for the max), RMS from the first
    four moments of the sum of squares given delta; then over delta's distribution (law of
    total variance)."""
    out: dict[str, Any] = {}
    for a, ar in res.axes.items():
        p = ar.targets_mm
        out[a] = {}
        for t, tr in ar.terms.items():
            tu = fu.terms[a][t]
            r = tr.stats.mean - basis_matrix(ar.table, p) @ tr.coef
            scales = scale_inputs(fu.budget, ar.data.normalisation) if t == OWN_TERM[a] else []
            rep = tu.inputs["u_repeatability"]
            rep = rep if np.isfinite(rep) else tu.inputs["u_per_target"]
            s = math.sqrt(rep ** 2 + tu.inputs["u_resolution"] ** 2)
            out[a][t] = residual_summary(r, s, tu.inputs["linearity_half_width"], scales,
                                         p * 1e-3)
    return out


def _cdf_normal_plus_rect(x: np.ndarray, s: float, L: float) -> np.ndarray:
    """CDF of N(0, s^2) + U(-L, L) at x."""
    from scipy.special import ndtr
    if L <= 0:
        return ndtr(x / s)
    if s <= 0:
        return np.clip((x + L) / (2 * L), 0.0, 1.0)

    def G(z: np.ndarray) -> np.ndarray:  # the integral of Phi(z / s) dz
        return z * ndtr(z / s) + s * np.exp(-0.5 * (z / s) ** 2) / math.sqrt(2 * math.pi)
    return (G(x + L) - G(x - L)) / (2 * L)


def _max_abs_moments(m: np.ndarray, s: float, L: float) -> tuple[float, float]:
    """Mean and variance of max_i |m_i + e_i|, e_i independent N(0, s^2) + U(-L, L):
    P(max <= y) = prod_i P(|m_i + e_i| <= y), integrated on a grid."""
    s = max(s, 1e-9)
    hi = float(np.max(np.abs(m))) + L + 9 * s
    y = np.linspace(0.0, hi, 801)
    H = np.ones_like(y)
    for mi in m:
        H *= np.clip(_cdf_normal_plus_rect(y - mi, s, L) - _cdf_normal_plus_rect(-y - mi, s, L),
                     0.0, 1.0)
    mean = float(np.trapezoid(1.0 - H, y))
    second = float(np.trapezoid(2.0 * y * (1.0 - H), y))
    return mean, max(second - mean * mean, 0.0)


def residual_summary(r: np.ndarray, s: float, L: float = 0.0, scales: list[Any] | None = None,
                     v: np.ndarray | None = None) -> dict[str, float]:
    """max |r| and RMS of residuals r (T,): independent per target N(0, s^2) + U(-L, L),
    and a shared scale error delta (ppm, from ``scales``) acting as delta x v (um)."""
    r = np.asarray(r, dtype=float)
    if scales:
        d, w = _delta_density(scales, points=21)
        d = d - float(np.sum(w * d))  # centred: u(delta) as in the covariance
    else:
        d, w = np.zeros(1), np.ones(1)
    vv = np.zeros_like(r) if v is None else np.asarray(v, dtype=float)
    var_e = s * s + L * L / 3.0
    mu4 = 3 * s ** 4 + 2 * s * s * L * L + L ** 4 / 5.0  # E e^4 of N + U
    T = r.size
    mx_m, mx_v, rm_m, rm_v = [], [], [], []
    for dk in d:
        m = r + dk * vv
        mm, mv = _max_abs_moments(m, s, L)
        mx_m.append(mm)
        mx_v.append(mv)
        q_mean = float(m @ m) / T + var_e
        q_var = (4.0 * var_e * float(m @ m) + T * (mu4 - var_e ** 2)) / T ** 2
        rm_m.append(math.sqrt(q_mean))
        # no noise and no residual: the RMS is exactly 0 (no spread to divide by)
        rm_v.append(q_var / (4.0 * q_mean) if q_mean > 0 else 0.0)

    def total(means: list[float], variances: list[float]) -> float:
        mu, va = np.asarray(means), np.asarray(variances)
        mean = float(np.sum(w * mu))
        return math.sqrt(float(np.sum(w * (va + (mu - mean) ** 2))))

    u_max, u_rms = total(mx_m, mx_v), total(rm_m, rm_v)
    u_t = math.sqrt(var_e)
    return {"max_abs": float(np.max(np.abs(r))), "max_abs_u": u_max, "max_abs_U": K * u_max,
            "rms": float(np.sqrt(np.mean(r ** 2))), "rms_u": u_rms, "rms_U": K * u_rms,
            "u_per_target": u_t, "U_per_target": K * u_t}


# --------------------------------------------------------------------------- Monte Carlo

def _draw_scale(budget: Budget, norm: Any, rng: np.random.Generator, n: int) -> np.ndarray:
    d = np.zeros(n)
    for s in scale_inputs(budget, norm):
        d += rng.uniform(s.low_ppm, s.high_ppm, n) - 0.5 * (s.low_ppm + s.high_ppm)  # centred
    return d


def _refit_axis(ar: "AxisResult", Ystar: dict[str, np.ndarray], reselect: bool, opts: Any
                ) -> AxisTable:
    """The pipeline's steps 4-6 on new means (the structure kept unless ``reselect``)."""
    p = ar.targets_mm
    ref = float(ar.ref_mm)
    present = list(ar.terms)
    cols = []
    for t in present:
        y = Ystar[t]
        if t in LINEAR_TERMS and t != OWN_TERM[ar.axis]:
            y = detrend_line(p, y)[0]
        cols.append(relative_to_reference(p, y, ref)[0])
    Y = np.column_stack(cols)
    if reselect:
        m = select_auto(make_design(p, opts), p, Y, opts.one_se)
    else:
        m = ar.fit.model
        m = fit_structure(make_design(p, opts), p, Y, m.orders, m.period_mm)
    bref = basis_matrix(m.table, np.array([ref]))[0]
    coef = {}
    for i, t in enumerate(present):
        c = m.coef[i].copy()
        c[0] -= float(bref @ c)
        coef[t] = c
    return AxisTable(travel_mm=m.table.travel_mm, trend_degree=m.table.trend_degree,
                     blocks=m.table.blocks, coef=coef)


def monte_carlo(res: "FitResult", fu: FitUncertainty, draws: int = 1000, seed: int = 1,
                points_mm: np.ndarray | None = None, reselect: bool = False,
                grid: int = GRID_POINTS) -> dict[str, Any]:
    """GUM S1 check: U (k = 2, 2 x the standard deviation over draws) of every term on the
    grid of each axis, of dX, dY, dZ at ``points_mm`` (N, 3), and of the compensated
    residual's max |r| and RMS, from redrawn means through the pipeline's own steps and the
    reference evaluation. Returns per axis/term the grid, the MC U and the analytic U."""
    rng = np.random.default_rng(seed)
    budget = fu.budget
    grids = {a: np.linspace(*ar.table.travel_mm, grid) for a, ar in res.axes.items()}
    vals = {a: {t: np.zeros((draws, grid)) for t in ar.terms} for a, ar in res.axes.items()}
    comp = {a: {t: np.zeros((draws, 2)) for t in ar.terms} for a, ar in res.axes.items()}
    pts = None if points_mm is None else np.asarray(points_mm, dtype=float).reshape(-1, 3)
    pvals = None if pts is None else np.zeros((draws, pts.shape[0], 3))
    scale = {a: _draw_scale(budget, ar.data.normalisation, rng, draws) for a, ar in res.axes.items()}
    for k in range(draws):
        axes = dict(res.table.axes)
        for a, ar in res.axes.items():
            p = ar.targets_mm
            Ystar: dict[str, np.ndarray] = {}
            meas_err: dict[str, np.ndarray] = {}
            for t, tr in ar.terms.items():
                inp = fu.terms[a][t].inputs
                rep = inp["u_repeatability"] if np.isfinite(inp["u_repeatability"]) \
                    else inp["u_per_target"]
                # the measurement's own error of the means (what the compensated residual
                # is uncertain by) and the extra lack of fit the model leaves
                e_meas = rng.normal(0.0, rep, p.size)
                lin = budget.figures["linearity_um"] if tr.unit == "um" else 0.0
                res_um = budget.figures["resolution_um"] if tr.unit == "um" else 0.0
                if lin > 0:
                    e_meas += rng.uniform(-lin, lin, p.size)
                if res_um > 0:
                    e_meas += rng.uniform(-res_um / 2, res_um / 2, p.size)
                if t == OWN_TERM[a]:
                    e_meas += scale[a][k] * p * 1e-3
                lof2 = max(inp["u_per_target"] ** 2 - rep ** 2, 0.0)
                e_fit = rng.normal(0.0, math.sqrt(lof2), p.size) if lof2 > 0 else 0.0
                Ystar[t] = tr.stats.mean + e_meas + e_fit
                meas_err[t] = e_meas
            at = _refit_axis(ar, Ystar, reselect, res.options)
            axes[a] = at
            for t, tr in ar.terms.items():
                vals[a][t][k] = basis_matrix(at, grids[a]) @ at.coef[t]
                r = tr.stats.mean + meas_err[t] - basis_matrix(ar.table, p) @ tr.coef
                comp[a][t][k] = (np.max(np.abs(r)), np.sqrt(np.mean(r ** 2)))
        if pts is not None:
            tk = Table(axes=axes, reference_mm=res.table.reference_mm,
                       tool_offset_mm=res.table.tool_offset_mm,
                       squareness_urad=res.table.squareness_urad)
            pvals[k] = spatial_error(tk, pts)
    out: dict[str, Any] = {"draws": draws, "seed": seed, "reselect": reselect, "axes": {}}
    for a, ar in res.axes.items():
        out["axes"][a] = {}
        for t in ar.terms:
            U_mc = K * vals[a][t].std(axis=0, ddof=1)
            U_an = K * fu.terms[a][t].u_at(ar.table, grids[a])
            c = fu.compensated[a][t]
            cs = comp[a][t].std(axis=0, ddof=1)
            out["axes"][a][t] = {"grid_mm": grids[a], "U_mc": U_mc, "U": U_an,
                                 "compensated_max_abs_U_mc": K * float(cs[0]),
                                 "compensated_max_abs_U": c["max_abs_U"],
                                 "compensated_rms_U_mc": K * float(cs[1]),
                                 "compensated_rms_U": c["rms_U"]}
    if pts is not None:
        out["points_mm"] = pts
        out["points_U_mc"] = K * pvals.std(axis=0, ddof=1)
        out["points_U"] = K * fu.point_u(pts)
    return out


def worst_ratio(U_mc: np.ndarray, U: np.ndarray, floor: float = 0.1) -> float:
    """The largest |U_mc / U - 1| where U is at least ``floor`` of its largest value (the
    U of a term vanishes at the reference point, where a ratio says nothing)."""
    U_mc = np.asarray(U_mc, dtype=float).reshape(-1)
    U = np.asarray(U, dtype=float).reshape(-1)
    keep = U >= floor * float(np.max(U)) if np.max(U) > 0 else np.zeros(U.shape, bool)
    if not np.any(keep):
        return 0.0
    return float(np.max(np.abs(U_mc[keep] / U[keep] - 1.0)))


# --------------------------------------------------------------------------- JSON

def _r(x: float, nd: int = 6) -> float | None:
    x = float(x)
    return float(f"{x:.{nd}g}") if math.isfinite(x) else None


def to_json(res: "FitResult", fu: FitUncertainty, grid: int = GRID_POINTS) -> dict[str, Any]:
    """The ``uncertainty`` block of model.json (docs/uncertainty.md, "Fitted table")."""
    axes: dict[str, Any] = {}
    for a, ar in res.axes.items():
        g = np.linspace(*ar.table.travel_mm, grid)
        terms: dict[str, Any] = {}
        for t, tu in fu.terms[a].items():
            u = tu.unit
            tr = ar.terms[t]
            Ug = K * tu.u_at(ar.table, g)
            terms[t] = {
                "unit": u,
                f"u_repeatability_{u}": _r(tu.inputs["u_repeatability"]),
                f"u_lack_of_fit_{u}": _r(tu.inputs["u_lack_of_fit"]),
                f"u_per_target_{u}": _r(tu.inputs["u_per_target"]),
                f"u_instrument_{u}": _r(tu.inputs["u_instrument"]),
                "scale_u_ppm": _r(tu.inputs["scale_u_ppm"]),
                "grid_mm": [_r(v) for v in g],
                f"value_{u}": [_r(v) for v in basis_matrix(ar.table, g) @ tr.coef],
                f"U_{u}": [_r(v) for v in Ug],
                f"U_max_{u}": _r(float(np.max(Ug))),
                f"U_max_by_input_{u}": {k: _r(K * float(np.max(np.sqrt(np.maximum(
                    np.einsum("ij,jk,ik->i", basis_matrix(ar.table, g), c,
                              basis_matrix(ar.table, g)), 0.0)))))
                    for k, c in tu.parts.items()},
                f"covariance_{u}2": [[float(f"{v:.9g}") for v in row] for row in tu.cov],
                f"compensated_residual_{u}": {k: _r(v) for k, v in fu.compensated[a][t].items()},
            }
        axes[a] = {"terms": terms}
    return {"method": METHOD, "k": K, "budget_inputs": fu.budget.to_json(),
            "assumptions": ("per-target errors independent (run-to-run drift correlated along "
                            "the line is not modelled); the laser lines independent of one "
                            "another; the structure (degree, harmonics, period) held fixed; "
                            "angular and straightness channels carry repeatability and lack of "
                            "fit only (no instrument figure for them in the budget); U = 0 at "
                            "the reference point, where every term is 0 by definition"),
            "compensated_note": ("compensated_residual: the measured mean minus the stored table "
                                 "at the targets (the machine's error after compensation), max "
                                 "|r| and RMS with u and U (k = 2); uncertain by the measurement "
                                 "of the means only, the table being known once written"),
            "axes": axes}



#: The largest scale uncertainty model.json may state (ppm, standard): 1 % of the length,
#: far above any laser's (its squares stay finite in every covariance they enter).
SCALE_U_PPM_MAX = 1e4


def terms_from_json(d: Any, table: Table, source: str) -> dict[str, dict[str, TermUncertainty]]:
    """The covariances of model.json's ``uncertainty`` block, checked against ``table``
    (one n_basis x n_basis matrix of finite numbers per fitted term, symmetric)."""
    from abbe.errors import AbbeInputError

    def err(msg: str, fld: str) -> AbbeInputError:
        return AbbeInputError(msg, file=source, field=fld)

    if not isinstance(d, dict) or not isinstance(d.get("axes"), dict):
        raise err("no uncertainty block with axes: a model.json written by this abbe's "
                  "`abbe fit` carries one", "uncertainty.axes")
    out: dict[str, dict[str, TermUncertainty]] = {}
    for a, ad in d["axes"].items():
        if a not in AXES or not isinstance(ad, dict) or not isinstance(ad.get("terms"), dict):
            raise err(f"expected an axis X, Y or Z with its terms, got {a!r}", f"uncertainty.axes.{a}")
        nb = table.axes[a].n_basis()
        out[a] = {}
        for t, td in ad["terms"].items():
            fld = f"uncertainty.axes.{a}.terms.{t}"
            if t not in table.axes[a].coef or not isinstance(td, dict):
                raise err(f"term {t!r} is not a fitted term of axis {a} in the table", fld)
            unit = "um" if t in LINEAR_TERMS else "urad"
            key = f"covariance_{unit}2"
            m = td.get(key)
            ok = isinstance(m, list) and len(m) == nb and all(
                isinstance(row, list) and len(row) == nb and all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                    for v in row) for row in m)
            if not ok:
                raise err(f"expected a {nb} x {nb} matrix of finite numbers ({unit}^2: the "
                          "table's rows of this axis)", f"{fld}.{key}")
            cov = np.array(m, dtype=float)
            scale = max(float(np.max(np.abs(cov))), 1e-300)
            if float(np.max(np.abs(cov - cov.T))) > 1e-6 * scale or np.any(np.diag(cov) < 0):
                raise err("not a covariance matrix (asymmetric or a negative variance)",
                          f"{fld}.{key}")
            su = td.get("scale_u_ppm")
            if su is not None and not (isinstance(su, (int, float)) and not isinstance(su, bool)
                                       and math.isfinite(su) and 0.0 <= su <= SCALE_U_PPM_MAX):
                raise err(f"expected the scale's standard uncertainty in ppm, a finite number "
                          f"from 0 to {SCALE_U_PPM_MAX:g} (or none)", f"{fld}.scale_u_ppm")
            out[a][t] = TermUncertainty(a, t, unit, cov, {},
                                        {} if su is None else {"scale_u_ppm": float(su)})
    return out
