"""Candidate effects and their signatures: the sensitivity of every check to each.

:class:`Engine` holds the problem and the base model; a candidate's signature is
the change of the prediction when its parameters are perturbed (finite
differences through the model), with grid searches for nonlinear parameters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from abbe.diagnose.backlash_pair import is_pair, pair_grid
from abbe.diagnose.checks import BallbarCheck, Check, LaserCheck
from abbe.diagnose.effects import (
    BACKLASH_TAKEUP_GRID_MM,
    REVERSAL_MAX_DEGREE,
    REVERSAL_MAX_TARGETS,
    EffectSpec,
    NotRepresentable,
    PredParams,
    copy_table,
)
from abbe.diagnose.evaluator import Evaluator
from abbe.diagnose.problem import (
    Problem,
    lstsq_rss,
    project_out,
)
from abbe.diagnose.results import DiagnoseOptions
from abbe.model.geometry import PLANE_AXES
from abbe.model.table import AXES, OWN_TERM, Table

#: Finite-difference step, as a fraction of the parameter's typical magnitude.
FD_FRACTION = 1.0
#: Warm-up time constants searched, as multiples of the longest check's drift span.
TAU_GRID_FACTORS = (0.5, 1.0, 2.0, 4.0)


@dataclass
class Cand:
    """A candidate with its sensitivity columns at the current model."""

    spec: EffectSpec
    cols: np.ndarray              # (N, k) raw sensitivities (units of y per unit parameter)
    param_idx: list[int]          # which of spec.params the columns are
    scan_value: Any = None        # grid value (float), a backlash's take-up pair, or None
    n_scan: int = 1               # independent grid points searched (look-elsewhere)
    observable: bool = True
    why_not: str = ""
    #: fixed change of the prediction the grid value itself causes (e.g. a new take-up of a
    #: backlash the model already has), or None
    offset: np.ndarray | None = None


def reference_temperature(table: Table, checks: list[Check], model_temp_c: float | None) -> float:
    """Temperature (deg C) at which the model's geometric terms hold: the table's own
    ``thermal_tref_c`` if an axis has a thermal term, else ``model_temp_c`` (the user
    knows when the model was measured), else the lowest temperature logged in the
    checks (a warm-up starts from the cold machine; the model is taken as the cold
    state). Any other choice adds a static scale alpha (T_model - T_ref) that would be
    named as a scale error."""
    for ax in table.axes.values():
        if ax.thermal_expansion_ppm_per_k or ax.thermal_offset_um_per_k:
            return float(ax.thermal_tref_c)
    if model_temp_c is not None:
        return float(model_temp_c)
    lows = [float(np.min(t)) for t in (getattr(c, "all_temp", None) if isinstance(c, BallbarCheck)
                                       else getattr(c, "temp_grid", None) for c in checks)
            if t is not None]
    return min(lows) if lows else 20.0


class Engine:
    """Holds the problem, the base model and the candidate sensitivities."""

    def __init__(self, table: Table, checks: list[Check], opts: DiagnoseOptions,
                 pp: PredParams | None = None, ev: Evaluator | None = None) -> None:
        self.opts = opts
        self.table = table
        self.pp = pp.copy() if pp is not None else PredParams()
        self.ev = ev or Evaluator(opts.backend)
        self.prob = Problem(checks)
        #: a factor (N, r) of the predictions' covariance from the table's own fit error
        #: (table_uncertainty.table_factor; None: no model.json, not carried)
        self.table_M: np.ndarray | None = None
        # One drift variable for all checks: the temperature if a check has one (the drift
        # then goes into the table's thermal term; checks without a temperature carry no
        # drift), else the time, else the run index.
        units = [set(c.drift_options) for c in checks]
        self.drift_unit = next((u for u in ("K", "h", "run") if any(u in s for s in units)),
                               None)
        for c in checks:
            c.set_drift_unit(self.drift_unit)
        self.drift_on_table = self.drift_unit == "K"
        self.tref_c = reference_temperature(table, checks, opts.model_temp_c) \
            if self.drift_on_table else 20.0
        # knots of a per-target reversal: the targets of each axis' repeated laser checks
        for j, a in enumerate(AXES):
            tg = [c.targets for c in checks if isinstance(c, LaserCheck) and c.axis == a
                  and c.n_runs >= 2]
            if tg and self.pp.reversal_knots_mm[j] is None:
                kn = np.unique(np.concatenate(tg))
                if 4 <= kn.size <= REVERSAL_MAX_TARGETS:
                    self.pp.reversal_knots_mm[j] = kn
        self.y0 = self.prob.predict(self.ev, table, self.pp)
        self.r0 = self.prob.y - self.y0

    def on_checks(self, checks: list[Check], table: Table) -> "Engine":
        """The same settings (options, prediction parameters, drift variable, evaluator)
        on other checks, e.g. hypothetical tests of a separating-test search."""
        sub = Engine.__new__(Engine)
        sub.opts, sub.table, sub.pp, sub.ev = self.opts, table, self.pp, self.ev
        sub.prob = Problem(checks)
        sub.table_M = None
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
                    pp: PredParams, y_ref: np.ndarray, idx: list[int] | None = None) -> np.ndarray:
        """(N, k) d prediction / d parameter, by re-predicting through the model (only the
        parameters ``idx`` are computed; the other columns are zero)."""
        return self.sensitivity_offset(spec, scan_value, table, pp, y_ref, idx)[0]

    def sensitivity_offset(self, spec: EffectSpec, scan_value: float | None, table: Table,
                           pp: PredParams, y_ref: np.ndarray, idx: list[int] | None = None
                           ) -> tuple[np.ndarray, np.ndarray | None]:
        """(N, k) d prediction / d parameter by re-predicting through the model, and the
        change (N,) the grid value alone causes (None if it causes none). ``idx``: the
        parameters to compute (default: all but a reversal's per-target ones)."""
        k = len(spec.params)
        cols = np.zeros((self.prob.N, k))
        offset = None
        if idx is None:
            idx = [i for i, ps in enumerate(spec.params)
                   if not (spec.kind == "reversal" and ps.optional)]
        for i in idx:
            ps = spec.params[i]
            h = ps.typical * FD_FRACTION
            th = np.zeros(k)
            th[i] = h
            t2, p2 = self.apply(table, pp, spec, th, scan_value)
            if scan_value is not None and (
                    (spec.kind == "backlash" and table.axes[spec.axis].has_reversal())  # type: ignore[index]
                    or (spec.kind == "thermal" and not self.drift_on_table
                        and (np.any(pp.drift_offset) or np.any(pp.drift_scale_ppm)
                             or np.any(pp.drift_bow_um)))):
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
            if spec.kind == "reversal":
                out.append(self._reversal_cand(spec, table, pp, y_ref, W, Qn))
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
            if spec.kind == "thermal":
                # a drift's optional parameters (scale, bow) one at a time too: each is a
                # shape of the rate along the travel the BIC keeps only if the data need it
                opt = [i for i, ps in enumerate(spec.params) if ps.optional]
                if len(opt) > 1:
                    subsets += [req + [i] for i in opt]
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
            # a backlash's per-direction take-up pairs pay for the whole grid they were
            # searched on, the single take-ups for theirs (abbe.diagnose.backlash_pair)
            n_single = max(sum(not is_pair(v) for v in scan_vals) * len(subsets), 1)
            if failed is not None or not alts:
                c = failed or Cand(spec, np.zeros((self.prob.N, 0)), [], observable=False,
                                   why_not="no signature on these checks (at a typical magnitude "
                                           "it is below the noise or absorbed by the nuisance "
                                           "terms)")
                out.append(c)
                continue
            for c in alts:
                c.n_scan = n_alt if is_pair(c.scan_value) else n_single
            # the pool's candidate is a copy: each selection step sets its grid value /
            # parameter subset from the alternatives (alternatives._tool_components and the
            # BIC choice), which must stay intact for the next step (issue 36: the first
            # alternative overwritten at step 1 lost a tool offset's lateral components
            # for good, docs/effects.md §3)
            best = replace(alts[0])
            if len(alts) > 1:
                self._alts[spec.key] = alts
            out.append(best)
        return out

    def reversal_points(self, axis: str) -> np.ndarray:
        """Axis positions (mm) where the checks see the reversal: the targets of the laser /
        positioning checks of ``axis``, else the positions its ballbar circles pass."""
        j = AXES.index(axis)
        tg = [c.targets for c in self.prob.checks if isinstance(c, LaserCheck) and c.axis == axis]
        if tg:
            return np.unique(np.concatenate(tg))
        pos = [c.positions()[:, j] for c in self.prob.checks
               if isinstance(c, BallbarCheck) and j in PLANE_AXES[c.plane]]
        return np.concatenate(pos) if pos else np.zeros(0)

    def reversal_design(self, axis: str, param_idx: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """(points (M,) mm, J (M, k)): the position-dependent reversal at the points where
        the checks see it is J @ theta for the parameters ``param_idx`` (Chebyshev r_k and
        per-target contrasts t_k)."""
        j = AXES.index(axis)
        knots = self.pp.reversal_knots_mm[j]
        pts = self.reversal_points(axis)
        lo, hi = self.table.axes[axis].travel_mm
        u = (2.0 * np.clip(pts, lo, hi) - lo - hi) / (hi - lo)
        V = np.polynomial.chebyshev.chebvander(u, REVERSAL_MAX_DEGREE)
        J = np.zeros((pts.size, len(param_idx)))
        for c, i in enumerate(param_idx):
            if i < REVERSAL_MAX_DEGREE:
                J[:, c] = V[:, i + 1]
            elif knots is not None:
                e = np.zeros(len(knots))
                e[i - REVERSAL_MAX_DEGREE] = 1.0
                e[-1] = -1.0
                J[:, c] = np.interp(pts, knots, e)
        return pts, J

    def _reversal_cand(self, spec: EffectSpec, table: Table, pp: PredParams, y_ref: np.ndarray,
                       W: np.ndarray, Qn: np.ndarray) -> Cand:
        """Position-dependent reversal: Chebyshev T1..Td of the reversal over the travel, the
        degree d searched from 1 to min(REVERSAL_MAX_DEGREE, targets - 2) (laser /
        positioning checks of the axis; circles alone: at most 3), each degree one
        alternative (look-elsewhere over the degrees)."""
        axis = spec.axis  # type: ignore[assignment]
        lasers = [c for c in self.prob.checks if isinstance(c, LaserCheck) and c.axis == axis
                  and c.n_runs >= 2]
        if not lasers:
            # a circle sees the reversal at its two reversal points and as level steps: the
            # lost motion at each end is reported with a named backlash, the dependence on
            # the position needs the axis' bidirectional (ISO 230-2) runs
            return Cand(spec, np.zeros((self.prob.N, 0)), [], observable=False,
                        why_not="needs bidirectional laser / ISO 230-2 runs of the axis (a "
                                "circle shows the lost motion at its reversal points only)")
        dmax = min(REVERSAL_MAX_DEGREE, max(c.T for c in lasers) - 2)
        none = Cand(spec, np.zeros((self.prob.N, 0)), [], observable=False,
                    why_not="no signature on these checks")
        if dmax < 1:
            return none
        j = AXES.index(axis)  # type: ignore[arg-type]
        knots = pp.reversal_knots_mm[j]
        pt_idx = [] if knots is None else \
            list(range(REVERSAL_MAX_DEGREE, REVERSAL_MAX_DEGREE + len(knots) - 1))
        cols, _ = self.sensitivity_offset(spec, None, table, pp, y_ref,
                                          list(range(dmax)) + pt_idx)
        alts = []
        for d in range(1, dmax + 1):
            c = self._prune(Cand(spec, cols[:, :d], list(range(d)), float(d)), W, Qn)
            if c.observable and c.param_idx == list(range(d)):
                alts.append(c)
        if pt_idx and len(pt_idx) > dmax:
            # per target: the ISO 230-2 reversal values, linear between the targets
            c = self._prune(Cand(spec, cols[:, pt_idx], pt_idx, -float(len(knots))), W, Qn)
            if c.observable and c.param_idx == pt_idx:
                alts.append(c)
        if not alts:
            return none
        for c in alts:
            c.n_scan = len(alts)
        if len(alts) > 1:
            self._alts[spec.key] = alts
        return replace(alts[0])  # a copy: the alternatives stay intact (above)

    def _tau_grid(self) -> list[float | None]:
        """Warm-up time constants to search (drift-variable units): linear (inf) and
        0.5 .. 4 x the time span of the checks (a shorter one would saturate early in
        the check and look like a static error)."""
        span = max(float(np.max(c.drift)) for c in self.prob.checks if c.drift is not None)
        if not span > 0:
            return [math.inf]
        return [math.inf] + [f * span for f in TAU_GRID_FACTORS]

    def tau_rows(self, cols: np.ndarray | None = None) -> np.ndarray:
        """Rows (N,) bool of the checks that can tell the warm-up's shape: those whose
        drift variable spans at least the shortest time constant searched
        (:meth:`_tau_grid`). A shorter check (a ballbar trace of minutes beside a laser
        campaign) sees every warm-up on the grid as a straight line; its only say in the
        choice of tau would come through the warm-up's origin, which is each check's own
        start (the files share no clock, so a later check is not further along the
        warm-up), and through what its ccw / cw pair carries in time besides the drift
        (a direction-dependent centre). Such checks bias the time constant short and the
        drift rate (the slope at the origin) up; tau is chosen on the others.

        ``cols`` (N, k): the drift candidate's columns. Only the checks on which they
        act count, for the longest span as for the rows: a check the drift does not move
        (the laser line of X beside a drift of Z) tells nothing of its warm-up, and as the
        longest check it excluded the one line that sees the drift, leaving the choice to
        a tie (docs/diagnose-validation.md, "The team suite's two drift-of-Z misses")."""
        sees = [True] * len(self.prob.checks)
        if cols is not None:
            a = np.abs(np.asarray(cols, dtype=np.float64).reshape(self.prob.N, -1))
            top = float(a.max(initial=0.0))
            sees = [bool(top > 0.0 and a[self.prob.slice(i)].max(initial=0.0) > 1e-9 * top)
                    for i in range(len(self.prob.checks))]
        spans = [float(np.max(c.drift)) if see and c.drift is not None and c.drift.size else 0.0
                 for c, see in zip(self.prob.checks, sees)]
        shortest = TAU_GRID_FACTORS[0] * max(spans, default=0.0)
        rows = np.zeros(self.prob.N, dtype=bool)
        for i, sp in enumerate(spans):
            if sp > 0.0 and sp >= shortest:
                rows[self.prob.slice(i)] = True
        return rows

    def _takeup_grid(self, axis: str, table: Table) -> list[Any]:
        """Take-up values to search: only if a check has continuous motion (ballbar); then
        also the per-direction pairs (abbe.diagnose.backlash_pair)."""
        j = AXES.index(axis)
        dyn = any(isinstance(c, BallbarCheck) and j in PLANE_AXES[c.plane] for c in self.prob.checks)
        if not dyn:
            tk = table.axes[axis].backlash_takeup_mm
            return [tk if tk > 0 else 1.0]
        return list(BACKLASH_TAKEUP_GRID_MM) + pair_grid(BACKLASH_TAKEUP_GRID_MM)

    def _prune(self, c: Cand, W: np.ndarray, Qn: np.ndarray) -> Cand:
        """Drop parameters the checks cannot see; mark unobservable candidates."""
        Z = project_out(Qn, c.cols * W[:, None])
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

    def cyclic_cols(self, axis: str, period: float, table: Table, harmonics: int = 1) -> np.ndarray:
        """Probe-based cyclic columns (N, 2 x harmonics) at ``period`` (phase origin: travel
        min): sin, cos of the fundamental, then of the second harmonic (period / 2)."""
        g = self._probe[axis]
        p = self._cyc_pos[axis]
        o = float(table.axes[axis].travel_mm[0])
        phi = 2 * np.pi * (p - o) / period
        cols = [g * np.sin(phi), g * np.cos(phi)]
        if harmonics > 1:
            cols += [g * np.sin(2 * phi), g * np.cos(2 * phi)]
        return np.stack(cols, axis=1)

    def _cyc_trig_cache(self, axis: str, o: float, p: np.ndarray, freqs: np.ndarray
                        ) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]] | None:
        """sin / cos of 2 pi f (p - o) per chunk of the period grid of ``axis``, at the
        distinct positions only (a laser line repeats its targets in every run and
        channel), with the index of each sample's position: the same at every call of
        cyclic_scan, so computed once; None when they would hold more than
        _TRIG_CACHE_MAX values (then each call computes them again)."""
        cache = self.__dict__.setdefault("_cyc_trig", {})
        key = (axis, o, p.tobytes(), freqs.tobytes())
        if key not in cache:
            u, inv = np.unique(p, return_inverse=True)
            if u.size * freqs.size > _TRIG_CACHE_MAX:
                return None
            cache[key] = (inv.reshape(-1), [
                _trig(u, o, freqs[chunk]) for chunk in
                np.array_split(np.arange(freqs.size), max(1, freqs.size // 128))])
        return cache[key]

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
        # (rb is orthogonal to Q). Products over samples are BLAS matrix products. The
        # sines and cosines depend on the axis only (not on the weights, the basis or the
        # residual): computed once per axis and kept (up to _TRIG_CACHE_MAX values).
        trig = self._cyc_trig_cache(axis, o, p, freqs)
        for ci, chunk in enumerate(np.array_split(np.arange(freqs.size),
                                                  max(1, freqs.size // 128))):
            f = freqs[chunk]
            if trig is not None:    # the same values as _trig(p, o, f), bit for bit
                inv, parts = trig
                sin_phi, cos_phi = parts[ci][0][inv], parts[ci][1][inv]
            else:
                sin_phi, cos_phi = _trig(p, o, f)
            Ss = g[:, None] * sin_phi
            Sc = g[:, None] * cos_phi
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
                S = project_out(Qb, S)
                _, d = lstsq_rss(S, rb)
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


#: most sine and cosine values (each) Engine._cyc_trig_cache keeps per axis (8 bytes each)
_TRIG_CACHE_MAX = 4_000_000


def _trig(p: np.ndarray, o: float, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """sin and cos of 2 pi f (p - o): (N, F) each (p (N,) mm, f (F,) 1/mm)."""
    phi = 2 * np.pi * np.outer(p - o, f)
    return np.sin(phi), np.cos(phi)


@dataclass
class Selected:
    cand: Cand
    stats: dict[str, Any]

def selection_residual(eng: "Engine", sel: list["Selected"]) -> np.ndarray:
    """Residual of the base model minus the fixed offsets of the selected effects."""
    r = eng.r0
    for s in sel:
        if s.cand.offset is not None:
            r = r - s.cand.offset
    return r

def apply_selection(eng: Engine, sel: list[Selected], values: list[np.ndarray],
               table: Table | None = None, pp: PredParams | None = None) -> tuple[Table, PredParams]:
    t = table if table is not None else eng.table
    p = pp if pp is not None else eng.pp
    for s, v in zip(sel, values):
        th = np.zeros(len(s.cand.spec.params))
        th[s.cand.param_idx] = v
        t, p = eng.apply(t, p, s.cand.spec, th, s.cand.scan_value)
    return t, p
