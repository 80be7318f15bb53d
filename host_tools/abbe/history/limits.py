"""Tolerances and alert settings of ``abbe history report`` (a TOML file, ``--limits``).

::

    horizon_days = 180        # a trend that reaches a limit within this time raises an alert
    baseline_campaigns = 3    # the band: mean of the first N campaigns +- band_sigma x their s
    band_sigma = 3.0
    trend_campaigns = 5       # the trend line: least squares through the last N campaigns

    [limits]                  # |value| tolerance per series, in the series' unit; keys are
    "iso230-2 B X bi" = 8.0   # series names or shell patterns ("diagnose squareness_*")

Every key is checked (unknown keys, wrong types, NaN, a negative limit are refused
with file, line, field). A series named by no pattern has no limit (band alerts
only). The defaults below are a starting point for a machining centre of the
vmc500 class; a shop sets its own from its acceptance tolerances.
"""

from __future__ import annotations

import fnmatch
from dataclasses import dataclass, field
from pathlib import Path

from abbe.errors import AbbeInputError, check_int, check_number
from abbe.formats.structured import load_toml, unknown_key

DEFAULT_LIMITS: dict[str, float] = {
    "iso230-2 B * bi": 10.0,              # reversal, um
    "fit backlash *": 10.0,               # mean reversal, um
    "diagnose backlash_*": 10.0,          # reversal missing from the table, um
    "diagnose squareness_*": 50.0,        # urad
    "fit squareness *": 50.0,             # urad
    "ballbar G * bi": 25.0,               # circular deviation, um
}


@dataclass
class Settings:
    """Alert settings and limits (module docstring)."""

    horizon_days: float = 180.0
    baseline_campaigns: int = 3
    band_sigma: float = 3.0
    trend_campaigns: int = 5
    limits: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_LIMITS))

    def limit_of(self, series: str) -> float | None:
        """The tolerance of ``series``: an exact key first, else the first matching pattern."""
        if series in self.limits:
            return self.limits[series]
        for pat, v in self.limits.items():
            if fnmatch.fnmatchcase(series, pat):
                return v
        return None


_KEYS = ("horizon_days", "baseline_campaigns", "band_sigma", "trend_campaigns", "limits")


def load_settings(path: str | Path | None) -> Settings:
    """The settings of ``--limits FILE`` (defaults without); its limits replace the defaults'
    of the same key and come first."""
    s = Settings()
    if path is None:
        return s
    data, tf = load_toml(path, what="history limits", max_bytes=1 << 20)
    f = str(path)
    for k in data:
        if k not in _KEYS:
            raise AbbeInputError(unknown_key(k, _KEYS), file=f, field=k)
    if "horizon_days" in data:
        s.horizon_days = check_number(data["horizon_days"], file=f, field="horizon_days",
                                      lo=0, hi=36500, unit="days", lo_open=True)
    if "band_sigma" in data:
        s.band_sigma = check_number(data["band_sigma"], file=f, field="band_sigma", lo=0,
                                    hi=100, lo_open=True)
    if "baseline_campaigns" in data:
        s.baseline_campaigns = check_int(data["baseline_campaigns"], file=f,
                                         field="baseline_campaigns", lo=1, hi=1000)
    if "trend_campaigns" in data:
        s.trend_campaigns = check_int(data["trend_campaigns"], file=f, field="trend_campaigns",
                                      lo=3, hi=1000)
    lim = data.get("limits", {})
    if not isinstance(lim, dict):
        raise AbbeInputError("expected a table of series = limit", file=f, field="limits")
    mine: dict[str, float] = {}
    for k, v in lim.items():
        mine[k] = check_number(v, file=f, field=f"limits.{k}", lo=0, hi=1e7, lo_open=True)
    s.limits = {**mine, **{k: v for k, v in DEFAULT_LIMITS.items() if k not in mine}}
    return s
