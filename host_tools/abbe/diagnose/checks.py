"""Check measurements for ``abbe diagnose``: measured vector + prediction through the model.

A :class:`Check` is one measurement the model must reproduce: a ballbar trace
(ISO 230-4) or a laser line (6D laser CSV, or ISO 230-2 positioning data). It
holds the measured values ``y`` (um or urad), labels (direction, run, time,
replicate cell, hold-out folds), the nuisance columns that are always allowed
(ballbar centre offset and radius set-up error; laser zero offsets, straightness
set-up slopes, per-run offsets where the instrument was re-zeroed) and a
``predict(evaluator, table, pred_params)`` function.

Predictions go through an :class:`abbe.diagnose.evaluator.Evaluator`: the C library (``abbe.model.clib``,
``abbe_error_eval_f32`` / ``abbe_term_eval_f32`` on the blob written by
``abbe.formats.blob.write_blob``) by default, or the float64 reference
(``abbe.model.reference``) of the quantized table.

Units: positions mm, linear values um, angles urad, time s (drift variable h,
run or K as stated by ``drift_unit``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from abbe.diagnose.effects import PredParams
from abbe.diagnose.evaluator import Evaluator
from abbe.errors import AbbeInputError
from abbe.diagnose.backlash_pair import pair_state
from abbe.model.backlash import direction_state
from abbe.model.geometry import PLANE_AXES
from abbe.model.table import AXES, LINEAR_TERMS, OWN_SIGN, OWN_TERM, Table


#: Take-up (mm) of the direction state when the table has no backlash term (the machine
#: file's default).
DEFAULT_TAKEUP_MM = 1.0


#: Highest degree of the polynomial in time that stands for a check's temperature
#: (:func:`smooth_temperature`; at most a quarter of the readings): enough for a
#: temperature that swings a few times over a long campaign (a ripple of 1.4 h over 3.5 h
#: needs about 12), while the BIC keeps a trace of a minute at degree 1 or 2.
TEMP_SMOOTH_MAX_DEGREE = 20


def smooth_temperature(abscissa: np.ndarray, temp_c: np.ndarray) -> np.ndarray:
    """The temperature of one check (deg C, the shape of ``temp_c``) as the polynomial in
    its time (``abscissa``: time in s, or the reading order when the file has no time)
    that the BIC chooses (degree 0 .. :data:`TEMP_SMOOTH_MAX_DEGREE`, Chebyshev on the
    check's span) -- regression calibration of a noisy regressor (docs/effects.md §3,
    "a temperature is smoothed in time before it drives a drift").

    A drift with the temperature as its variable is a regression on the temperature
    sensor's readings. Their noise (a few hundredths of a kelvin) does not average out
    there: it sits in the regressor, and attenuates the fitted drift by var(T) / (var(T) +
    sigma²) (regression dilution). Within one ballbar trace of a minute the temperature
    changes by a few hundredths of a kelvin, as much as the noise, and the drift that trace
    carries came out at a fraction of its size (issue 36, tenth round: the team's
    ``thermal_lin+scale_x``, -3.40 for -4.60 um/K; -4.46 with noise-free sensors). The
    machine's temperature is smooth in time while the sensor's noise is white, so the
    readings are replaced by their expectation given the time. Non-finite values, fewer
    than four readings or no change are returned as they are."""
    T = np.asarray(temp_c, dtype=np.float64)
    t = np.asarray(abscissa, dtype=np.float64).reshape(-1)
    y = T.reshape(-1)
    n = y.size
    if n < 4 or t.size != n or not (np.all(np.isfinite(y)) and np.all(np.isfinite(t))):
        return T.copy()
    lo, hi = float(t.min()), float(t.max())
    if not hi > lo or float(np.ptp(y)) == 0.0:
        return T.copy()
    u = (2.0 * t - lo - hi) / (hi - lo)
    best = None
    for d in range(min(TEMP_SMOOTH_MAX_DEGREE, n // 4) + 1):
        V = np.polynomial.chebyshev.chebvander(u, d)
        coef, *_ = np.linalg.lstsq(V, y, rcond=None)
        fit = V @ coef
        rss = float(np.sum((y - fit) ** 2))
        if rss <= 1e-24 * n:
            return fit.reshape(T.shape)   # the readings are the polynomial itself
        bic = n * np.log(rss / n) + (d + 1) * np.log(n)
        if best is None or bic < best[0]:
            best = (bic, fit)
    return best[1].reshape(T.shape)  # type: ignore[index]


def _outside_msg(axis: str, lo: float, hi: float, vmin: float, vmax: float) -> str:
    return (f"spans {axis} = [{vmin:g}, {vmax:g}] mm but the model covers only "
            f"[{lo:g}, {hi:g}] mm of axis {axis}: the check is outside the model's travel "
            "(or the model belongs to another machine)")


@dataclass
class Check:
    """One check measurement (base class; see :class:`BallbarCheck`, :class:`LaserCheck`).

    y: (N,) measured values; group: (N,) noise-group index into ``group_names`` /
    ``group_units`` ("um" or "urad"); cell: (N,) replicate cell (samples that repeat
    the same situation: same target, direction, channel) or -1; folds: split name ->
    (N,) {0, 1} hold-out labels, in order of preference; nuisance: (N, m) columns
    always fitted; drift_options: unit -> (N,) drift variable (time "h", "run"
    index, temperature "K"), one chosen by :meth:`set_drift_unit`; x: (N,) angle (deg) or target (mm) for plots; direction: (N,) labels;
    run: (N,) run numbers (1..n) or zeros; source: file and line for messages.
    """

    name: str
    kind: str
    y: np.ndarray
    group: np.ndarray
    group_names: list[str]
    group_units: list[str]
    cell: np.ndarray
    folds: dict[str, np.ndarray]
    nuisance: np.ndarray
    nuisance_names: list[str]
    drift_options: dict[str, np.ndarray]
    x: np.ndarray
    direction: np.ndarray
    run: np.ndarray
    source: str = ""
    meta: dict[str, Any] = field(default_factory=dict)
    drift_unit: str | None = None

    @property
    def n(self) -> int:
        return int(self.y.size)

    @property
    def drift(self) -> np.ndarray | None:
        """The active drift variable (N,) (unit ``drift_unit``), or None."""
        if self.drift_unit is None:
            return None
        return self.drift_options.get(self.drift_unit)

    def set_drift_unit(self, unit: str | None) -> None:
        """Select the drift variable: "h" (time), "K" (temperature), "run" or None."""
        self.drift_unit = unit if unit in self.drift_options else None

    def predict(self, ev: Evaluator, table: Table, pp: PredParams) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def positions(self) -> np.ndarray:  # pragma: no cover
        """Distinct commanded positions (M, 3) mm (for the travel check)."""
        raise NotImplementedError

    def sample_positions(self) -> np.ndarray:  # pragma: no cover
        """Position (N, 3) mm of every sample."""
        raise NotImplementedError

    def with_y(self, y: np.ndarray) -> "Check":
        """A copy with other measured values (same geometry)."""
        import copy
        c = copy.copy(self)
        c.y = np.asarray(y, dtype=np.float64).reshape(-1).copy()
        return c


class BallbarCheck(Check):
    """A ballbar trace (CCW then CW) of one circular test.

    Prediction: the actual position of each plane axis is the commanded circle point
    ``lag`` earlier (servo lag, PredParams) and, with first-order loops, at a slightly
    different amplitude (PredParams.plane_gains), the backlash direction state is tracked
    along the commanded path (feed arcs included) with the table's take-up, and the
    radial deviation is the exact length change ``|p + E - c| - R`` (um) with E the
    model's spatial error (+ the time drift of PredParams).
    """

    def __init__(self, name: str, plane: str, center_mm: tuple[float, float, float],
                 radius_mm: float, feed_mm_min: float, direction: np.ndarray,
                 angle_deg: np.ndarray, radial_um: np.ndarray, time_s: np.ndarray,
                 reference_mm: tuple[float, float, float], source: str = "",
                 temp_c: np.ndarray | None = None, drift_ref_c: float | None = None,
                 data_from_deg: float = 0.0) -> None:
        self.plane = plane
        self.center_mm = np.asarray(center_mm, dtype=np.float64)
        self.radius_mm = float(radius_mm)
        self.feed_mm_min = float(feed_mm_min)
        self.all_dir = np.asarray(direction).astype(str)
        self.all_ang = np.asarray(angle_deg, dtype=np.float64)
        self.all_time = np.asarray(time_s, dtype=np.float64)
        # the sensor's readings -> the temperature as a smooth curve in time (regression
        # calibration: smooth_temperature)
        self.all_temp = None if temp_c is None else \
            smooth_temperature(self.all_time, np.asarray(temp_c, dtype=np.float64))
        self.reference_mm = np.asarray(reference_mm, dtype=np.float64)
        # The data arc: [0, 360) unless the file says otherwise (a Renishaw START_ANGLE).
        m = (self.all_ang >= data_from_deg) & (self.all_ang < data_from_deg + 360.0)
        self.mask = m
        ang = self.all_ang[m]
        d = self.all_dir[m]
        th = np.radians(ang)
        nuis = np.stack([np.cos(th), np.sin(th), np.ones_like(th)], axis=1)
        a, b = PLANE_AXES[plane]
        na, nb = "XYZ"[a], "XYZ"[b]
        sector = (np.floor(ang / 45.0).astype(int) % 2)
        t = self.all_time[m]
        drift = {"h": (t - float(self.all_time.min())) / 3600.0}
        self.temp_first_c: float | None = None
        if self.all_temp is not None:
            tref = float(self.all_temp[0]) if drift_ref_c is None else float(drift_ref_c)
            drift["K"] = self.all_temp[m] - tref
            self.temp_first_c = tref
        super().__init__(
            name=name, kind="ballbar", y=np.asarray(radial_um, dtype=np.float64)[m],
            group=np.zeros(ang.size, dtype=int), group_names=[f"{name}:radial"],
            group_units=["um"], cell=np.full(ang.size, -1),
            folds={"angle sectors (alternate 45 deg, both directions)": sector,
                   "direction (fit CCW, judge CW and back)": (d == "cw").astype(int)},
            nuisance=nuis,
            nuisance_names=[f"centre_{na.lower()}_um", f"centre_{nb.lower()}_um", "radius_um"],
            drift_options=drift, x=ang, direction=d,
            run=np.where(d == "ccw", 1, 2), source=source,
            meta={"plane": plane, "radius_mm": self.radius_mm, "center_mm": self.center_mm.tolist(),
                  "feed_mm_min": self.feed_mm_min})

    def _angles(self, pp: PredParams) -> dict[int, np.ndarray]:
        """Per plane axis: the (lagged) angle in rad of every trace sample."""
        om = self.feed_mm_min / 60.0 / self.radius_mm  # rad/s
        s = np.where(self.all_dir == "cw", -1.0, 1.0)
        th = np.radians(self.all_ang)
        a, b = PLANE_AXES[self.plane]
        la, lb = pp.plane_lags_ms(self.plane)
        return {a: th - s * om * la * 1e-3, b: th - s * om * lb * 1e-3}

    def commanded_all(self) -> np.ndarray:
        """Commanded positions (M, 3) mm of all trace samples (feed arcs included)."""
        th = np.radians(self.all_ang)
        a, b = PLANE_AXES[self.plane]
        p = np.tile(self.center_mm, (th.size, 1))
        p[:, a] += self.radius_mm * np.cos(th)
        p[:, b] += self.radius_mm * np.sin(th)
        return p

    def positions(self) -> np.ndarray:
        return self.commanded_all()[self.mask]

    def _reversal_path(self) -> tuple[np.ndarray, np.ndarray]:
        """The commanded path (M, 3) with the plane axes' reversal points (the circle's
        extremes, every 90 deg) inserted between the samples, and the index of each
        sample in it: the direction state is then exact at the samples (the axis
        moves monotonically between consecutive points)."""
        key = "_rev_path"
        if key in self.__dict__:
            return self.__dict__[key]
        ang = self.all_ang
        pts, idx = [ang[:1]], [0]
        k = 0
        for a0, a1 in zip(ang[:-1], ang[1:]):
            lo, hi = min(a0, a1), max(a0, a1)
            q = np.arange(math.floor(lo / 90.0) + 1, math.ceil(hi / 90.0)) * 90.0
            q = q[(q > lo) & (q < hi)]
            if a1 < a0:
                q = q[::-1]
            pts.append(np.concatenate([q, [a1]]))
            k += q.size + 1
            idx.append(k)
        th = np.radians(np.concatenate(pts))
        a, b = PLANE_AXES[self.plane]
        p = np.tile(self.center_mm, (th.size, 1))
        p[:, a] += self.radius_mm * np.cos(th)
        p[:, b] += self.radius_mm * np.sin(th)
        self.__dict__[key] = (p, np.asarray(idx))
        return self.__dict__[key]

    def sample_positions(self) -> np.ndarray:
        """Commanded position (N, 3) mm of every sample."""
        return self.positions()

    def predict(self, ev: Evaluator, table: Table, pp: PredParams) -> np.ndarray:
        angs = self._angles(pp)
        a, b = PLANE_AXES[self.plane]
        cmd = self.commanded_all()
        pos = cmd.copy()
        ga, gb = pp.plane_gains(self.plane, self.feed_mm_min / 60.0 / self.radius_mm)
        pos[:, a] = self.center_mm[a] + self.radius_mm * ga * np.cos(angs[a])
        pos[:, b] = self.center_mm[b] + self.radius_mm * gb * np.sin(angs[b])
        ds = np.zeros_like(cmd)
        dense = None
        for j, ax in enumerate(AXES):
            at = table.axes[ax]
            if at.has_reversal() or pp.has_reversal(j):
                if dense is None:
                    dense, at_sample = self._reversal_path()
                tk = at.backlash_takeup_mm if at.backlash_takeup_mm > 0 else DEFAULT_TAKEUP_MM
                pr = pp.backlash_takeup_pair_mm[j]
                ds[:, j] = (pair_state(dense[:, j], pr[0], pr[1]) if pr[0] > 0
                            else direction_state(dense[:, j], tk))[at_sample]
        m = self.mask
        temp = None
        if self.all_temp is not None:
            temp = np.repeat(self.all_temp[m][:, None], 3, axis=1)
        e = ev.error(table, pos[m], ds[m], temp)
        for j, ax in enumerate(AXES):
            if pp.has_reversal(j):
                e[:, j] += OWN_SIGN[ax] * ds[m][:, j] * 0.5 * pp.reversal_at(
                    j, table.axes[ax].travel_mm, pos[m][:, j])
        if self.drift is not None and (np.any(pp.drift_offset) or np.any(pp.drift_scale_ppm)
                                       or np.any(pp.drift_bow_um)):
            rel = pos[m] - self.reference_mm
            for j, ax in enumerate(AXES):
                lo, hi = table.axes[ax].travel_mm
                u = (2.0 * pos[m][:, j] - lo - hi) / (hi - lo)
                own = (pp.drift_offset[j] + pp.drift_scale_ppm[j] * rel[:, j] * 1e-3
                       + pp.drift_bow_um[j] * (1.0 - u * u)) * pp.drift_shape(self.drift)
                e[:, j] += OWN_SIGN[ax] * own
        v = pos[m] + e * 1e-3 - self.center_mm
        return (np.linalg.norm(v, axis=1) - self.radius_mm) * 1e3


@dataclass
class LaserChannel:
    """One instrument channel of a laser line mapped to a model term (reading = sign * term)."""

    channel: str
    term: str
    sign: int
    values: np.ndarray  # (n_runs, 2, T) instrument readings (um / urad)


class LaserCheck(Check):
    """A laser line (6D laser CSV channels, or ISO 230-2 positioning = the linear channel).

    Readings are ``sign * term`` of the line's axis at the targets (docs/formats.md);
    the own positioning term also carries backlash (direction state +1 for the ``+``
    approach, -1 for ``-``), the table's thermal term (with a temperature column) and
    the drift of PredParams (time/run-driven; with ``K`` the table's thermal term). Nuisance: a zero offset per channel (per run and channel
    with ``rezeroed``), and a set-up slope for straightness channels.
    """

    #: the check before an "inconsistent run" exclusion and its residual before the
    #: diagnosis (um), set by selection.diagnose: what the drift's temperature tie is
    #: tested on (abbe.diagnose.drift_temperature.ties_of); None: this check as it is
    tie_source: "tuple[LaserCheck, np.ndarray] | None" = None

    def __init__(self, name: str, axis: str, line_mm: tuple[float, float, float],
                 targets_mm: np.ndarray, channels: list[LaserChannel],
                 order: np.ndarray, reference_mm: tuple[float, float, float],
                 time_s: np.ndarray | None = None, temp_c: np.ndarray | None = None,
                 rezeroed: bool = False, source: str = "", drift_ref_c: float | None = None) -> None:
        self._args = dict(name=name, axis=axis, line_mm=line_mm, targets_mm=targets_mm,
                          order=order, reference_mm=reference_mm, time_s=time_s, temp_c=temp_c,
                          rezeroed=rezeroed, source=source, drift_ref_c=drift_ref_c)
        #: run numbers (1-based, as in the file) of the runs this check holds
        self.run_numbers = list(range(1, channels[0].values.shape[0] + 1))
        self.axis = axis
        self.j = AXES.index(axis)
        self.line_mm = np.asarray(line_mm, dtype=np.float64)
        self.targets = np.asarray(targets_mm, dtype=np.float64)
        self.channels = channels
        self.reference_mm = np.asarray(reference_mm, dtype=np.float64)
        n_runs, _, T = channels[0].values.shape
        self.n_runs, self.T = n_runs, T
        #: the table is these runs' own mean per target (diagnose_positioning without a
        #: model): the drift is then referred to the runs' mean state, not the first reading
        self.drift_from_table_mean = False
        # the sensor's readings -> a smooth curve in time (or in the reading order):
        # regression calibration, smooth_temperature
        self.temp_grid = None if temp_c is None else smooth_temperature(
            np.asarray(order if time_s is None else time_s, dtype=np.float64),
            np.asarray(temp_c, dtype=np.float64))
        # Drift variables per reading (n_runs, 2, T): time (h), temperature (K) or,
        # without a time column, the fractional run index from the measured order.
        grids: dict[str, np.ndarray] = {}
        if time_s is not None:
            ts = np.asarray(time_s, dtype=np.float64)
            grids["h"] = (ts - float(ts.min())) / 3600.0
        else:
            rank = np.argsort(np.argsort(np.asarray(order).reshape(-1))).reshape(order.shape)
            grids["run"] = (rank + 0.5) / (2.0 * T)
        self.temp_first_c: float | None = None
        if temp_c is not None:
            first = int(np.argmin(np.asarray(order).reshape(-1)))
            tref = float(self.temp_grid.reshape(-1)[first]) if drift_ref_c is None \
                else float(drift_ref_c)
            grids["K"] = self.temp_grid - tref
            self.temp_first_c = tref
        self.drift_grids = grids
        ys, grp, cell, runs, dirs, xs, fold_t, fold_s = [], [], [], [], [], [], [], []
        nuis_cols: list[np.ndarray] = []
        nuis_names: list[str] = []
        r_idx, d_idx, t_idx = np.meshgrid(np.arange(n_runs), np.arange(2), np.arange(T), indexing="ij")
        r_idx, d_idx, t_idx = r_idx.reshape(-1), d_idx.reshape(-1), t_idx.reshape(-1)
        n_per = r_idx.size
        early = int(math.ceil(n_runs / 2.0))
        total = n_per * len(channels)
        self._rows = (r_idx, d_idx, t_idx)
        for c_i, ch in enumerate(channels):
            ys.append(ch.values.reshape(-1))
            grp.append(np.full(n_per, c_i))
            cell.append(c_i * 2 * T + d_idx * T + t_idx)
            runs.append(r_idx + 1)
            dirs.append(np.where(d_idx == 0, "+", "-"))
            xs.append(self.targets[t_idx])
            fold_t.append((r_idx >= early).astype(int))
            fold_s.append(t_idx % 2)
            sl = slice(c_i * n_per, (c_i + 1) * n_per)
            if rezeroed:
                for r in range(n_runs):
                    col = np.zeros(total)
                    col[sl] = (r_idx == r).astype(float)
                    nuis_cols.append(col)
                    nuis_names.append(f"{ch.channel}_zero_run{r + 1}")
            else:
                col = np.zeros(total)
                col[sl] = 1.0
                nuis_cols.append(col)
                nuis_names.append(f"{ch.channel}_zero")
            if ch.term in LINEAR_TERMS and ch.term != OWN_TERM[axis]:
                lo, hi = float(self.targets.min()), float(self.targets.max())
                col = np.zeros(total)
                col[sl] = (2.0 * self.targets[t_idx] - lo - hi) / max(hi - lo, 1e-9)
                nuis_cols.append(col)
                nuis_names.append(f"{ch.channel}_setup_slope")
        units = ["um" if ch.term in LINEAR_TERMS else "urad" for ch in channels]
        if n_runs >= 2:
            folds = {"runs (fit early runs, judge late runs and back)": np.concatenate(fold_t),
                     "alternate targets": np.concatenate(fold_s)}
        else:
            folds = {"alternate targets": np.concatenate(fold_s)}
        super().__init__(
            name=name, kind="laser", y=np.concatenate(ys), group=np.concatenate(grp),
            group_names=[f"{name}:{ch.channel}" for ch in channels], group_units=units,
            cell=np.concatenate(cell), folds=folds, nuisance=np.stack(nuis_cols, axis=1),
            nuisance_names=nuis_names,
            drift_options={u: np.tile(g.reshape(-1), len(channels)) for u, g in grids.items()},
            x=np.concatenate(xs), direction=np.concatenate(dirs), run=np.concatenate(runs),
            source=source, meta={"axis": axis, "line_mm": self.line_mm.tolist(),
                                 "channels": [f"{ch.channel}={'+' if ch.sign > 0 else '-'}{ch.term}"
                                              for ch in channels], "runs": n_runs})

    def without_runs(self, drop: set[int]) -> "LaserCheck":
        """The same check without the runs ``drop`` (run numbers as in the file)."""
        keep = [i for i, r in enumerate(self.run_numbers) if r not in drop]
        a = dict(self._args)
        for k in ("order", "time_s", "temp_c"):
            if a[k] is not None:
                a[k] = np.asarray(a[k])[keep]
        chans = [LaserChannel(ch.channel, ch.term, ch.sign, ch.values[keep]) for ch in self.channels]
        c = LaserCheck(channels=chans, **a)
        c.run_numbers = [self.run_numbers[i] for i in keep]
        c.drift_from_table_mean = self.drift_from_table_mean
        c.run = np.asarray(c.run_numbers)[c.run - 1]
        c.meta.update({k: v for k, v in self.meta.items() if k.startswith("source_")})
        c.meta["runs_excluded"] = sorted(set(self.run_numbers) - set(c.run_numbers)) + \
            list(self.meta.get("runs_excluded", []))
        c.meta["runs_excluded"] = sorted(set(c.meta["runs_excluded"]))
        return c

    def positions(self) -> np.ndarray:
        p = np.tile(self.line_mm, (self.T, 1))
        p[:, self.j] = self.targets
        return p

    def sample_positions(self) -> np.ndarray:
        """Position (N, 3) mm of every reading row."""
        t_idx = self._rows[2]
        return np.tile(self.positions()[t_idx], (len(self.channels), 1))

    def predict(self, ev: Evaluator, table: Table, pp: PredParams) -> np.ndarray:
        r_idx, d_idx, t_idx = self._rows
        pos_t = self.positions()
        out = []
        own = OWN_TERM[self.axis]
        extra = None
        for ch in self.channels:
            v = ev.term(table, self.axis, ch.term, self.targets)[t_idx]
            if ch.term == own:
                if extra is None:
                    extra = self._own_extra(ev, table, pp, pos_t)
                v = v + extra
            out.append(ch.sign * v)
        return np.concatenate(out)

    def _own_extra(self, ev: Evaluator, table: Table, pp: PredParams,
                   pos_t: np.ndarray) -> np.ndarray:
        """Backlash + thermal (table) + drift (PredParams) of the own term per reading row."""
        r_idx, d_idx, t_idx = self._rows
        j = self.j
        at = table.axes[self.axis]
        n = r_idx.size
        extra = np.zeros(n)
        has_t = self.temp_grid is not None and bool(at.thermal_expansion_ppm_per_k
                                                     or at.thermal_offset_um_per_k)
        if at.has_reversal() or has_t:
            if has_t:
                pos = pos_t[t_idx]
                ds = np.zeros((n, 3))
                ds[:, j] = np.where(d_idx == 0, 1.0, -1.0)
                temp = np.repeat(self.temp_grid.reshape(-1)[:, None], 3, axis=1)
                extra += ev.own_extra(table, self.axis, pos, ds, temp)
            else:
                # Direction only: evaluate each (direction, target) once.
                pos = np.concatenate([pos_t, pos_t])
                ds = np.zeros((2 * self.T, 3))
                ds[: self.T, j] = 1.0
                ds[self.T:, j] = -1.0
                e2 = ev.own_extra(table, self.axis, pos, ds, None)
                extra += e2[d_idx * self.T + t_idx]
        if pp.has_reversal(j):
            s_dir = np.where(d_idx == 0, 1.0, -1.0)
            extra += s_dir * 0.5 * pp.reversal_at(j, at.travel_mm, self.targets[t_idx])
        if np.any(pp.drift_offset) or np.any(pp.drift_scale_ppm) or np.any(pp.drift_bow_um):
            rel = self.targets[t_idx] - self.reference_mm[j]
            lo, hi = at.travel_mm
            u = (2.0 * self.targets[t_idx] - lo - hi) / (hi - lo)
            if self.drift is not None:
                sh = pp.drift_shape(self.drift[:n])
                if self.drift_from_table_mean:
                    # the table is these runs' mean per target (position_only_table): it
                    # holds the drift's mean state already, so the drift is the change
                    # from that state (docs/effects.md section 3, drift and its origin)
                    cnt = np.bincount(t_idx, minlength=self.T)
                    sh = sh - (np.bincount(t_idx, weights=sh, minlength=self.T) / cnt)[t_idx]
                extra += (pp.drift_offset[j] + pp.drift_scale_ppm[j] * rel * 1e-3
                          + pp.drift_bow_um[j] * (1.0 - u * u)) * sh
        return extra


def check_travel(checks: list[Check], table: Table, tol_mm: float = 1e-3) -> None:
    """Every check must lie inside the model's travel (else AbbeInputError)."""
    for c in checks:
        pos = c.positions()
        for j, a in enumerate(AXES):
            lo, hi = table.axes[a].travel_mm
            vmin, vmax = float(pos[:, j].min()), float(pos[:, j].max())
            if vmin < lo - tol_mm or vmax > hi + tol_mm:
                src = c.meta.get("source_file")
                raise AbbeInputError(f"{c.kind} {c.name!r} " + _outside_msg(a, lo, hi, vmin, vmax),
                                     file=src, line=c.meta.get("source_line"),
                                     field=c.meta.get("source_field"))


def ballbar_check(machine: Any, name: str, reference_mm: tuple[float, float, float]) -> BallbarCheck:
    """Read the ballbar test ``name`` of a machine file into a check."""
    from abbe.formats.ballbar_csv import check_trace_timing
    from abbe.formats.ballbar_file import read_ballbar_file
    from abbe.model.geometry import from_machine
    if name not in machine.ballbar:
        raise AbbeInputError(f"no [ballbar.{name}] section; the machine file has "
                             f"{sorted(machine.ballbar) or 'none'}", file=str(machine.path),
                             field=f"ballbar.{name}")
    bt = machine.ballbar[name]
    tr = read_ballbar_file(bt, str(machine.path))
    check_trace_timing(tr, from_machine(bt), str(machine.path))
    c = BallbarCheck(name, bt.plane, bt.center_mm, bt.radius_mm, bt.feed_mm_min, tr.direction,
                     tr.angle_deg, tr.radial_um, tr.time_s, reference_mm, source=str(bt.file),
                     temp_c=tr.temp_c, data_from_deg=tr.data_from_deg)
    c.meta.update(source_file=str(machine.path), source_line=bt.line,
                  source_field=f"ballbar.{name}.center_mm")
    return c


def laser_check(machine: Any, axis: str, reference_mm: tuple[float, float, float],
                rezeroed: bool = False) -> LaserCheck:
    """Read the laser line of ``axis`` of a machine file into a check (mapped channels)."""
    from abbe.formats.laser_file import read_laser_line
    if axis not in machine.laser:
        raise AbbeInputError(f"no [laser.{axis}] section; the machine file has "
                             f"{sorted(machine.laser) or 'none'}", file=str(machine.path),
                             field=f"laser.{axis}")
    line = machine.laser[axis]
    j = AXES.index(axis)
    data = read_laser_line(line, channels=tuple(line.map),
                           span_mm=(line.start_mm[j], line.end_mm[j]))
    chans = [LaserChannel(ch, cm.term, cm.sign, data.channels[ch]) for ch, cm in line.map.items()]
    c = LaserCheck(f"laser_{axis}", axis, line.start_mm, data.targets_mm, chans, data.line_no,
                   reference_mm, time_s=data.time_s, temp_c=data.temp_c, rezeroed=rezeroed,
                   source=str(line.file))
    c.meta.update(source_file=str(machine.path), source_line=line.line,
                  source_field=f"laser.{axis}.start_mm")
    return c


def positioning_check(path: str | Path, axis: str, reference_mm: tuple[float, float, float],
                      rezeroed: bool = False) -> LaserCheck:
    """ISO 230-2 positioning data (ESS ecmc .dat, or a laser CSV's linear channel) of
    ``axis`` as a check: deviation = + own positioning term."""
    from abbe.formats import ess_dat as ess
    from abbe.formats.positioning import load_positioning
    path = Path(path)
    data = load_positioning(path)
    n_runs, T = data.up_um.shape
    vals = np.stack([data.up_um, data.down_um], axis=1)  # (n_runs, 2, T)
    time_s = temp_c = None
    if ess.looks_like_dat(path):
        # Runs in time order: cycle c forward (ascending) then backward (descending).
        order = np.zeros((n_runs, 2, T), dtype=np.int64)
        for r in range(n_runs):
            order[r, 0] = r * 2 * T + np.arange(T)
            order[r, 1] = r * 2 * T + T + np.arange(T)[::-1]
    elif path.suffix.lower() == ".rtl":
        from abbe.formats.renishaw_rtl import read_rtl
        order = read_rtl(path).by_direction()[3]  # (n_runs, 2, T) source lines: time order
    else:
        from abbe.formats.laser_csv import read_laser_csv
        d = read_laser_csv(path, channels=("linear",))
        order, time_s, temp_c = d.line_no, d.time_s, d.temp_c
    line = list(reference_mm)
    chans = [LaserChannel("linear", OWN_TERM[axis], +1, vals)]
    c = LaserCheck(f"positioning_{axis}", axis, tuple(line), data.targets_mm, chans, order,
                   reference_mm, time_s=time_s, temp_c=temp_c, rezeroed=rezeroed,
                   source=str(path))
    c.meta.update(source_file=str(path), source_field="target")
    return c


def position_only_table(check: LaserCheck, travel_mm: tuple[float, float] | None = None) -> Table:
    """A position-only model of a positioning check's axis: its own positioning term
    interpolates the bidirectional mean deviation of every target over all runs (a
    well-conditioned basis: Fourier block 0 with period T x mean target spacing and up to
    8 harmonics, plus a Chebyshev trend of degree <= 1; square up to 18 targets, least
    squares beyond), zero at the reference point; no
    backlash, no drift; the other axes carry no terms. Units um, mm."""
    from abbe.model.table import OWN_TERM as OWN
    from abbe.model.table import AxisTable, FourierBlock, basis_matrix
    a = check.axis
    tg = check.targets
    ch = next(c for c in check.channels if c.term == OWN[a])
    mean = ch.sign * ch.values.mean(axis=(0, 1))
    lo, hi = (float(tg.min()), float(tg.max())) if travel_mm is None else travel_mm
    T = tg.size
    h = int(min(8, (T - 1) // 2))
    # trend degree <= 1: a higher degree beside 8 harmonics of about the span's period is
    # nearly collinear with them (condition ~1e3), and the cancelling coefficients
    # overflow the table (examples/vmc500/laser/x.csv, 51 targets)
    deg = int(min(1, max(T - 1 - 2 * h, 0)))
    block = None
    if h > 0:
        period = (float(tg.max()) - float(tg.min())) * T / max(T - 1, 1)
        block = FourierBlock(period_mm=period, origin_mm=float(tg.min()), harmonics=h)
    ax = AxisTable(travel_mm=(lo, hi), trend_degree=deg, blocks=(block, None))
    B = basis_matrix(ax, tg)
    coef, *_ = np.linalg.lstsq(B, mean, rcond=None)
    ref = float(check.reference_mm[check.j])
    coef[0] -= float((basis_matrix(ax, np.array([ref])) @ coef)[0])
    ax.coef[OWN[a]] = coef
    axes = {}
    for j, name in enumerate(AXES):
        if name == a:
            axes[name] = ax
        else:
            r = float(check.reference_mm[j])
            axes[name] = AxisTable(travel_mm=(r - 1.0, r + 1.0))
    return Table(axes=axes, reference_mm=tuple(float(v) for v in check.reference_mm))
