"""Model selection and fitting of one axis' error terms in the library's basis (step 6).

Every model here is a column subset of the exact design matrix of the library,
:func:`abbe.model.table.basis_matrix`: a Chebyshev trend T_0..T_d on the normalised
travel plus ``h`` sin/cos harmonics of Fourier block 0 (period P, phase origin at
the start of the travel). Within an axis all six terms share the trend degree and
the block (period, origin, harmonics count) in the table; a term that uses fewer
rows is stored with zero coefficients there, so the model a term is selected
with is exactly the model that is stored.

Selection (``model="auto"``), per axis:

1. *Period search* (:func:`search_period`): candidate frequencies from the joint
   least-squares periodogram of the terms (after a cubic trend; its highest peaks
   and their 1/2 and 1/3), on a grid of step 1/(8 span) from 1/(1.5 span) up to
   the shortest wavelength the targets resolve (``samples_per_wavelength`` x
   median spacing). Each candidate is refined locally (lowest joint score on a
   small grid, then a least-squares fit of the frequency for the orders found
   there). The joint score is J(P) = sum over terms of CV_t(P) / CV_t,best,
   CV_t(P) being the leave-one-target-out mean squared prediction error (exact,
   from the hat matrix) of the term's one-SE choice at P. Among the refined
   candidates: the fewest total parameters within one SE of the lowest J.
2. *Orders*: at the chosen period, per term, the one-standard-error rule over
   all admissible (d, h) including pure polynomials (h = 0): the fewest
   parameters whose CV is within one SE of the best CV. The frequency is then
   refined once more by least squares for these orders.

Admissible: d + 1 + 2h <= T - 2 parameters, d <= 7 for polynomials and
d <= ``max_wave_degree`` (3) with harmonics, every harmonic resolvable
(P / h >= samples_per_wavelength x spacing), every column at least ``col_tol``
independent of the columns before it (QR diagonal / column norm), no target
with leverage ~1. Block 1 (short period) is never used: periods shorter than
~2.5 target spacings are not resolved by the data.

Comparison models (the paper, §3): ``paper_fourier3`` = a_0 + 3 harmonics with
a per-term period fitted by least squares (MATLAB ``fourier3``-like; the paper's
sin(n y) in raw mm has no usable period) and ``paper_poly7`` = 7th-degree
polynomial (Chebyshev basis: the same function space as a power basis).

Held-out metrics come from an outer K-fold over targets (interleaved: target i
in fold i mod K) that repeats the whole procedure -- period search, order
selection, coefficients -- on the training targets of each fold, so they measure
what the procedure does on targets it has not seen.

Units: positions and periods mm; values um (linear terms) or urad (angular).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from abbe.analysis.fit.options import COMPARED, MODELS, FitOptions
from abbe.analysis.fit.scan import (
    AxisDesign,
    Scan,
    make_design,
    one_se_choice,
    refine_period,
    scan,
    search_period,
    search_period_each,
    search_period_ls,
)
from abbe.model.table import AxisTable, basis_matrix


@dataclass
class AxisModel:
    """A selected axis structure: per term (degree, harmonics), one shared period.

    orders[j] for column j of Y; period_mm None if no term uses harmonics.
    table: AxisTable with the packed structure (trend degree = max, harmonics =
    max) and coefficients coef[j] in its row order (zeros where unused).
    """

    orders: list[tuple[int, int]]
    period_mm: float | None
    table: AxisTable
    coef: list[np.ndarray]
    score: float = float("nan")

    def predict(self, pos: np.ndarray) -> np.ndarray:
        """(N, m) values at positions (mm), through the library basis."""
        B = basis_matrix(self.table, pos)
        return B @ np.column_stack(self.coef) if self.coef else np.zeros((np.size(pos), 0))
def columns(tab: AxisTable, d: int, h: int) -> list[int]:
    """Row indices of T_0..T_d and block-0 harmonics 1..h in ``tab``'s row order."""
    nt = tab.n_trend()
    return list(range(d + 1)) + list(range(nt, nt + 2 * h))
def fit_structure(design: AxisDesign, pos: np.ndarray, Y: np.ndarray,
                  orders: list[tuple[int, int]], period_mm: float | None) -> AxisModel:
    """Least-squares coefficients of each term with its (d, h), packed into the
    shared structure (zeros in the unused rows)."""
    Y = np.asarray(Y, dtype=float).reshape(np.size(pos), -1)
    D = max(d for d, _ in orders)
    H = max(h for _, h in orders) if period_mm is not None else 0
    tab = design.axis_table(D, period_mm if H > 0 else None, H)
    B = basis_matrix(tab, pos)
    coef = []
    for j, (d, h) in enumerate(orders):
        cols = columns(tab, d, h if H > 0 else 0)
        c = np.zeros(tab.n_basis())
        c[cols], *_ = np.linalg.lstsq(B[:, cols], Y[:, j], rcond=None)
        coef.append(c)
    return AxisModel(orders=list(orders), period_mm=period_mm if H > 0 else None, table=tab,
                     coef=coef)
#: Conditioning guard: a term's selected coefficients may sum (in absolute value) to at
#: most this many times the largest |value| it fits. A sum far above the values means
#: columns that cancel (harmonics of a period near the span beside a cubic trend):
#: the same curve with huge opposite coefficients, fragile and soon over the table's cap.
CONDITION_GAIN = 10.0
#: ... and to at most this fraction of the table's cap (the reference shift adds at
#: most the same again; the rest is margin): sum |c| <= 0.5 cap.
CAP_FRACTION = 0.5


def well_conditioned(coef: np.ndarray, y: np.ndarray, cap: float | None) -> bool:
    """True if ``coef`` (one term, the table's basis) passes the conditioning guard for
    values ``y`` (um or urad) and the table's cap on sum |coefficients| (same unit)."""
    total = float(np.abs(coef).sum())
    scale = float(np.max(np.abs(y))) if np.size(y) else 0.0
    if total > CONDITION_GAIN * scale + 1e-9:
        return False
    return cap is None or total <= CAP_FRACTION * cap


def select_auto(design: AxisDesign, pos: np.ndarray, Y: np.ndarray,
                one_se: bool = True, caps: list[float] | None = None) -> AxisModel:
    """The automatic selection (module docstring) on targets pos (T,), values Y (T, m).

    Only models the table can hold are considered: a term whose choice fails the
    conditioning guard (:func:`well_conditioned`; ``caps[j]`` the table's cap on
    sum |c| of column j, um or urad) has that (degree, harmonics) struck out and
    takes its next one-SE choice. The constant (0, 0) is never struck out, and a term
    whose values themselves exceed half the cap is not held to it: the measured error
    is larger than the table holds, and the table writer says so (never a constant in
    place of an error too large to store)."""
    Y = np.asarray(Y, dtype=float).reshape(np.size(pos), -1)
    m_cols = Y.shape[1]
    f0, J = search_period(design, pos, Y, one_se)
    if f0 is None:
        s = scan(design, pos, Y, np.array([design.freqs[0] if design.freqs.size else 1.0]), hg=0)
    else:
        s = scan(design, pos, Y, np.array([f0]))
    cv = np.array(s.cv[0], dtype=float)  # (D+1, H+1, m): struck-out models become inf
    se = s.se[0]
    cap = list(caps) if caps is not None else [None] * m_cols
    for j in range(m_cols):
        # values themselves beyond what the table holds: no model within the cap fits
        # them, so none is forced on the term; the table writer reports it (term, amount)
        if cap[j] is not None and float(np.max(np.abs(Y[:, j]))) > CAP_FRACTION * cap[j]:
            cap[j] = None
    while True:
        orders = [one_se_choice(cv[:, :, j], se[:, :, j], one_se) for j in range(m_cols)]
        f = f0
        if f is not None and any(h for _, h in orders):
            f = refine_period(design, pos, Y, f, orders)
        m = fit_structure(design, pos, Y, orders, None if f is None else 1.0 / f)
        bad = [j for j in range(m_cols) if orders[j] != (0, 0)
               and not well_conditioned(m.coef[j], Y[:, j], cap[j])]
        if not bad:
            break
        for j in bad:
            cv[orders[j][0], orders[j][1], j] = np.inf
    m.score = J
    return m
def select_paper_fourier3_axis(design: AxisDesign, pos: np.ndarray, Y: np.ndarray) -> AxisModel:
    """Paper Fourier (a_0 + 3 harmonics) for every term, one shared period per axis
    (the storable variant): period minimising sum_t SSE_t / SST_t."""
    Y = np.asarray(Y, dtype=float).reshape(np.size(pos), -1)
    sst = np.maximum(((Y - Y.mean(axis=0)) ** 2).sum(axis=0), 1e-300)

    def score(s: Scan) -> np.ndarray:
        return (s.sse[:, 0, 3, :] / sst).sum(axis=1)

    f, J = search_period_ls(design, pos, Y, 0, 3, score)
    if f is None or not np.isfinite(J):
        raise ValueError("no period with 3 resolvable harmonics for these targets")
    return fit_structure(design, pos, Y, [(0, 3)] * Y.shape[1], 1.0 / f)
def paper_fourier3(design: AxisDesign, pos: np.ndarray, Y: np.ndarray) -> list[AxisModel | None]:
    """The paper's 3rd-order Fourier per term (column of Y):
    a_0 + sum_{n<=3} (a_n sin n w p + b_n cos n w p) with w fitted by least squares
    (grid + zoom), like MATLAB ``fourier3``. None where 3 harmonics are never
    resolvable."""
    Y = np.asarray(Y, dtype=float).reshape(np.size(pos), -1)
    fs = search_period_each(design, pos, Y, 0, 3)
    return [None if f is None else fit_structure(design, pos, Y[:, [j]], [(0, 3)], 1.0 / f)
            for j, f in enumerate(fs)]
def paper_poly7(design: AxisDesign, pos: np.ndarray, Y: np.ndarray) -> list[AxisModel]:
    """The paper's 7th-order polynomial per term (degree capped at T - 3 for few targets)."""
    Y = np.asarray(Y, dtype=float).reshape(np.size(pos), -1)
    d = min(7, design.max_degree)
    return [fit_structure(design, pos, Y[:, [j]], [(d, 0)], None) for j in range(Y.shape[1])]
def select(design: AxisDesign, pos: np.ndarray, Y: np.ndarray, opts: FitOptions,
           caps: list[float] | None = None) -> AxisModel:
    """The stored model by ``opts.model``: auto, paper-fourier3 (shared period), paper-poly7.
    ``caps``: per column, the table's cap on sum |coefficients| (um or urad)."""
    if opts.model == "auto":
        return select_auto(design, pos, Y, opts.one_se, caps)
    if opts.model == "paper-fourier3":
        return select_paper_fourier3_axis(design, pos, Y)
    if opts.model == "paper-poly7":
        Y = np.asarray(Y, dtype=float).reshape(np.size(pos), -1)
        return fit_structure(design, pos, Y, [(min(7, design.max_degree), 0)] * Y.shape[1], None)
    raise ValueError(f"unknown model {opts.model!r}; expected one of {', '.join(MODELS)}")
def metrics(y: np.ndarray, yhat: np.ndarray) -> dict[str, float]:
    """Paper Eqs. 6-8 plus emax: emax = max |y - yhat|, R^2 = 1 - SSE/SST,
    SSE = sum (y - yhat)^2, RMSE = sqrt(SSE / n). Units of y (SSE squared)."""
    y = np.asarray(y, dtype=float)
    e = y - np.asarray(yhat, dtype=float)
    sse = float(np.sum(e ** 2))
    sst = float(np.sum((y - y.mean()) ** 2))
    return {"emax": float(np.max(np.abs(e))), "r2": 1.0 - sse / sst if sst > 0 else float("nan"),
            "sse": sse, "rmse": float(np.sqrt(sse / y.size))}
@dataclass
class AxisFit:
    """Fit of one axis: the stored model, the paper comparison models, predictions.

    in_sample[name][:, j] and held_out[name][:, j]: predictions at the targets
    (held-out: each target predicted by the fold that left it out). Names:
    COMPARED. paper_f3_period_mm[j]: the per-term period of the paper Fourier.
    """

    model: AxisModel
    paper_f3: list[AxisModel | None]
    paper_p7: list[AxisModel]
    in_sample: dict[str, np.ndarray]
    held_out: dict[str, np.ndarray]
    folds: int
    metrics: list[dict[str, dict[str, dict[str, float]]]] = field(default_factory=list)
def _predict_or_nan(m: AxisModel | None, pos: np.ndarray) -> np.ndarray:
    if m is None:
        return np.full(np.size(pos), np.nan)
    return m.predict(pos)[:, 0]
def fit_axis(pos: np.ndarray, Y: np.ndarray, opts: FitOptions,
             caps: list[float] | None = None) -> AxisFit:
    """Select and fit the stored model of one axis (values Y (T, m) at targets pos),
    fit the paper models per term, and run the outer K-fold for held-out metrics.
    ``caps``: per column, the table's cap on sum |coefficients| (um or urad)."""
    pos = np.asarray(pos, dtype=float)
    Y = np.asarray(Y, dtype=float).reshape(pos.size, -1)
    T, m = Y.shape
    design = make_design(pos, opts)
    model = select(design, pos, Y, opts, caps)
    f3 = paper_fourier3(design, pos, Y)
    p7 = paper_poly7(design, pos, Y)
    ins = {"chosen": model.predict(pos),
           "paper_fourier3": np.column_stack([_predict_or_nan(f, pos) for f in f3]),
           "paper_poly7": np.column_stack([_predict_or_nan(p, pos) for p in p7])}

    K = int(min(opts.folds, T))
    held = {k: np.full((T, m), np.nan) for k in COMPARED}
    idx = np.arange(T)
    for k in range(K):
        test = idx % K == k
        tr = ~test
        pt, Yt = pos[tr], Y[tr]
        mk = select(design, pt, Yt, opts, caps)
        held["chosen"][test] = mk.predict(pos[test])
        for j, (f, p) in enumerate(zip(paper_fourier3(design, pt, Yt),
                                       paper_poly7(design, pt, Yt))):
            held["paper_fourier3"][test, j] = _predict_or_nan(f, pos[test])
            held["paper_poly7"][test, j] = _predict_or_nan(p, pos[test])

    met = []
    for j in range(m):
        met.append({name: {"in_sample": metrics(Y[:, j], ins[name][:, j]),
                           "held_out": metrics(Y[:, j], held[name][:, j])}
                    for name in COMPARED})
    return AxisFit(model=model, paper_f3=f3, paper_p7=p7, in_sample=ins, held_out=held,
                   folds=K, metrics=met)
