"""The real 46-hour record (third_party/spindle-thermal, CAIVIAC/FL_THERMAL, MIT): identified
on hours 0-24, scored on hours 24-46 (never seen by identification or selection)."""

from __future__ import annotations

import numpy as np
import pytest

from abbe.analysis.thermal.identify import candidates_of, identify_channel
from abbe.analysis.thermal.pipeline import TARGET_RATIO, check_model
from abbe.model.thermal import as_dict, evaluate, from_dict


def test_the_written_model_is_the_scored_one(real_fit):
    assert check_model(real_fit) < 1e-9
    again = from_dict(as_dict(real_fit.model))
    rec = real_fit.record
    x = np.column_stack([rec.temps_c, rec.speed_rpm])
    np.testing.assert_array_equal(evaluate(again, rec.time_s, x),
                                  evaluate(real_fit.model, rec.time_s, x))
    outs = sorted(c.output for c in real_fit.model.channels)
    assert outs == ["a", "b", "x", "y", "z"]


def test_held_out_scores(real_fit):
    """Every channel compensated better than not at all; the model beats the static
    regression on all 16 temperatures on most channels and reaches the 20 % target on
    most (docs/thermal.md has the table and says which miss and why)."""
    for s in real_fit.channels:
        assert s.rms_comp < s.rms_uncomp, s.name
    met = [s.name for s in real_fit.channels if s.ratio <= TARGET_RATIO]
    beats = [s.name for s in real_fit.channels if s.rms_comp < s.rms_mlr]
    assert len(met) >= 3, [(s.name, s.ratio) for s in real_fit.channels]
    assert len(beats) >= 4, [(s.name, s.rms_comp, s.rms_mlr) for s in real_fit.channels]


def test_every_term_has_intervals(real_fit):
    for c in real_fit.model.channels:
        for t in c.terms:
            assert t.gain_u95 is not None and t.gain_u95 > 0
            assert t.tau_s == 0.0 or t.tau_u95_s is None or t.tau_u95_s > 0


def test_identification_never_sees_the_held_out_displacements(real_record):
    """Garbage in the held-out hours' displacement changes nothing identified."""
    r = real_record
    cands = candidates_of(r.temps_c, list(r.temp_names), r.speed_rpm)
    ident = r.hours < 24.0
    y = r.disp_um[:, 4] - r.disp_um[0, 4]
    y2 = y.copy()
    y2[~ident] = 1e3 * np.sin(np.arange((~ident).sum()))
    a = identify_channel("ch5", r.time_s, y, cands, ident, 8 * 3600.0, max_terms=2)
    b = identify_channel("ch5", r.time_s, y2, cands, ident, 8 * 3600.0, max_terms=2)
    assert a.terms == b.terms and a.steps == b.steps


def test_the_committed_example_model_is_a_fresh_fit(real_fit):
    """examples/spindle_thermal/thermal.json (what the runtime's tables embed) is what the
    identification gives today."""
    import json

    from thermal_helpers import ROOT
    path = ROOT / "examples" / "spindle_thermal" / "thermal.json"
    committed = from_dict(json.loads(path.read_text()))
    fresh = real_fit.model
    assert [c.name for c in committed.channels] == [c.name for c in fresh.channels]
    assert [i.name for i in committed.inputs] == [i.name for i in fresh.inputs]
    for a, b in zip(committed.channels, fresh.channels):
        assert a.output == b.output and len(a.terms) == len(b.terms)
        for ta, tb in zip(a.terms, b.terms):
            assert ta.input == tb.input
            assert ta.gain == pytest.approx(tb.gain, rel=1e-6, abs=1e-9)
            assert ta.tau_s == pytest.approx(tb.tau_s, rel=1e-6, abs=1e-9)
