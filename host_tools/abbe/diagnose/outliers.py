"""Outlier runs of repeated laser / ISO 230-2 checks: found, named, excluded, reported.

Two tests, both on repeated runs (at least 3):

* **gross readings** (before any fit, model free): each reading's deviation from
  the median of its cell (same channel, direction and target over the runs), less
  a robust line per pass (Theil-Sen; a drift between runs shifts and tilts whole
  passes), in units of a robust scale (1.4826 x the median absolute deviation,
  pooled over the channel). A reading beyond ``GROSS_Z`` robust sigmas makes its
  run an outlier run ("start-up outlier, cycle 1, +85.2 um at 15 mm");
* **inconsistent runs** (after the diagnosis, on the residual through the updated
  model): a run whose residual variance is ``INCONSISTENT_RATIO`` times that of the
  other runs (median), significant by an F-test at 0.001 / runs.

An outlier run is excluded from the check (all its channels), the user is told,
and the rest is diagnosed. At most a third of the runs (and never below 3 runs
left) are excluded: beyond that the runs disagree among themselves, which is
reported instead. Values um / urad, positions mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import stats

from abbe.diagnose.checks import Check, LaserCheck

#: A reading this many robust sigmas off its cell median makes its run an outlier.
GROSS_Z = 8.0
#: A run whose residual variance is this many times the others' is inconsistent.
INCONSISTENT_RATIO = 4.0
#: Smallest robust scale assumed (um / urad).
SCALE_FLOOR = 0.01


@dataclass
class OutlierRun:
    """One excluded run of a check: why, and the readings that gave it away."""

    check: str
    run: int
    kind: str                      # "start-up outlier" | "outlier run" | "inconsistent run"
    readings: list[dict[str, Any]] = field(default_factory=list)
    ratio: float | None = None     # inconsistent run: its residual variance / the others'
    excluded: bool = True

    def message(self) -> str:
        what = f"{self.kind}, {'cycle' if self.check.startswith('positioning') else 'run'} {self.run}"
        if self.readings:
            parts = [f"{r['deviation']:+.1f} {r['unit']} at {r['target_mm']:g} mm"
                     + (f" ({r['channel']}, {r['direction']})" if r.get("channel") != "linear"
                        else f" ({'forward' if r['direction'] == '+' else 'backward'})")
                     for r in self.readings[:3]]
            more = f" and {len(self.readings) - 3} more" if len(self.readings) > 3 else ""
            what += ": " + ", ".join(parts) + more
        elif self.ratio is not None:
            what += f": residual scatter {math.sqrt(self.ratio):.1f} x that of the other runs"
        tail = (" -- excluded, the other runs diagnosed" if self.excluded
                else " -- NOT excluded (too many runs disagree)")
        return f"{self.check}: {what}{tail}"

    def to_json(self) -> dict[str, Any]:
        d: dict[str, Any] = {"check": self.check, "run": self.run, "kind": self.kind,
                             "excluded": self.excluded, "message": self.message()}
        if self.readings:
            d["readings"] = self.readings
        if self.ratio is not None:
            d["variance_ratio"] = round(self.ratio, 3)
        return d


def _robust_line(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    if x.size < 3:
        return np.full(y.shape, float(np.median(y)))
    slope, icpt = _theil_sen(x, y)
    return icpt + slope * x


def _theil_sen(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Theil-Sen line of y on x (slope, intercept): the median of the pairwise slopes and
    median(y) - slope median(x), computed as scipy.stats.theilslopes does (the same
    numbers, bit for bit) without its confidence interval and argument handling, which
    took most of the outlier screen's time (thousands of calls of a few points)."""
    x = np.asarray(x, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    deltax = x[:, np.newaxis] - x
    deltay = y[:, np.newaxis] - y
    pos = deltax > 0
    slopes = deltay[pos] / deltax[pos]
    slopes.sort()
    medslope = np.median(slopes)
    return medslope, np.median(y) - medslope * np.median(x)


def gross_outliers(c: LaserCheck) -> list[OutlierRun]:
    """Runs holding a reading ``GROSS_Z`` robust sigmas off its cell (see module doc)."""
    R = c.n_runs
    if R < 3:
        return []
    found: dict[int, list[dict[str, Any]]] = {}
    for ch in c.channels:
        v = ch.values                      # (R, 2, T)
        dev, res = _cell_residual(v, c.targets)
        # deviations about the median of R values, less a line per pass, are smaller than
        # the noise: scale their MAD by the factor that holds for normal noise
        mad = float(np.median(np.abs(res)))
        sig = max(SCALE_FLOOR, mad / _mad_factor(R, c.targets))
        z = np.abs(res) / sig
        unit = "um" if ch.term.startswith("d") else "urad"
        for r, d, t in zip(*np.nonzero(z > GROSS_Z)):
            found.setdefault(c.run_numbers[r], []).append({
                "channel": ch.channel, "direction": "+" if d == 0 else "-",
                "target_mm": round(float(c.targets[t]), 4),
                "deviation": round(float(dev[r, d, t]), 3), "unit": unit,
                "robust_z": round(float(z[r, d, t]), 1)})
    out = []
    for run, rd in sorted(found.items()):
        rd.sort(key=lambda x: -abs(x["deviation"]))
        kind = "start-up outlier" if run == c.run_numbers[0] else "outlier run"
        out.append(OutlierRun(c.name, run, kind, rd))
    return _cap(out, R)


def _cell_residual(v: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R, 2, T) deviations from the cell medians, and those less a robust line per pass."""
    R = v.shape[0]
    dev = v - np.median(v, axis=0)[None]
    res = np.empty_like(dev)
    for r in range(R):
        for d in range(2):
            res[r, d] = dev[r, d] - _robust_line(targets, dev[r, d])
    return dev, res


_FACTORS: dict[tuple[int, int], float] = {}


def _mad_factor(R: int, targets: np.ndarray) -> float:
    """Median |residual| of :func:`_cell_residual` for unit normal noise of this shape
    (R runs, T targets), by a seeded simulation (cached)."""
    key = (R, int(targets.size))
    if key not in _FACTORS:
        rng = np.random.default_rng(230)
        vals = [float(np.median(np.abs(_cell_residual(rng.normal(size=(R, 2, targets.size)),
                                                      targets)[1]))) for _ in range(40)]
        _FACTORS[key] = float(np.median(vals))
    return _FACTORS[key]


def _cap(out: list[OutlierRun], R: int) -> list[OutlierRun]:
    """Exclude at most a third of the runs and keep at least 3."""
    if len(out) > max(1, R // 3) or R - len(out) < 3:
        for o in out:
            o.excluded = False
    return out


def inconsistent_runs(c: LaserCheck, resid_w: np.ndarray) -> list[OutlierRun]:
    """Runs of ``c`` whose whitened residual variance is INCONSISTENT_RATIO times the other
    runs' (median) and significant (F-test at 0.001 / runs). ``resid_w``: (N,) the check's
    whitened residual (nuisance removed) in its row order."""
    R = c.n_runs
    if R < 3:
        return []
    runs = np.asarray(c.run)
    var = {}
    cnt = {}
    for r in c.run_numbers:
        m = runs == r
        x = resid_w[m]
        x = x[np.isfinite(x)]
        if x.size:
            var[r] = float(np.mean(x * x))
            cnt[r] = int(x.size)
    out = []
    for r, v in var.items():
        others = [var[o] for o in var if o != r]
        if not others:
            continue
        base = max(float(np.median(others)), 1e-12)
        ratio = v / base
        n_o = sum(cnt[o] for o in var if o != r)
        p = float(stats.f.sf(ratio, cnt[r], n_o))
        if ratio >= INCONSISTENT_RATIO and p < 1e-3 / R:
            out.append(OutlierRun(c.name, r, "inconsistent run", ratio=ratio))
    return _cap(out, R)


def screen(checks: list[Check]) -> tuple[list[Check], list[OutlierRun]]:
    """Gross-outlier screen of every laser / positioning check (model free): returns the
    checks with the outlier runs excluded and the outliers found."""
    out_checks: list[Check] = []
    found: list[OutlierRun] = []
    for c in checks:
        if isinstance(c, LaserCheck) and not c.meta.get("screened"):
            o = gross_outliers(c)
            found += o
            drop = {x.run for x in o if x.excluded}
            if drop:
                c = c.without_runs(drop)
            c.meta["screened"] = True
        out_checks.append(c)
    return out_checks, found
