"""Bands, trend lines and alerts of one series, as they would have been raised at each
campaign (every alert uses only the campaigns up to and including its own).

* **band**: the mean of the first ``baseline_campaigns`` values +- the larger of
  ``band_sigma`` x their standard deviation, the median U (k = 2) the producer stated
  (else its 95 % half-interval), 10 % of the limit and 5 % of the mean (a band never narrower than
  what the measurement can resolve). A later value outside it: alert ``band``, for the
  quantities that matter -- those with a tolerance (a series without one has its band
  drawn and marked in the tables, but raises nothing: three campaigns cannot tell the
  noise of every by-product quantity, and a page of alerts is read by no one).
* **limit**: \\|value\\| above the series' tolerance: alert ``limit``.
* **trend**: least-squares line through the last ``trend_campaigns`` values
  (value against days); when its slope differs from zero by more than 2 standard
  errors and the line reaches +-limit within ``horizon_days`` after the campaign:
  alert ``trend`` with the date it is expected.
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass, field

import numpy as np

from abbe.history.limits import Settings
from abbe.history.store import Point, Series


@dataclass
class Alert:
    """An alert raised at a campaign."""

    series: str
    campaign_id: int
    measured_at: dt.datetime
    kind: str  # "band", "limit" or "trend"
    message: str


@dataclass
class Analysis:
    """One series analysed: band, limit, trend at the last campaign, alerts over time."""

    series: Series
    limit: float | None
    band: tuple[float, float] | None  # (low, high)
    trend: tuple[float, float] | None = None  # (slope per day, value at the last campaign)
    crossing: dt.datetime | None = None  # when the trend at the last campaign reaches the limit
    alerts: list[Alert] = field(default_factory=list)

    def out_of_band(self) -> bool:
        """The last value lies outside the band."""
        if self.band is None or not self.series.points:
            return False
        return not self.band[0] <= self.series.points[-1].value <= self.band[1]

    def current(self) -> list[Alert]:
        """The alerts of the last campaign."""
        if not self.series.points:
            return []
        last = self.series.points[-1].campaign_id
        return [a for a in self.alerts if a.campaign_id == last]


def band_of(points: list[Point], s: Settings, limit: float | None) -> tuple[float, float] | None:
    """The band from the baseline campaigns (module docstring); None before it is complete."""
    base = points[:s.baseline_campaigns]
    if len(base) < s.baseline_campaigns:
        return None
    v = np.array([p.value for p in base])
    centre = float(v.mean())
    sd = float(v.std(ddof=1)) if v.size > 1 else 0.0
    # each value's own half-width: U (k = 2) where stated, else its 95 % interval's
    halves = [p.U if p.U is not None else (p.ci_high - p.ci_low) / 2 for p in base
              if p.U is not None or (p.ci_low is not None and p.ci_high is not None)]
    half = max(s.band_sigma * sd, float(np.median(halves)) if halves else 0.0,
               0.1 * limit if limit else 0.0, 0.05 * abs(centre), 1e-9)
    return centre - half, centre + half


def trend_of(points: list[Point], s: Settings) -> tuple[float, float, float] | None:
    """(slope per day, its standard error, value of the line at the last point) through the
    last ``trend_campaigns`` points; None with fewer than 3 points or no time span.

    The closed form of the straight-line least squares (a few points, called once per
    campaign and series: numpy's general solver would dominate the report's time)."""
    pts = points[-s.trend_campaigns:]
    n = len(pts)
    if n < 3:
        return None
    last = pts[-1].measured_at
    t = [(p.measured_at - last).total_seconds() / 86400.0 for p in pts]
    v = [p.value for p in pts]
    tm, vm = sum(t) / n, sum(v) / n
    sxx = sum((ti - tm) ** 2 for ti in t)
    if sxx <= 0:
        return None
    slope = sum((ti - tm) * (vi - vm) for ti, vi in zip(t, v)) / sxx
    rss = sum((vi - vm - slope * (ti - tm)) ** 2 for ti, vi in zip(t, v))
    se = math.sqrt(rss / (n - 2) / sxx)
    return slope, se, vm - slope * tm


def _crossing_days(slope: float, se: float, now: float, limit: float) -> float | None:
    """Days after the last point until the line reaches +-limit (None: not heading there)."""
    if limit is None or slope == 0 or abs(slope) <= 2 * se:
        return None
    target = limit if slope > 0 else -limit
    d = (target - now) / slope
    return d if d > 0 else None


def analyse(series: Series, s: Settings) -> Analysis:
    """The series' band, limit, trend and the alerts at every campaign (module docstring)."""
    limit = s.limit_of(series.key)
    pts = series.points
    an = Analysis(series, limit, band_of(pts, s, limit))
    for i, p in enumerate(pts):
        upto = pts[max(0, i + 1 - s.trend_campaigns):i + 1]  # all trend_of uses
        if limit is not None and an.band is not None and i >= s.baseline_campaigns and not (
                an.band[0] <= p.value <= an.band[1]):
            an.alerts.append(Alert(series.key, p.campaign_id, p.measured_at, "band",
                                   f"{p.value:.4g} {series.unit} outside the band "
                                   f"[{an.band[0]:.4g}, {an.band[1]:.4g}]"))
        if limit is not None and abs(p.value) > limit:
            an.alerts.append(Alert(series.key, p.campaign_id, p.measured_at, "limit",
                                   f"|{p.value:.4g}| {series.unit} over the limit {limit:g}"))
            continue
        tr = trend_of(upto, s)
        if tr is None or limit is None:
            continue
        slope, se, now = tr
        d = _crossing_days(slope, se, now, limit)
        if d is not None and d <= s.horizon_days:
            when = p.measured_at + dt.timedelta(days=d)
            an.alerts.append(Alert(series.key, p.campaign_id, p.measured_at, "trend",
                                   f"trend {slope * 30.44:+.3g} {series.unit}/month reaches "
                                   f"{limit:g} in {d:.0f} days (about {when:%Y-%m-%d}; "
                                   f"horizon {s.horizon_days:g} days)"))
    tr = trend_of(pts, s)
    if tr is not None:
        an.trend = (tr[0], tr[2])
        d = _crossing_days(tr[0], tr[1], tr[2], limit) if limit is not None else None
        if d is not None:
            an.crossing = pts[-1].measured_at + dt.timedelta(days=d)
    return an
