"""The product end to end on the real record: the model `abbe thermal fit` identifies
(hours 0-24), embedded in a table by the thermal block writer (format 1.3), run by the C
runtime sample by sample over the whole 46 hours: it gives the Python reference's
channels, and so the held-out scores the identification reported."""

from __future__ import annotations

import numpy as np
import pytest

from abbe.formats.blob import write_blob
from abbe.formats.thermal_blob import quantize_thermal, write_thermal_blob
from abbe.model import clib
from abbe.model.examples import paper_table
from abbe.model.thermal import evaluate

pytestmark = pytest.mark.skipif(not clib.available(), reason="C library not built")


def _inputs(model, rec):
    cols = []
    for inp in model.inputs:
        if inp.kind == "speed":
            cols.append(rec.speed_rpm)
        else:
            cols.append(rec.temps_c[:, list(rec.temp_names).index(inp.name)])
    return np.column_stack(cols)


def test_fitted_model_runs_in_the_c_runtime_as_scored(real_fit):
    rec = real_fit.record
    model = real_fit.model
    blob = write_thermal_blob(write_blob(paper_table()), model)
    ct = clib.CThermal(blob, "fitted thermal table")
    x = _inputs(model, rec)
    dt = np.concatenate([[0.0], np.diff(rec.time_s)])
    out = ct.run_f32(dt, x, period_s=1.0, applies=0)
    ref = evaluate(quantize_thermal(model), rec.time_s, x)
    # no sensor fault, limit or hold on the real record (0x3F: OPEN, RANGE, STEP, GAP,
    # LIMIT, HOLD; FADING stays: with no evaluations the start-up fade-in never advances)
    assert not np.any(out["flags"][1:] & 0x3F), np.unique(out["flags"])
    diff = np.max(np.abs(out["channels"] - ref), axis=0)
    assert np.all(diff < 0.05), diff  # um / urad, float32 over 11,115 samples
    # the held-out scores through the C runtime: what the identification reported
    held = real_fit.valid_mask
    by_out = {c.output: j for j, c in enumerate(model.channels)}
    for s in real_fit.outputs:
        j = next((by_out[c.output] for c in model.channels if c.name == s.name), None)
        if j is None:
            continue
        # the sensor's zero (the displacement at the record's start) is the fit's, not
        # the runtime's: the runtime gives the thermal error from the cold state
        resid = s.measured[held] - (s.fit.offset_um + out["channels"][held, j])
        rms_c = float(np.sqrt(np.mean(resid ** 2)))
        assert rms_c == pytest.approx(s.rms_comp, abs=0.05), s.name
