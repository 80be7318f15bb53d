"""The discrepancy workflow on five axes: what a location-only model misses.

After a location-only identification (:func:`abbe.analysis.five_axis.identify.identify`
with no error motions), each candidate effect of the catalogue is added in turn
and the whole plan refitted; its held-out sphere-centre dispersion (probing
positions left out fold by fold) is compared with the model's. An effect is
named when (a) every parameter it adds is observable with the plan, (b) its
parameters are significant together (chi-square of the estimate against its
covariance above the 99.99 % quantile) and (c) the held-out dispersion falls by
at least :data:`MIN_GAIN`. The best such effect is added and the search repeats
(at most :data:`MAX_EFFECTS`). Catalogue (docs/effects.md, section 7):

* ``cyclic <C> k``: an angular positioning error of k cycles per turn
  (``ECC(C)`` harmonic k, the worm gear's), urad;
* ``pivot drift <A|B>`` / ``pivot drift C``: the axis line's position drifting
  linearly during the campaign (um/h).

A once-per-revolution wobble of C is not in the catalogue yet: under ISO 230-7's
convention it is mostly the tilt of the axis average line (a location error the
base model has); its remainder, a constant tilt of the table frame, is partly
confounded with the tilt axis' zero with one sphere (docs/effects.md, section 7).

Units: um, urad, um/h.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.stats import chi2

from abbe.analysis.five_axis.identify import FitResult, identify
from abbe.analysis.five_axis.problem import Block, Param, build_params
from abbe.formats.five_axis import FiveAxisSpec
from abbe.model.five_axis import LOCATION_ERRORS, motion_name

#: Held-out dispersion must fall by this fraction for an effect to be named.
MIN_GAIN = 0.05
#: Joint significance of an effect's parameters.
SIGNIFICANCE = 0.9999
MAX_EFFECTS = 2
#: Highest cyclic harmonic of the table axis tried (probing rarely resolves more).
MAX_CYCLIC = 4


@dataclass(frozen=True)
class Effect:
    """A candidate: ``key`` (e.g. ``cyclic C 2``), what it is, the parameters it adds."""

    key: str
    what: str
    params: tuple[Param, ...]


def catalogue(spec: FiveAxisSpec, n_c_angles: int) -> list[Effect]:
    """The candidate effects for this machine and plan (cyclic harmonics below Nyquist)."""
    tilt, table = spec.geometry.rotaries
    out: list[Effect] = []
    for k in range(1, min(MAX_CYCLIC, max((n_c_angles - 1) // 2, 1)) + 1):
        out.append(Effect(f"cyclic {table} {k}", f"angular positioning error of {table}, "
                          f"{k} cycle(s) per turn (urad)",
                          tuple(Param(f"{motion_name(table, table)} {t}{k}", "motion", "urad", 5.0,
                                      table, table, k, t) for t in ("sin", "cos"))))
    for ax in (tilt, table):
        names = LOCATION_ERRORS[ax][:2]
        out.append(Effect(f"pivot drift {ax}", f"drift of the {ax} axis line's position (um/h)",
                          tuple(Param(f"{n} drift", "drift", "um/h", 2.0, ax, n) for n in names)))
    return out


@dataclass
class Named:
    """A named effect: its parameters' values and 95 % intervals, the amplitude and the
    held-out dispersion before and after adding it."""

    effect: Effect
    values: dict[str, float]
    ci95: dict[str, float]
    amplitude: float
    amplitude_ci95: float
    heldout_before_um: float
    heldout_after_um: float


@dataclass
class FiveAxisDiagnosis:
    base: FitResult
    final: FitResult
    named: list[Named] = field(default_factory=list)
    tried: list[dict[str, Any]] = field(default_factory=list)

    #: expected RMS 3-D length of the sphere centres' noise (um), from the sphere fits'
    #: residuals (:meth:`SphereCentres.centre_noise_um`); None without redundant points
    noise_floor_um: float | None = None

    @property
    def shrink(self) -> float:
        """Raw held-out gap shrink: (before - after) / before of the held-out RMS of
        prediction minus measured sphere centre (the location-only model before, with the
        named effects after)."""
        b, a = self.base.heldout_after_um, self.final.heldout_after_um
        return (b - a) / b if b > 0 else 0.0

    @property
    def excess_shrink(self) -> float | None:
        """Shrink of the held-out gap's excess over the centres' noise floor f, as the 3-axis
        diagnose reports it (bench/bench_diagnose.py): 1 - sqrt(a^2 - f^2) / sqrt(b^2 - f^2)
        (a below f counts as 0 excess). The part of the gap no model can remove is left out;
        None without a floor or when the gap is already at it."""
        f = self.noise_floor_um
        b, a = self.base.heldout_after_um, self.final.heldout_after_um
        if f is None or not b > f:
            return None
        return 1.0 - float(np.sqrt(max(a * a - f * f, 0.0) / (b * b - f * f)))

    def to_json(self) -> dict[str, Any]:
        return {"heldout_before_um": self.base.heldout_after_um,
                "heldout_after_um": self.final.heldout_after_um, "shrink": self.shrink,
                "noise_floor_um": self.noise_floor_um, "excess_shrink": self.excess_shrink,
                "named": [{"effect": n.effect.key, "what": n.effect.what, "values": n.values,
                           "ci95": n.ci95, "amplitude": n.amplitude,
                           "amplitude_ci95": n.amplitude_ci95,
                           "heldout_before_um": n.heldout_before_um,
                           "heldout_after_um": n.heldout_after_um} for n in self.named],
                "tried": self.tried}

    def text(self) -> str:
        out = [f"Five-axis discrepancy: held-out sphere-centre dispersion "
               f"{self.base.heldout_after_um:.3f} um with the location-only model"]
        if not self.named:
            out.append("Nothing named: no catalogue effect is observable, significant and "
                       f"lowers the held-out dispersion by {MIN_GAIN:.0%}")
        for n in self.named:
            vals = ", ".join(f"{k} {v:.3f} +- {n.ci95[k]:.3f}" for k, v in n.values.items())
            out.append(f"Named: {n.effect.what}: amplitude {n.amplitude:.3f} +- "
                       f"{n.amplitude_ci95:.3f} ({vals}); held out {n.heldout_before_um:.3f} -> "
                       f"{n.heldout_after_um:.3f} um")
        out.append(f"Held-out shrink {self.shrink:.0%}")
        if self.noise_floor_um is not None:
            ex = self.excess_shrink
            out.append("Sphere-centre noise floor (from the sphere fits) "
                       f"{self.noise_floor_um:.3f} um; "
                       + ("shrink of the gap above it " + f"{ex:.0%}" if ex is not None
                          else "the gap is at the floor"))
        return "\n".join(out) + "\n"


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
    amp = float(np.sqrt(np.sum(v ** 2))) if eff.params[0].kind == "motion" else \
        float(np.max(np.abs(v)))
    g = v / amp if amp > 0 and eff.params[0].kind == "motion" else np.eye(len(v))[np.argmax(np.abs(v))]
    amp_ci = 1.96 * float(np.sqrt(max(g @ C @ g, 0.0)))
    names = [res.params[i].name for i in idx]
    return (stat > chi2.ppf(SIGNIFICANCE, len(idx)), stat,
            {n: float(x) for n, x in zip(names, v)},
            {n: float(1.96 * s) for n, s in zip(names, sd)}, amp, amp_ci)


def diagnose_five_axis(spec: FiveAxisSpec, blocks: list[Block]) -> FiveAxisDiagnosis:
    """Name what a location-only model of this plan misses (module docstring)."""
    spec0 = dataclasses.replace(spec, fit=dataclasses.replace(spec.fit, harmonics=0))
    params = build_params(spec0, blocks)
    base = _fit(spec0, blocks, params)
    n_c = max((len(np.unique(np.round(b.angles_deg[:, 1], 6))) for b in blocks
               if b.kind == "probe"), default=0)
    cands = catalogue(spec0, n_c)
    floors = [(b.noise_floor_um, len(b.obs)) for b in blocks
              if b.kind == "probe" and b.noise_floor_um is not None]
    floor = float(np.sqrt(sum(f * f * m for f, m in floors) / sum(m for _, m in floors))) \
        if floors else None
    diag = FiveAxisDiagnosis(base, base, noise_floor_um=floor)
    current, gap = params, base.heldout_after_um
    for _ in range(MAX_EFFECTS):
        best = None
        for eff in cands:
            if any(n.effect.key == eff.key for n in diag.named):
                continue
            trial = current + list(eff.params)
            res = _fit(spec0, blocks, trial)
            ok, stat, vals, ci, amp, amp_ci = _judge(res, eff)
            gain = (gap - res.heldout_after_um) / gap if gap > 0 else 0.0
            diag.tried.append({"effect": eff.key, "observable": bool(vals), "chi2": stat,
                               "heldout_um": res.heldout_after_um, "gain": gain})
            if ok and gain >= MIN_GAIN and (best is None or gain > best[0]):
                best = (gain, eff, res, vals, ci, amp, amp_ci)
        if best is None:
            break
        gain, eff, res, vals, ci, amp, amp_ci = best
        diag.named.append(Named(eff, vals, ci, amp, amp_ci, gap, res.heldout_after_um))
        current, gap, diag.final = current + list(eff.params), res.heldout_after_um, res
    return diag
