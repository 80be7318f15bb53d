"""The discrepancy workflow on five axes: what a location-only model misses.

After a location-only identification (:func:`abbe.analysis.five_axis.identify.identify`
with no error motions), each candidate effect of the catalogue is added in turn
and the whole plan refitted; its held-out sphere-centre residuals (probing
positions left out fold by fold) are compared with the model's, position by
position. An effect is named when (a) every parameter it adds is observable
with the plan, (b) its parameters are significant together (chi-square of the
estimate against its covariance above the :data:`SIGNIFICANCE` quantile: a
Bonferroni level for the catalogue's few candidates) and (c) it predicts the
held-out positions better: their RMS falls by at least :data:`MIN_GAIN` (the
paired t of the per-position improvement and :func:`heldout_beta` are reported). The best
such effect (largest held-out gain) is added and the search repeats (at most
:data:`MAX_EFFECTS`). A named effect whose signature (the part the location
errors cannot take) another candidate reproduces to :data:`AMBIGUITY_R2` is
reported as ambiguous with it, with the test that separates them. Catalogue
(docs/effects.md, section 7):

* ``cyclic <C> k``: an angular positioning error of k cycles per turn
  (``ECC(C)`` harmonic k: an encoder's eccentricity or a gear's runout), urad;
* ``pivot drift <A|B>`` / ``pivot drift C``: the axis line's position drifting
  linearly during the campaign (um/h);
* ``wobble C``: the once-per-turn tilt error motion of the table axis
  (``EAC(C)``, ``EBC(C)``), its counter-rotating part (the rest is the axis
  average line's tilt and the table face's, which the location errors and the
  sphere's place take), urad.

The gap a user means is the systematic part of the held-out dispersion: the
held-out RMS less, in quadrature, what a right model would show on this plan
(the sphere centres' noise plus the scatter of its fold estimates,
:attr:`FitResult.heldout_floor_um`).

Units: um, urad, um/h.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.stats import chi2

from abbe.analysis.five_axis.identify import FitResult, _jacobian, identify
from abbe.analysis.five_axis.problem import Block, Param, build_params
from abbe.formats.five_axis import FiveAxisSpec
from abbe.model.five_axis import LOCATION_ERRORS, motion_name

#: Joint significance of an effect's parameters: 1 % false alarms over the catalogue's
#: candidates (up to 7 per round), Bonferroni.
SIGNIFICANCE = 0.999
#: The held-out dispersion must fall by this fraction: an effect-size guard. Significance
#: alone names a chance pattern at the SIGNIFICANCE rate per candidate, and a rule that
#: the held-out positions merely confirm the effect (:func:`heldout_beta` >= 0.75 with
#: any fall) named one such pattern on 36 clean machines (docs/effects.md, section 7).
#: The paired t of the improvement and heldout_beta are reported as evidence.
MIN_GAIN = 0.05
#: Another candidate reproducing this fraction of a named effect's signature makes it
#: ambiguous (as the 3-axis diagnose's ambiguity_r2).
AMBIGUITY_R2 = 0.9
MAX_EFFECTS = 2
#: Highest cyclic harmonic of the table axis tried (probing rarely resolves more).
MAX_CYCLIC = 4


@dataclass(frozen=True)
class Effect:
    """A candidate: ``key`` (e.g. ``cyclic C 2``), what it is, the parameters it adds, and
    what else (outside the catalogue) a one-sphere plan cannot tell it from, with the test
    that would (empty when the plan itself does)."""

    key: str
    what: str
    params: tuple[Param, ...]
    alike: str = ""


def catalogue(spec: FiveAxisSpec, n_c_angles: int, blocks: list[Block] | None = None
              ) -> list[Effect]:
    """The candidate effects for this machine and plan (cyclic harmonics below Nyquist)."""
    tilt, table = spec.geometry.rotaries
    has_indexer = any(b.kind == "indexer" and b.name == table for b in blocks or [])
    out: list[Effect] = []
    for k in range(1, min(MAX_CYCLIC, max((n_c_angles - 1) // 2, 1)) + 1):
        out.append(Effect(
            f"cyclic {table} {k}", f"angular positioning error of {table}, "
            f"{k} cycle(s) per turn (urad)",
            tuple(Param(f"{motion_name(table, table)} {t}{k}", "motion", "urad", 5.0,
                        table, table, k, t) for t in ("sin", "cos")),
            "" if has_indexer else
            f"a sphere sees an angular error of {table} as a radial error motion "
            f"(EX{table}, EY{table}) of its own pattern; a laser + rotary indexer (ISO 230-2) "
            "or a second sphere at another radius tells them apart"))
    for ax in (tilt, table):
        names = LOCATION_ERRORS[ax][:2]
        out.append(Effect(f"pivot drift {ax}", f"drift of the {ax} axis line's position (um/h)",
                          tuple(Param(f"{n} drift", "drift", "um/h", 2.0, ax, n) for n in names),
                          "the diagnosis plan (abbe program --passes 2) or one probing position "
                          "repeated at the start, middle and end of the "
                          "campaign confirms a drift"))
    if n_c_angles >= 5:  # its axial part turns twice per turn of C
        out.append(Effect(
            f"wobble {table}", f"once-per-turn tilt error motion of {table} (EA{table}, "
            f"EB{table}), counter-rotating part (urad)",
            tuple(Param(f"wobble {table} {c}", "wobble", "urad", 5.0, table, c, 1)
                  for c in ("x", "y")),
            "one sphere sees it as an axial (2 per turn) + radial (1 per turn) error motion; "
            "the table face's axial motion at two radii or spheres at two heights tell them "
            "apart"))
    return out


@dataclass
class Named:
    """A named effect: its parameters' values and 95 % intervals, the amplitude, the
    held-out dispersion before and after adding it, the share of its signature the
    location-only model cannot take (``seen``), the smallest amplitude this plan names
    (``detectable``, in the worst phase: expected chi-square at the threshold) and the
    candidates it is ambiguous with (key, R^2)."""

    effect: Effect
    values: dict[str, float]
    ci95: dict[str, float]
    amplitude: float
    amplitude_ci95: float
    heldout_before_um: float
    heldout_after_um: float
    seen: float = float("nan")
    detectable: float = float("nan")
    ambiguous_with: list[tuple[str, float]] = field(default_factory=list)

    @property
    def exact(self) -> bool:
        """Named without an ambiguity inside the catalogue."""
        return not self.ambiguous_with


def gap_um(heldout_um: float, floor_um: float | None) -> float | None:
    """The systematic part of a held-out dispersion: sqrt(max(h^2 - f^2, 0)) (um); None
    without a floor."""
    if floor_um is None or not np.isfinite(heldout_um):
        return None
    return float(np.sqrt(max(heldout_um ** 2 - floor_um ** 2, 0.0)))


@dataclass
class FiveAxisDiagnosis:
    base: FitResult
    final: FitResult
    named: list[Named] = field(default_factory=list)
    tried: list[dict[str, Any]] = field(default_factory=list)

    #: expected RMS 3-D length of the sphere centres' noise (um), from the sphere fits'
    #: residuals (:meth:`SphereCentres.centre_noise_um`); None without redundant points
    noise_floor_um: float | None = None
    #: set when the probing ran its tilts one way only (one pass of the grid): campaign time
    #: then follows the tilt and a drift is mostly taken by the location errors
    one_way: bool = False

    @property
    def shrink(self) -> float:
        """Raw held-out shrink: (before - after) / before of the held-out RMS of prediction
        minus measured sphere centre (the location-only model before, with the named
        effects after). Most of it is the centres' noise on this kind of plan."""
        b, a = self.base.heldout_after_um, self.final.heldout_after_um
        return (b - a) / b if b > 0 else 0.0

    @property
    def gap_before_um(self) -> float | None:
        return gap_um(self.base.heldout_after_um, self.base.heldout_floor_um)

    @property
    def gap_after_um(self) -> float | None:
        return gap_um(self.final.heldout_after_um, self.final.heldout_floor_um)

    @property
    def excess_shrink(self) -> float | None:
        """Shrink of the gap (module docstring): 1 - gap after / gap before, each model's
        held-out dispersion less its own floor in quadrature. None without a floor or when
        the location-only model's held-out dispersion is already at its floor."""
        b, a = self.gap_before_um, self.gap_after_um
        if b is None or a is None or not b > 0:
            return None
        return 1.0 - a / b

    def to_json(self) -> dict[str, Any]:
        return {"heldout_before_um": self.base.heldout_after_um,
                "heldout_after_um": self.final.heldout_after_um, "shrink": self.shrink,
                "noise_floor_um": self.noise_floor_um,
                "heldout_floor_before_um": self.base.heldout_floor_um,
                "heldout_floor_after_um": self.final.heldout_floor_um,
                "gap_before_um": self.gap_before_um, "gap_after_um": self.gap_after_um,
                "excess_shrink": self.excess_shrink, "tilt_one_way": self.one_way,
                "named": [{"effect": n.effect.key, "what": n.effect.what, "values": n.values,
                           "ci95": n.ci95, "amplitude": n.amplitude,
                           "amplitude_ci95": n.amplitude_ci95,
                           "heldout_before_um": n.heldout_before_um,
                           "heldout_after_um": n.heldout_after_um,
                           "seen_fraction": _f(n.seen), "detectable": _f(n.detectable),
                           "ambiguous_with": [{"effect": k, "r2": r} for k, r in
                                              n.ambiguous_with],
                           "alike": n.effect.alike} for n in self.named],
                "tried": self.tried}

    def text(self) -> str:
        out = [f"Five-axis discrepancy: held-out sphere-centre dispersion "
               f"{self.base.heldout_after_um:.3f} um with the location-only model"]
        if not self.named:
            out.append("Nothing named: no catalogue effect is observable, significant and "
                       f"lowers the held-out dispersion by {MIN_GAIN:.0%}")
        for n in self.named:
            vals = ", ".join(f"{k} {v:.3f} +- {n.ci95[k]:.3f}" for k, v in n.values.items())
            head = "Ambiguous" if n.ambiguous_with else "Named"
            out.append(f"{head}: {n.effect.what}: amplitude {n.amplitude:.3f} +- "
                       f"{n.amplitude_ci95:.3f} ({vals}); held out {n.heldout_before_um:.3f} -> "
                       f"{n.heldout_after_um:.3f} um; {n.seen:.0%} of its signature is beyond "
                       f"the location errors; this plan names it from {n.detectable:.2f}")
            for k, r in n.ambiguous_with:
                out.append(f"  as well explained by {k} (R^2 {r:.2f}): the plan cannot tell "
                           "them apart")
            if n.effect.alike:
                out.append(f"  note: {n.effect.alike}")
        lim = {}
        for t in self.tried:  # the first round's: against the location-only model
            if t.get("detectable") is not None and t["effect"] not in lim:
                lim[t["effect"]] = f"{t['detectable']:.2f} {t['unit']}"
        if lim:
            out.append("Smallest amplitude this plan names (worst phase): " + ", ".join(
                f"{k} {v}" for k, v in lim.items()))
        if self.one_way:
            out.append("Plan: the tilt went one way through the campaign, so campaign time "
                       "follows the tilt and the location errors take most of a drift; the "
                       "diagnosis plan (abbe program --passes 2: the grid again backwards) "
                       "tells a drift from the geometry")
        out.append(f"Held-out shrink {self.shrink:.0%} (raw)")
        if self.noise_floor_um is not None:
            out.append(f"Sphere-centre noise (from the sphere fits) {self.noise_floor_um:.3f} um")
        gb, ga, ex = self.gap_before_um, self.gap_after_um, self.excess_shrink
        if gb is not None and ga is not None:
            out.append(f"Gap (held-out dispersion above what a right model shows on this plan): "
                       f"{gb:.3f} -> {ga:.3f} um" + (f", shrink {ex:.0%}" if ex is not None
                                                     else " (at the floor)"))
        return "\n".join(out) + "\n"


def _tilt_one_way(blocks: list[Block]) -> bool:
    """Whether every probing block's tilt angle, in campaign time order, only rises or only
    falls (a single pass of the grid)."""
    probes = [b for b in blocks if b.kind == "probe" and b.time_s is not None]
    if not probes:
        return False
    for b in probes:
        tilt = b.angles_deg[np.argsort(b.time_s, kind="stable"), 0]
        d = np.diff(tilt)
        if np.any(d > 1e-9) and np.any(d < -1e-9):
            return False
    return True


def _f(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


def _fit(spec: FiveAxisSpec, blocks: list[Block], params: list[Param]) -> FitResult:
    return identify(spec, blocks, params)


def _judge(res: FitResult, eff: Effect) -> tuple[bool, float, dict, dict, float, float]:
    idx = [i for i, p in enumerate(res.params) if p.name in {q.name for q in eff.params}]
    if not all(res.obs.observable[i] for i in idx):
        return False, 0.0, {}, {}, 0.0, 0.0
    v = res.x[idx]
    sd = res.sd[idx]
    C = res.corr[np.ix_(idx, idx)] * np.outer(sd, sd)
    try:
        stat = float(v @ np.linalg.solve(C, v))
    except np.linalg.LinAlgError:
        return False, 0.0, {}, {}, 0.0, 0.0
    vector = eff.params[0].kind in ("motion", "wobble")  # an amplitude, not a component
    amp = float(np.sqrt(np.sum(v ** 2))) if vector else float(np.max(np.abs(v)))
    g = v / amp if amp > 0 and vector else np.eye(len(v))[np.argmax(np.abs(v))]
    amp_ci = 1.96 * float(np.sqrt(max(g @ C @ g, 0.0)))
    names = [res.params[i].name for i in idx]
    return (stat > chi2.ppf(SIGNIFICANCE, len(idx)), stat,
            {n: float(x) for n, x in zip(names, v)},
            {n: float(1.96 * s) for n, s in zip(names, sd)}, amp, amp_ci)


def heldout_t(before: FitResult, after: FitResult) -> float:
    """Paired comparison of two models' held-out residuals: the mean over probing positions
    of |before|^2 - |after|^2 over its standard error (0 when not comparable)."""
    b, a = before.heldout_residuals_um, after.heldout_residuals_um
    if b is None or a is None or b.shape != a.shape or len(b) < 3:
        return 0.0
    d = np.sum(b ** 2, axis=1) - np.sum(a ** 2, axis=1)
    se = float(np.std(d, ddof=1)) / np.sqrt(len(d))
    return float(np.mean(d)) / se if se > 0 else 0.0


def heldout_beta(before: FitResult, after: FitResult) -> float:
    """How far the held-out residuals follow the added effect's prediction: the regression
    coefficient of the before-model's held-out residuals on the change the effect makes to
    the predictions, sum(r_b . d) / sum(d . d) with d = r_b - r_a (1: the change is what the
    held-out positions show; 0: it fitted the training positions' noise; NaN when no change)."""
    b, a = before.heldout_residuals_um, after.heldout_residuals_um
    if b is None or a is None or b.shape != a.shape:
        return float("nan")
    d = b - a
    dd = float(np.sum(d * d))
    return float(np.sum(b * d)) / dd if dd > 0 else float("nan")


class _Signatures:
    """Linearised signatures (weighted residual columns at the base solution) of the base
    model's parameters and of every candidate, for the seen share, the detection limit and
    the ambiguity between candidates."""

    def __init__(self, spec: FiveAxisSpec, blocks: list[Block], base: FitResult,
                 cands: list[Effect]) -> None:
        from abbe.analysis.five_axis.problem import residual_block, residuals

        self.params = list(base.params) + [p for e in cands for p in e.params]
        xb = base.x_solution if base.x_solution is not None else np.nan_to_num(base.x)
        x0 = np.concatenate([xb, np.zeros(len(self.params) - len(xb))])
        g = spec.geometry
        scale = np.array([p.scale for p in self.params])
        # the predictions' change per unit of each parameter (identify's central differences)
        J = -_jacobian(lambda x: residuals(g, self.params, x, 0, blocks), x0, scale) / scale
        nb = len(base.params)
        U, sv, _ = np.linalg.svd(J[:, :nb], full_matrices=False)
        U = U[:, sv > 1e-9 * sv[0]]
        self.full = J
        self.beyond = J - U @ (U.T @ J)  # the part the location-only model cannot take
        self.index = {p.name: i for i, p in enumerate(self.params)}
        r = residuals(g, base.params, xb, 0, blocks)
        self.s2 = max(float(r @ r) / max(r.size - base.obs.rank, 1), 1e-12)  # ~1 (sigma units)
        # The same signatures in um on the probing positions' centres, per position: what
        # an effect adds to the held-out dispersion (the gain guard's side of the limit).
        sig_rows, probe_rows, n_pos = [], [], 0
        for b in blocks:
            n = residual_block(g, base.params, xb, 0, b).size
            sd = np.asarray(b.sigma, dtype=np.float64)
            sig_rows.append(np.tile(sd, n // sd.size) if sd.size > 1 else np.full(n, float(sd)))
            probe_rows.append(np.full(n, b.kind == "probe"))
            n_pos += len(b.obs) if b.kind == "probe" else 0
        um = self.beyond * np.concatenate(sig_rows)[:, None]
        self.beyond_um = um[np.concatenate(probe_rows)]
        self.n_positions = n_pos
        self.floor_um = base.heldout_floor_um

    def cols(self, eff: Effect) -> list[int]:
        return [self.index[p.name] for p in eff.params]

    def seen(self, eff: Effect, v: np.ndarray) -> float:
        c = self.cols(eff)
        full = float(np.sum((self.full[:, c] @ v) ** 2))
        return float(np.sum((self.beyond[:, c] @ v) ** 2)) / full if full > 0 else float("nan")

    def detectable(self, eff: Effect) -> float:
        """Smallest amplitude this plan names, in the worst phase (parameter units): its
        expected chi-square reaches the threshold and, on a machine whose held-out
        dispersion is this plan's floor f, adding it lowers the held-out RMS by MIN_GAIN
        (its signature's mean square per position s^2 a^2 >= f^2 (1 / (1 - MIN_GAIN)^2 - 1))."""
        c = self.cols(eff)
        B = self.beyond[:, c]
        lam = float(np.linalg.eigvalsh(B.T @ B)[0]) / self.s2
        thr = chi2.ppf(SIGNIFICANCE, B.shape[1])
        limit = float(np.sqrt(thr / lam)) if lam > 0 else float("inf")
        if self.floor_um is not None and self.n_positions and self.beyond_um.size:
            Bu = self.beyond_um[:, c]
            s2 = float(np.linalg.eigvalsh(Bu.T @ Bu)[0]) / self.n_positions
            need = self.floor_um ** 2 * (1.0 / (1.0 - MIN_GAIN) ** 2 - 1.0)
            limit = max(limit, float(np.sqrt(need / s2)) if s2 > 0 else float("inf"))
        return limit

    def ambiguity(self, eff: Effect, v: np.ndarray, others: list[Effect]) -> list[tuple[str, float]]:
        sig = self.beyond[:, self.cols(eff)] @ v
        n2 = float(sig @ sig)
        out = []
        for o in others:
            if o.key == eff.key or n2 <= 0:
                continue
            B = self.beyond[:, self.cols(o)]
            coef, *_ = np.linalg.lstsq(B, sig, rcond=None)
            r2 = 1.0 - float(np.sum((sig - B @ coef) ** 2)) / n2
            if r2 >= AMBIGUITY_R2:
                out.append((o.key, r2))
        return out


def diagnose_five_axis(spec: FiveAxisSpec, blocks: list[Block]) -> FiveAxisDiagnosis:
    """Name what a location-only model of this plan misses (module docstring)."""
    spec0 = dataclasses.replace(spec, fit=dataclasses.replace(spec.fit, harmonics=0))
    params = build_params(spec0, blocks)
    base = _fit(spec0, blocks, params)
    n_c = max((len(np.unique(np.round(b.angles_deg[:, 1], 6))) for b in blocks
               if b.kind == "probe"), default=0)
    cands = catalogue(spec0, n_c, blocks)
    sig = _Signatures(spec0, blocks, base, cands)
    floors = [(b.noise_floor_um, len(b.obs)) for b in blocks
              if b.kind == "probe" and b.noise_floor_um is not None]
    floor = float(np.sqrt(sum(f * f * m for f, m in floors) / sum(m for _, m in floors))) \
        if floors else None
    diag = FiveAxisDiagnosis(base, base, noise_floor_um=floor, one_way=_tilt_one_way(blocks))
    current, prev = params, base
    for _ in range(MAX_EFFECTS):
        best = None
        for eff in cands:
            if any(n.effect.key == eff.key for n in diag.named):
                continue
            trial = current + list(eff.params)
            res = _fit(spec0, blocks, trial)
            ok, stat, vals, ci, amp, amp_ci = _judge(res, eff)
            gap = prev.heldout_after_um
            gain = (gap - res.heldout_after_um) / gap if gap > 0 else 0.0
            t, beta = heldout_t(prev, res), heldout_beta(prev, res)
            diag.tried.append({"effect": eff.key, "observable": bool(vals), "chi2": stat,
                               "heldout_um": res.heldout_after_um, "gain": gain,
                               "heldout_t": t, "heldout_beta": _f(beta),
                               "detectable": _f(sig.detectable(eff)),
                               "unit": eff.params[0].unit})
            if ok and gain >= MIN_GAIN and (best is None or gain > best[0]):
                best = (gain, eff, res, vals, ci, amp, amp_ci)
        if best is None:
            break
        gain, eff, res, vals, ci, amp, amp_ci = best
        v = np.array(list(vals.values()))
        diag.named.append(Named(eff, vals, ci, amp, amp_ci, prev.heldout_after_um,
                                res.heldout_after_um, sig.seen(eff, v), sig.detectable(eff),
                                sig.ambiguity(eff, v, cands)))
        current, prev, diag.final = current + list(eff.params), res, res
    return diag
