"""U (k = 2) of ``abbe diagnose``'s named effects and gaps, with the budget and a Monte Carlo.

Each named effect's value (the headline: an amplitude, a norm, a rate, a single parameter;
:func:`abbe.diagnose.describe._headline`) and the gap figures (RMS and max |residual| of the
um-valued samples, each check's set-up nuisance removed) get ``u``, ``U`` = 2 u and the
lines they come from (docs/uncertainty.md, "Diagnosis"):

* **the fit's statistical part** (Type A): the final fit's covariance s^2 (X^T W^2 X)^-1
  (the noise of every check, its serial correlation inflated, s^2 >= 1 carrying the lack
  of fit), through the headline's gradient. For a gap: the readings' noise of a
  re-measurement, sigma^2 = s^2 / W^2 per reading, through the residual (first order plus
  the quadratic form's own variance, exact for normal noise);
* **the instruments' budget** (Type B; ``[uncertainty.*]``, else the class defaults): a
  laser line's scale errors (ppm of the distance from the reference point), linearity and
  resolution; a ballbar's scale, drift ramp, resolution and length calibration. The
  selection held fixed, the final fit is linear in the readings (theta = theta0 + L dy),
  so each line is |s . p| u_t; a laser's scale-like ramp: :mod:`abbe.diagnose.scale_free`.

The Monte Carlo (GUM S1) is independent of these formulas: each draw makes new readings
(normal noise + one draw of every instrument input) and fits them again through the
nonlinear model (:func:`_refitter`: Gauss-Newton, every residual through the C library)
and evaluates the headline and gap figures; U_MC = 2 x the draws' standard deviation. Beyond 10 %
the Monte Carlo's U is stated (``U_from``), as in the rest of abbe.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from abbe.diagnose.candidates import Engine, Selected, apply_selection
from abbe.diagnose.checks import OWN_TERM, BallbarCheck, LaserCheck
from abbe.diagnose.problem import project_out, qr_basis, remove_nuisance
from abbe.diagnose.results import FitState
from abbe.diagnose.scale_free import absorbed, free_scale_axes, free_scale_L, freed_columns, freed_with

K = 2.0
SQRT3 = math.sqrt(3.0)
#: beyond this relative difference the Monte Carlo's U is stated
AGREEMENT = 0.10
#: the budget line of the table's own fit error along the effect
TABLE_LINE = "table (fit) uncertainty"


@dataclass
class Systematic:
    """One input common to many readings: dy = t * pattern, t from U(low, high)."""

    name: str
    check: str
    pattern: np.ndarray     # (N,) um per unit of t
    low: float = -1.0
    high: float = 1.0
    normal_sd: float | None = None  # set: t is normal with this standard deviation
    #: a laser line's scale-like input (a ramp along this axis' own channel): propagated
    #: with the axis' scale free in the fit unless a scale of the axis is named
    ramp_axis: str | None = None

    @property
    def sd(self) -> float:
        if self.normal_sd is not None:
            return self.normal_sd
        return (self.high - self.low) / math.sqrt(12.0)

    def draw(self, rng: np.random.Generator) -> float:
        if self.normal_sd is not None:
            return float(rng.normal(0.0, self.normal_sd))
        return float(rng.uniform(self.low, self.high))


@dataclass
class Grouped:
    """An error per label (a target's linearity), independent between labels, the same for
    every reading of the label: U(-half, half) um; label -1 = not affected."""

    name: str
    check: str
    labels: np.ndarray      # (N,) int
    half_um: float


@dataclass
class PerReading:
    """An error per reading (resolution): U(-half_i, half_i) um, independent."""

    name: str
    check: str
    half_um: np.ndarray     # (N,)


@dataclass
class Inputs:
    systematic: list[Systematic]
    grouped: list[Grouped]
    per_reading: list[PerReading]
    budgets: dict[str, Any]


def instrument_inputs(prob: Any, laser_budget: Any, ballbar_budget: Any) -> Inputs:
    """The instrument inputs of every check of ``prob`` (one input per line of the budget)."""
    from abbe.analysis.uncertainty import scale_inputs
    N = prob.N
    sysl: list[Systematic] = []
    grp: list[Grouped] = []
    per: list[PerReading] = []
    budgets: dict[str, Any] = {}
    for i, c in enumerate(prob.checks):
        s = prob.slice(i)
        if isinstance(c, BallbarCheck) and ballbar_budget is not None:
            f = ballbar_budget.figures
            budgets[c.name] = ballbar_budget.to_json()
            t = np.asarray(c.all_time, dtype=np.float64)[c.mask]
            span = float(np.ptp(c.all_time)) or 1.0
            ramp = (t - float(np.min(c.all_time))) / span
            p = np.zeros(N)
            p[s] = c.y * f["scale_pct"] / 100.0
            sysl.append(Systematic("ballbar scale", c.name, p))
            p = np.zeros(N)
            p[s] = abs(f["expansion_ppm_per_k"]) * f["drift_c"] * c.radius_mm * 1e-3 * ramp
            sysl.append(Systematic("ballbar thermal drift", c.name, p))
            p = np.zeros(N)
            p[s] = 1.0
            sysl.append(Systematic("ballbar length (calibration)", c.name, p,
                                   normal_sd=f["calibration_U_um"] / 2.0))
            h = np.zeros(N)
            h[s] = f["resolution_um"] / 2.0
            per.append(PerReading("ballbar resolution", c.name, h))
        elif isinstance(c, LaserCheck) and laser_budget is not None:
            f = laser_budget.figures
            budgets[c.name] = laser_budget.to_json()
            own = next((k for k, ch in enumerate(c.channels) if ch.term == OWN_TERM[c.axis]), None)
            if own is None:
                continue
            rows = np.zeros(N, dtype=bool)
            rows[s] = c.group == own
            dist_um = (np.asarray(c.x, dtype=np.float64) - float(c.reference_mm[c.j])) * 1e3
            for si in scale_inputs(laser_budget, None):
                p = np.zeros(N)
                p[s] = np.where(c.group == own, dist_um * 1e-6, 0.0)
                sysl.append(Systematic(si.name, c.name, p, si.low_ppm, si.high_ppm,
                                       ramp_axis=c.axis))
            if f["linearity_um"] > 0:
                lab = np.full(N, -1)
                lab[s] = np.where(c.group == own, c.cell % c.T, -1)  # one error per target, both directions
                grp.append(Grouped("linearity (per target)", c.name, lab, f["linearity_um"]))
            if f["resolution_um"] > 0:
                h = np.zeros(N)
                h[rows] = f["resolution_um"] / 2.0
                per.append(PerReading("resolution", c.name, h))
    return Inputs(sysl, grp, per, budgets)


def budgets_of_machine(machine: Any) -> tuple[Any, Any]:
    """(laser budget, ballbar budget) of a machine file: its ``[uncertainty.*]``, else the
    class defaults (laser_interferometer, ballbar)."""
    from abbe.analysis.uncertainty import ballbar_budget
    from abbe.formats.uncertainty_spec import default_budget
    extra = getattr(machine, "extra", None) or {}
    spec = extra.get("uncertainty")
    laser = spec.laser if spec is not None and spec.laser is not None else None
    if laser is None:
        laser = default_budget("laser_interferometer")
        laser.source = "class defaults (docs/uncertainty.md)"
    if hasattr(machine, "extra"):
        return laser, ballbar_budget(machine)[0]
    ballbar = default_budget("ballbar")
    ballbar.source = "class defaults (docs/uncertainty.md)"
    return laser, ballbar


def budget_of_positioning_file(path: Any) -> Any:
    """The class default of an ISO 230-2 file: laser_triangulation for an ecmc .dat (the
    ESS file names an ILD sensor), else laser_interferometer (as ``abbe iso230-2``)."""
    from pathlib import Path

    from abbe.formats import ess_dat
    from abbe.formats.uncertainty_spec import default_budget
    cls = "laser_triangulation" if ess_dat.looks_like_dat(Path(path)) else "laser_interferometer"
    b = default_budget(cls)
    b.source = f"class defaults {cls} (docs/uncertainty.md)"
    return b


# ------------------------------------------------------------------ the linear propagation
def _line_u(s: np.ndarray, inp: Inputs,
            s_free: dict[str, np.ndarray] | None = None) -> dict[str, float]:
    """Each input's standard uncertainty of a figure whose change is s . dy; a ramp along
    a: the smaller with ``s_free[a]`` (:mod:`abbe.diagnose.scale_free`)."""
    out: dict[str, float] = {}
    for x in inp.systematic:
        v = abs(float(s @ x.pattern)) * x.sd
        if x.ramp_axis in (s_free or {}):
            v = min(v, abs(float(s_free[x.ramp_axis] @ x.pattern)) * x.sd)  # type: ignore[index]
        out[f"{x.check}: {x.name}"] = out.get(f"{x.check}: {x.name}", 0.0) + v
    for g in inp.grouped:
        m = g.labels >= 0
        if not np.any(m):
            continue
        sums = np.bincount(g.labels[m], weights=s[m])
        out[f"{g.check}: {g.name}"] = float(np.sqrt(np.sum(sums ** 2))) * g.half_um / SQRT3
    for r in inp.per_reading:
        out[f"{r.check}: {r.name}"] = float(np.sqrt(np.sum((s * r.half_um) ** 2))) / SQRT3
    return {k: v for k, v in out.items()}


def _headline_fn(eng: Engine, s: Selected, C: np.ndarray) -> Callable[[np.ndarray], float]:
    from abbe.diagnose.describe import _headline
    spec, idx = s.cand.spec, s.cand.param_idx
    return lambda v: float(_headline(spec, idx, v, C, 1.96, eng)[0])


def _grad(fn: Callable[[np.ndarray], float], v: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Central differences, each step 1e-3 of the parameter's standard deviation."""
    g = np.zeros(v.size)
    for j in range(v.size):
        h = max(1e-3 * math.sqrt(max(C[j, j], 0.0)), 1e-9 * max(abs(v[j]), 1.0))
        e = np.zeros(v.size)
        e[j] = h
        g[j] = (fn(v + e) - fn(v - e)) / (2 * h)
    return g


def _final_design(st: FitState) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(X (N, p) unweighted sensitivities at the solution, L (p, N) = d theta / d y,
    y_fit (N,) the prediction at the solution)."""
    eng, prob = st.eng, st.eng.prob
    t, p = apply_selection(eng, st.selected, st.values)
    y = prob.predict(eng.ev, t, p)
    cols = [eng.sensitivity(s.cand.spec, s.cand.scan_value, t, p, y, s.cand.param_idx)[:, s.cand.param_idx]
            for s in st.selected]
    X = np.hstack(cols)
    Q = qr_basis(prob.nuis * st.W[:, None])
    Xe = project_out(Q, X * st.W[:, None])
    L = np.linalg.pinv(Xe) * st.W[None, :]
    return X, L, y


def _nuisance_removal_T(prob: Any, v: np.ndarray) -> np.ndarray:
    """P_n^T v = P_n v (each check's unweighted least-squares removal is symmetric)."""
    return np.nan_to_num(remove_nuisance(prob, v))


def _random_parts(prob: Any, inp: Inputs, um: np.ndarray) -> dict[str, tuple[np.ndarray, list[np.ndarray]]]:
    """Per instrument input acting as a random error of the samples (a target's linearity,
    a reading's resolution): its variance per sample (N,) and its blocks (rows that share
    one error), for the quadratic form of an RMS and the competition of a max."""
    out: dict[str, tuple[np.ndarray, list[np.ndarray]]] = {}
    for g in inp.grouped:
        v = np.where(g.labels >= 0, g.half_um ** 2 / 3.0, 0.0) * um
        blocks = [np.flatnonzero((g.labels == lab) & um) for lab in np.unique(g.labels[g.labels >= 0])]
        out[f"{g.check}: {g.name}"] = (v, blocks)
    for r in inp.per_reading:
        v = (r.half_um ** 2 / 3.0) * um
        out[f"{r.check}: {r.name}"] = (v, [])
    return out


def _max_abs_variance(r: np.ndarray, um: np.ndarray,
                      rand: dict[str, tuple[np.ndarray, list[np.ndarray]]]) -> float:
    """Variance of max_i |r_i + e_i| over the um samples: e_i normal (the noise and the
    resolution, variance summed) plus, where a block of samples shares one rectangular
    error (a target's linearity), that error: within a block the max is the error plus the
    largest of its normals; blocks, and the two signs, independent. CDF on a grid."""
    from scipy.special import log_ndtr
    v_norm = np.zeros(r.size)
    block_of = np.full(r.size, -1)
    half: list[float] = []
    for name, (v, blocks) in rand.items():
        if blocks:
            for b in blocks:
                block_of[b] = len(half)
                half.append(math.sqrt(3.0 * float(v[b[0]])))
        else:
            v_norm = v_norm + v
    idx = np.flatnonzero(um)
    sd = np.maximum(np.sqrt(v_norm[idx]), 1e-9)
    a = np.array([half[b] if b >= 0 else 0.0 for b in block_of[idx]])
    x_all = np.concatenate([r[idx], -r[idx]])
    sd_all, a_all = np.concatenate([sd, sd]), np.concatenate([a, a])
    blk = np.concatenate([block_of[idx], block_of[idx] + len(half)])
    blk = np.where(np.concatenate([block_of[idx], block_of[idx]]) < 0, -1, blk)
    lo = float(np.max(x_all - 9 * sd_all - a_all))
    hi = float(np.max(x_all + 9 * sd_all + a_all))
    keep = x_all + 9 * sd_all + a_all >= lo
    amax = float(np.max(a_all[keep])) if np.any(keep) else 0.0
    y = np.linspace(lo - amax, hi + amax, 2001)
    hstep = y[1] - y[0]
    logF = np.zeros_like(y)
    single = keep & (blk < 0)
    xs, ss = x_all[single], sd_all[single]
    for j in range(0, xs.size, 256):
        logF += np.sum(log_ndtr((y[:, None] - xs[None, j:j + 256]) / ss[None, j:j + 256]), axis=1)
    for b in np.unique(blk[keep & (blk >= 0)]):
        m = keep & (blk == b)
        FM = np.exp(np.sum(log_ndtr((y[:, None] - x_all[m][None, :]) / sd_all[m][None, :]), axis=1))
        ab = float(a_all[m][0])
        w = int(round(ab / hstep))
        if w >= 1:  # the mean of F_M over [y - a, y + a]: the rectangular error added
            C = np.concatenate([[0.0], np.cumsum(FM)])
            i = np.arange(y.size)
            i0, i1 = np.clip(i - w, 0, y.size), np.clip(i + w + 1, 0, y.size)
            FB = (C[i1] - C[i0] + np.maximum(0, (i + w + 1) - y.size)) / (2 * w + 1)
        else:
            FB = FM
        logF += np.log(np.maximum(FB, 1e-300))
    F = np.exp(logF)
    top = y[-1]
    mean = top - np.trapezoid(F, y)
    second = top * top - np.trapezoid(2 * y * F, y)
    return max(float(second - mean * mean), 0.0)


def _systematic_gap_lines(r: np.ndarray, um: np.ndarray, inp: Inputs,
                          forward: Callable[[np.ndarray], np.ndarray]) -> dict[str, np.ndarray]:
    """Each input common to many samples acting alone on the residual r + t M p: the
    standard deviation of (RMS, max |r|) over t's distribution (12-point Gauss-Legendre for
    a rectangular t, Gauss-Hermite for a normal one) of the exact figures, not a
    derivative at t's centre: a residual left by a least-squares fit sits near a minimum
    in some directions (a scale error nearly orthogonal to it), where the derivative is
    near 0 and the spread is not."""
    def figures(x: np.ndarray) -> np.ndarray:
        v = x[um]
        return np.array([math.sqrt(float(np.mean(v * v))), float(np.max(np.abs(v)))])

    gl_x, gl_w = np.polynomial.legendre.leggauss(12)
    gh_x, gh_w = np.polynomial.hermite_e.hermegauss(12)
    gh_w = gh_w / gh_w.sum()
    out: dict[str, np.ndarray] = {}
    for x in inp.systematic:
        mp = np.nan_to_num(forward(x.pattern))
        if not np.any(mp[um]):
            continue
        if x.normal_sd is not None:
            ts, ws = gh_x * x.normal_sd, gh_w
        else:
            ts = 0.5 * (x.low + x.high) + 0.5 * (x.high - x.low) * gl_x
            ws = gl_w / 2.0
        F = np.array([figures(r + t * mp) for t in ts])
        mean = ws @ F
        sd = np.sqrt(np.clip(ws @ (F - mean) ** 2, 0.0, None))
        name = f"{x.check}: {x.name}"
        out[name] = np.sqrt(out.get(name, np.zeros(2)) ** 2 + sd ** 2)
    return out


def _gap_lines(prob: Any, r_clean: np.ndarray, back: Callable[[np.ndarray], np.ndarray],
               var_noise: np.ndarray, inp: Inputs,
               forward: Callable[[np.ndarray], np.ndarray] | None = None) -> dict[str, Any]:
    """u of RMS and max |r| (um rows) of a residual r(y + dy) = r + M dy, M^T given by
    ``back``; noise of a re-measurement with variance ``var_noise`` per reading.

    The errors that are random from sample to sample (the noise, a target's linearity, a
    reading's resolution) enter an RMS through the exact variance of a quadratic form in
    them (first order 4 r^T S r plus 2 tr(S^2), S their covariance, the projections M
    dropped) and a max through the competition of the samples (the largest of independent
    normals, the exact distribution ISO 230-2's E uses); the inputs common to many samples
    (scale, drift, calibration) to first order."""
    um = prob.um_rows & np.isfinite(r_clean)
    r = np.where(um, r_clean, 0.0)
    n = int(um.sum())
    k = int(np.argmax(np.abs(r)))
    rand = {"fit / readings' noise (Type A)": (var_noise * um, [])}
    rand.update(_random_parts(prob, inp, um))
    # Var(e^2) = (2 + excess kurtosis) sigma^4: 2 for the normal noise, 0.8 for a
    # rectangular error (a target's linearity, a reading's resolution)
    kurt = {name: (2.0 if i == 0 else 0.8) for i, name in enumerate(rand)}
    # new errors raise the sum of squares on average by their variance (E ss' = ss +
    # tr S): the square root is linearised at that mean, where the draws are
    ss_mean = float(r @ r) + sum(float(np.sum(v)) for v, _ in rand.values())
    rms_mean = math.sqrt(ss_mean / n)
    rms = math.sqrt(float(r @ r) / n)
    out: dict[str, Any] = {}
    # RMS
    a = r / (n * rms_mean)
    s = back(a)
    lines = {}
    for name, (v, blocks) in rand.items():
        if blocks:  # one error per block: first order through the block's sum, tr(S^2) by blocks
            v1 = sum(float(np.sum(s[b])) ** 2 * float(v[b[0]]) for b in blocks if b.size)
            tr2 = sum((b.size * float(v[b[0]])) ** 2 for b in blocks if b.size)
        else:
            v1 = float(np.sum(s * s * v))
            tr2 = float(np.sum(v * v))
        lines[name] = math.sqrt(v1 + kurt[name] * tr2 / (2.0 * n * rms_mean) ** 2)
    sys_lines = _systematic_gap_lines(r, um, inp, forward) if forward is not None else {}
    lines.update({k: float(v[0]) for k, v in sys_lines.items()})
    u = math.sqrt(sum(x * x for x in lines.values()))
    out["rms_um"] = {"value": rms, "u": u, "U": K * u, "budget_u": lines}
    # max |r|: the random errors together, by the competition of the samples (a target's
    # linearity shared by its samples), shared between their lines in proportion to their
    # variance at the sample that makes the max
    var = _max_abs_variance(r, um, rand)
    v_all = sum(v for v, _ in rand.values())
    tot = float(v_all[k]) or 1.0
    lines = {name: math.sqrt(var * float(v[k]) / tot) for name, (v, _) in rand.items()}
    lines.update({k: float(v[1]) for k, v in sys_lines.items()})
    u = math.sqrt(sum(x * x for x in lines.values()))
    out["max_um"] = {"value": abs(r[k]), "u": u, "U": K * u, "budget_u": lines}
    return out


def diagnosis_uncertainty(res: Any, laser_budget: Any, ballbar_budget: Any,
                          draws: int = 0, seed: int = 20241,
                          model_from_the_data: bool = False,
                          table_cov: dict[tuple[str, str], np.ndarray] | None = None
                          ) -> dict[str, Any] | None:
    """u, U (k = 2) and the budget of each named effect's value and of the gap figures of a
    :class:`~abbe.diagnose.results.DiagnoseResult` (its ``fit_state`` kept by diagnose);
    with ``draws``, the Monte Carlo check. Sets ``u``, ``U``, ``budget_u`` (and the Monte
    Carlo's) on each effect and component and ``res.uncertainty`` (the JSON section), and
    returns that section.

    ``model_from_the_data``: the model was built from the same readings (``abbe diagnose
    --iso230-2`` without ``--model``: the position-only model is each target's mean), so an
    error per target (the sensor's linearity) moves the model with the readings and
    cancels in every residual: it is left out (stated in the assumptions).

    ``table_cov``: the table's coefficient covariance (abbe.diagnose.table_uncertainty):
    each effect gets a line "table (fit) uncertainty" (a tool offset: the model's angular
    uncertainty its interval already carries, describe.tool_model_cov), and each effect's
    95 % interval grows in quadrature by 2 u of the lines it did not carry yet (the
    instruments', the table's), so it contains the whole budget (:func:`_widen`)."""
    st: FitState | None = getattr(res, "fit_state", None)
    if st is None:
        return None
    eng, prob = st.eng, st.eng.prob
    inp = instrument_inputs(prob, laser_budget, ballbar_budget)
    if model_from_the_data:
        # every input that is a function of the target alone (the scale errors, a
        # target's linearity) moves the position-only model with the readings
        inp.grouped = []
        inp.systematic = [x for x in inp.systematic if x.name.startswith("ballbar")]
    sig2 = st.s2 / np.maximum(st.W, 1e-300) ** 2
    per_key: dict[str, dict[str, Any]] = {}
    fns: list[tuple[str, Callable[[np.ndarray], float], slice]] = []
    u_time_constant: dict[str, float] = {}   # a drift's time-constant line (not simulated)
    extra_u: dict[str, float] = {}   # u of the lines the describe interval does not carry
    whole: set[int] = set()   # the ramps some effect takes with the selection fixed
    if st.selected:
        X, L, _ = _final_design(st)
        _, p_fin = apply_selection(eng, st.selected, st.values)
        # a drift's rate under the grid's other warm-up time constants (the same mixture its
        # 95 % interval is: shape.drift_tau_average): the spread about the value reported
        from abbe.diagnose.shape import drift_tau_average
        tau_avg = drift_tau_average(eng, st.selected, st.values, st.W, st.s2)
        L_free = {a: free_scale_L(st, X, freed_columns(st, freed_with(inp, st, a)))
                  for a in free_scale_axes(inp, st)}
        k0 = 0
        for s, v in zip(st.selected, st.values):
            n = len(v)
            C = st.cov[k0:k0 + n, k0:k0 + n]
            fn = _headline_fn(eng, s, C)
            g = _grad(fn, np.asarray(v, dtype=np.float64), C)
            sens = g @ L[k0:k0 + n]
            s_free = {a: g @ Lf[k0:k0 + n] for a, Lf in L_free.items()}
            u_fit = math.sqrt(max(float(g @ C @ g), 0.0))
            whole |= {i for i, x in enumerate(inp.systematic) if x.ramp_axis in s_free and (
                abs(float(s_free[x.ramp_axis] @ x.pattern)) - abs(float(sens @ x.pattern)))
                * x.sd > 0.1 * u_fit}   # beyond a tenth of the fit's own part
            lines = {"fit (Type A: noise, lack of fit)": u_fit, **_line_u(sens, inp, s_free)}
            extra = sum(x * x for x in lines.values()) - u_fit ** 2
            if s.cand.spec.kind == "tool_offset":
                # the model's angular uncertainty along the lever (the selection's sigma_m),
                # already in the interval (describe.tool_model_cov)
                from abbe.diagnose.describe import tool_model_cov
                _, f = tool_model_cov(eng, s.cand, np.asarray(v, dtype=np.float64), C)
                lines[TABLE_LINE] = math.sqrt(max(f * f - 1.0, 0.0)) * u_fit
            elif table_cov:
                from abbe.diagnose.table_uncertainty import table_u
                # the derivative by the model's own coefficients (the table as loaded: the
                # effects may add rows), at the final prediction parameters
                lines[TABLE_LINE] = table_u(eng, eng.table, p_fin, sens, table_cov)
                extra += lines[TABLE_LINE] ** 2
            extra_u[s.cand.spec.key] = math.sqrt(max(extra, 0.0))
            ta = tau_avg.get(s.cand.spec.key)
            u_tau = 0.0
            if ta is not None:
                v0 = fn(np.asarray(v))
                u_tau = math.sqrt(sum(a["weight"] * (a["value"] - v0) ** 2
                                      for a in ta["alternatives"]))
                lines["drift time constant (the grid's alternatives, BIC weights)"] = u_tau
            u = math.sqrt(sum(x * x for x in lines.values()))
            per_key[s.cand.spec.key] = {"value": fn(np.asarray(v)), "u": u, "U": K * u,
                                        "budget_u": lines}
            # the Monte Carlo's draws simulate neither line: added to its U in quadrature
            u_time_constant[s.cand.spec.key] = math.hypot(u_tau, lines.get(TABLE_LINE, 0.0))
            fns.append((s.cand.spec.key, fn, slice(k0, k0 + n)))
            k0 += n
    else:
        X = np.zeros((prob.N, 0))
        L = np.zeros((0, prob.N))
    # gaps. Before: the base model is fixed, r_b(y') = P_n (y' - y0): M^T = P_n.
    clean_b = np.concatenate(res.residual_before)
    clean_a = np.concatenate(res.residual_after)
    # no um-valued sample (angular channels only): no gap figure, no U
    no_gap = res.gap.get("before") is None or res.gap.get("after") is None
    gaps: dict[str, Any] = {} if no_gap else {"before": _gap_lines(
        prob, clean_b, lambda a: _nuisance_removal_T(prob, a), sig2, inp,
        lambda p: remove_nuisance(prob, p))}

    def back_after(a: np.ndarray) -> np.ndarray:
        # r_a(y') = P_n (y' - X L y'): M^T a = (I - L^T X^T) P_n a
        pa = _nuisance_removal_T(prob, a)
        return pa - L.T @ (X.T @ pa)
    if not no_gap:
        gaps["after"] = _gap_lines(prob, clean_a, back_after, sig2, inp,
                                   lambda p: remove_nuisance(prob, p - X @ (L @ p)))
    out: dict[str, Any] = {
        "k": K, "method": "GUM first order: the final fit's covariance (Type A) and the "
                          "instruments' inputs through the fit's linear operator (Type B)",
        "budgets": inp.budgets,
        "assumptions": [
            "the selection (which effects, their grid values) held fixed; a drift's warm-up "
            "time constant has its own line (the rate under the grid's other time constants)",
            *(["the position-only model is built from these readings (each target's mean): "
               "an error that depends on the target alone (the scale errors, a target's "
               "linearity) moves it too and cancels; left out"]
              if model_from_the_data else
              ["the model held fixed: an instrument error shared by the model's own "
               "measurement and this check (the same laser file) is counted as independent "
               "(conservative)"]),
            "laser lines: instrument inputs on the own positioning channel only (the budget "
            "has no figure for straightness and angular optics); results not normalised to "
            "20 deg C (temp_deviation_c)",
            "gap max |r|: first order at the sample that makes it (the samples compete for "
            "the max; the Monte Carlo states its U where they part)"],
        "effects": per_key, "gap": gaps,
    }
    if draws:
        out["monte_carlo"] = _monte_carlo(res, st, inp, sig2, fns, draws, seed, per_key, gaps,
                                          u_time_constant, whole)
    _attach(res, per_key, gaps)
    _widen(res, extra_u)
    res.uncertainty = _round(out)
    return res.uncertainty


def _refitter(st: FitState, iterations: int = 4) -> Callable[[np.ndarray], list[np.ndarray]]:
    """The final fit of new readings, nonlinear: Gauss-Newton from the solution, each step's
    residual through the model (the C library, every effect applied), the Jacobian at the
    solution steering the steps (as the chain's and the trunnion's Monte Carlo do); the
    set-up nuisance refitted with it. Its fixed point is the weighted least squares of the
    model on the new readings (to the Jacobian's change over the draws' spread)."""
    eng, prob = st.eng, st.eng.prob
    X, _, _ = _final_design(st)
    A = np.hstack([prob.nuis, X]) * st.W[:, None]
    P = np.linalg.pinv(A)
    k0 = prob.nuis.shape[1]
    sizes = [len(v) for v in st.values]
    theta0 = np.concatenate([np.asarray(v, dtype=np.float64) for v in st.values])

    def refit(y_new: np.ndarray) -> list[np.ndarray]:
        theta = theta0.copy()
        for _ in range(iterations):
            vals = np.split(theta, np.cumsum(sizes)[:-1])
            t, p = apply_selection(eng, st.selected, vals)
            r = (y_new - prob.predict(eng.ev, t, p)) * st.W
            step = (P @ r)[k0:]
            theta = theta + step
            if np.max(np.abs(step)) <= 1e-6 * max(float(np.max(np.abs(theta))), 1e-9):
                break
        return list(np.split(theta, np.cumsum(sizes)[:-1]))
    return refit


def _monte_carlo(res: Any, st: FitState, inp: Inputs, sig2: np.ndarray,
                 fns: list[tuple[str, Callable[[np.ndarray], float], slice]], draws: int,
                 seed: int, per_key: dict[str, Any], gaps: dict[str, Any],
                 u_time_constant: dict[str, float] | None = None,
                 whole: set[int] | None = None) -> dict[str, Any]:
    from abbe.diagnose.effects import fold_reversal
    from abbe.diagnose.checks import DEFAULT_TAKEUP_MM
    from abbe.diagnose.problem import gap_stats
    eng, prob = st.eng, st.eng.prob
    rng = np.random.default_rng(seed)
    refit = _refitter(st) if st.selected else None
    # a ramp moves the effects through the scales it would name: their refit takes each draw
    # without the part those scales take (scale_free.absorbed) where the first order did so
    # for every effect (else whole: one that parts states the MC's U); the gaps take it whole
    free = free_scale_axes(inp, st) if st.selected else []
    X = _final_design(st)[0] if free else np.zeros((prob.N, 0))
    eff_pattern = {i: -absorbed(st, X, freed_columns(st, freed_with(inp, st, str(x.ramp_axis))),
                                x.pattern) for i, x in enumerate(inp.systematic)
                   if x.ramp_axis in free and i not in (whole or set())}
    sd = np.sqrt(sig2)
    names = [k for k, _, _ in fns] + ["before.rms_um", "before.max_um", "after.rms_um",
                                      "after.max_um"]
    F = np.full((draws, len(names)), np.nan)
    for d in range(draws):
        dy = rng.normal(0.0, 1.0, prob.N) * sd
        dy_eff = np.zeros(prob.N)   # what the scales the ramps would name take back
        for i, x in enumerate(inp.systematic):
            t_x = x.draw(rng)
            dy += t_x * x.pattern
            dy_eff += t_x * eff_pattern.get(i, 0.0)
        for g in inp.grouped:
            m = g.labels >= 0
            e = rng.uniform(-g.half_um, g.half_um, int(g.labels[m].max()) + 1)
            dy[m] += e[g.labels[m]]
        for r in inp.per_reading:
            dy += rng.uniform(-1.0, 1.0, prob.N) * r.half_um
        y_new = prob.y + dy
        row = []
        if refit is not None:
            vals = refit(y_new + dy_eff)
            row += [fn(np.asarray(v)) for (_, fn, _), v in zip(fns, vals)]
            if eff_pattern:
                vals = refit(y_new)
            t, pp = apply_selection(eng, st.selected, vals)
            t, pp = fold_reversal(t, pp, DEFAULT_TAKEUP_MM)
            r_after = y_new - prob.predict(eng.ev, t, pp)
        else:
            r_after = y_new - eng.y0
        gb = gap_stats(prob, remove_nuisance(prob, y_new - eng.y0))
        ga = gap_stats(prob, remove_nuisance(prob, r_after))
        row += [gb.rms_um, gb.max_um, ga.rms_um, ga.max_um] if gb and ga else [np.nan] * 4
        F[d] = row
    out: dict[str, Any] = {"draws": draws, "seed": seed, "figures": {}}
    n_ok = 0
    for j, name in enumerate(names):
        col = F[:, j][np.isfinite(F[:, j])]
        U_mc = K * float(np.std(col, ddof=1)) if col.size > 1 else float("nan")
        which, _, fig = name.partition(".")
        tgt = per_key.get(name) if not fig else gaps.get(which, {}).get(fig)
        if tgt is None:
            continue
        # the draws hold the selection and the table fixed: they check the first order's
        # propagation of the noise and the instruments, not a drift's time-constant line nor
        # the table's line, which are added to either in quadrature
        U_sel = K * float((u_time_constant or {}).get(name, 0.0)) if not fig else 0.0
        U_fo = math.sqrt(max(tgt["U"] ** 2 - U_sel ** 2, 0.0))
        ratio = U_mc / U_fo - 1.0 if U_fo > 0 else float("nan")
        agree = bool(abs(ratio) <= AGREEMENT)
        n_ok += agree
        tgt["U_first_order"] = tgt["U"]
        tgt["U_mc"] = U_mc
        tgt["mc_agreement"] = ratio
        tgt["mc_interval95"] = [float(np.percentile(col, 2.5)), float(np.percentile(col, 97.5))]
        if not agree:
            U_new = math.sqrt(U_mc ** 2 + U_sel ** 2)
            tgt["U"], tgt["u"] = U_new, U_new / K
        tgt["U_from"] = "first order" if agree else "Monte Carlo"
        out["figures"][name] = {"U": tgt["U_first_order"], "U_mc": U_mc, "agreement": ratio}
    out["agree_within_10pct"] = n_ok
    out["of"] = len(out["figures"])
    return out


def _attach(res: Any, per_key: dict[str, Any], gaps: dict[str, Any]) -> None:
    def put(d: Any, u: dict[str, Any]) -> None:
        keys = ("u", "U", "budget_u", "U_first_order", "U_mc", "mc_agreement", "U_from")
        src = {k: u[k] for k in keys if k in u}
        if isinstance(d, dict):
            d.update(_round(src))
        else:
            d.uncertainty = _round(src)
    for e in res.effects:
        if e.key in per_key:
            put(e, per_key[e.key])
        for c in e.components:
            if c["key"] in per_key:
                put(c, per_key[c["key"]])
    res.gap_uncertainty = _round(gaps)


def _widen(res: Any, extra_u: dict[str, float]) -> None:
    """Each named effect's 95 % interval (describe: Student t on the fit's covariance, a
    tool offset's model inflation, a drift's time-constant mixture) with the budget lines
    it did not carry (the instruments', the table's) added in quadrature to each
    half-width at k = 2: the interval the report states then contains the whole budget."""
    def wid(v: float, ci: Any, u: float) -> list[float]:
        lo, hi = float(ci[0]), float(ci[1])
        return [float(f"{v - math.hypot(v - lo, K * u):.6g}"),
                float(f"{v + math.hypot(hi - v, K * u):.6g}")]
    for e in res.effects:
        u = extra_u.get(e.key, 0.0)
        if u > 0 and e.ci95 is not None:
            # the fit's part alone, kept for the reader who compares with earlier reports
            e.evidence["ci95_fit_only"] = [float(e.ci95[0]), float(e.ci95[1])]
            e.evidence["u_not_in_fit_interval"] = float(f"{u:.6g}")
            e.ci95 = wid(float(e.value), e.ci95, u)
            if len(e.params) == 1:
                e.params[0]["ci95"] = wid(float(e.params[0]["value"]), e.params[0]["ci95"], u)
        for c in e.components:
            uc = extra_u.get(c["key"], 0.0)
            if uc > 0 and c.get("ci95") is not None:
                c["ci95"] = wid(float(c["value"]), c["ci95"], uc)


def _round(o: Any) -> Any:
    if isinstance(o, float):
        return float(f"{o:.6g}") if math.isfinite(o) else None
    if isinstance(o, dict):
        return {k: _round(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_round(v) for v in o]
    return o
