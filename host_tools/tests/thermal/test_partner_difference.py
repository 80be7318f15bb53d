"""Issue 35, round 5 (docs/thermal.md, "Issue 35, fifth round"): a paired channel of the
ISO 230-3 nest predicted as its partner's model plus the model of the pair's difference
(:func:`abbe.analysis.thermal.structure.partner_difference_rms`, :func:`prefers_partner`),
and the composed channel's terms (:func:`abbe.analysis.thermal.pipeline._merged`), on a
record made here with known truth."""

from __future__ import annotations

import numpy as np
import pytest

from abbe.analysis.thermal.identify import Candidate, cycles_of
from abbe.analysis.thermal.pipeline import _merged
from abbe.analysis.thermal.structure import (forward_chain_rms, loco_rms,
                                             partner_difference_rms, prefers_partner)
from abbe.model.thermal import TEMPERATURE, ThermalTerm, lag_states

CYCLE_S = 8 * 3600.0


def _nest(seed: int = 2):
    """24 h, three cycles at 1, 2, 3 krpm: the lower channel 4 um/K x lag(h0, 1800 s), the
    upper the same plus a small tilt -1.5 um/K x h1 (static); 0.05 um noise."""
    t = np.arange(0.0, 24 * 3600.0, 15.0)
    speed = np.where((t % CYCLE_S) < 14400.0, 1.0 + (t // CYCLE_S), 0.0)
    rng = np.random.default_rng(seed)
    h0 = 2.0 * lag_states(speed, t, 2400.0)
    h1 = 1.0 * lag_states(speed, t, 600.0) + 0.3 * np.sin(t / 9000.0)
    cands = [Candidate("h0", TEMPERATURE, h0), Candidate("h1", TEMPERATURE, h1)]
    low = 4.0 * lag_states(h0, t, 1800.0) + 0.05 * rng.standard_normal(t.size)
    diff = -1.5 * h1 + 0.05 * rng.standard_normal(t.size)
    mask = np.ones(t.size, bool)
    return t, cands, low, low + diff, diff, cycles_of(t, mask, CYCLE_S)


LOW = [ThermalTerm(0, 1800.0, 0.0)]
DIFF = [ThermalTerm(1, 0.0, 0.0)]


def test_the_upper_channel_takes_partner_plus_difference():
    t, cands, low, up, diff, cyc = _nest()
    # the upper channel's own model lacks the tilt's input: partner + difference wins both
    use, f = prefers_partner(t, up, cands, LOW, LOW, low, DIFF, up - low, 1.0, cyc)
    assert use
    assert f["loco_partner"] < 0.1 < f["loco_direct"]  # the noise against the missing tilt
    assert f["forward_partner"] < 0.1 < f["forward_direct"]
    assert f["loco_direct"] == pytest.approx(loco_rms(t, up, cands, LOW, cyc))
    assert f["forward_direct"] == pytest.approx(forward_chain_rms(t, up, cands, LOW, cyc))
    # the lower channel from the upper's full model minus the difference: the same quality;
    # its own exact model ties within the noise and keeps it only when strictly worse
    both = [ThermalTerm(0, 1800.0, 0.0), ThermalTerm(1, 0.0, 0.0)]
    lo = partner_difference_rms(t, low, cands, both, up, DIFF, up - low, -1.0, cyc)
    assert lo < 0.1
    # a wrong sign makes it the sum, not the difference: far off
    assert partner_difference_rms(t, low, cands, both, up, DIFF, up - low, 1.0, cyc) > 1.0


def test_composition_equals_the_two_fits_by_hand():
    """The leave-one-cycle-out figure is each model's own least squares on the training
    cycles (its signal, its offset), summed, scored on the left-out cycle."""
    t, cands, low, up, diff, cyc = _nest(5)
    s0 = lag_states(cands[0].rise, t, 1800.0)
    s1 = cands[1].rise
    sq = 0.0
    for c in range(3):
        tr, te = cyc != c, cyc == c
        a0 = np.column_stack([np.ones(t.size), s0])
        a1 = np.column_stack([np.ones(t.size), s1])
        p = a0 @ np.linalg.lstsq(a0[tr], low[tr], rcond=None)[0] + \
            a1 @ np.linalg.lstsq(a1[tr], (up - low)[tr], rcond=None)[0]
        sq += float(np.sum((up - p)[te] ** 2))
    want = np.sqrt(sq / t.size)
    got = partner_difference_rms(t, up, cands, LOW, low, DIFF, up - low, 1.0, cyc, "loco")
    assert got == pytest.approx(want, rel=1e-9)
    with pytest.raises(ValueError, match="scheme"):
        partner_difference_rms(t, up, cands, LOW, low, DIFF, up - low, 1.0, cyc, "k-fold")


def test_a_direct_model_as_good_stays_direct():
    """Ties (and losses on either cross-validation) keep the channel's own model."""
    t, cands, low, up, diff, cyc = _nest()
    both = [ThermalTerm(0, 1800.0, 0.0), ThermalTerm(1, 0.0, 0.0)]
    # the difference modelled by nothing useful (h0 static): the composition loses
    use, f = prefers_partner(t, up, cands, both, LOW, low, [ThermalTerm(0, 0.0, 0.0)],
                             up - low, 1.0, cyc)
    assert not use and f["loco_partner"] > f["loco_direct"]


def test_merged_terms_add_the_same_input_and_lag():
    a = [ThermalTerm(0, 600.0, 2.0, 0.3, 50.0), ThermalTerm(1, 0.0, 1.0, 0.1, 0.0)]
    b = [ThermalTerm(0, 600.0, -0.5, 0.4, 80.0), ThermalTerm(2, 60.0, 3.0, None, None)]
    got = _merged(a, b)
    assert [(x.input, x.tau_s) for x in got] == [(0, 600.0), (1, 0.0), (2, 60.0)]
    assert got[0].gain == pytest.approx(1.5) and got[0].gain_u95 == pytest.approx(0.5)
    assert got[2].gain == 3.0 and got[2].gain_u95 is None
