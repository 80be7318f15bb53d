"""Identification of the dynamic thermal model (docs/thermal.md, "Identification").

Per displacement channel y (um, displacement from the record's start), the model of
:mod:`abbe.model.thermal`: y = sum_k g_k * lag(u_k, tau_k), u_k an input's rise from the
record's first sample (temperature, K; spindle speed, krpm), the lag the runtime's backward
Euler discretisation (:func:`abbe.model.thermal.lag_states`), no intercept (at the start
every rise is 0 and so is y).

Selection (forward, greedy): candidates are every input at every time constant of a grid
(:data:`TAU_GRID_S`, 0 = static). A candidate is scored by leave-one-cycle-out
cross-validation inside the identification hours (gains refitted by linear least squares
on the other cycles, RMS on the left-out cycle; the lag states run over the whole record,
they use only inputs, never the held-out displacement). A candidate whose lagged state
makes the regressor set collinear (a variance inflation factor above :data:`MAX_VIF`) is
refused. Selection stops at :data:`MAX_TERMS` terms (the runtime's limit) or when a term
improves the cross-validated RMS by less than :data:`MIN_GAIN_FRACTION`. At each step the
best three grid candidates are refined (their time constant and those already chosen, by
nonlinear least squares) before the cross-validation decides: a grid that misses the true
lag would otherwise make a second term of the same input look useful.

Refinement: the selected time constants (log tau) are refined by nonlinear least squares
(``scipy.optimize.least_squares``) on all identification hours, the gains solved linearly
inside (variable projection) and then jointly; the 95 % intervals of gains and taus come
from the Jacobian at the optimum, the residual variance inflated for the residuals' serial
correlation (effective sample count n (1 - rho) / (1 + rho), rho the lag-1
autocorrelation): 15 s samples of a slow drift are far from independent.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from abbe.model.thermal import (MAX_TERMS_PER_CHANNEL, SPEED, TEMPERATURE, ThermalInput,
                                ThermalTerm, lag_states)

#: Candidate time constants of the selection, s (0 = static). None longer than the 4-h
#: heating phase of a cycle: with 8-h cycles a longer lag is not identifiable (on the real
#: record, refined taus ran to a 24-h bound with intervals of 1e8 s and extrapolated worse).
TAU_GRID_S: tuple[float, ...] = (0.0, 300.0, 600.0, 1200.0, 1800.0, 2700.0, 3600.0, 5400.0,
                                 7200.0, 10800.0, 14400.0)
#: Refined time constants are kept inside this range, s.
TAU_BOUNDS_S = (1.0, 14400.0)
#: Largest variance inflation factor of a selected set (collinearity guard).
MAX_VIF = 30.0
#: Terms per channel (the runtime's limit).
MAX_TERMS = MAX_TERMS_PER_CHANNEL
#: Inputs whose best grid CV RMS is within this fraction of the chosen one's are reported
#: as rivals of the choice (the selection between them is not decided by the data).
RIVAL_FRACTION = 0.10
#: A term must lower the cross-validated RMS by at least this fraction.
MIN_GAIN_FRACTION = 0.10


@dataclass(frozen=True)
class Candidate:
    """One input of the selection: its name, kind and rise over the record."""

    name: str
    kind: str
    rise: np.ndarray  # K or krpm, one value per sample


@dataclass
class ChannelFit:
    """The identified model of one channel and how it was chosen.

    ``terms``: (candidate index, tau s, gain, gain_u95, tau_u95_s) per term;
    ``steps``: the selection's trace: (added term's name, tau s, CV RMS um, max VIF, rival
    inputs within :data:`RIVAL_FRACTION` of it on the grid).
    """

    name: str
    terms: list[ThermalTerm]
    cv_rms_um: float
    steps: list[tuple[str, float, float, float]] = field(default_factory=list)
    rho: float = 0.0
    n_eff: float = 0.0
    fit_rms_um: float = 0.0
    offset_um: float = 0.0  # the displacement sensor's zero (a nuisance, not in the model)
    dropped: list[str] = field(default_factory=list)  # selected, then pruned: not decided
    selection_cv_um: float = float("inf")  # the selection's CV RMS (before any ridge)
    ridge_lambda: float = 0.0  # the ridge penalty of the gains (0: least squares)
    input_set: str = "all"  # the inputs the selection used: "all" or "heated"
    #: the selected (input, tau) terms after each step of the selection, and (by_cv) the
    #: heated-input run's path and trace (reused by the round-4 room term, same result)
    path: list = field(default_factory=list)
    heated_path: list | None = None  # None: no heated-input run (not inputs="by_cv")
    heated_steps: list | None = None


def _vif_max(cols: np.ndarray) -> float:
    """Largest variance inflation factor of the columns (inf for an exact dependence)."""
    k = cols.shape[1]
    if k < 2:
        return 1.0
    z = (cols - cols.mean(0)) / np.maximum(cols.std(0), 1e-300)
    c = np.corrcoef(z, rowvar=False)
    try:
        inv = np.linalg.inv(c)
    except np.linalg.LinAlgError:
        return float("inf")
    d = np.diag(inv)
    return float(np.max(d)) if np.all(np.isfinite(d)) else float("inf")


def _lstsq(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.linalg.lstsq(a, b, rcond=None)[0]


def _with_offset(cols: np.ndarray) -> np.ndarray:
    """The columns after a column of ones: the displacement sensor's zero, a nuisance
    parameter (the record's first sample carries the sensor's noise; without it that one
    sample's noise would bias every gain). Not part of the runtime model."""
    return np.column_stack([np.ones(cols.shape[0]), cols])


def cycles_of(t_s: np.ndarray, mask: np.ndarray, cycle_s: float) -> np.ndarray:
    """Cycle number of every sample inside ``mask`` (-1 outside): consecutive blocks of
    ``cycle_s`` seconds from the first masked sample (one speed step on and off)."""
    out = np.full(t_s.shape, -1, dtype=int)
    t0 = t_s[mask][0]
    out[mask] = ((t_s[mask] - t0) // cycle_s).astype(int)
    return out


def _cv_rms(cols: np.ndarray, y: np.ndarray, cyc: np.ndarray) -> float:
    """Leave-one-cycle-out RMS (um) of a linear fit of y on cols and the sensor's zero
    offset (samples with cyc >= 0)."""
    cols = _with_offset(cols)
    sq, n = 0.0, 0
    for c in np.unique(cyc[cyc >= 0]):
        tr, te = (cyc >= 0) & (cyc != c), cyc == c
        g = _lstsq(cols[tr], y[tr])
        r = y[te] - cols[te] @ g
        sq += float(r @ r)
        n += int(te.sum())
    return float(np.sqrt(sq / n))


def _refine_taus(t_s: np.ndarray, y: np.ndarray, cands: list[Candidate],
                 chosen: list[tuple[int, float]], mask: np.ndarray,
                 n_fixed: int = 0) -> list[tuple[int, float]]:
    """The terms with their (non-static, not fixed) time constants refined by nonlinear
    least squares on the masked samples, the gains solved linearly inside (variable
    projection)."""
    free = [j for j, (_, tau) in enumerate(chosen) if tau > 0 and j >= n_fixed]
    if not free:
        return list(chosen)
    fixed_cols = {j: lag_states(cands[i].rise, t_s, tau) for j, (i, tau) in enumerate(chosen)
                  if j not in free}

    def cols(logtau: np.ndarray) -> np.ndarray:
        out = []
        for j, (i, _) in enumerate(chosen):
            out.append(fixed_cols[j] if j in fixed_cols else
                       lag_states(cands[i].rise, t_s, float(np.exp(logtau[free.index(j)]))))
        return _with_offset(np.column_stack(out))[mask]

    def resid(logtau: np.ndarray) -> np.ndarray:
        s = cols(logtau)
        return y[mask] - s @ _lstsq(s, y[mask])

    lo, hi = np.log(TAU_BOUNDS_S)
    x0 = np.clip(np.log([chosen[j][1] for j in free]), lo, hi)
    sol = least_squares(resid, x0, bounds=(lo, hi), diff_step=1e-4)
    out = list(chosen)
    for j, lt in zip(free, sol.x):
        out[j] = (chosen[j][0], float(np.exp(lt)))
    return out


def spindle_coupling(t_s: np.ndarray, cands: list[Candidate], mask: np.ndarray,
                     grid: tuple[float, ...] = TAU_GRID_S) -> list[float]:
    """How much of each input's rise on the masked samples the spindle's heat input
    explains: R^2 of the rise regressed (with an offset) on the speed through the best lag
    of ``grid``; 1 for the speed itself, 0 for every input without a speed candidate.

    The physical support of an input when the data cannot decide between inputs: a sensor
    the spindle heats follows the test's varying condition (the speed) into hours never
    seen, a sensor that follows the room does not (and on one day of identification the
    room's swing and an increasing speed schedule can look alike)."""
    speed = [i for i, c in enumerate(cands) if c.kind == SPEED]
    if not speed:
        return [0.0] * len(cands)
    lags = [lag_states(cands[speed[0]].rise, t_s, tau)[mask] for tau in grid]
    out = []
    for i, c in enumerate(cands):
        if c.kind == SPEED:
            out.append(1.0)
            continue
        u = c.rise[mask] - c.rise[mask].mean()
        ss = float(u @ u)
        best = 0.0
        for s in lags:
            a = _with_offset(s[:, None])
            r = u - a @ _lstsq(a, u)
            best = max(best, 1.0 - float(r @ r) / ss if ss > 0 else 0.0)
        out.append(best)
    return out


def bounded(term: ThermalTerm, max_tau_s: float = TAU_BOUNDS_S[1]) -> bool:
    """Whether the data decide a term (:data:`BOUND_RULE`): its gain's 95 % interval
    excludes 0, and a lag's time constant is known within a factor of two (the upper
    95 % half-width at most the value: the lag is told apart from a static term and from
    twice itself) and not held at the time-constant cap (the data asked for a longer lag
    than the record can identify)."""
    if term.gain_u95 is None or not np.isfinite(term.gain_u95) or \
            term.gain_u95 >= abs(term.gain):
        return False
    if term.tau_s == 0.0:
        return True
    return (term.tau_u95_s is not None and term.tau_u95_s <= term.tau_s
            and term.tau_s < 0.99 * max_tau_s)


#: What a term of an identified model must satisfy (:func:`bounded`, :func:`prune`).
BOUND_RULE = "gain interval excludes 0; tau within a factor of 2 at 95 %, below the cap"
#: Candidates tried (in preference order) at each selection step before it stops.
MAX_TRIALS = 8


def select_terms(t_s: np.ndarray, y: np.ndarray, cands: list[Candidate], cyc: np.ndarray,
                 *, max_terms: int = MAX_TERMS, max_vif: float = MAX_VIF,
                 min_gain: float = MIN_GAIN_FRACTION,
                 grid: tuple[float, ...] = TAU_GRID_S,
                 start: list[tuple[int, float]] | None = None,
                 physical_tiebreak: bool = False,
                 allowed: set[int] | None = None,
                 path: list | None = None
                 ) -> tuple[list[tuple[int, float]], list]:
    """Forward selection: the (candidate index, tau s) terms and the trace (added input,
    its refined tau, CV RMS, max VIF, rivals). ``start``: terms taken as given (a diagnosis
    adds to a known model).

    Each step scores every (input, grid tau) candidate beside the terms so far by
    leave-one-cycle-out CV. Inputs whose best grid score is within :data:`RIVAL_FRACTION`
    of the best are *undecided* by the data (reported as rivals). By default the best
    three grid candidates are tried by score. With ``physical_tiebreak`` the undecided
    inputs are tried first, the one the spindle's heat input explains best
    (:func:`spindle_coupling`; the speed itself first) leading, then the remaining
    candidates by score, at most :data:`MAX_TRIALS`. A trial's time
    constants are refined with the others' (nonlinear least squares on the identification
    samples); it is kept if the refined set's CV RMS drops by ``min_gain`` and its largest
    VIF stays <= ``max_vif``. ``allowed``: the candidate indices the selection may use
    (None: all; :func:`heated_inputs`). ``path``: if given, the chosen terms after each
    accepted step are appended to it (the first k steps do not depend on ``max_terms``)."""
    usable = [i for i in range(len(cands)) if allowed is None or i in allowed]
    grid_states = {(i, tau): lag_states(cands[i].rise, t_s, tau)
                   for i in usable for tau in grid}
    fit_mask = cyc >= 0
    n_fixed = len(start or [])
    coupling = spindle_coupling(t_s, cands, fit_mask, grid) if physical_tiebreak else None

    def st(k: tuple[int, float]) -> np.ndarray:
        if k not in grid_states:
            grid_states[k] = lag_states(cands[k[0]].rise, t_s, k[1])
        return grid_states[k]

    chosen: list[tuple[int, float]] = list(start or [])
    trace: list[tuple[str, float, float, float]] = []
    best_rms = _cv_rms(np.column_stack([st(k) for k in chosen]) if chosen
                       else np.empty((y.size, 0)), y, cyc)
    while len(chosen) < max_terms:
        base = [st(k) for k in chosen]
        ranked = []
        for key in [(i, tau) for i in usable for tau in grid]:
            if key in chosen:
                continue
            cols = np.column_stack(base + [grid_states[key]])
            if _vif_max(cols[fit_mask]) > max_vif:
                continue
            ranked.append((_cv_rms(cols, y, cyc), key))
        ranked.sort()
        if not ranked:
            break
        # each input's best grid key; the undecided ones (within RIVAL_FRACTION of the
        # best) ordered by their physical support, then every other key by score
        best_key: dict[int, tuple[float, tuple[int, float]]] = {}
        for r, k in ranked:
            best_key.setdefault(k[0], (r, k))
        top = ranked[0][0]
        if coupling is not None:
            undecided = sorted((v for v in best_key.values()
                                if v[0] <= top * (1 + RIVAL_FRACTION)),
                               key=lambda v: (-coupling[v[1][0]], v[0]))
            order = [k for _, k in undecided]
            order += [k for _, k in ranked if k not in order]
            order = order[:MAX_TRIALS]
        else:
            order = [k for _, k in ranked[:3]]  # the best three on the grid, refined
        accepted = False
        for key in order:
            trial = _refine_taus(t_s, y, cands, chosen + [key], fit_mask, n_fixed)
            cols = np.column_stack([st(k) for k in trial])
            vif = _vif_max(cols[fit_mask])
            rms = _cv_rms(cols, y, cyc)
            if not (vif <= max_vif and rms <= best_rms * (1.0 - min_gain)):
                continue
            chosen, best_rms, accepted = trial, rms, True
            if path is not None:
                path.append(list(chosen))
            grid_rms = next(r for r, k in ranked if k == key)
            rivals = []  # other inputs nearly as good on the grid: an ambiguous choice
            for r, k in ranked:
                if r > grid_rms * (1.0 + RIVAL_FRACTION):
                    break
                name = cands[k[0]].name
                if k[0] != key[0] and name not in rivals:
                    rivals.append(name)
            trace.append((cands[key[0]].name, trial[-1][1], rms, vif, tuple(rivals)))
            break
        if not accepted:
            break
    return chosen, trace


def refine(t_s: np.ndarray, y: np.ndarray, cands: list[Candidate],
           chosen: list[tuple[int, float]], mask: np.ndarray
           ) -> tuple[list[ThermalTerm], float, float, float, float]:
    """Nonlinear least squares of taus and gains on the masked samples; 95 % intervals.

    Returns (terms, fit RMS um, rho, n_eff, the sensor's zero offset um)."""
    dyn = [j for j, (_, tau) in enumerate(chosen) if tau > 0]

    def states(logtau: np.ndarray) -> np.ndarray:
        taus = [tau for _, tau in chosen]
        for j, lt in zip(dyn, logtau):
            taus[j] = float(np.exp(lt))
        return _with_offset(np.column_stack([lag_states(cands[i].rise, t_s, tau)
                                             for (i, _), tau in zip(chosen, taus)]))

    def resid_vp(logtau: np.ndarray) -> np.ndarray:
        s = states(logtau)[mask]
        return y[mask] - s @ _lstsq(s, y[mask])

    lt0 = np.log([chosen[j][1] for j in dyn]) if dyn else np.empty(0)
    lo, hi = np.log(TAU_BOUNDS_S)
    if dyn:
        sol = least_squares(resid_vp, lt0, bounds=(lo, hi), x_scale=1.0, diff_step=1e-4)
        lt = sol.x
    else:
        lt = lt0
    s_all = states(lt)
    gains = _lstsq(s_all[mask], y[mask])

    # joint parameter vector (offset, gains, log taus): residual and Jacobian at the optimum
    ng = len(chosen) + 1

    def resid_joint(p: np.ndarray) -> np.ndarray:
        g, l_ = p[:ng], p[ng:]
        return y[mask] - states(l_)[mask] @ g

    p = np.concatenate([gains, lt])
    r = resid_joint(p)
    jac = np.empty((r.size, p.size))
    for k in range(p.size):
        h = 1e-6 * max(1.0, abs(p[k]))
        dp = p.copy()
        dp[k] += h
        jac[:, k] = (resid_joint(dp) - r) / h
    n = r.size
    rho = float(np.clip(np.corrcoef(r[:-1], r[1:])[0, 1], 0.0, 0.999)) if n > 2 else 0.0
    n_eff = max(n * (1 - rho) / (1 + rho), p.size + 1.0)
    s2 = float(r @ r) / max(n - p.size, 1) * (n / n_eff)
    try:
        cov = s2 * np.linalg.inv(jac.T @ jac)
        half = 1.96 * np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        half = np.full(p.size, np.inf)
    terms = []
    for j, (i, tau0) in enumerate(chosen):
        g_u = float(half[j + 1])
        if j in dyn:
            k = ng + dyn.index(j)
            tau = float(np.exp(lt[dyn.index(j)]))
            # the interval of log tau mapped to tau: the larger half-width (asymmetric)
            t_u = (float(tau * np.expm1(half[k])) if np.isfinite(half[k]) and half[k] < 20.0
                   else None)  # None: the data do not bound this time constant
        else:
            tau, t_u = 0.0, 0.0
        terms.append(ThermalTerm(input=i, tau_s=tau, gain=float(gains[j + 1]),
                                 gain_u95=g_u if np.isfinite(g_u) else None, tau_u95_s=t_u))
    return terms, float(np.sqrt(np.mean(r ** 2))), rho, float(n_eff), float(gains[0])


def prune(t_s: np.ndarray, y: np.ndarray, cands: list[Candidate],
          chosen: list[tuple[int, float]], mask: np.ndarray, n_fixed: int = 0
          ) -> tuple[list[tuple[int, float]], list[str]]:
    """The terms the data do not decide, dropped in one step: every term (after the first
    ``n_fixed``, taken as given) that fails :func:`bounded` on the joint refinement of the
    whole selected set, where the intervals are least inflated by missing structure. Not
    repeated on the smaller set: with terms missing, the residuals' serial correlation
    inflates every interval and an iterated elimination removes everything. Returns the
    kept (candidate index, tau s) terms and the dropped terms' descriptions."""
    if len(chosen) <= n_fixed:
        return list(chosen), []
    terms = refine(t_s, y, cands, chosen, mask)[0]
    keep, dropped = [], []
    for j, tt in enumerate(terms):
        if j < n_fixed or bounded(tt):
            keep.append((tt.input, tt.tau_s))
            continue
        g_u = tt.gain_u95 if tt.gain_u95 is not None else float("inf")
        t_u = tt.tau_u95_s if tt.tau_u95_s is not None else float("inf")
        dropped.append(f"{cands[tt.input].name} tau {tt.tau_s:.0f} s (gain {tt.gain:.3g} "
                       f"+/- {g_u:.2g}, tau +/- {t_u:.3g} s)")
    return keep, dropped


def heated_inputs(t_s: np.ndarray, cands: list[Candidate], mask: np.ndarray) -> set[int]:
    """The inputs the spindle heats (docs/thermal.md, "The heated-inputs method"): the
    speed, and the temperatures whose :func:`spindle_coupling` on the masked samples lies
    above the largest gap of the temperatures' sorted couplings (a split the data make,
    no threshold set by hand). Without a speed candidate every input is kept.

    Real record, hours 0-24: couplings 0.02-0.10 (ten sensors: the room) and 0.39-0.51
    (t4, t5, t6, t7, t10, t11), split at the gap 0.10 -> 0.39."""
    coupling = spindle_coupling(t_s, cands, mask)
    speed = {i for i, c in enumerate(cands) if c.kind == SPEED}
    temps = sorted((coupling[i], i) for i in range(len(cands)) if i not in speed)
    if not speed or len(temps) < 2:
        return set(range(len(cands)))
    gaps = [temps[k + 1][0] - temps[k][0] for k in range(len(temps) - 1)]
    cut = int(np.argmax(gaps))
    return speed | {i for _, i in temps[cut + 1:]}


def identify_channel(name: str, t_s: np.ndarray, y: np.ndarray, cands: list[Candidate],
                     fit_mask: np.ndarray, cycle_s: float, *, decided_only: bool = False,
                     inputs: str = "all", ridge: bool = False, **kw) -> ChannelFit:
    """Select and refine one channel's terms on the samples of ``fit_mask``.

    ``decided_only`` (the "decided" method, docs/thermal.md): undecided choices go to the
    input with physical support (``physical_tiebreak``) and the terms the data do not
    decide are dropped (:func:`prune`). Off by default: the committed example model and
    the runtime's end-to-end check use the forward selection alone.

    ``inputs``: "all" (every candidate), "heated" (the speed and the temperatures the
    spindle heats, :func:`heated_inputs` on ``fit_mask``) or "by_cv" (both selections run,
    the one with the lower cross-validated RMS kept, ties to "all"). ``ridge``: the gains
    by :func:`ridge_gains` (penalty chosen by the same cross-validation)."""
    if inputs == "by_cv":
        a = identify_channel(name, t_s, y, cands, fit_mask, cycle_s, decided_only=decided_only,
                             inputs="all", ridge=ridge, **kw)
        b = identify_channel(name, t_s, y, cands, fit_mask, cycle_s, decided_only=decided_only,
                             inputs="heated", ridge=ridge, **kw)
        won = b if b.terms and b.selection_cv_um < a.selection_cv_um else a
        won.heated_path, won.heated_steps = b.path, b.steps
        return won
    if inputs not in ("all", "heated"):
        raise ValueError(f"inputs: expected 'all', 'heated' or 'by_cv', got {inputs!r}")
    cyc = cycles_of(t_s, fit_mask, cycle_s)
    if inputs == "heated":
        kw = {**kw, "allowed": heated_inputs(t_s, cands, fit_mask)}
    path: list = []
    chosen, trace = select_terms(t_s, y, cands, cyc, physical_tiebreak=decided_only,
                                 path=path, **kw)
    dropped: list[str] = []
    if decided_only:
        chosen, dropped = prune(t_s, y, cands, chosen, fit_mask)
    if not chosen:
        off = float(np.mean(y[fit_mask]))
        rms0 = float(np.sqrt(np.mean((y[fit_mask] - off) ** 2)))
        return ChannelFit(name, [], rms0, trace, offset_um=off, dropped=dropped,
                          selection_cv_um=rms0, input_set=inputs, path=path)
    terms, fit_rms, rho, n_eff, offset = refine(t_s, y, cands, chosen, fit_mask)
    cv = (_cv_rms(np.column_stack([lag_states(cands[t.input].rise, t_s, t.tau_s)
                                   for t in terms]), y, cyc) if decided_only else trace[-1][2])
    selection_cv = cv
    lam = 0.0
    if ridge:
        terms, offset, lam, cv = ridge_gains(t_s, y, cands, terms, fit_mask, cyc)
        fit_rms = _rms_of_terms(t_s, y, cands, terms, offset, fit_mask)
    return ChannelFit(name, terms, cv, trace, rho, n_eff, fit_rms, offset, dropped,
                      selection_cv, lam, inputs, path)


#: The ridge penalties :func:`ridge_gains` chooses from (per sample, standardised columns).
RIDGE_GRID: tuple[float, ...] = (0.0, 1e-4, 1e-3, 3e-3, 1e-2, 3e-2, 1e-1)


def _ridge_solve(cols: np.ndarray, y: np.ndarray, lam: float
                 ) -> tuple[float, np.ndarray]:
    """Offset (unpenalised) and gains of a ridge fit of y on cols: the penalty lam * n on
    the gains of the standardised columns. Returns (offset, gains in the columns' units)."""
    mu, sd = cols.mean(0), np.maximum(cols.std(0), 1e-300)
    z = (cols - mu) / sd
    ym = float(y.mean())
    b = np.linalg.solve(z.T @ z + lam * len(z) * np.eye(z.shape[1]), z.T @ (y - ym))
    g = b / sd
    return ym - float(mu @ g), g


def ridge_gains(t_s: np.ndarray, y: np.ndarray, cands: list[Candidate],
                terms: list[ThermalTerm], mask: np.ndarray, cyc: np.ndarray,
                grid: tuple[float, ...] = RIDGE_GRID
                ) -> tuple[list[ThermalTerm], float, float, float]:
    """The terms' gains by ridge regression, the penalty the grid's lowest leave-one-cycle-out
    RMS (inputs and time constants unchanged; the gain intervals stay the unpenalised fit's:
    a ridge estimate has no comparable interval). Returns (terms, offset um, lambda, CV RMS)."""
    cols = np.column_stack([lag_states(cands[t.input].rise, t_s, t.tau_s) for t in terms])
    best: tuple[float, float] | None = None
    for lam in grid:
        sq, n = 0.0, 0
        for c in np.unique(cyc[cyc >= 0]):
            tr, te = (cyc >= 0) & (cyc != c), cyc == c
            off, g = _ridge_solve(cols[tr], y[tr], lam)
            r = y[te] - off - cols[te] @ g
            sq += float(r @ r)
            n += int(te.sum())
        rms = float(np.sqrt(sq / n))
        if best is None or rms < best[0]:
            best = (rms, lam)
    assert best is not None
    off, g = _ridge_solve(cols[mask], y[mask], best[1])
    out = [ThermalTerm(input=t.input, tau_s=t.tau_s, gain=float(gk), gain_u95=t.gain_u95,
                       tau_u95_s=t.tau_u95_s) for t, gk in zip(terms, g)]
    return out, off, best[1], best[0]


def _rms_of_terms(t_s: np.ndarray, y: np.ndarray, cands: list[Candidate],
                  terms: list[ThermalTerm], offset: float, mask: np.ndarray) -> float:
    pred = offset + sum(t.gain * lag_states(cands[t.input].rise, t_s, t.tau_s) for t in terms)
    return float(np.sqrt(np.mean((y - pred)[mask] ** 2)))


def candidates_of(temps_c: np.ndarray, temp_names: list[str], speed_rpm: np.ndarray | None,
                  speed_name: str = "spindle") -> list[Candidate]:
    """The selection's candidates: every temperature's rise from its first sample (K) and
    the speed (krpm, from 0 rpm)."""
    out = [Candidate(n, TEMPERATURE, temps_c[:, k] - temps_c[0, k])
           for k, n in enumerate(temp_names)]
    if speed_rpm is not None:
        out.append(Candidate(speed_name, SPEED, speed_rpm / 1000.0))  # reference 0 rpm
    return out


def inputs_of(cands: list[Candidate], temps_c: np.ndarray, speed_rpm: np.ndarray | None
              ) -> tuple[ThermalInput, ...]:
    """The model's inputs, their references the record's first sample (a cold machine)."""
    out = []
    for k, c in enumerate(cands):
        if c.kind == SPEED:
            out.append(ThermalInput(c.name, SPEED, reference=0.0,
                                    valid_min=-1.0, valid_max=60000.0, max_step=60000.0))
        else:
            out.append(ThermalInput(c.name, TEMPERATURE, reference=float(temps_c[0, k]),
                                    valid_min=-20.0, valid_max=120.0, max_step=5.0))
    return tuple(out)


def mlr_baseline(temps_c: np.ndarray, y: np.ndarray, fit_mask: np.ndarray) -> np.ndarray:
    """The static multi-linear regression on every temperature's rise plus an offset,
    fitted on ``fit_mask``: its prediction over the whole record (um)."""
    x = np.column_stack([np.ones(len(y)), temps_c - temps_c[0]])
    return x @ _lstsq(x[fit_mask], y[fit_mask])
