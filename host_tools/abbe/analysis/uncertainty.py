"""Measurement uncertainty of ISO 230-2 and ISO 230-4 results (ISO/TR 230-9, GUM) and the
ISO 14253-1 verdict against a tolerance (docs/uncertainty.md).

The analytic budget is the GUM's law of propagation, first order: each input's standard
uncertainty u_i times its sensitivity c_i, combined in quadrature, U = 2 u_c (k = 2).
The independent check, :func:`monte_carlo_iso230_2` / :func:`monte_carlo_ballbar`
(GUM Supplement 1), draws every input and runs the unchanged evaluation
(:func:`abbe.analysis.iso230_2.evaluate`, :func:`abbe.analysis.iso230_4.evaluate_ballbar`)
on each draw; it shares no formula with the budget.

Units: um for results, mm for positions, ppm for scale errors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from abbe.analysis.iso230_2 import Iso230Result, evaluate
from abbe.formats.deviations import PositioningData
from abbe.formats.thermal20 import APPLIED, BY_INSTRUMENT, REFERENCE_C
from abbe.formats.uncertainty_spec import Budget

K = 2.0
SQRT3 = math.sqrt(3.0)
#: Refractive index of air, sensitivities at 20 deg C, 1013.25 hPa, 50 %RH (Edlen 1966,
#: Birch & Downs 1993): ppm per K, per hPa, per %RH (magnitudes).
N_AIR_PPM_PER_K = 0.93
N_AIR_PPM_PER_HPA = 0.27
N_AIR_PPM_PER_PCT = 0.0085
QUANTITIES = ("E", "A", "B", "R", "M")
#: Candidates kept for the distribution of a max (bounds the time on flat curves with
#: thousands of targets; the ones left out lie lowest and barely move the max).
MAX_CANDIDATES = 64


@dataclass
class Contribution:
    """One line of a budget: an input, its standard uncertainty, its effect on the result."""

    name: str
    what: str          # the input and its distribution, in words
    u_input: float     # standard uncertainty of the input (its own unit)
    unit: str
    sensitivity: float  # um per unit of the input
    u_um: float        # |sensitivity| x u_input, um

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "what": self.what, "u_input": _r(self.u_input),
                "unit": self.unit, "sensitivity": _r(self.sensitivity), "u_um": _r(self.u_um)}


@dataclass
class Uncertain:
    """A result with its budget, um. ``contributions``: each input's standard uncertainty
    acting alone (first order). ``combined_u_um``: u_c when the evaluation gives it
    directly (ISO 230-2: the targets competing for a max / min, docs/uncertainty.md);
    otherwise u_c is the quadrature sum of the contributions. U = k u_c, k = 2."""

    value_um: float
    contributions: list[Contribution]
    combined_u_um: float | None = None

    @property
    def quadrature_u_um(self) -> float:
        return math.sqrt(sum(c.u_um ** 2 for c in self.contributions))

    @property
    def u_um(self) -> float:
        return self.quadrature_u_um if self.combined_u_um is None else self.combined_u_um

    @property
    def U_um(self) -> float:
        return K * self.u_um

    def to_json(self) -> dict[str, Any]:
        return {"value_um": _r(self.value_um), "u_um": _r(self.u_um), "U_um": _r(self.U_um),
                "k": K, "quadrature_u_um": _r(self.quadrature_u_um),
                "budget": [c.to_json() for c in self.contributions]}


def _r(x: float) -> float:
    return float(round(float(x), 6))


# ------------------------------------------------------------------ decision rule
PASS, FAIL, INCONCLUSIVE = "pass", "fail", "inconclusive"


def verdict(value_um: float, U_um: float, limit_um: float) -> str:
    """ISO 14253-1 for an upper limit T: pass when value + U <= T (conformance proven),
    fail when value - U > T (non-conformance proven), inconclusive otherwise (the result
    lies within U of the limit)."""
    if value_um + U_um <= limit_um:
        return PASS
    if value_um - U_um > limit_um:
        return FAIL
    return INCONCLUSIVE


def verdicts(results: dict[str, Uncertain], limits: dict[str, float]) -> dict[str, Any]:
    """Verdict per stated limit (keys like ``E_um``); quantities without a limit are left out."""
    out: dict[str, Any] = {}
    for key, lim in limits.items():
        q = key[:-3]
        if q in results:
            r = results[q]
            out[key] = {"value_um": _r(r.value_um), "U_um": _r(r.U_um), "limit_um": lim,
                        "verdict": verdict(r.value_um, r.U_um, lim)}
    return out


# ------------------------------------------------------------------ ISO 230-2
@dataclass
class ScaleInput:
    """A relative (scale) error of the reading: deviation error = delta x (x - x0)."""

    name: str
    what: str
    u_ppm: float          # standard uncertainty, ppm
    low_ppm: float        # the rectangular distribution drawn by the Monte Carlo
    high_ppm: float


def scale_inputs(budget: Budget, norm: Any) -> list[ScaleInput]:
    """The budget's scale errors (ppm of the distance from the datum), with the 20 deg C
    status of the file deciding which thermal terms apply."""
    f = budget.figures
    out: list[ScaleInput] = []

    def rect(name: str, what: str, a_ppm: float) -> None:
        if a_ppm > 0:
            out.append(ScaleInput(name, what, a_ppm / SQRT3, -a_ppm, a_ppm))

    rect("instrument scale", f"instrument accuracy +-{f['accuracy_ppm']:g} ppm, rectangular",
         f["accuracy_ppm"])
    rect("air temperature", f"air sensor +-{f['air_temp_u_c']:g} deg C x "
         f"{N_AIR_PPM_PER_K} ppm/K, rectangular", f["air_temp_u_c"] * N_AIR_PPM_PER_K)
    rect("air pressure", f"air sensor +-{f['air_pressure_u_hpa']:g} hPa x "
         f"{N_AIR_PPM_PER_HPA} ppm/hPa, rectangular", f["air_pressure_u_hpa"] * N_AIR_PPM_PER_HPA)
    rect("air humidity", f"air sensor +-{f['air_humidity_u_pct']:g} %RH x "
         f"{N_AIR_PPM_PER_PCT} ppm/%RH, rectangular", f["air_humidity_u_pct"] * N_AIR_PPM_PER_PCT)
    status = getattr(norm, "status", None)
    if status in (APPLIED, BY_INSTRUMENT):
        alpha = abs(norm.expansion_ppm_per_k or f["expansion_ppm_per_k"])
        dt = abs((norm.material_temp_c if norm.material_temp_c is not None else REFERENCE_C)
                 - REFERENCE_C)
        rect("material temperature", f"sensor +-{f['material_temp_u_c']:g} deg C x alpha "
             f"{alpha:g} ppm/K, rectangular", f["material_temp_u_c"] * alpha)
        rect("expansion coefficient", f"alpha +-{f['expansion_u_ppm_per_k']:g} ppm/K x "
             f"|T - 20| {dt:.3g} K, rectangular", f["expansion_u_ppm_per_k"] * dt)
    else:
        alpha = abs(f["expansion_ppm_per_k"])
        dev = f["temp_deviation_c"]
        if norm is not None and norm.material_temp_c is not None:
            dev = max(dev, abs(norm.material_temp_c - REFERENCE_C))
        rect("temperature not normalised", f"results as measured: |T - 20| up to {dev:g} K x "
             f"alpha {alpha:g} ppm/K, rectangular", dev * alpha)
    theta = f["misalignment_mrad"] * 1e-3
    cos_ppm = 0.5 * theta ** 2 * 1e6
    if cos_ppm > 0:  # one-sided: the reading is short by up to L theta^2 / 2
        out.append(ScaleInput("misalignment (cosine)", f"beam misalignment up to "
                              f"{f['misalignment_mrad']:g} mrad, rectangular on [0, theta^2/2]",
                              cos_ppm / math.sqrt(12.0), -cos_ppm, 0.0))
    return out


def _air_ppm_u(budget: Budget) -> float:
    f = budget.figures
    return math.sqrt(sum((a / SQRT3) ** 2 for a in (
        f["air_temp_u_c"] * N_AIR_PPM_PER_K, f["air_pressure_u_hpa"] * N_AIR_PPM_PER_HPA,
        f["air_humidity_u_pct"] * N_AIR_PPM_PER_PCT)))


@dataclass
class Iso230Uncertainty:
    """Every ISO 230-2 result with its budget, and the per-target mean deviations."""

    results: dict[str, Uncertain]
    per_target: list[dict[str, Any]]
    budget: Budget
    datum_mm: float
    monte_carlo: dict[str, Any] | None = None
    limits: dict[str, float] = field(default_factory=dict)

    def verdicts(self) -> dict[str, Any]:
        return verdicts(self.results, self.limits)

    def to_json(self) -> dict[str, Any]:
        return {"method": "ISO/TR 230-9, GUM first order; U = k u_c, k = 2",
                "budget_inputs": self.budget.to_json(), "datum_mm": self.datum_mm,
                "results": {q: r.to_json() for q, r in self.results.items()},
                "per_target": self.per_target, "monte_carlo": self.monte_carlo}


def _argext(x: np.ndarray, largest: bool) -> int:
    return int(np.argmax(x) if largest else np.argmin(x))


def iso230_2_uncertainty(res: Iso230Result, budget: Budget,
                         limits: dict[str, float] | None = None) -> Iso230Uncertainty:
    """The analytic budget of E, A, B, R, M (bidirectional) and of each target's mean
    deviations (docs/uncertainty.md, "ISO 230-2"). First order: the targets and
    directions that decide each max / min are held fixed."""
    x = res.targets_mm
    n = res.n_runs
    x0 = float(x[0])  # the laser's datum: the first target (as thermal20 assumes)
    scales = scale_inputs(budget, res.normalisation)
    f = budget.figures
    u_lin = f["linearity_um"] / SQRT3
    u_res = f["resolution_um"] / math.sqrt(12.0)
    xs = np.concatenate([x, x])                   # the 2T (direction, target) means
    means = np.concatenate([res.mean_up_um, res.mean_down_um])
    sds = np.concatenate([res.s_up_um, res.s_down_um])
    u_mean = sds / math.sqrt(n)                   # type A: a mean of n runs
    u_sd = sds / math.sqrt(2.0 * (n - 1))         # type A: a standard deviation of n runs

    def instrument(lever_mm: float, same_target: bool, n_points: int) -> list[Contribution]:
        """Contributions of the instrument to a difference of readings lever_mm apart
        (n_points independent target readings; 0 lever and same target: all cancel)."""
        out = []
        for s in scales:
            if lever_mm > 0:
                out.append(Contribution(s.name, s.what, s.u_ppm, "ppm", lever_mm * 1e-3,
                                        abs(lever_mm) * 1e-3 * s.u_ppm))
        if not same_target and u_lin > 0:
            out.append(Contribution("linearity", f"+-{f['linearity_um']:g} um per target, "
                                    "rectangular, independent between targets", u_lin, "um",
                                    math.sqrt(n_points), math.sqrt(n_points) * u_lin))
        if u_res > 0:
            c = math.sqrt(n_points / n)
            out.append(Contribution("resolution", f"+-{f['resolution_um'] / 2:g} um per "
                                    f"reading, rectangular, mean of {n}", u_res, "um", c,
                                    c * u_res))
        return out

    results: dict[str, Uncertain] = {}
    # E: the largest minus the smallest of the 2T means
    a, b = _argext(means, True), _argext(means, False)
    lever = abs(xs[a] - xs[b])
    cs = [Contribution("repeatability (max)", f"s / sqrt(n) of the mean at {xs[a]:g} mm",
                       u_mean[a], "um", 1.0, u_mean[a]),
          Contribution("repeatability (min)", f"s / sqrt(n) of the mean at {xs[b]:g} mm",
                       u_mean[b], "um", 1.0, u_mean[b])]
    results["E"] = Uncertain(res.E_um, cs + instrument(lever, xs[a] == xs[b], 2))
    # M: range of the bidirectional means (x_up + x_down) / 2
    mid = 0.5 * (res.mean_up_um + res.mean_down_um)
    u_mid = 0.5 * np.sqrt(res.s_up_um ** 2 + res.s_down_um ** 2) / math.sqrt(n)
    a, b = _argext(mid, True), _argext(mid, False)
    cs = [Contribution("repeatability (max)", f"of (x_up + x_down) / 2 at {x[a]:g} mm",
                       u_mid[a], "um", 1.0, u_mid[a]),
          Contribution("repeatability (min)", f"of (x_up + x_down) / 2 at {x[b]:g} mm",
                       u_mid[b], "um", 1.0, u_mid[b])]
    results["M"] = Uncertain(res.M_um, cs + instrument(abs(x[a] - x[b]), a == b, 2))
    # A: max(x + 2 s) - min(x - 2 s)
    a, b = _argext(means + 2 * sds, True), _argext(means - 2 * sds, False)
    cs = [Contribution("repeatability (max)", f"mean and 2 s at {xs[a]:g} mm", math.hypot(
        u_mean[a], 2 * u_sd[a]), "um", 1.0, math.hypot(u_mean[a], 2 * u_sd[a])),
        Contribution("repeatability (min)", f"mean and 2 s at {xs[b]:g} mm", math.hypot(
            u_mean[b], 2 * u_sd[b]), "um", 1.0, math.hypot(u_mean[b], 2 * u_sd[b]))]
    results["A"] = Uncertain(res.A_um, cs + instrument(abs(xs[a] - xs[b]), xs[a] == xs[b], 2))
    # B: max |x_up - x_down| at one target: the instrument's scale and linearity cancel
    i = int(np.argmax(np.abs(res.reversal_um)))
    ub = math.hypot(u_mean[i], u_mean[i + x.size])
    results["B"] = Uncertain(res.B_um, [Contribution(
        "repeatability", f"s / sqrt(n) of both means at {x[i]:g} mm", ub, "um", 1.0, ub)]
        + instrument(0.0, True, 2))
    # R: max_i of max(2 s_up + 2 s_dn + |B_i|, 4 s_up, 4 s_dn)
    i = int(np.argmax(res.repeatability_um))
    su, sd_ = res.s_up_um[i], res.s_down_um[i]
    cand = [2 * su + 2 * sd_ + abs(res.reversal_um[i]), 4 * su, 4 * sd_]
    which = int(np.argmax(cand))
    uu, ud = u_sd[i], u_sd[i + x.size]
    if which == 0:
        ur = math.sqrt((2 * uu) ** 2 + (2 * ud) ** 2 + u_mean[i] ** 2 + u_mean[i + x.size] ** 2)
        what = f"2 s_up + 2 s_down + |B_i| at {x[i]:g} mm; u(s) = s / sqrt(2 (n - 1))"
    else:
        ur = 4 * (uu if which == 1 else ud)
        what = f"4 s at {x[i]:g} mm; u(s) = s / sqrt(2 (n - 1))"
    results["R"] = Uncertain(res.R_um, [Contribution("repeatability", what, ur, "um", 1.0, ur)])
    # per target: each mean deviation (the instrument does not cancel: lever x - x0, and the
    # dead path's air contribution shifts every reading)
    u_air = _air_ppm_u(budget)
    u_dead = f["dead_path_mm"] * 1e-3 * u_air
    lever = np.abs(xs - x0) * 1e-3
    u2 = (u_mean ** 2 + u_lin ** 2 + u_res ** 2 / n + u_dead ** 2
          + lever ** 2 * sum(s.u_ppm ** 2 for s in scales))
    U_t = K * np.sqrt(u2)
    T = x.size
    per_target = [{"target_mm": float(x[j]), "mean_up_um": _r(means[j]),
                   "U_mean_up_um": _r(U_t[j]), "mean_down_um": _r(means[T + j]),
                   "U_mean_down_um": _r(U_t[T + j])} for j in range(T)]
    for q, u in _competing_u(res, budget, scales).items():
        results[q].combined_u_um = u
    return Iso230Uncertainty(results, per_target, budget, x0, limits=dict(limits or {}))


def _delta_density(scales: list[ScaleInput], points: int = 41) -> tuple[np.ndarray, np.ndarray]:
    """The distribution of the summed scale error (ppm): the convolution of its rectangular
    inputs, on ``points`` nodes with weights summing to 1."""
    if not scales:
        return np.zeros(1), np.ones(1)
    lo = sum(s.low_ppm for s in scales)
    hi = sum(s.high_ppm for s in scales)
    fine = 2001
    h = (hi - lo) / (fine - 1)
    dens = np.zeros(1)
    dens[0] = 1.0
    for s in scales:
        width = int(round((s.high_ppm - s.low_ppm) / h))
        dens = np.convolve(dens, np.ones(max(width, 1)) / max(width, 1))
    grid = lo + h * np.arange(dens.size) if dens.size > 1 else np.array([lo])
    # re-bin onto ``points`` nodes (mass-preserving)
    edges = np.linspace(grid[0], grid[-1] + 1e-12, points + 1)
    idx = np.clip(np.searchsorted(edges, grid, side="right") - 1, 0, points - 1)
    w = np.bincount(idx, weights=dens, minlength=points)
    nodes = np.bincount(idx, weights=dens * grid, minlength=points)
    keep = w > 0
    return nodes[keep] / w[keep], w[keep] / w.sum()


def _max_moments(mu: np.ndarray, sigma: np.ndarray) -> tuple[float, float]:
    """Mean and variance of the largest of independent normals N(mu_i, sigma_i^2), from its
    CDF prod Phi((y - mu_i) / sigma_i) integrated on a grid."""
    from scipy.special import log_ndtr
    sig = np.maximum(sigma, max(1e-6, 1e-3 * float(np.max(sigma))))
    c = float(np.max(mu))
    m = mu - c
    lo = float(np.max(m - 9 * sig))
    hi = float(np.max(m + 9 * sig))
    # candidates entirely below lo never make the max (their CDF is 1 on the grid)
    keep = m + 9 * sig >= lo
    m, sig = m[keep], sig[keep]
    if m.size > MAX_CANDIDATES:  # many ties (a flat curve): the top ones decide the max
        top = np.argsort(m + 3 * sig)[-MAX_CANDIDATES:]
        m, sig = m[top], sig[top]
    y = np.linspace(lo, hi, 801)
    logF = np.zeros_like(y)
    for k in range(0, m.size, 256):  # bounded memory for many competing candidates
        logF += np.sum(log_ndtr((y[:, None] - m[None, k:k + 256]) / sig[None, k:k + 256]),
                       axis=1)
    F = np.exp(logF)
    mean = hi - np.trapezoid(F, y)
    second = hi * hi - np.trapezoid(2 * y * F, y)
    return c + float(mean), max(float(second - mean * mean), 0.0)


def _competing_u(res: Iso230Result, budget: Budget, scales: list[ScaleInput]
                 ) -> dict[str, float]:
    """u_c of E, A, M, B, R with the targets competing for each max / min: the exact
    distribution of a max of independent normal candidates (repeatability, linearity and
    resolution per target), averaged over the distribution of the common scale error
    (law of total variance). No random draws."""
    x = res.targets_mm
    n = res.n_runs
    x0 = float(x[0])
    f = budget.figures
    u_lin = f["linearity_um"] / SQRT3
    u_res2 = (f["resolution_um"] ** 2 / 12.0) / n
    xs = np.concatenate([x, x])
    means = np.concatenate([res.mean_up_um, res.mean_down_um])
    sds = np.concatenate([res.s_up_um, res.s_down_um])
    u_mean = sds / math.sqrt(n)
    u_sd = sds / math.sqrt(2.0 * (n - 1))
    s_e = np.sqrt(u_mean ** 2 + u_lin ** 2 + u_res2)
    s_a = np.sqrt(u_mean ** 2 + 4 * u_sd ** 2 + u_lin ** 2 + u_res2)
    mid = 0.5 * (res.mean_up_um + res.mean_down_um)
    s_m = np.sqrt(0.25 * (res.s_up_um ** 2 + res.s_down_um ** 2) / n + u_lin ** 2 + u_res2)
    nodes, w = _delta_density(scales)
    acc: dict[str, list[tuple[float, float]]] = {"E": [], "A": [], "M": []}
    for d in nodes:
        tilt = d * 1e-3 * (xs - x0)
        hi_m, hi_v = _max_moments(means + tilt, s_e)
        lo_m, lo_v = _max_moments(-(means + tilt), s_e)
        acc["E"].append((hi_m + lo_m, hi_v + lo_v))
        hi_m, hi_v = _max_moments(means + 2 * sds + tilt, s_a)
        lo_m, lo_v = _max_moments(-(means - 2 * sds + tilt), s_a)
        acc["A"].append((hi_m + lo_m, hi_v + lo_v))
        t = tilt[: x.size]
        hi_m, hi_v = _max_moments(mid + t, s_m)
        lo_m, lo_v = _max_moments(-(mid + t), s_m)
        acc["M"].append((hi_m + lo_m, hi_v + lo_v))
    out = {}
    for q, mv in acc.items():
        m = np.array([a for a, _ in mv])
        v = np.array([b for _, b in mv])
        mbar = float(np.sum(w * m))
        out[q] = math.sqrt(max(float(np.sum(w * (v + m * m))) - mbar * mbar, 0.0))
    T = x.size
    u_b = np.sqrt(u_mean[:T] ** 2 + u_mean[T:] ** 2)
    out["B"] = math.sqrt(_max_moments(np.abs(res.reversal_um), u_b)[1])
    su, sd_ = res.s_up_um, res.s_down_um
    uu, ud = u_sd[:T], u_sd[T:]
    branch = np.stack([2 * su + 2 * sd_ + np.abs(res.reversal_um), 4 * su, 4 * sd_])
    u_branch = np.stack([np.sqrt(4 * uu ** 2 + 4 * ud ** 2 + u_b ** 2), 4 * uu, 4 * ud])
    k = np.argmax(branch, axis=0)
    cols = np.arange(T)
    out["R"] = math.sqrt(_max_moments(branch[k, cols], u_branch[k, cols])[1])
    return out


def monte_carlo_iso230_2(data: PositioningData, res: Iso230Result, budget: Budget,
                         draws: int = 4000, seed: int = 20230) -> dict[str, Any]:
    """GUM Supplement 1 check: ``draws`` new data sets, each with new runs drawn about the
    measured means with the measured standard deviations (normal; the machine's
    repeatability) plus one draw of every instrument input (the scale errors, a
    linearity error per target, a resolution error per reading), each run through
    :func:`abbe.analysis.iso230_2.evaluate`. Returns per quantity the mean, the
    standard deviation (2 x it is U_MC) and the 95 % probabilistically symmetric interval."""
    rng = np.random.default_rng(seed)
    x = np.asarray(res.targets_mm, dtype=np.float64)
    n = res.n_runs
    x0 = float(x[0])
    scales = scale_inputs(budget, res.normalisation)
    f = budget.figures
    out: dict[str, list[float]] = {q: [] for q in QUANTITIES}
    for _ in range(draws):
        delta_ppm = sum(rng.uniform(s.low_ppm, s.high_ppm) for s in scales)
        inst = delta_ppm * 1e-3 * (x - x0)
        if f["linearity_um"] > 0:
            inst = inst + rng.uniform(-f["linearity_um"], f["linearity_um"], size=x.size)
        sets = []
        for mean, sd in ((res.mean_up_um, res.s_up_um), (res.mean_down_um, res.s_down_um)):
            runs = mean + sd * rng.standard_normal((n, x.size)) + inst
            if f["resolution_um"] > 0:
                half = 0.5 * f["resolution_um"]
                runs = runs + rng.uniform(-half, half, size=runs.shape)
            sets.append(runs)
        r = evaluate(PositioningData("monte carlo", x, sets[0], sets[1],
                                     normalisation=res.normalisation))
        for q in QUANTITIES:
            out[q].append(getattr(r, f"{q}_um"))
    return {"draws": draws, "seed": seed, "method": (
        "GUM Supplement 1: new runs about the measured means with the measured s, plus every "
        "instrument input drawn, through the same ISO 230-2 evaluation; U_MC = 2 x std"),
        "results": {q: _mc_summary(np.asarray(v)) for q, v in out.items()}}


def _mc_summary(v: np.ndarray) -> dict[str, float]:
    lo, hi = np.quantile(v, [0.025, 0.975])
    return {"mean_um": _r(v.mean()), "u_um": _r(v.std(ddof=1)), "U_um": _r(K * v.std(ddof=1)),
            "interval95_um": [_r(lo), _r(hi)]}


def agreement(analytic: dict[str, Uncertain], mc: dict[str, Any]) -> dict[str, float]:
    """U_MC / U_analytic - 1 per quantity (the 10 % criterion of docs/uncertainty.md)."""
    out = {}
    for q, r in analytic.items():
        m = mc["results"].get(q)
        if m is not None and r.U_um > 0:
            out[q] = _r(m["U_um"] / r.U_um - 1.0)
    return out


# ------------------------------------------------------------------ ISO 230-4
@dataclass
class BallbarUncertainty:
    """G (per direction and bidirectional), H, radius deviation with their budgets."""

    results: dict[str, Uncertain]
    budget: Budget
    monte_carlo: dict[str, Any] | None = None
    limits: dict[str, float] = field(default_factory=dict)

    def verdicts(self) -> dict[str, Any]:
        # the circularity tolerance applies to the bidirectional G
        res = {"G": self.results["G_bidirectional"], "H": self.results["H"]}
        return verdicts(res, self.limits)

    def to_json(self) -> dict[str, Any]:
        return {"method": "ISO/TR 230-9, GUM first order; U = k u_c, k = 2",
                "budget_inputs": self.budget.to_json(),
                "results": {q: r.to_json() for q, r in self.results.items()},
                "monte_carlo": self.monte_carlo}


def _ballbar_values(res: Any) -> dict[str, float]:
    return {"G_ccw": res.per_direction["ccw"].G_um, "G_cw": res.per_direction["cw"].G_um,
            "G_bidirectional": res.both.G_um, "H": res.H_um,
            "radius_dev": res.both.radius_dev_um}


def _perturbed(trace: Any, radial_um: np.ndarray) -> Any:
    import copy
    t = copy.copy(trace)
    t.radial_um = radial_um
    return t


def ballbar_budget(machine: Any) -> tuple[Budget, dict[str, float]]:
    """The machine file's ``[uncertainty.ballbar]`` budget (else the ballbar class
    defaults, docs/uncertainty.md) and its ISO 230-4 tolerances (um; empty: none)."""
    from abbe.formats.uncertainty_spec import default_budget
    spec = machine.extra.get("uncertainty")
    budget = spec.ballbar if spec is not None and spec.ballbar is not None else None
    if budget is None:
        budget = default_budget("ballbar")
        budget.source = "class defaults (docs/uncertainty.md)"
    limits = dict(spec.tolerances.get("ballbar", {})) if spec is not None else {}
    return budget, limits


def ballbar_uncertainty(trace: Any, test: Any, res: Any, budget: Budget,
                        limits: dict[str, float] | None = None) -> BallbarUncertainty:
    """Analytic budget of the ballbar results (docs/uncertainty.md, "ISO 230-4").

    Sensitivities of the scale and drift inputs are finite differences of the same
    evaluation (GUM 5.1.3 allows numerical sensitivity coefficients); resolution acts on
    the two readings that make each max - min; calibration and bar temperature act on the
    radius deviation only (a change of the bar's length moves every reading alike, which
    the least-squares circle absorbs)."""
    from abbe.analysis.iso230_4 import evaluate_ballbar
    f = budget.figures
    base = _ballbar_values(res)
    r = np.asarray(trace.radial_um, dtype=np.float64)
    L_mm = float(test.radius_mm)
    # scale: the reading deviation (um) is off by a relative error eps
    eps = 1e-3
    sc = _ballbar_values(evaluate_ballbar(_perturbed(trace, r * (1 + eps)), test))
    # drift: the bar's length changes linearly over the test by alpha dT L
    ramp = _ramp(trace)
    d_um = 1.0
    dr = _ballbar_values(evaluate_ballbar(_perturbed(trace, r + d_um * ramp), test))
    u_scale = f["scale_pct"] / 100.0 / SQRT3
    drift_um = abs(f["expansion_ppm_per_k"]) * f["drift_c"] * L_mm * 1e-3
    u_drift = drift_um / SQRT3
    u_res = f["resolution_um"] / math.sqrt(12.0)
    out: dict[str, Uncertain] = {}
    for q, v in base.items():
        cs = []
        c = (sc[q] - v) / eps
        if u_scale > 0:
            cs.append(Contribution("scale", f"reading scale +-{f['scale_pct']:g} %, rectangular",
                                   u_scale, "1", c, abs(c) * u_scale))
        c = (dr[q] - v) / d_um
        if u_drift > 0:
            cs.append(Contribution("thermal drift", f"bar / machine {f['drift_c']:g} K during "
                                   f"the test x alpha x {L_mm:g} mm = {drift_um:.3g} um ramp, "
                                   "rectangular", u_drift, "um", c, abs(c) * u_drift))
        if q == "radius_dev":
            ucal = f["calibration_U_um"] / K
            cs.append(Contribution("length calibration", f"calibrator U = "
                                   f"{f['calibration_U_um']:g} um (k = 2)", ucal, "um", 1.0, ucal))
            ut = abs(f["expansion_ppm_per_k"]) * f["bar_temp_u_c"] / SQRT3 * L_mm * 1e-3
            cs.append(Contribution("bar temperature", f"+-{f['bar_temp_u_c']:g} K x alpha x "
                                   f"{L_mm:g} mm, rectangular", f["bar_temp_u_c"] / SQRT3, "K",
                                   abs(f["expansion_ppm_per_k"]) * L_mm * 1e-3, ut))
            if f["resolution_um"] > 0:
                cs.append(Contribution("resolution", "averaged over the circle", u_res, "um",
                                       0.0, 0.0))
        elif u_res > 0 and q == "H":
            # H compares a CCW reading with a CW value interpolated linearly between two
            # readings: variance factor 1 + mean over the weight w of (w^2 + (1 - w)^2) = 5/3
            c = math.sqrt(5.0 / 3.0)
            cs.append(Contribution("resolution", f"+-{f['resolution_um'] / 2:g} um per "
                                   "reading, rectangular; one CCW reading against an "
                                   "interpolated CW value", u_res, "um", c, c * u_res))
        elif u_res > 0:
            cs.append(Contribution("resolution", f"+-{f['resolution_um'] / 2:g} um at the two "
                                   "readings of max - min, rectangular", u_res, "um",
                                   math.sqrt(2.0), math.sqrt(2.0) * u_res))
        out[q] = Uncertain(v, cs)
    return BallbarUncertainty(out, budget, limits=dict(limits or {}))


def _ramp(trace: Any) -> np.ndarray:
    """0 at the first sample, 1 at the last: the test's time order (its time stamps when
    the trace has them, else the sample order)."""
    t = getattr(trace, "time_s", None)
    if t is None:
        t = np.arange(np.size(trace.radial_um), dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    span = float(t.max() - t.min())
    return (t - t.min()) / span if span > 0 else np.zeros_like(t)


def monte_carlo_ballbar(trace: Any, test: Any, budget: Budget, draws: int = 200,
                        seed: int = 20231) -> dict[str, Any]:
    """GUM Supplement 1 check of the ballbar budget: every input drawn (scale, drift ramp,
    a resolution error per sample, calibration and bar temperature as a length offset),
    through :func:`abbe.analysis.iso230_4.evaluate_ballbar`."""
    from abbe.analysis.iso230_4 import evaluate_ballbar
    rng = np.random.default_rng(seed)
    f = budget.figures
    r = np.asarray(trace.radial_um, dtype=np.float64)
    ramp = _ramp(trace)
    L_mm = float(test.radius_mm)
    drift_um = abs(f["expansion_ppm_per_k"]) * f["drift_c"] * L_mm * 1e-3
    bar_um = abs(f["expansion_ppm_per_k"]) * f["bar_temp_u_c"] * L_mm * 1e-3
    out: dict[str, list[float]] = {}
    for _ in range(draws):
        s = rng.uniform(-1, 1) * f["scale_pct"] / 100.0
        offset = rng.normal(0.0, f["calibration_U_um"] / K) + rng.uniform(-bar_um, bar_um)
        rr = r * (1 + s) + rng.uniform(-drift_um, drift_um) * ramp + offset
        if f["resolution_um"] > 0:
            rr = rr + rng.uniform(-0.5, 0.5, size=rr.shape) * f["resolution_um"]
        vals = _ballbar_values(evaluate_ballbar(_perturbed(trace, rr), test))
        for q, v in vals.items():
            out.setdefault(q, []).append(v)
    return {"draws": draws, "seed": seed, "method": (
        "GUM Supplement 1: every instrument input drawn, through the same ISO 230-4 "
        "evaluation; U_MC = 2 x std"),
        "results": {q: _mc_summary(np.asarray(v)) for q, v in out.items()}}
