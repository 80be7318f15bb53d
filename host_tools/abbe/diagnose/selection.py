"""``abbe diagnose``: name what the model is missing, add it, show the gap shrink.

Steps (docs/effects.md):

1. **Simulate**: predict every check (:mod:`abbe.diagnose.checks`) with the
   current model through the C library.
2. **Compare**: residual = measured - predicted, sample by sample; the nuisance
   columns of each check (ballbar centre and radius, laser zeros and set-up
   slopes, per-run zeros) are always fitted.
3. **Candidates** (:mod:`abbe.diagnose.effects`): each is a set of extra model
   parameters; its signature on the checks is its sensitivity, computed by
   perturbing the parameter and re-predicting through the model (finite
   differences). Nonlinear parameters (cyclic period, backlash take-up) are
   searched on a grid.
4. **Decide**: forward stepwise selection on the whitened residual (weights =
   the noise of each channel, estimated from repeated runs / the scatter about
   a saturated smooth fit). A candidate is accepted only if it passes an F-test
   against the noise (Bonferroni over the candidates of the step and, for grid
   searches, over the independent grid points), lowers the BIC by at least
   ``bic_min``, and lowers the residual on held-out data (fit on one fold, e.g.
   CCW or early runs, judge on the other, and back). Selection stops when no
   candidate qualifies. Candidates whose signature on the given checks is
   (almost) reproduced by another's are reported as ambiguous, with the test
   that would separate them.
5. **Name** each effect with its value, 95 % interval and evidence.
6. **Add** it to the model: the table (blob, C, JSON) gets the term the C
   library evaluates; effects it cannot hold stay in the prediction model.
7. **Gap**: predict again through the C library with the updated model.

Units: positions mm, linear values um, angles urad; see each field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import stats

from abbe.diagnose.checks import BallbarCheck, Check, Evaluator, LaserCheck, check_travel
from abbe.diagnose.effects import (BACKLASH_TAKEUP_GRID_MM, OWN_TERM, EffectSpec, NotRepresentable,
                          PredParams, catalogue, copy_table)
from abbe.errors import AbbeInputError
from abbe.formats.blob import AXES, Table

#: Smallest noise level assumed (um or urad): float32 prediction resolution and
#: instrument resolution; keeps noiseless synthetic data from making everything significant.
NOISE_FLOOR = 0.01
#: Finite-difference step, as a fraction of the parameter's typical magnitude.
FD_FRACTION = 1.0


@dataclass
class DiagnoseOptions:
    """Settings of the decision (defaults are the documented ones).

    alpha: significance level of a step (Bonferroni-divided by the candidates tested);
    bic_min: minimal BIC decrease; heldout_fraction: the held-out residual decrease must
    be at least this fraction of the in-sample decrease (and at least 2 per parameter,
    in noise units); ambiguity_r2: a candidate reproducing this fraction of a named
    effect's signature makes it ambiguous; min_effect_um: an effect whose fitted
    contribution has a smaller RMS (um, on um-valued samples) is not named;
    candidates: keys or families to consider (None = all); max_effects: safety stop.
    """

    alpha: float = 0.01
    bic_min: float = 10.0
    heldout_fraction: float = 0.1
    ambiguity_r2: float = 0.9
    min_effect_um: float = 0.15
    candidates: list[str] | None = None
    max_effects: int = 8
    backend: str = "auto"
    max_period_mm: float = 60.0


# --------------------------------------------------------------------------- results


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
    ambiguous_with: list[dict[str, Any]] = field(default_factory=list)
    #: per check: residual (nuisance removed) before / after adding this effect (plots)
    stage_before: list[np.ndarray] = field(default_factory=list, repr=False)
    stage_after: list[np.ndarray] = field(default_factory=list, repr=False)
    tentative: bool = False

    def to_json(self) -> dict[str, Any]:
        d: dict[str, Any] = {"id": self.id, "key": self.key, "value": _r(self.value),
                             "unit": self.unit, "ci95": [_r(self.ci95[0]), _r(self.ci95[1])]}
        if self.axis:
            d["axis"] = self.axis
        if self.plane:
            d["plane"] = self.plane
        d["parameters"] = self.params
        if self.scan:
            d["scan"] = {k: _r(v) for k, v in self.scan.items()}
        d["compensated_by"] = self.where
        d["remedy"] = self.remedy
        d["evidence"] = self.evidence
        d["ambiguous_with"] = self.ambiguous_with
        d["tentative"] = self.tentative
        return d


def _r(v: float, nd: int = 6) -> float:
    return float(round(float(v), nd))


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

    @property
    def nothing_missing(self) -> bool:
        """No effect named and the model explains the checks down to the noise."""
        return not self.effects and not self.tentative

    def to_json(self, model_path: str | None = None) -> dict[str, Any]:
        return {
            "effects": [e.to_json() for e in self.effects],
            "gap": {**{k: (None if v is None else v.to_json()) for k, v in self.gap.items()},
                    "held_out_split": self.heldout_split},
            "model": model_path,
            "lack_of_fit": {"residual_over_noise": round(self.lack_of_fit, 3),
                            "limit": LACK_OF_FIT_LIMIT, "tentative": self.tentative},
            "backend": self.backend,
            "checks": [{"name": c.name, "kind": c.kind, "n": c.n, **_jsonable(c.meta)}
                       for c in self.checks],
            "noise": self.noise,
            "not_observable": self.not_observable,
            "candidates": self.tested,
            "notes": self.notes,
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


# --------------------------------------------------------------------------- linear algebra


def _qr_basis(A: np.ndarray, tol: float = 1e-10) -> np.ndarray:
    """Orthonormal basis of the column space of A (columns scaled first)."""
    if A.shape[1] == 0:
        return np.zeros((A.shape[0], 0))
    nrm = np.linalg.norm(A, axis=0)
    keep = nrm > 0
    A = A[:, keep] / nrm[keep]
    if A.shape[1] == 0:
        return np.zeros((A.shape[0], 0))
    u, s, _ = np.linalg.svd(A, full_matrices=False)
    return u[:, s > tol * max(s[0], 1e-300)]


def _proj_out(Q: np.ndarray, A: np.ndarray) -> np.ndarray:
    if Q.shape[1] == 0:
        return A.copy()
    return A - Q @ (Q.T @ A)


def _lstsq_rss(Z: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, float]:
    """Least squares of r on Z: (coef, decrease of the residual sum of squares)."""
    if Z.shape[1] == 0:
        return np.zeros(0), 0.0
    coef, *_ = np.linalg.lstsq(Z, r, rcond=None)
    fit = Z @ coef
    return coef, float(fit @ fit)


def _identifiable(A: np.ndarray, tol: float = 1e-4) -> bool:
    """Full column rank with a sane condition (columns normalised)."""
    if A.shape[1] == 0:
        return True
    if A.shape[0] < A.shape[1]:
        return False
    nrm = np.linalg.norm(A, axis=0)
    if np.any(nrm <= 0):
        return False
    s = np.linalg.svd(A / nrm, compute_uv=False)
    return bool(s[-1] > tol * s[0])


# --------------------------------------------------------------------------- stacked problem


class Problem:
    """All checks stacked: measured vector, nuisance (block diagonal), labels."""

    def __init__(self, checks: list[Check]) -> None:
        self.checks = checks
        self.offsets = np.cumsum([0] + [c.n for c in checks])
        self.N = int(self.offsets[-1])
        self.y = np.concatenate([c.y for c in checks])
        m = sum(c.nuisance.shape[1] for c in checks)
        self.nuis = np.zeros((self.N, m))
        col = 0
        groups, units, names = [], [], []
        for i, c in enumerate(checks):
            s = slice(self.offsets[i], self.offsets[i + 1])
            k = c.nuisance.shape[1]
            self.nuis[s, col:col + k] = c.nuisance
            col += k
            groups.append(c.group + len(names))
            names += c.group_names
            units += c.group_units
        self.group = np.concatenate(groups)
        self.group_names = names
        self.group_units = units
        self.um_rows = np.array([units[g] == "um" for g in self.group])
        self.check_of = np.concatenate([np.full(c.n, i) for i, c in enumerate(checks)])

    def split(self, level: int) -> tuple[np.ndarray, str] | None:
        """Fold labels (N,) of split ``level`` (0 = preferred) of every check."""
        labs, names = [], []
        for c in self.checks:
            keys = list(c.folds)
            if not keys:
                return None
            k = keys[min(level, len(keys) - 1)]
            labs.append(c.folds[k])
            names.append(k)
        uniq = sorted(set(names))
        return np.concatenate(labs), "; ".join(uniq)

    def predict(self, ev: Evaluator, table: Table, pp: PredParams) -> np.ndarray:
        return np.concatenate([c.predict(ev, table, pp) for c in self.checks])

    def slice(self, i: int) -> slice:
        return slice(int(self.offsets[i]), int(self.offsets[i + 1]))


def _remove_nuisance(prob: Problem, r: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """Residual with each check's nuisance fitted (unweighted per noise group) and removed.
    ``rows``: only these rows take part (others returned as NaN)."""
    out = np.full(prob.N, np.nan)
    for i, c in enumerate(prob.checks):
        s = prob.slice(i)
        idx = np.arange(s.start, s.stop)
        if rows is not None:
            idx = idx[rows[s]]
        if idx.size == 0:
            continue
        A = prob.nuis[idx][:, np.any(prob.nuis[idx] != 0, axis=0)]
        rr = r[idx]
        if A.shape[1]:
            coef, *_ = np.linalg.lstsq(A, rr, rcond=None)
            rr = rr - A @ coef
        out[idx] = rr
    return out


def _gap(prob: Problem, r_clean: np.ndarray, rows: np.ndarray | None = None) -> GapStats | None:
    sel = prob.um_rows & np.isfinite(r_clean)
    if rows is not None:
        sel &= rows
    if not np.any(sel):
        return None
    v = r_clean[sel]
    return GapStats(float(np.sqrt(np.mean(v * v))), float(np.max(np.abs(v))), int(v.size))


# --------------------------------------------------------------------------- noise


def estimate_noise(prob: Problem, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict[str, dict[str, float]]]:
    """Noise standard deviation and autocorrelation inflation per noise group.

    Groups with repeated readings (laser runs): pooled within-cell scatter of the
    residual (same channel, target and direction in every run). Ballbar groups: the
    scatter of each direction's residual about a saturated smooth fit (Fourier series
    in the angle, up to min(40, n/8) harmonics); the lag-1 autocorrelation rho of that
    scatter inflates the variance by (1 + rho) / (1 - rho). Returns (sigma (G,),
    inflation (G,), report dict). ``r`` is the current residual (N,).
    """
    G = len(prob.group_names)
    pair: dict[int, float | None] = {}
    sig = np.full(G, NOISE_FLOOR)
    infl = np.ones(G)
    dof = np.zeros(G)
    for i, c in enumerate(prob.checks):
        s = prob.slice(i)
        rr = r[s]
        for g in np.unique(c.group):
            gg = int(g) + int(prob.group[s][0] - c.group[0])
            sel = c.group == g
            cells = c.cell[sel]
            x = rr[sel]
            if np.all(cells >= 0):
                _, inv, cnt = np.unique(cells, return_inverse=True, return_counts=True)
                means = np.bincount(inv, weights=x) / cnt
                dev = x - means[inv]
                d = x.size - cnt.size
                if d >= 2:
                    sig[gg] = max(NOISE_FLOOR, math.sqrt(float(dev @ dev) / d))
                    dof[gg] = d
                    continue
            # Saturated smooth fit per direction (ballbar) / per run and direction.
            ss, d_tot, rho_num, rho_den = 0.0, 0, 0.0, 0.0
            labels = c.direction[sel].astype(str)
            xs = c.x[sel]
            for lab in np.unique(labels):
                m = labels == lab
                xv, rv = xs[m], x[m]
                n = xv.size
                K = int(min(40, max(1, n // 8)))
                if c.kind == "ballbar":
                    th = np.radians(xv)
                    cols = [np.ones(n)]
                    for k in range(1, K + 1):
                        cols += [np.cos(k * th), np.sin(k * th)]
                else:
                    u = (2 * xv - xv.min() - xv.max()) / max(np.ptp(xv), 1e-9)
                    cols = list(np.polynomial.chebyshev.chebvander(u, min(K, n - 2)).T)
                A = np.stack(cols, axis=1)
                coef, *_ = np.linalg.lstsq(A, rv, rcond=None)
                e = rv - A @ coef
                ss += float(e @ e)
                d_tot += max(n - A.shape[1], 0)
                rho_num += float(e[1:] @ e[:-1])
                rho_den += float(e @ e)
            if d_tot >= 2:
                sig[gg] = max(NOISE_FLOOR, math.sqrt(ss / d_tot))
                dof[gg] = d_tot
                rho = rho_num / rho_den if rho_den > 0 else 0.0
                rho = min(max(rho, 0.0), 0.9)
                infl[gg] = (1 + rho) / (1 - rho)
            if c.kind == "ballbar":
                pair[gg] = _pair_sigma(xs, labels, x)
    rep = {prob.group_names[g]: {"sigma": round(float(sig[g]), 5), "unit": prob.group_units[g],
                                 "inflation": round(float(infl[g]), 4), "dof": int(dof[g])}
           for g in range(G)}
    for g, v in pair.items():
        if v is not None:
            rep[prob.group_names[g]]["pair_sigma"] = round(float(v), 5)
    return sig, infl, rep


def _pair_sigma(ang: np.ndarray, labels: np.ndarray, r: np.ndarray) -> float | None:
    """Cross-check of a ballbar's noise from its CW/CCW pair: the CW residual taken at the
    CCW angles (periodic interpolation), the difference of the pair about a smooth fit,
    divided by sqrt(2). Direction-dependent effects not yet modelled inflate it."""
    a, b = labels == "ccw", labels == "cw"
    if a.sum() < 16 or b.sum() < 16:
        return None
    o = np.argsort(ang[b])
    cw = np.interp(ang[a], ang[b][o], r[b][o], period=360.0)
    d = r[a] - cw
    th = np.radians(ang[a])
    K = int(min(40, max(1, d.size // 8)))
    cols = [np.ones(d.size)] + [f(k * th) for k in range(1, K + 1) for f in (np.cos, np.sin)]
    A = np.stack(cols, axis=1)
    e = d - A @ np.linalg.lstsq(A, d, rcond=None)[0]
    dof = d.size - A.shape[1]
    if dof < 2:
        return None
    return math.sqrt(float(e @ e) / dof / 2.0)


# --------------------------------------------------------------------------- candidates


@dataclass
class Cand:
    """A candidate with its sensitivity columns at the current model."""

    spec: EffectSpec
    cols: np.ndarray              # (N, k) raw sensitivities (units of y per unit parameter)
    param_idx: list[int]          # which of spec.params the columns are
    scan_value: float | None = None
    n_scan: int = 1               # independent grid points searched (look-elsewhere)
    observable: bool = True
    why_not: str = ""
    #: fixed change of the prediction the grid value itself causes (e.g. a new take-up of a
    #: backlash the model already has), or None
    offset: np.ndarray | None = None


class Engine:
    """Holds the problem, the base model and the candidate sensitivities."""

    def __init__(self, table: Table, checks: list[Check], opts: DiagnoseOptions,
                 pp: PredParams | None = None, ev: Evaluator | None = None) -> None:
        self.opts = opts
        self.table = table
        self.pp = pp.copy() if pp is not None else PredParams()
        self.ev = ev or Evaluator(opts.backend)
        self.prob = Problem(checks)
        # One drift variable for all checks: the temperature if a check has one (the drift
        # then goes into the table's thermal term; checks without a temperature carry no
        # drift), else the time, else the run index.
        units = [set(c.drift_options) for c in checks]
        self.drift_unit = next((u for u in ("K", "h", "run") if any(u in s for s in units)),
                               None)
        for c in checks:
            c.set_drift_unit(self.drift_unit)
        self.drift_on_table = self.drift_unit == "K"
        self.tref_c = 20.0
        if self.drift_on_table:
            temps = [getattr(c, "temp_first_c", None) for c in checks]
            temps = [t for t in temps if t is not None]
            self.tref_c = float(temps[0]) if temps else 20.0
        self.y0 = self.prob.predict(self.ev, table, self.pp)
        self.r0 = self.prob.y - self.y0

    def on_checks(self, checks: list[Check], table: Table) -> "Engine":
        """The same settings (options, prediction parameters, drift variable, evaluator)
        on other checks, e.g. hypothetical tests of a separating-test search."""
        sub = Engine.__new__(Engine)
        sub.opts, sub.table, sub.pp, sub.ev = self.opts, table, self.pp, self.ev
        sub.prob = Problem(checks)
        for c in checks:
            c.set_drift_unit(self.drift_unit)
        sub.drift_unit, sub.drift_on_table = self.drift_unit, self.drift_on_table
        sub.tref_c = self.tref_c
        sub.y0 = sub.prob.predict(sub.ev, table, self.pp)
        sub.r0 = sub.prob.y - sub.y0
        return sub

    # ---------------------------------------------------------------- sensitivities

    def apply(self, table: Table, pp: PredParams, spec: EffectSpec, theta: np.ndarray,
              scan_value: float | None) -> tuple[Table, PredParams]:
        return spec.apply(table, pp, theta, scan_value, drift_on_table=self.drift_on_table,
                          tref_c=self.tref_c)

    def sensitivity(self, spec: EffectSpec, scan_value: float | None, table: Table,
                    pp: PredParams, y_ref: np.ndarray) -> np.ndarray:
        """(N, k) d prediction / d parameter, by re-predicting through the model."""
        return self.sensitivity_offset(spec, scan_value, table, pp, y_ref)[0]

    def sensitivity_offset(self, spec: EffectSpec, scan_value: float | None, table: Table,
                           pp: PredParams, y_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """(N, k) d prediction / d parameter by re-predicting through the model, and the
        change (N,) the grid value alone causes (None if it causes none)."""
        k = len(spec.params)
        cols = np.zeros((self.prob.N, k))
        offset = None
        for i, ps in enumerate(spec.params):
            h = ps.typical * FD_FRACTION
            th = np.zeros(k)
            th[i] = h
            t2, p2 = self.apply(table, pp, spec, th, scan_value)
            if scan_value is not None and (
                    (spec.kind == "backlash" and table.axes[spec.axis].backlash_um)  # type: ignore[index]
                    or (spec.kind == "thermal" and not self.drift_on_table
                        and (np.any(pp.drift_offset) or np.any(pp.drift_scale_ppm)))):
                # the take-up changes the state of an existing backlash too: difference
                # against the same take-up with zero added reversal
                if offset is None:
                    t0, p0 = self.apply(table, pp, spec, np.zeros(k), scan_value)
                    base = self.prob.predict(self.ev, t0, p0)
                    offset = base - y_ref
                    if not np.any(np.abs(offset) > 1e-9):
                        offset = None
                else:
                    base = y_ref + offset
            else:
                base = y_ref
            cols[:, i] = (self.prob.predict(self.ev, t2, p2) - base) / h
        return cols, offset

    def own_probe(self, axis: str, table: Table, pp: PredParams, y_ref: np.ndarray) -> np.ndarray:
        """d prediction / d (own positioning term of ``axis``), per sample: the model's
        response to a constant added to the term (through the library)."""
        t = copy_table(table)
        ax = t.axes[axis]
        from abbe.diagnose.effects import ensure_term, ensure_trend
        ensure_trend(ax, 0)
        ensure_term(ax, OWN_TERM[axis])
        h = 1.0
        ax.coef[OWN_TERM[axis]] = np.asarray(ax.coef[OWN_TERM[axis]], dtype=np.float64).copy()
        ax.coef[OWN_TERM[axis]][0] += h
        g = (self.prob.predict(self.ev, t, pp) - y_ref) / h
        # samples the term cannot reach differ only by float32 rounding: exactly zero
        g[np.abs(g) < 1e-3 * max(float(np.max(np.abs(g))), 1e-300)] = 0.0
        return g

    def build_candidates(self, table: Table, pp: PredParams, y_ref: np.ndarray,
                         W: np.ndarray, Qn: np.ndarray, specs: list[EffectSpec]) -> list[Cand]:
        """Sensitivity columns of every candidate at (table, pp), observability pruned."""
        out: list[Cand] = []
        self._probe: dict[str, np.ndarray] = {}
        self._alts: dict[str, list[Cand]] = {}
        for spec in specs:
            if spec.kind == "cyclic":
                out.append(self._cyclic_cand(spec, table, pp, y_ref, W, Qn))
                continue
            if spec.kind == "thermal" and self.drift_unit is None:
                out.append(Cand(spec, np.zeros((self.prob.N, 0)), [], observable=False,
                                why_not="no time or temperature in the checks"))
                continue
            scan_vals: list[float | None] = [None]
            if spec.kind == "backlash":
                scan_vals = self._takeup_grid(spec.axis, table)  # type: ignore[arg-type]
            elif spec.kind == "thermal" and not self.drift_on_table:
                scan_vals = self._tau_grid()
            # parameter subsets: all, and without the optional ones
            subsets = [list(range(len(spec.params)))]
            req = [i for i, ps in enumerate(spec.params) if not ps.optional]
            if len(req) < len(subsets[0]):
                subsets.append(req)
            alts: list[Cand] = []
            failed: Cand | None = None
            for sv in scan_vals:
                try:
                    cols, off = self.sensitivity_offset(spec, sv, table, pp, y_ref)
                except NotRepresentable as exc:
                    failed = Cand(spec, np.zeros((self.prob.N, 0)), [], observable=False,
                                  why_not=str(exc))
                    break
                for sub in subsets:
                    c = self._prune(Cand(spec, cols[:, sub], sub, sv), W, Qn)
                    c.offset = off
                    if c.observable:
                        alts.append(c)
            n_alt = max(len(scan_vals) * len(subsets), 1)
            if failed is not None or not alts:
                c = failed or Cand(spec, np.zeros((self.prob.N, 0)), [], observable=False,
                                   why_not="no signature on these checks (at a typical magnitude "
                                           "it is below the noise or absorbed by the nuisance "
                                           "terms)")
                out.append(c)
                continue
            for c in alts:
                c.n_scan = n_alt
            best = alts[0]
            if len(alts) > 1:
                self._alts[spec.key] = alts
            out.append(best)
        return out

    def _tau_grid(self) -> list[float | None]:
        """Warm-up time constants to search (drift-variable units): linear (inf) and
        0.5 .. 4 x the time span of the checks (a shorter one would saturate early in
        the check and look like a static error)."""
        span = max(float(np.max(c.drift)) for c in self.prob.checks if c.drift is not None)
        if not span > 0:
            return [math.inf]
        return [math.inf] + [f * span for f in (0.5, 1.0, 2.0, 4.0)]

    def _takeup_grid(self, axis: str, table: Table) -> list[float | None]:
        """Take-up values to search: only if a check has continuous motion (ballbar)."""
        j = AXES.index(axis)
        dyn = any(isinstance(c, BallbarCheck) and j in _plane_axes(c.plane) for c in self.prob.checks)
        if not dyn:
            tk = table.axes[axis].backlash_takeup_mm
            return [tk if tk > 0 else 1.0]
        return list(BACKLASH_TAKEUP_GRID_MM)

    def _prune(self, c: Cand, W: np.ndarray, Qn: np.ndarray) -> Cand:
        """Drop parameters the checks cannot see; mark unobservable candidates."""
        Z = _proj_out(Qn, c.cols * W[:, None])
        raw = np.linalg.norm(c.cols * W[:, None], axis=0)
        eff = np.linalg.norm(Z, axis=0)
        keep = []  # column positions (c.param_idx[pos] is the parameter)
        for pos, i in enumerate(c.param_idx):
            ps = c.spec.params[i]
            if eff[pos] * ps.typical >= 0.5 and eff[pos] >= 1e-3 * max(raw[pos], 1e-300):
                keep.append(pos)
        # collinear parameters within the candidate
        if len(keep) > 1:
            Zk = Z[:, keep] / np.linalg.norm(Z[:, keep], axis=0)
            _, s, vt = np.linalg.svd(Zk, full_matrices=False)
            while len(keep) > 1 and s[-1] < 1e-3 * s[0]:
                drop = int(np.argmax(np.abs(vt[-1])))
                keep.pop(drop)
                Zk = Z[:, keep] / np.linalg.norm(Z[:, keep], axis=0)
                _, s, vt = np.linalg.svd(Zk, full_matrices=False)
        if not keep:
            return Cand(c.spec, c.cols[:, :0], [], c.scan_value, c.n_scan, observable=False,
                        why_not="no signature on these checks (at a typical magnitude it is "
                                "below the noise or absorbed by the nuisance terms)")
        return Cand(c.spec, c.cols[:, keep], [c.param_idx[p] for p in keep], c.scan_value,
                    c.n_scan)

    def _cyclic_cand(self, spec: EffectSpec, table: Table, pp: PredParams, y_ref: np.ndarray,
                     W: np.ndarray, Qn: np.ndarray) -> Cand:
        """Cyclic: probe the own term once, then columns g(p) sin/cos(2 pi p / P) on a grid
        of periods (chosen later against the residual); the chosen period's columns are
        recomputed through the model (apply + re-predict)."""
        axis = spec.axis  # type: ignore[assignment]
        j = AXES.index(axis)  # type: ignore[arg-type]
        g = self.own_probe(axis, table, pp, y_ref)  # type: ignore[arg-type]
        self._probe[axis] = g  # type: ignore[index]
        act = g != 0.0
        c = Cand(spec, np.zeros((self.prob.N, 0)), [], observable=False)
        if act.sum() < 8:
            c.why_not = "the checks do not move this axis"
            return c
        pos = np.concatenate([ch.sample_positions()[:, j] for ch in self.prob.checks])
        self._cyc_pos = getattr(self, "_cyc_pos", {})
        self._cyc_pos[axis] = pos
        p = pos[act]
        span = float(np.ptp(p))
        if span <= 0:
            c.why_not = "the axis does not move in the checks"
            return c
        # Shortest period searched: 2 x the 10th percentile of the steps between
        # consecutive samples (a circle samples its axes non-uniformly, so periods
        # below the mean step are still resolved where the axis moves slowly), >= 1 mm.
        steps = []
        for ch in self.prob.checks:
            q = ch.sample_positions()[:, j]
            d = np.abs(np.diff(q))
            d = d[d > 1e-6]
            if d.size:
                steps.append(float(np.percentile(d, 10)))
        pmin = max(1.0, 2.0 * min(steps)) if steps else span
        pmax = min(0.5 * span, self.opts.max_period_mm)
        if pmax <= pmin:
            c.why_not = "the checks do not resolve a cyclic period (too few or too coarse samples)"
            return c
        df = 1.0 / (4.0 * span)
        freqs = np.arange(1.0 / pmax, 1.0 / pmin + df / 2, df)
        c.observable = True
        c.n_scan = max(1, int(round((freqs[-1] - freqs[0]) * span)))
        c.scan_value = None
        c.cols = np.zeros((self.prob.N, 2))
        c.param_idx = [0, 1]
        self._cyc_freqs = getattr(self, "_cyc_freqs", {})
        self._cyc_freqs[axis] = freqs
        return c

    def cyclic_cols(self, axis: str, period: float, table: Table) -> np.ndarray:
        """Probe-based cyclic columns (N, 2) at ``period`` (phase origin: travel min)."""
        g = self._probe[axis]
        p = self._cyc_pos[axis]
        o = float(table.axes[axis].travel_mm[0])
        phi = 2 * np.pi * (p - o) / period
        return np.stack([g * np.sin(phi), g * np.cos(phi)], axis=1)

    def cyclic_scan(self, axis: str, table: Table, W: np.ndarray, Qb: np.ndarray,
                    rb: np.ndarray) -> tuple[float, float]:
        """Best period (mm) and its RSS decrease on the whitened, projected residual rb."""
        freqs = self._cyc_freqs[axis]
        g = self._probe[axis] * W
        act = np.abs(g) > 0
        g, p = g[act], self._cyc_pos[axis][act]
        Qa, ra = Qb[act], rb[act]
        o = float(table.axes[axis].travel_mm[0])
        best = (float("nan"), -1.0)
        # For each frequency f: columns S = g (sin, cos)(2 pi f (p - o)); with Q the basis
        # already fitted, the RSS decrease is b' A^-1 b, A = S'S - (Q'S)'(Q'S), b = S' rb
        # (rb is orthogonal to Q). Products over samples are BLAS matrix products.
        for chunk in np.array_split(np.arange(freqs.size), max(1, freqs.size // 128)):
            f = freqs[chunk]
            phi = 2 * np.pi * np.outer(p - o, f)  # (N, F)
            Ss = g[:, None] * np.sin(phi)
            Sc = g[:, None] * np.cos(phi)
            a_ss = np.einsum("nf,nf->f", Ss, Ss)
            a_cc = np.einsum("nf,nf->f", Sc, Sc)
            a_sc = np.einsum("nf,nf->f", Ss, Sc)
            if Qa.shape[1]:
                Ms, Mc = Qa.T @ Ss, Qa.T @ Sc  # (p, F)
                a_ss = a_ss - np.einsum("kf,kf->f", Ms, Ms)
                a_cc = a_cc - np.einsum("kf,kf->f", Mc, Mc)
                a_sc = a_sc - np.einsum("kf,kf->f", Ms, Mc)
            bs, bc = ra @ Ss, ra @ Sc
            det = a_ss * a_cc - a_sc * a_sc
            ok = det > 1e-12 * np.maximum(a_ss * a_cc, 1e-300)
            d = np.where(ok, (a_cc * bs * bs - 2 * a_sc * bs * bc + a_ss * bc * bc)
                         / np.where(ok, det, 1.0), -1.0)
            i = int(np.argmax(d))
            if d[i] > best[1]:
                best = (1.0 / f[i], float(d[i]))
        # refine around the best frequency (golden section on the RSS decrease)
        if np.isfinite(best[0]):
            f0 = 1.0 / best[0]
            df = freqs[1] - freqs[0] if freqs.size > 1 else f0 * 0.01

            def gain(f: float) -> float:
                S = self.cyclic_cols(axis, 1.0 / f, table) * W[:, None]
                S = _proj_out(Qb, S)
                _, d = _lstsq_rss(S, rb)
                return d
            lo, hi = f0 - df, f0 + df
            gr = (math.sqrt(5) - 1) / 2
            a, b_ = hi - gr * (hi - lo), lo + gr * (hi - lo)
            ga, gb = gain(a), gain(b_)
            for _ in range(30):
                if ga > gb:
                    hi, b_, gb = b_, a, ga
                    a = hi - gr * (hi - lo)
                    ga = gain(a)
                else:
                    lo, a, ga = a, b_, gb
                    b_ = lo + gr * (hi - lo)
                    gb = gain(b_)
            fb = a if ga > gb else b_
            gbest = max(ga, gb)
            if gbest > best[1]:
                best = (1.0 / fb, gbest)
        return best


def _plane_axes(plane: str) -> tuple[int, int]:
    from abbe.diagnose.checks import PLANE_AXES
    return PLANE_AXES[plane]


# --------------------------------------------------------------------------- selection


@dataclass
class _Sel:
    cand: Cand
    stats: dict[str, Any]


def _r_sel(eng: "Engine", sel: list["_Sel"]) -> np.ndarray:
    """Residual of the base model minus the fixed offsets of the selected effects."""
    r = eng.r0
    for s in sel:
        if s.cand.offset is not None:
            r = r - s.cand.offset
    return r


def _weights(prob: Problem, sig: np.ndarray, infl: np.ndarray) -> np.ndarray:
    return 1.0 / (sig[prob.group] * np.sqrt(infl[prob.group]))


def _eval_candidate(eng: Engine, cand: Cand, sel: list[_Sel], W: np.ndarray, Qb: np.ndarray,
                    rb: np.ndarray, rss_base: float, dof_noise: float, n_tested: int,
                    table: Table, rb_raw: np.ndarray) -> dict[str, Any]:
    """Statistics for adding ``cand`` to the selected set."""
    prob = eng.prob
    N = prob.N
    if cand.spec.kind == "cyclic":
        period, _ = eng.cyclic_scan(cand.spec.axis, table, W, Qb, rb)  # type: ignore[arg-type]
        if not np.isfinite(period):
            return {"ok": False, "reason": "no period fits"}
        cand.scan_value = float(period)
        cand.cols = eng.cyclic_cols(cand.spec.axis, period, table)  # type: ignore[arg-type]
        cand.param_idx = [0, 1]
    S = cand.cols * W[:, None]
    Z = _proj_out(Qb, S)
    rb_c = rb if cand.offset is None else _proj_out(Qb, (rb_raw - cand.offset * W)[:, None])[:, 0]
    coef, fit = _lstsq_rss(Z, rb_c)
    dr = rss_base - (float(rb_c @ rb_c) - fit)
    k = Z.shape[1]
    k_eff = k + (1 if cand.spec.kind == "cyclic" or cand.n_scan > 1 else 0)
    p_sel = Qb.shape[1]
    dof_res = N - p_sel - k
    rss_c = max(rss_base - dr, 0.0)
    s2_res = rss_c / max(dof_res, 1)
    s2 = max(1.0, s2_res)
    dof_den = dof_noise if s2_res <= 1.0 else dof_res
    F = (dr / max(k, 1)) / s2
    p = float(stats.f.sf(F, max(k, 1), max(dof_den, 1)))
    p_eff = 1.0 - (1.0 - p) ** max(cand.n_scan, 1) if p < 1 else 1.0
    if p_eff == 0.0 or p < 1e-300:
        p_eff = min(1.0, p * max(cand.n_scan, 1))
    dbic = -dr / s2 + k_eff * math.log(N)
    # fitted contribution (um rows)
    contrib = cand.cols @ coef if k else np.zeros(N)
    um = prob.um_rows
    contrib_rms = float(np.sqrt(np.mean(contrib[um] ** 2))) if np.any(um) else 0.0
    ho = _heldout(eng, sel, cand, W, s2)
    implausible = [cand.spec.params[i].name for i, v in zip(cand.param_idx, coef)
                   if abs(v) > cand.spec.params[i].limit]
    return {"ok": True, "implausible": implausible, "F": F, "p": p, "p_eff": p_eff, "dbic": dbic, "drss": dr / s2,
            "k": k, "k_eff": k_eff, "coef": coef, "contrib_rms_um": contrib_rms,
            "heldout": ho, "s2": s2, "alpha_step": eng.opts.alpha / max(n_tested, 1)}


def _heldout(eng: Engine, sel: list[_Sel], cand: Cand | None, W: np.ndarray,
             s2: float) -> dict[str, Any]:
    """Held-out RSS (whitened, / s2) without and with ``cand``: fit the effects (and the
    nuisance) on one fold, judge the other (nuisance refitted there), and back."""
    prob = eng.prob
    r_sel = _r_sel(eng, sel) * W
    Nw = prob.nuis * W[:, None]
    X_sel = [s.cand.cols for s in sel]
    for level in (0, 1):
        sp = prob.split(level)
        if sp is None:
            continue
        lab, name = sp
        res = {}
        ok = True
        for with_c in (False, True):
            r = r_sel
            if with_c and cand is not None and cand.offset is not None:
                r = r_sel - cand.offset * W
            cols = X_sel + ([cand.cols] if (with_c and cand is not None) else [])
            X = np.hstack(cols) * W[:, None] if cols else np.zeros((prob.N, 0))
            tot = 0.0
            for f in (0, 1):
                A, B = lab == f, lab != f
                if A.sum() == 0 or B.sum() == 0:
                    ok = False
                    break
                nA = Nw[A][:, np.any(Nw[A] != 0, axis=0)]
                QA = _qr_basis(nA)
                XA = _proj_out(QA, X[A])
                if not _identifiable(XA):
                    ok = False
                    break
                beta, *_ = np.linalg.lstsq(XA, _proj_out(QA, r[A][:, None])[:, 0], rcond=None) \
                    if X.shape[1] else (np.zeros(0),)
                eB = r[B] - (X[B] @ beta if X.shape[1] else 0.0)
                nB = Nw[B][:, np.any(Nw[B] != 0, axis=0)]
                eB = _proj_out(_qr_basis(nB), eB[:, None])[:, 0]
                tot += float(eB @ eB)
            if not ok:
                break
            res["with" if with_c else "without"] = tot / s2
        if ok:
            return {"split": name, "rss_without": res["without"], "rss_with": res["with"],
                    "gain": res["without"] - res["with"]}
    return {"split": None, "gain": float("nan")}


def _qualifies(st: dict[str, Any], opts: DiagnoseOptions) -> tuple[bool, str]:
    if not st.get("ok"):
        return False, st.get("reason", "")
    if st["p_eff"] >= st["alpha_step"]:
        return False, f"not significant (p = {st['p_eff']:.2g} >= {st['alpha_step']:.2g})"
    if st["dbic"] > -opts.bic_min:
        return False, f"BIC decrease {-st['dbic']:.1f} < {opts.bic_min:g}"
    if st.get("implausible"):
        return False, "implausible value of " + ", ".join(st["implausible"])
    ho = st["heldout"]
    if ho["split"] is None:
        return False, "cannot be validated on held-out data (not identifiable in a fold)"
    need = max(2.0 * st["k_eff"], opts.heldout_fraction * st["drss"])
    if not ho["gain"] >= need:
        return False, (f"does not hold on held-out data (gain {ho['gain']:.1f} < {need:.1f} "
                       "noise units)")
    if st["contrib_rms_um"] < opts.min_effect_um and st["contrib_rms_um"] > 0:
        return False, f"too small to matter (RMS {st['contrib_rms_um']:.3f} um)"
    return True, ""


# --------------------------------------------------------------------------- main entry


def diagnose(table: Table, checks: list[Check], options: DiagnoseOptions | None = None,
             pred_params: PredParams | None = None, evaluator: Evaluator | None = None) -> DiagnoseResult:
    """Diagnose what ``table`` is missing to reproduce ``checks``; see the module doc.

    Returns a :class:`DiagnoseResult` with the named effects, the gap before/after
    (also on held-out data) and the updated table. Raises AbbeInputError for checks
    outside the model's travel or too little data to decide.
    """
    opts = options or DiagnoseOptions()
    if not checks:
        raise AbbeInputError("no check measurement given (--ballbar NAME / --laser AXIS / "
                             "--iso230-2 FILE)", field="checks")
    check_travel(checks, table)
    eng = Engine(table, checks, opts, pred_params, evaluator)
    prob = eng.prob
    specs = [s for s in catalogue() if opts.candidates is None
             or s.key in opts.candidates or s.family in opts.candidates]
    for c in checks:
        if isinstance(c, LaserCheck) and c.n_runs < 2:
            raise AbbeInputError(f"{c.name}: {c.n_runs} run: the noise cannot be estimated "
                                 "without repeated runs (ISO 230-2: 5 bidirectional runs; at "
                                 "least 2 needed)", file=c.source, field="run")
    max_k = max(len(s.params) for s in specs) if specs else 1
    n_nuis = prob.nuis.shape[1]
    need = max(30, 3 * (n_nuis + 2 * max_k + 2))
    if prob.N < need:
        raise AbbeInputError(f"too few points to decide: {prob.N} samples for {n_nuis} nuisance "
                             f"terms; need at least {need}",
                             file=checks[0].source if len(checks) == 1 and checks[0].source
                             else None, field="checks")
    # Before.
    r0 = eng.r0
    clean0 = _remove_nuisance(prob, r0)
    gap_before = _gap(prob, clean0)
    if gap_before is not None and gap_before.rms_um > 200.0:
        raise AbbeInputError(
            f"the model misses the measurement by {gap_before.rms_um:.0f} um RMS (after centre/zero "
            "removal): the model and the measurement do not belong to the same machine, or a "
            "unit/sign is wrong; nothing can be diagnosed", field="model")

    # Noise and weights from the base residual (re-estimated after each addition).
    sig, infl, noise_rep = estimate_noise(prob, clean0)
    W = _weights(prob, sig, infl)
    dof_noise = float(sum(v["dof"] for v in noise_rep.values())) or float(prob.N)
    Qn = _qr_basis(prob.nuis * W[:, None])
    cands = eng.build_candidates(table, eng.pp, eng.y0, W, Qn, specs)
    not_obs = [f"{c.spec.key}: {c.why_not}" for c in cands if not c.observable]
    pool = [c for c in cands if c.observable]

    selected: list[_Sel] = []
    tested: dict[str, dict[str, Any]] = {}
    notes: list[str] = []
    rw = eng.r0 * W
    while len(selected) < opts.max_effects:
        rw = _r_sel(eng, selected) * W
        X_sel = np.hstack([s.cand.cols for s in selected]) * W[:, None] if selected \
            else np.zeros((prob.N, 0))
        Qb = _qr_basis(np.hstack([prob.nuis * W[:, None], X_sel]))
        rb = _proj_out(Qb, rw[:, None])[:, 0]
        rss_base = float(rb @ rb)
        remaining = [c for c in pool if c.spec.key not in {s.cand.spec.key for s in selected}]
        if not remaining:
            break
        results = []
        for c in remaining:
            alts = eng._alts.get(c.spec.key)
            if alts:
                # nonlinear grid value / parameter subset: the alternative with the best BIC
                best_c, best_b = None, math.inf
                for a in alts:
                    Z = _proj_out(Qb, a.cols * W[:, None])
                    ra = rb if a.offset is None else \
                        _proj_out(Qb, (rw - a.offset * W)[:, None])[:, 0]
                    _, fit = _lstsq_rss(Z, ra)
                    d = rss_base - (float(ra @ ra) - fit)
                    b = -d + Z.shape[1] * math.log(prob.N)
                    if b < best_b:
                        best_c, best_b = a, b
                if best_c is not None:
                    c.cols, c.param_idx, c.scan_value = best_c.cols, best_c.param_idx, best_c.scan_value
                    c.offset = best_c.offset
            st = _eval_candidate(eng, c, selected, W, Qb, rb, rss_base, dof_noise,
                                 len(remaining), table, rw)
            ok, why = _qualifies(st, opts)
            st["qualifies"], st["why_not"] = ok, why
            results.append((c, st))
            tested[c.spec.key] = _summ(st, c)
        good = [(c, st) for c, st in results if st["qualifies"]]
        if not good:
            break
        c, st = min(good, key=lambda cs: cs[1]["dbic"])
        selected.append(_Sel(c, st))
        tested[c.spec.key]["selected"] = True
        # re-estimate the noise with the effect in the model
        theta_lin = _linear_fit(prob, _r_sel(eng, selected), selected, W)
        rr = _r_sel(eng, selected) - sum((s.cand.cols @ th) for s, th in zip(selected, theta_lin))
        sig, infl, noise_rep = estimate_noise(prob, _remove_nuisance(prob, rr))
        W = _weights(prob, sig, infl)
        dof_noise = float(sum(v["dof"] for v in noise_rep.values())) or float(prob.N)

    # Backward check: every selected effect must still be significant with the others.
    selected = _backward(eng, selected, W, dof_noise, notes)

    # Final fit through the model (Gauss-Newton), values, intervals.
    new_table, new_pp, values, cov, s2_final = _final_fit(eng, selected, W)
    y_after = prob.predict(eng.ev, new_table, new_pp)
    r_after = prob.y - y_after
    clean_after = _remove_nuisance(prob, r_after)
    gap_after = _gap(prob, clean_after)

    # Held-out gap through the model: fit on one fold, judge the other (and back).
    ho_before, ho_after, ho_split = _heldout_gap(eng, selected, W, clean0)

    effects = _describe(eng, selected, values, cov, s2_final, W, pool, new_table, new_pp)
    lof = _lack_of_fit(eng, r_after)
    tentative = lof > LACK_OF_FIT_LIMIT
    if not effects and not tentative:
        obs = ", ".join(c.spec.key for c in pool) or "none"
        notes.insert(0, "Nothing is missing: no candidate effect is significant against the "
                        f"noise on these checks (tested: {obs}).")
    undecided = [k for k, v in tested.items() if not v.get("selected") and v.get("significant")
                 and k not in {e.key for e in effects}]
    if undecided:
        notes.append("Significant but not named (failed the held-out or size test): "
                     + ", ".join(f"{k} ({tested[k]['why_not']})" for k in undecided))
    if tentative:
        notes.insert(0, (
            f"LACK OF FIT: after the update the residual is still {lof:.1f} x the noise. "
            + ("The named effects are TENTATIVE: the model may not belong to this machine, or "
               "something outside the catalogue is present; check the model and the tests "
               "before using the update." if effects else
               "Nothing in the catalogue explains it: the model may not belong to this machine, "
               "or something outside the catalogue is present.")))
        for e in effects:
            e.tentative = True
    return DiagnoseResult(
        effects=effects,
        gap={"before": gap_before, "after": gap_after, "held_out_before": ho_before,
             "held_out_after": ho_after},
        table=new_table, pred_params=new_pp, base_table=table, checks=checks,
        residual_before=[clean0[prob.slice(i)] for i in range(len(checks))],
        residual_after=[clean_after[prob.slice(i)] for i in range(len(checks))],
        noise=noise_rep, tested=tested, not_observable=not_obs, notes=notes,
        backend=eng.ev.backend, drift_unit=eng.drift_unit, lack_of_fit=lof, tentative=tentative,
        heldout_split=ho_split)


def _summ(st: dict[str, Any], c: Cand) -> dict[str, Any]:
    d = {"significant": bool(st.get("ok") and st["p_eff"] < st["alpha_step"]),
         "qualifies": bool(st.get("qualifies")), "why_not": st.get("why_not", "")}
    if st.get("ok"):
        d.update({"p_value": float(f"{st['p_eff']:.3g}"), "delta_bic": round(st["dbic"], 2),
                  "F": round(st["F"], 3), "heldout_gain": (None if not np.isfinite(st["heldout"]["gain"])
                                                            else round(st["heldout"]["gain"], 2)),
                  "contribution_rms_um": round(st["contrib_rms_um"], 4)})
        if c.scan_value is not None:
            d["scan"] = {c.spec.scan or "scan": round(float(c.scan_value), 4)}
    return d


def _linear_fit(prob: Problem, r: np.ndarray, sel: list[_Sel], W: np.ndarray) -> list[np.ndarray]:
    """Coefficients of the selected effects (with nuisance) on residual r, whitened LS."""
    if not sel:
        return []
    X = np.hstack([prob.nuis] + [s.cand.cols for s in sel]) * W[:, None]
    coef, *_ = np.linalg.lstsq(X, r * W, rcond=None)
    out, k = [], prob.nuis.shape[1]
    for s in sel:
        n = s.cand.cols.shape[1]
        out.append(coef[k:k + n])
        k += n
    return out


def _backward(eng: Engine, sel: list[_Sel], W: np.ndarray, dof_noise: float,
              notes: list[str]) -> list[_Sel]:
    prob = eng.prob
    changed = True
    while changed and len(sel) > 1:
        changed = False
        for i, s in enumerate(sel):
            others = sel[:i] + sel[i + 1:]
            X_o = np.hstack([o.cand.cols for o in others]) * W[:, None]
            Qb = _qr_basis(np.hstack([prob.nuis * W[:, None], X_o]))
            rb = _proj_out(Qb, (_r_sel(eng, others) * W)[:, None])[:, 0]
            rb_s = _proj_out(Qb, (_r_sel(eng, sel) * W)[:, None])[:, 0]
            Z = _proj_out(Qb, s.cand.cols * W[:, None])
            _, fit = _lstsq_rss(Z, rb_s)
            dr = float(rb @ rb) - (float(rb_s @ rb_s) - fit)
            k = Z.shape[1]
            dof_res = prob.N - Qb.shape[1] - k
            s2 = max(1.0, (float(rb_s @ rb_s) - fit) / max(dof_res, 1))
            F = dr / max(k, 1) / s2
            p = float(stats.f.sf(F, max(k, 1), max(dof_noise, 1)))
            if p > eng.opts.alpha or (-dr / s2 + k * math.log(prob.N)) > -eng.opts.bic_min:
                notes.append(f"{s.cand.spec.key} dropped: no longer significant once "
                             + ", ".join(o.cand.spec.key for o in others) + " are in the model")
                sel = others
                changed = True
                break
    return sel


def _apply_all(eng: Engine, sel: list[_Sel], values: list[np.ndarray],
               table: Table | None = None, pp: PredParams | None = None) -> tuple[Table, PredParams]:
    t = table if table is not None else eng.table
    p = pp if pp is not None else eng.pp
    for s, v in zip(sel, values):
        th = np.zeros(len(s.cand.spec.params))
        th[s.cand.param_idx] = v
        t, p = eng.apply(t, p, s.cand.spec, th, s.cand.scan_value)
    return t, p


def _final_fit(eng: Engine, sel: list[_Sel], W: np.ndarray
               ) -> tuple[Table, PredParams, list[np.ndarray], np.ndarray, float]:
    """Gauss-Newton through the model: values of the selected parameters, covariance."""
    prob = eng.prob
    if not sel:
        return copy_table(eng.table), eng.pp.copy(), [], np.zeros((0, 0)), 1.0
    values = _linear_fit(prob, _r_sel(eng, sel), sel, W)
    for it in range(3):
        t, p = _apply_all(eng, sel, values)
        y = prob.predict(eng.ev, t, p)
        r = prob.y - y
        # re-linearise (columns at the current point)
        cols = []
        for s, v in zip(sel, values):
            c = eng.sensitivity(s.cand.spec, s.cand.scan_value, t, p, y)
            cols.append(c[:, s.cand.param_idx])
        X = np.hstack([prob.nuis] + cols) * W[:, None]
        d, *_ = np.linalg.lstsq(X, r * W, rcond=None)
        k = prob.nuis.shape[1]
        step_norm = 0.0
        new_vals = []
        for s, v, c in zip(sel, values, cols):
            n = c.shape[1]
            dv = d[k:k + n]
            k += n
            new_vals.append(v + dv)
            step_norm = max(step_norm, float(np.max(np.abs(dv) / np.array(
                [s.cand.spec.params[i].typical for i in s.cand.param_idx]))))
        values = new_vals
        if step_norm < 1e-4:
            break
    t, p = _apply_all(eng, sel, values)
    y = prob.predict(eng.ev, t, p)
    r = (prob.y - y) * W
    Q = _qr_basis(prob.nuis * W[:, None])
    Xe = _proj_out(Q, np.hstack(cols) * W[:, None])
    re = _proj_out(Q, r[:, None])[:, 0]
    dof = max(prob.N - Q.shape[1] - Xe.shape[1], 1)
    s2 = max(1.0, float(re @ re) / dof)
    cov = s2 * np.linalg.pinv(Xe.T @ Xe)
    return t, p, values, cov, s2


def _heldout_gap(eng: Engine, sel: list[_Sel], W: np.ndarray, clean0: np.ndarray
                 ) -> tuple[GapStats | None, GapStats | None, str | None]:
    """Gap on held-out data: effect parameters fitted on one fold (linearised, with the
    fold's nuisance), the updated model predicted through the library on the other fold
    (nuisance refitted there); both ways, pooled."""
    prob = eng.prob
    for level in (0, 1):
        sp = prob.split(level)
        if sp is None:
            continue
        lab, name = sp
        before = np.full(prob.N, np.nan)
        after = np.full(prob.N, np.nan)
        ok = True
        for f in (0, 1):
            A, B = lab == f, lab != f
            if A.sum() == 0 or B.sum() == 0:
                ok = False
                break
            before_B = _remove_nuisance(prob, eng.r0, B)
            before[B] = before_B[B]
            if not sel:
                after[B] = before_B[B]
                continue
            X = np.hstack([s.cand.cols for s in sel]) * W[:, None]
            nA = (prob.nuis * W[:, None])[A]
            nA = nA[:, np.any(nA != 0, axis=0)]
            QA = _qr_basis(nA)
            XA = _proj_out(QA, X[A])
            if not _identifiable(XA):
                ok = False
                break
            beta, *_ = np.linalg.lstsq(XA, _proj_out(QA, (_r_sel(eng, sel) * W)[A][:, None])[:, 0],
                                       rcond=None)
            vals, k = [], 0
            for s in sel:
                n = s.cand.cols.shape[1]
                vals.append(beta[k:k + n])
                k += n
            t, p = _apply_all(eng, sel, vals)
            r = prob.y - prob.predict(eng.ev, t, p)
            after_B = _remove_nuisance(prob, r, B)
            after[B] = after_B[B]
        if ok:
            return _gap(prob, before), _gap(prob, after), name
    return None, None, None


def _describe(eng: Engine, sel: list[_Sel], values: list[np.ndarray], cov: np.ndarray,
              s2: float, W: np.ndarray, pool: list[Cand], table: Table,
              pp: PredParams) -> list[EffectResult]:
    """EffectResult per selected effect: value, 95 % interval, evidence, ambiguity."""
    prob = eng.prob
    out: list[EffectResult] = []
    dof = max(prob.N - prob.nuis.shape[1] - sum(len(v) for v in values), 1)
    tq = float(stats.t.ppf(0.975, dof))
    k0 = 0
    for i, (s, v) in enumerate(zip(sel, values)):
        spec = s.cand.spec
        n = len(v)
        C = cov[k0:k0 + n, k0:k0 + n]
        k0 += n
        params = []
        for jj, pi in enumerate(s.cand.param_idx):
            ps = spec.params[pi]
            sd = math.sqrt(max(C[jj, jj], 0.0))
            params.append({"name": ps.name, "value": _r(v[jj]), "unit": _unit(ps.unit, spec, eng),
                           "ci95": [_r(v[jj] - tq * sd), _r(v[jj] + tq * sd)]})
        value, unit, ci = _headline(spec, s.cand.param_idx, v, C, tq, eng)
        # evidence: residual before/after adding this effect (through the model)
        t_b, p_b = _apply_all(eng, sel[:i], values[:i])
        t_a, p_a = _apply_all(eng, sel[:i + 1], values[:i + 1])
        rb_ = _remove_nuisance(prob, prob.y - prob.predict(eng.ev, t_b, p_b))
        ra_ = _remove_nuisance(prob, prob.y - prob.predict(eng.ev, t_a, p_a))
        gb, ga = _gap(prob, rb_), _gap(prob, ra_)
        st = s.stats
        ho = st["heldout"]
        ev = {
            "residual_before": None if gb is None else gb.to_json(),
            "residual_after": None if ga is None else ga.to_json(),
            "delta_bic": round(st["dbic"], 2),
            "F": round(st["F"], 3),
            "p_value": float(f"{st['p_eff']:.3g}"),
            "heldout_split": ho["split"],
            "heldout_rss_before": round(ho.get("rss_without", float("nan")), 2),
            "heldout_rss_after": round(ho.get("rss_with", float("nan")), 2),
            "heldout_change_percent": round(100.0 * (ho["rss_with"] - ho["rss_without"])
                                            / max(ho["rss_without"], 1e-300), 2),
            "contribution_rms_um": round(st["contrib_rms_um"], 4),
            "checks": _per_check_contrib(eng, s, v),
        }
        if spec.kind == "backlash":
            b0 = eng.table.axes[spec.axis]  # type: ignore[index]
            if b0.backlash_um:
                ev["model_before"] = {"backlash_um": float(b0.backlash_um),
                                      "takeup_mm": float(b0.backlash_takeup_mm)}
                ev["note"] = ("the model already had a backlash term: the value is the change of "
                              "the reversal; the take-up is the one that fits the checks")
        amb = _ambiguity(eng, sel, i, v, W, pool, table, pp)
        if spec.kind == "tool_offset":
            zs = {round(float(c.center_mm[2]), 3) for c in prob.checks
                  if isinstance(c, BallbarCheck)}
            if len(zs) <= 1:
                amb.append({"key": "model_angular_error", "id": "model error", "r2": None,
                            "separating_test": "a circle at another Z height or with another "
                                               "tool length (a tool offset scales with the "
                                               "tool length, an error of the model's angular "
                                               "terms with the height)"})
        scan = None
        if s.cand.scan_value is not None and spec.scan:
            name = spec.scan if spec.kind != "thermal" else f"tau_{eng.drift_unit or 'h'}"
            scan = {name: float(s.cand.scan_value)}
        where = "table" if spec.compensable and not (spec.kind == "thermal" and not eng.drift_on_table) \
            else "prediction model only"
        remedy = spec.remedy
        if spec.kind == "thermal" and not eng.drift_on_table:
            remedy = ("not compensable by the table without a temperature input: warm the machine "
                      "up before measuring / machining, or log the temperature (laser temp_c) so "
                      "the table's thermal term can be fitted")
        out.append(EffectResult(
            id=spec.family, key=spec.key, value=value, unit=unit, ci95=ci, params=params,
            compensable=where == "table", where=where, physics=spec.physics, remedy=remedy,
            evidence=ev, axis=spec.axis, plane=spec.plane, scan=scan, ambiguous_with=amb,
            stage_before=[rb_[prob.slice(k)] for k in range(len(prob.checks))],
            stage_after=[ra_[prob.slice(k)] for k in range(len(prob.checks))]))
    return out


def _unit(u: str, spec: EffectSpec, eng: Engine) -> str:
    if spec.kind == "thermal":
        per = eng.drift_unit or "h"
        return f"{u}/{per}"
    return u


def _headline(spec: EffectSpec, idx: list[int], v: np.ndarray, C: np.ndarray, tq: float,
              eng: Engine) -> tuple[float, str, tuple[float, float]]:
    """The effect's value, unit and 95 % interval (amplitude for cyclic, norm for the tool
    offset, offset rate for the drift: else the single parameter)."""
    if spec.kind == "cyclic":
        a = float(np.hypot(v[0], v[1]))
        g = np.array([v[0], v[1]]) / max(a, 1e-300)
        sd = math.sqrt(max(float(g @ C @ g), 0.0))
        return a, "um", (max(0.0, a - tq * sd), a + tq * sd)
    if spec.kind == "tool_offset":
        a = float(np.linalg.norm(v))
        g = v / max(a, 1e-300)
        sd = math.sqrt(max(float(g @ C @ g), 0.0))
        return a, "mm", (max(0.0, a - tq * sd), a + tq * sd)
    if spec.kind == "thermal":
        i = 0 if 0 in idx else None
        if i is None:
            jj = 0
            return float(v[jj]), _unit(spec.params[idx[0]].unit, spec, eng), \
                (float(v[jj] - tq * math.sqrt(C[jj, jj])), float(v[jj] + tq * math.sqrt(C[jj, jj])))
        jj = idx.index(0)
        sd = math.sqrt(max(C[jj, jj], 0.0))
        return float(v[jj]), _unit("um", spec, eng), (float(v[jj] - tq * sd), float(v[jj] + tq * sd))
    sd = math.sqrt(max(C[0, 0], 0.0))
    return float(v[0]), spec.params[idx[0]].unit, (float(v[0] - tq * sd), float(v[0] + tq * sd))


def _per_check_contrib(eng: Engine, s: _Sel, v: np.ndarray) -> dict[str, float]:
    prob = eng.prob
    contrib = s.cand.cols @ v
    out = {}
    for i, c in enumerate(prob.checks):
        sl = prob.slice(i)
        out[c.name] = round(float(np.sqrt(np.mean(contrib[sl] ** 2))), 4)
    return out


def _ambiguity(eng: Engine, sel: list[_Sel], i: int, v: np.ndarray, W: np.ndarray,
               pool: list[Cand], table: Table, pp: PredParams) -> list[dict[str, Any]]:
    """Other candidates that reproduce >= ambiguity_r2 of this effect's fitted signature."""
    prob = eng.prob
    s = sel[i]
    others = [o for j, o in enumerate(sel) if j != i]
    X_o = np.hstack([o.cand.cols for o in others]) * W[:, None] if others else np.zeros((prob.N, 0))
    Qb = _qr_basis(np.hstack([prob.nuis * W[:, None], X_o]))
    sig = _proj_out(Qb, (s.cand.cols @ v * W)[:, None])[:, 0]
    nrm = float(sig @ sig)
    if nrm <= 0:
        return []
    out = []
    sel_keys = {o.cand.spec.key for o in sel}
    for c in pool:
        if c.spec.key in sel_keys or c.cols.shape[1] == 0:
            continue
        cols = c.cols
        if c.spec.kind == "cyclic":
            per, _ = eng.cyclic_scan(c.spec.axis, table, W, Qb, sig)  # type: ignore[arg-type]
            if not np.isfinite(per):
                continue
            cols = eng.cyclic_cols(c.spec.axis, per, table)  # type: ignore[arg-type]
        Z = _proj_out(Qb, cols * W[:, None])
        coef, d = _lstsq_rss(Z, sig)
        r2 = d / nrm
        ps = [c.spec.params[i] for i in c.param_idx] if c.spec.kind != "cyclic" else \
            list(c.spec.params)
        if any(abs(x) > p.limit for x, p in zip(coef, ps)):
            continue  # only with an implausible value
        if r2 >= eng.opts.ambiguity_r2:
            out.append({"key": c.spec.key, "id": c.spec.family, "r2": round(r2, 4),
                        "value": [round(float(x), 4) for x in coef],
                        "unit": [p.unit for p in ps],
                        "separating_test": _separating_test(eng, s, v, c, coef, table)})
    return out


def _separating_test(eng: Engine, s: _Sel, v: np.ndarray, other: Cand, coef: np.ndarray,
                     table: Table) -> str:
    """The standard test (ballbar in each plane, CW + CCW; laser line per axis) on which the
    two explanations differ most, computed through the model on hypothetical checks."""
    from cases.hidden_effects import standard_checks
    best, best_d = "a test in another plane or a laser line of the axis", 0.0
    try:
        hyp = standard_checks(table)
    except Exception:  # pragma: no cover - defensive
        return best
    for hc in hyp:
        sub = eng.on_checks([hc], table)
        y0 = sub.y0
        try:
            a = sub.sensitivity(s.cand.spec, s.cand.scan_value, table, eng.pp, y0)[:, s.cand.param_idx] @ v
            if other.spec.kind == "cyclic":
                continue
            b = sub.sensitivity(other.spec, other.scan_value, table, eng.pp, y0)[:, other.param_idx] @ coef
        except NotRepresentable:
            continue
        Q = _qr_basis(sub.prob.nuis)
        d = _proj_out(Q, (a - b)[:, None])[:, 0]
        dn = float(np.sqrt(np.mean(d * d)))
        if dn > best_d:
            best, best_d = (f"{hc.name} (the two explanations differ by {dn:.2f} um RMS there)",
                            dn)
    if best_d < 0.1:
        return ("none of the standard tests (ballbar XY/YZ/ZX CW+CCW, laser X/Y/Z) separates "
                "them by 0.1 um or more")
    return best


#: Residual RMS after the update, in noise units, above which the names are tentative.
LACK_OF_FIT_LIMIT = 2.0


def _lack_of_fit(eng: Engine, r_after: np.ndarray) -> float:
    """RMS of the residual after the update in units of the noise (with the
    autocorrelation inflation), about 1 when the updated model explains the checks."""
    prob = eng.prob
    clean = _remove_nuisance(prob, r_after)
    sig, infl, _ = estimate_noise(prob, clean)
    w = _weights(prob, sig, infl)
    return float(np.sqrt(np.nanmean((clean * w) ** 2)))


# --------------------------------------------------------------------------- front ends


def load_model(path: str | Any) -> Table:
    """A table from a blob (``model.bin``) or a table JSON (``model.json``); AbbeInputError
    naming the file on any problem."""
    import json
    from pathlib import Path
    from abbe.formats.blob import TableError, read_blob, table_from_json
    if isinstance(path, Table):
        return path
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise AbbeInputError(f"cannot read the model: {exc.strerror}", file=str(p),
                             field="model") from None
    if data[:4] == b"ABBE":
        try:
            return read_blob(data, source=str(p))
        except TableError as exc:
            raise AbbeInputError(exc.message, file=str(p), field=exc.field or "model") from None
    try:
        d = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError):
        raise AbbeInputError("not an abbe table: neither a blob (magic ABBE) nor table JSON",
                             file=str(p), field="model") from None
    return table_from_json(d, str(p))


def check_model_matches(table: Table, machine: Any, model_source: str = "model") -> None:
    """The model must belong to the machine file: same reference point (1 um), and every
    fitted travel inside the machine's travel (1 mm); else AbbeInputError."""
    ref_m = np.asarray(machine.reference_mm, dtype=np.float64)
    ref_t = np.asarray(table.reference_mm, dtype=np.float64)
    if np.max(np.abs(ref_m - ref_t)) > 1e-3:
        raise AbbeInputError(
            f"the model's reference point {tuple(round(v, 3) for v in ref_t)} mm differs from the "
            f"machine file's {tuple(round(v, 3) for v in ref_m)} mm: the model ({model_source}) "
            "and the measurements are for different machines", file=str(machine.path),
            line=machine.line_of("reference.point_mm"), field="reference.point_mm")
    for a, spec in machine.axes.items():
        lo, hi = table.axes[a].travel_mm
        mlo, mhi = spec.travel_mm
        if lo < mlo - 1.0 or hi > mhi + 1.0:
            raise AbbeInputError(
                f"the model covers {a} = [{lo:g}, {hi:g}] mm, outside the machine's travel "
                f"[{mlo:g}, {mhi:g}] mm: the model ({model_source}) belongs to another machine",
                file=str(machine.path), line=machine.line_of(f"axes.{a}.travel_mm"),
                field=f"axes.{a}.travel_mm")


def diagnose_machine(machine: Any, model: Any, ballbar: list[str] | None = None,
                     laser: list[str] | None = None, options: DiagnoseOptions | None = None,
                     rezeroed: bool = False) -> DiagnoseResult:
    """Diagnose the checks of a machine file against a model (the demo's entry point).

    ``machine``: path or :class:`abbe.formats.machine.Machine`; ``model``: path (blob / JSON) or
    Table; ``ballbar``: test names, ``laser``: axes (both None = every test in the file).
    """
    from abbe.diagnose.checks import ballbar_check, laser_check
    from abbe.formats.machine import load_machine
    m = machine if hasattr(machine, "ballbar") else load_machine(machine)
    table = load_model(model)
    check_model_matches(table, m, str(model) if not isinstance(model, Table) else "model")
    if ballbar is None and laser is None:
        ballbar, laser = sorted(m.ballbar), sorted(m.laser)
    checks: list[Check] = []
    for name in ballbar or []:
        checks.append(ballbar_check(m, name, table.reference_mm))
    for axis in laser or []:
        checks.append(laser_check(m, axis.upper(), table.reference_mm, rezeroed=rezeroed))
    if not checks:
        raise AbbeInputError("the machine file has no [ballbar.*] or [laser.*] test to check "
                             "the model with", file=str(m.path), field="ballbar")
    return diagnose(table, checks, options)


def diagnose_positioning(path: Any, axis: str, model: Any = None,
                         options: DiagnoseOptions | None = None,
                         rezeroed: bool = False) -> DiagnoseResult:
    """Diagnose repeated positioning runs (ISO 230-2 .dat or laser CSV) of one axis.

    Without ``model`` the model is position-only: the axis' own positioning term
    interpolating the mean deviation of each target (abbe.diagnose.checks.position_only_table).
    """
    from abbe.diagnose.checks import position_only_table, positioning_check
    axis = axis.upper()
    if axis not in AXES:
        raise AbbeInputError(f"axis {axis!r}: expected X, Y or Z", field="axis")
    if model is None:
        c = positioning_check(path, axis, (0.0, 0.0, 0.0), rezeroed=rezeroed)
        ref = [0.0, 0.0, 0.0]
        tg = c.targets
        ref[AXES.index(axis)] = 0.0 if tg.min() <= 0.0 <= tg.max() else float(tg[0])
        c = positioning_check(path, axis, tuple(ref), rezeroed=rezeroed)  # type: ignore[arg-type]
        table = position_only_table(c)
    else:
        table = load_model(model)
        c = positioning_check(path, axis, table.reference_mm, rezeroed=rezeroed)
    return diagnose(table, [c], options)
