"""A drift found in a laser campaign, tied to the temperatures the campaign carries.

Repeated laser / ISO 230-2 runs read the same targets at different times; what changes
between the readings of one target (and approach direction) is drift. When the file also
carries a temperature per reading (a laser CSV's ``temp_c``: the material or air
temperature of the compensation unit), the drift is tested against it:

    d_i = mu_g + (o + k * 1e-3 * x_i) * L_i,   L = lag(T - T_0, tau)   (backward Euler)

``d_i`` the gap between model and reading (um; the diagnosis' residual before it adds
anything, so the static error of each target is in ``mu_g``, one mean per target and
direction, not in the drift), ``x_i`` the target position (mm), ``o`` the offset per kelvin
(um/K), ``k`` the expansion coefficient (ppm/K = um/m/K), ``tau`` the lag (s) through which the
axis follows the measured temperature (0: it follows at once). Fitted by least squares
over a time-constant grid, then refined; 95 % intervals from the Jacobian with the
residuals' serial correlation (effective sample count n (1 - rho) / (1 + rho)). The
alternative it must beat is a drift linear in time (the same two columns with the time in
hours instead of L): temperature "explains" the drift when it leaves less than the
time-only drift, the explained fraction of the drift's variance is at least
:data:`MIN_EXPLAINED`, the offset's or the expansion's interval excludes 0, and the lag is
decided by the data (known within a factor of 2 at 95 % and shorter than the campaign: a
longer lag cannot be told from a trend in time). The axis' state at the campaign's start
is unknown (a machine still catching up with its temperature): the decay of an unknown
initial state is fitted with the offset and the expansion as a nuisance.

Ballbar traces are not tied (one pass per direction cannot tell the shape of the circle
from a drift along it); see docs/thermal.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

from abbe.model.thermal import lag_states

#: Fraction of the drift's variance (after the per-target means) the temperature must
#: explain to be named as its cause.
MIN_EXPLAINED = 0.5


@dataclass(frozen=True)
class DriftTie:
    """The drift of one check against its temperature (module docs); units in the names."""

    check: str
    n: int
    span_h: float
    temp_range_k: float
    tau_s: float
    tau_u95_s: float | None  # None: the data do not bound the lag
    offset_um_per_k: float
    offset_u95: float
    expansion_ppm_per_k: float
    expansion_u95: float
    drift_rms_um: float      # the drift (readings minus their target's mean)
    rms_temperature_um: float  # what the lagged temperature term leaves
    rms_time_only_um: float    # what a drift linear in time leaves
    explained: float           # 1 - (rms_temperature / drift_rms)^2
    named: bool                # the temperature explains the drift (module docs)

    def to_json(self) -> dict[str, Any]:
        return {k: (round(v, 6) if isinstance(v, float) else v) for k, v in self.__dict__.items()}

    def sentence(self) -> str:
        lag = ("at once (lag 0)" if self.tau_s == 0.0 else
               f"through a lag of {self.tau_s / 60.0:.0f} min"
               + (f" +/- {self.tau_u95_s / 60.0:.0f}" if self.tau_u95_s is not None
                  else " (not bounded by the data)"))
        head = (f"{self.check}: the drift ({self.drift_rms_um:.2f} um RMS over {self.span_h:.1f} h, "
                f"temperature range {self.temp_range_k:.2f} K) ")
        if not self.named:
            return head + (f"is not explained by the temperature (explained {100 * self.explained:.0f} %, "
                           f"left {self.rms_temperature_um:.2f} um vs {self.rms_time_only_um:.2f} um "
                           "by a drift linear in time)")
        return head + (f"follows the temperature {lag}: expansion {self.expansion_ppm_per_k:.2f} "
                       f"+/- {self.expansion_u95:.2f} ppm/K, offset {self.offset_um_per_k:.2f} "
                       f"+/- {self.offset_u95:.2f} um/K; left {self.rms_temperature_um:.2f} um "
                       f"(a drift linear in time leaves {self.rms_time_only_um:.2f} um)")


def _demean(cols: np.ndarray, groups: np.ndarray) -> np.ndarray:
    out = np.array(cols, dtype=float, copy=True)
    for g in np.unique(groups):
        m = groups == g
        out[m] -= out[m].mean(axis=0)
    return out


def _lagged(time_s: np.ndarray, rise_k: np.ndarray, tau_s: float
            ) -> tuple[np.ndarray, np.ndarray]:
    """At every reading (readings sharing a time share it): the lag of the temperature
    rise started in equilibrium at the first reading, and the decay of a unit initial
    state (the axis' state when the campaign starts is unknown: a warm machine still
    catching up with its temperature). The temperature between readings is taken as
    linear and the lag run on a grid of at most tau / 20 (a pause between runs is not
    one backward-Euler step)."""
    rise = np.asarray(rise_k, float)
    if tau_s == 0.0:
        return rise.copy(), np.zeros(rise.shape)
    order = np.argsort(time_s, kind="stable")
    ts, first = np.unique(time_s[order], return_index=True)
    u = rise[order][first]
    if ts.size < 2:
        return np.full(time_s.shape, float(u[0])), np.ones(time_s.shape)
    step = max(tau_s / 20.0, (ts[-1] - ts[0]) / 200000.0)
    fine = np.union1d(ts, np.arange(ts[0], ts[-1], step))
    s = lag_states(np.interp(fine, ts, u), fine, tau_s)
    unit = np.zeros(fine.size)
    unit[0] = 1.0
    d = lag_states(unit, fine, tau_s)
    d[0] = 1.0
    return np.interp(time_s, fine, s), np.interp(time_s, fine, d)


def tie_drift(name: str, time_s: np.ndarray, temp_c: np.ndarray, pos_mm: np.ndarray,
              drift_um: np.ndarray, groups: np.ndarray) -> DriftTie | None:
    """Fit the drift of the readings (module docs). ``groups``: one label per reading
    (target and direction); ``pos_mm``: the target's position along the axis. None when
    the readings cannot carry the fit (fewer than two readings per group on average, no
    temperature change or no time span)."""
    t = np.asarray(time_s, float)
    T = np.asarray(temp_c, float)
    x = np.asarray(pos_mm, float)
    y = np.asarray(drift_um, float)
    g = np.asarray(groups)
    n = y.size
    if not (t.shape == T.shape == x.shape == y.shape == g.shape) or t.ndim != 1:
        raise ValueError("time, temperature, position, drift and groups: one value per reading")
    n_groups = np.unique(g).size
    span = float(t.max() - t.min()) if n else 0.0
    t_range = float(T.max() - T.min()) if n else 0.0
    if n < 2 * n_groups + 3 or span <= 0.0 or t_range <= 0.0:
        return None
    rise = T - T[np.argmin(t)]
    yd = _demean(y[:, None], g)[:, 0]
    x0 = x - np.mean(x)  # an origin inside the travel: o and k less correlated

    def design(tau: float) -> np.ndarray:
        """Columns: offset and expansion on the lag; the same on the initial state's
        decay (nuisance: o c and k c, c the unknown initial state; absent for tau 0)."""
        lag, decay = _lagged(t, rise, tau)
        cols = [lag, 1e-3 * x0 * lag] + ([decay, 1e-3 * x0 * decay] if tau > 0.0 else [])
        return _demean(np.column_stack(cols), g)

    def rss(tau: float) -> float:
        a = design(tau)
        r = yd - a @ np.linalg.lstsq(a, yd, rcond=None)[0]
        return float(r @ r)

    grid = [0.0] + list(np.geomspace(60.0, 4.0 * span, 24))
    scores = [rss(tau) for tau in grid]
    j = int(np.argmin(scores))
    tau = grid[j]
    if j > 0:
        lo = np.log(grid[max(j - 1, 1)])
        hi = np.log(grid[min(j + 1, len(grid) - 1)])
        if hi > lo:
            sol = minimize_scalar(lambda lt: rss(float(np.exp(lt))), bounds=(lo, hi),
                                  method="bounded", options={"xatol": 1e-4})
            if sol.fun <= scores[j]:
                tau = float(np.exp(sol.x))
    a = design(tau)
    coef = np.linalg.lstsq(a, yd, rcond=None)[0]
    r = yd - a @ coef
    coef_c = coef
    # intervals: Jacobian in (o, k, the decay's two, log tau) (the last three only for a
    # lag), serial correlation
    cols = [a[:, k] for k in range(a.shape[1])]
    if tau > 0.0:
        h = 1e-4
        cols.append((design(tau * np.exp(h)) @ coef_c - a @ coef_c) / h)
    jac = np.column_stack(cols)
    p = jac.shape[1] + n_groups
    in_time = r[np.argsort(t, kind="stable")]
    rho = float(np.clip(np.corrcoef(in_time[:-1], in_time[1:])[0, 1], 0.0, 0.999)) \
        if n > 3 and np.std(in_time) > 0 else 0.0
    n_eff = max(n * (1.0 - rho) / (1.0 + rho), p + 1.0)
    s2 = float(r @ r) / max(n - p, 1) * (n / n_eff)
    # the offset reported at position 0 (the targets' coordinate): o0 = o - k 1e-3 mean(x)
    xm = 1e-3 * float(np.mean(x))
    tr = np.eye(jac.shape[1])
    tr[0, 1] = -xm
    try:
        cov = tr @ (s2 * np.linalg.inv(jac.T @ jac)) @ tr.T
        half = 1.96 * np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        half = np.full(jac.shape[1], np.inf)
    coef = np.array([coef[0] - xm * coef[1], coef[1]])  # (the decay's nuisance dropped)
    tau_u = None
    kt = a.shape[1]  # log tau's index
    if tau > 0.0 and np.isfinite(half[kt]) and half[kt] < 20.0:
        tau_u = float(tau * np.expm1(half[kt]))
    # the alternative: a drift linear in time
    th = (t - t.min()) / 3600.0
    at = _demean(np.column_stack([th, 1e-3 * x0 * th]), g)
    rt = yd - at @ np.linalg.lstsq(at, yd, rcond=None)[0]
    drift_rms = float(np.sqrt(np.mean(yd ** 2)))
    rms_t = float(np.sqrt(np.mean(r ** 2)))
    rms_time = float(np.sqrt(np.mean(rt ** 2)))
    explained = 1.0 - (rms_t / drift_rms) ** 2 if drift_rms > 0 else 0.0
    return DriftTie(check=name, n=n, span_h=span / 3600.0, temp_range_k=t_range, tau_s=float(tau),
                    tau_u95_s=tau_u, offset_um_per_k=float(coef[0]), offset_u95=float(half[0]),
                    expansion_ppm_per_k=float(coef[1]), expansion_u95=float(half[1]),
                    drift_rms_um=drift_rms, rms_temperature_um=rms_t, rms_time_only_um=rms_time,
                    explained=float(explained),
                    named=bool(explained >= MIN_EXPLAINED and rms_t < rms_time
                               and (abs(coef[0]) > half[0] or abs(coef[1]) > half[1])
                               and (tau == 0.0 or (tau_u is not None and tau_u <= tau
                                                   and tau < span))))


def ties_of(checks: list[Any], residuals: list[np.ndarray]) -> list[DriftTie]:
    """The tie of every laser check that carries both a time and a temperature per
    reading, on its first channel (the positioning channel of an ISO 230-2 file);
    ``residuals``: per check, the gap before the diagnosis adds anything (um)."""
    from abbe.diagnose.checks import LaserCheck
    out = []
    for c, res in zip(checks, residuals):
        # the runs before an "inconsistent run" exclusion (selection.diagnose): the tie is
        # an explanation of that inconsistency, tested on the data it must explain
        if not isinstance(c, LaserCheck):
            continue
        c, res = c.tie_source or (c, res)
        if not isinstance(c, LaserCheck) or c.temp_grid is None or "h" not in c.drift_options:
            continue
        m = c.group == 0
        if not np.any(m):
            continue
        hours = c.drift_options["h"][m]
        temp = c.drift_options["K"][m] + (c.temp_first_c or 0.0)
        pos = np.asarray(c.x, float)[m]
        labels = np.asarray(c.cell)[m]  # target and direction
        tie = tie_drift(c.name, hours * 3600.0, temp, pos, np.asarray(res, float)[m], labels)
        if tie is not None:
            out.append(tie)
    return out
