"""Bands, trends and alerts (abbe.history.trends) on series whose answer is known by hand,
and the limits file (abbe.history.limits)."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from abbe.errors import AbbeInputError
from abbe.history.limits import DEFAULT_LIMITS, Settings, load_settings
from abbe.history.store import Point, Series
from abbe.history.trends import analyse

T0 = dt.datetime(2023, 1, 16, 9)
QUARTER_D = 91.0


def _series(values, key="s", unit="um", ci=None) -> Series:
    pts = [Point(i + 1, T0 + dt.timedelta(days=QUARTER_D * i), float(v),
                 None if ci is None else v - ci, None if ci is None else v + ci)
           for i, v in enumerate(values)]
    return Series(key, unit, pts)


def _at(an, kind):
    return sorted(a.campaign_id for a in an.alerts if a.kind == kind)


def test_a_stable_noisy_series_raises_nothing():
    rng = np.random.default_rng(7)
    s = Settings(limits={"s": 10.0})
    an = analyse(_series(5.0 + 0.1 * rng.standard_normal(40)), s)
    assert an.alerts == []
    assert an.band[0] < 5.0 < an.band[1]


def test_a_step_leaves_the_band_at_its_campaign_and_passes_the_limit():
    vals = [30.1, 29.8, 30.3, 29.9, 30.2, 30.0, 80.2, 79.9, 80.1]
    an = analyse(_series(vals, unit="urad", ci=0.5), Settings(limits={"s": 60.0}))
    assert _at(an, "band") == [7, 8, 9]
    assert _at(an, "limit") == [7, 8, 9]
    # the widest of 3 s (0.75), the interval (0.5), 10 % of the limit (6) around the mean
    m = np.mean(vals[:3])
    assert an.band == pytest.approx((m - 6.0, m + 6.0))


def test_linear_wear_is_announced_before_it_passes_the_limit():
    # 2.0 + 0.6 um per quarter, limit 7.5 um, horizon 180 days: the line reaches 7.5 at
    # k = 9.17 quarters (834 days). At k = 8 (728 d) that is 106 days ahead -> alert; at
    # k = 7 (637 d) 197 days ahead -> not yet. Over the limit from k = 10 (8.0 um).
    vals = [2.0 + 0.6 * k for k in range(13)]
    an = analyse(_series(vals), Settings(limits={"s": 7.5}, horizon_days=180, trend_campaigns=4))
    assert _at(an, "trend") == [9, 10]  # campaign numbers = k + 1
    assert _at(an, "limit") == [11, 12, 13]
    # the band of the first three quarters: 2.6 +- 3 x 0.6 = [0.8, 4.4]; k = 4 is on its
    # edge (inside), k = 5 (5.0 um, campaign 6) leaves it
    assert _at(an, "band") == list(range(6, 14))
    # the trend at the last campaign and the date it crossed (already over: in the past)
    assert an.trend[0] == pytest.approx(0.6 / QUARTER_D)
    msg = next(a.message for a in an.alerts if a.kind == "trend" and a.campaign_id == 9)
    assert "in 106 days" in msg


def test_a_trend_inside_the_noise_is_not_extrapolated():
    vals = [5.0, 5.4, 4.7, 5.3, 4.8, 5.5]  # no significant slope
    an = analyse(_series(vals), Settings(limits={"s": 6.0}, horizon_days=3650))
    assert _at(an, "trend") == []


def test_limits_file(tmp_path):
    f = tmp_path / "limits.toml"
    f.write_text('horizon_days = 90\n[limits]\n"iso230-2 B X bi" = 7.5\n"diagnose *" = 1.0\n')
    s = load_settings(f)
    assert s.horizon_days == 90
    assert s.limit_of("iso230-2 B X bi") == 7.5
    assert s.limit_of("iso230-2 B Y bi") == DEFAULT_LIMITS["iso230-2 B * bi"]
    assert s.limit_of("diagnose squareness_xy") == 1.0  # the file's pattern comes first
    assert s.limit_of("ballbar H XY F200") is None
    for text, field in (('horizon = 9\n', "horizon"), ('[limits]\n"a" = -1\n', "limits.a"),
                        ('band_sigma = nan\n', "band_sigma"), ('trend_campaigns = 2\n',
                                                               "trend_campaigns")):
        f.write_text(text)
        with pytest.raises(AbbeInputError) as e:
            load_settings(f)
        assert e.value.field == field and e.value.file == str(f)
