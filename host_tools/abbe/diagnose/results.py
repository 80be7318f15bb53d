"""Options and results of ``abbe diagnose``: named effects, gaps, JSON form.

Units: positions mm, linear values um, angles urad; see each field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from abbe.diagnose.checks import Check
from abbe.diagnose.effects import PredParams
from abbe.model.table import Table


@dataclass
class DiagnoseOptions:
    """Settings of the decision (defaults are the documented ones, docs/effects.md §3).

    The selection is one model comparison (:mod:`abbe.diagnose.evidence`): an effect is
    named when the posterior probability that it is absent is below ``alpha`` (prior odds
    ``prior_log_odds``, 0 = even), i.e. when its evidence ratio reaches (1 - alpha) /
    alpha (``evidence_log_min``; alpha 0.05: 19, "strong" on Jeffreys' scale), and the
    held-out data agree (arbiter): the held-out residual decrease must be at least
    ``heldout_fraction`` of the in-sample decrease and at least 2 per parameter (noise
    units); ``redundant_heldout_fraction`` when the effects already named reproduce
    ``ambiguity_r2`` of its signature (the held-out data must prefer the pair).
    ambiguity_r2: a candidate reproducing this fraction of a named effect's signature
    makes it ambiguous (two explanations are *undecided*, "A or B", when what one cannot
    reproduce of the other is within the noise: log likelihood ratio below
    ``evidence_log_min``, docs/effects.md §3), the misfit's variance being the noise plus
    (``model_rel_sigma`` x the signature)^2: the model predicts an effect's signature to
    a relative accuracy of 5 % RMS (undecided.misfit_log_lr; the independent generator's
    thermal drift + scale of X seen on circles: scale_y named, scale_x reproducing 0.9997
    of it, log LR 5.3 against the noise alone, 0.06 with the model's error);
    min_effect_um: an effect whose fitted contribution has a smaller RMS (um, on its
    channel) is not named (relevance, not statistics); candidates: keys or families to
    consider (None = all); max_effects: safety stop; model_temp_c: temperature (deg C)
    at which the model was measured (thermal reference; None = the table's, else the
    lowest logged temperature).

    Priors: each parameter uniform within the catalogue's plausible range; the tool
    offset within tool_offset_max_mm (norm of declared + found, mm). A declared
    quantity (the tool offset in the machine file) is a measurement: right within
    declared_tool_sigma_mm (1 sigma; a presetter 0.01 mm, or the machine file's
    ``[tool] offset_sigma_mm``), a blunder (wrong tool, typo) with probability
    declared_blunder_prob, then anywhere in the range. The tool counts as declared when
    the model's tool is not zero, or when the machine file states its uncertainty
    (declared_tool_stated: a zero tool is then a declaration too). model_angle_sigma_urad: the
    uncertainty of the model's angular terms (a 6D laser fit: 0.5 urad), which a tool
    offset's signature cannot be told from beyond lever x this.
    """

    alpha: float = 0.05
    heldout_fraction: float = 0.1
    ambiguity_r2: float = 0.9
    min_effect_um: float = 0.15
    candidates: list[str] | None = None
    max_effects: int = 8
    backend: str = "auto"
    max_period_mm: float = 60.0
    redundant_heldout_fraction: float = 0.5
    model_temp_c: float | None = None
    tool_offset_max_mm: float = 300.0
    declared_tool_sigma_mm: float = 0.01
    declared_tool_stated: bool = False
    declared_blunder_prob: float = 0.01
    model_angle_sigma_urad: float = 0.5
    prior_log_odds: float = 0.0
    model_rel_sigma: float = 0.05

    @property
    def evidence_log_min(self) -> float:
        """The log evidence ratio an effect needs: log((1 - alpha) / alpha)."""
        return math.log((1.0 - self.alpha) / self.alpha)


@dataclass
class GapStats:
    """RMS and max |residual| (um) over the um-valued samples, nuisance removed."""

    rms_um: float
    max_um: float
    n: int

    def to_json(self) -> dict[str, Any]:
        return {"rms_um": round(self.rms_um, 4), "max_um": round(self.max_um, 4), "n": self.n}


@dataclass
class EffectResult:
    """One named effect (see docs/formats.md "diagnose JSON")."""

    id: str
    key: str
    value: float
    unit: str
    ci95: tuple[float, float]
    params: list[dict[str, Any]]
    compensable: bool
    where: str
    physics: str
    remedy: str
    evidence: dict[str, Any]
    axis: str | None = None
    plane: str | None = None
    scan: dict[str, float] | None = None
    #: 95 % profile interval of each scanned shape value; None = open (not resolved) end
    scan_ci95: dict[str, list[float | None]] | None = None
    ambiguous_with: list[dict[str, Any]] = field(default_factory=list)
    #: per check: residual (nuisance removed) before / after adding this effect (plots)
    stage_before: list[np.ndarray] = field(default_factory=list, repr=False)
    stage_after: list[np.ndarray] = field(default_factory=list, repr=False)
    tentative: bool = False
    #: derived shape statements (servo model, lost motion at each reversal, ...)
    shape: dict[str, Any] | None = None
    shape_notes: list[str] = field(default_factory=list)
    #: the components of one effect seen on several axes (a thermal drift: one warm-up,
    #: one time constant, an offset and scale per axis): one entry, each component with
    #: its key, axis, value, unit, 95 % interval and parameters; the entry's own value is
    #: its first (largest-evidence) component's
    components: list[dict[str, Any]] = field(default_factory=list)
    #: undecided (issue 36): the explanations that reproduce each other on every check
    #: (this one first), each with its value, and the test that separates them; None =
    #: decided
    undecided: dict[str, Any] | None = None
    #: u, U (k = 2), budget_u (and the Monte Carlo's) of the value: abbe.diagnose.uncertainty
    uncertainty: dict[str, Any] | None = None

    def named_parts(self) -> list[tuple[str, float, str, tuple[float, float]]]:
        """(key, value, unit, 95 % interval) of each component (the entry itself when it
        has none): what the entry names, for a reader or a score."""
        if not self.components:
            return [(self.key, self.value, self.unit, self.ci95)]
        return [(c["key"], float(c["value"]), str(c["unit"]),
                 (float(c["ci95"][0]), float(c["ci95"][1]))) for c in self.components]

    def to_json(self) -> dict[str, Any]:
        d: dict[str, Any] = {"id": self.id, "key": self.key, "value": round_to(self.value),
                             "unit": self.unit, "ci95": [round_to(self.ci95[0]), round_to(self.ci95[1])]}
        if self.uncertainty:
            d.update(self.uncertainty)
        if self.axis:
            d["axis"] = self.axis
        if self.plane:
            d["plane"] = self.plane
        d["parameters"] = self.params
        if self.scan:
            d["scan"] = {k: round_to(v) for k, v in self.scan.items()}
        if self.scan_ci95:
            d["scan_ci95"] = {k: [None if x is None else round_to(x) for x in v]
                              for k, v in self.scan_ci95.items()}
        d["compensated_by"] = self.where
        d["remedy"] = self.remedy
        d["evidence"] = self.evidence
        if self.shape:
            d["shape"] = self.shape
        if self.components:
            d["components"] = self.components
        d["ambiguous_with"] = self.ambiguous_with
        d["tentative"] = self.tentative
        d["state"] = "undecided" if self.undecided else "named"
        if self.undecided:
            d["undecided"] = self.undecided
            d["undecided_between"] = [a["key"] for a in self.undecided["alternatives"]]
        return d


def named_by_key(effects: list[EffectResult]) -> dict[str, Any]:
    """Every name the effects state, by key: an entry under its key, and each component
    of a multi-component entry (a thermal drift on several axes) under its own key, as
    an EffectResult carrying the component's value, unit, interval and parameters (for
    a score or a reader that compares names with a truth)."""
    out: dict[str, Any] = {}
    for e in effects:
        if len(e.components) <= 1:
            out[e.key] = e
            continue
        for c in e.components:
            out[c["key"]] = EffectResult(
                id=e.id, key=c["key"], value=float(c["value"]), unit=str(c["unit"]),
                ci95=(float(c["ci95"][0]), float(c["ci95"][1])), params=c["parameters"],
                compensable=e.compensable, where=e.where, physics=e.physics, remedy=e.remedy,
                evidence={}, axis=c.get("axis"), scan=e.scan, scan_ci95=e.scan_ci95,
                ambiguous_with=e.ambiguous_with, tentative=e.tentative)
    return out


def round_to(v: float, nd: int = 6) -> float:
    return float(round(float(v), nd))


@dataclass
class FitState:
    """What the uncertainty of the named effects needs of the final fit (kept by
    ``diagnose`` on its result; abbe.diagnose.uncertainty): the engine, the selected
    effects, their values and covariance, s^2 and the weights (1 / um)."""

    eng: Any
    selected: list[Any]
    values: list[np.ndarray]
    cov: np.ndarray
    s2: float
    W: np.ndarray


@dataclass
class DiagnoseResult:
    """Outcome of :func:`diagnose`.

    effects: named effects in the order added; gap: "before", "after",
    "held_out_before", "held_out_after" (GapStats or None); table: the updated
    table (effects the library evaluates added); pred_params: the updated
    prediction parameters (servo lag, time drift); residual_before/after: per
    check (N_i,) residuals with nuisance removed (um / urad); notes: plain-language
    statements (nothing missing, not observable, undecided, ...).
    """

    effects: list[EffectResult]
    gap: dict[str, GapStats | None]
    table: Table
    pred_params: PredParams
    base_table: Table
    checks: list[Check]
    residual_before: list[np.ndarray]
    residual_after: list[np.ndarray]
    noise: dict[str, dict[str, float]]
    tested: dict[str, dict[str, Any]]
    not_observable: list[str]
    notes: list[str]
    backend: str
    drift_unit: str | None
    lack_of_fit: float = 1.0
    tentative: bool = False
    heldout_split: str | None = None
    #: excluded (or flagged) runs: abbe.diagnose.outliers.OutlierRun
    outliers: list[Any] = field(default_factory=list)
    #: what the machine file declares and the prior it is judged with (the tool offset, mm;
    #: its 1-sigma uncertainty and where that comes from), or None (no machine file)
    declared: dict[str, Any] | None = None
    #: candidates possibly present, not named ("nothing, or B": tested.possibly_present;
    #: key, value, unit, ci95, log_evidence, log_evidence_typical, statement, test)
    possible: list[dict[str, Any]] = field(default_factory=list)
    #: the final fit, kept for the uncertainty (FitState)
    fit_state: FitState | None = field(default=None, repr=False)
    #: U (k = 2) of the named effects and gaps with the budget (diagnosis_uncertainty)
    uncertainty: dict[str, Any] | None = None
    #: before / after: rms_um / max_um: value, u, U, budget_u
    gap_uncertainty: dict[str, Any] | None = None

    @property
    def drift_ties(self) -> list[Any]:
        """The drift of every laser check that carries a time and a temperature per
        reading, tied to that temperature (expansion coefficient, lag; computed once:
        abbe.diagnose.drift_temperature)."""
        if not hasattr(self, "_drift_ties"):
            from abbe.diagnose.drift_temperature import ties_of
            self._drift_ties = ties_of(self.checks, self.residual_before)
        return self._drift_ties

    @property
    def nothing_missing(self) -> bool:
        """No effect named and the model explains the checks down to the noise."""
        return not self.effects and not self.tentative and not self.possible

    def _gap_U(self, which: str) -> dict[str, Any]:
        g = (self.gap_uncertainty or {}).get(which)
        if not g:
            return {}
        return {f"{k[:-3]}_U_um": g[k]["U"] for k in ("rms_um", "max_um")} | \
            {f"{k[:-3]}_u_um": g[k]["u"] for k in ("rms_um", "max_um")}

    def to_json(self, model_path: str | None = None) -> dict[str, Any]:
        return {
            "effects": [e.to_json() for e in self.effects],
            "state": ("undecided" if any(e.undecided for e in self.effects) or self.possible
                      else "nothing missing" if not self.effects else "named"),
            "possibly_present": self.possible,
            "gap": {**{k: (None if v is None else {**v.to_json(), **self._gap_U(k)})
                       for k, v in self.gap.items()},
                    "held_out_split": self.heldout_split},
            "model": model_path,
            "lack_of_fit": {"residual_over_noise": round(self.lack_of_fit, 3),
                            "limit": LACK_OF_FIT_LIMIT, "tentative": self.tentative},
            "backend": self.backend,
            "checks": [{"name": c.name, "kind": c.kind, "n": c.n, **_jsonable(c.meta)}
                       for c in self.checks],
            "noise": self.noise,
            "outliers": [o.to_json() for o in self.outliers],
            "not_observable": self.not_observable,
            "candidates": self.tested,
            "declared": self.declared,
            "notes": self.notes,
            "drift_temperature": [t.to_json() for t in self.drift_ties],
            **({"uncertainty": self.uncertainty} if self.uncertainty else {}),
        }


def _jsonable(d: dict[str, Any]) -> dict[str, Any]:
    out = {}
    for k, v in d.items():
        if k.startswith("source_"):
            continue
        if isinstance(v, np.ndarray):
            v = v.tolist()
        out[k] = v
    return out


#: Residual RMS after the update, in noise units, above which the names are tentative.
LACK_OF_FIT_LIMIT = 2.0
