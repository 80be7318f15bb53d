"""The C thermal runtime (abbe_thermal_update/apply, through abbe.model.clib) against the
reference evaluator abbe.model.thermal.evaluate on the real 46-hour spindle record
(third_party/spindle-thermal/data.xlsx, its first 8 hours) with a hand-set model of
the 16 temperatures and the speed (no identification here: the runtime is checked, not
the model), and on a faulted copy of it (hold, flag, no jump)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from abbe.formats import golden
from abbe.formats.blob import write_blob
from abbe.formats.thermal_blob import read_thermal_blob, write_thermal_blob
from abbe.model import clib
from abbe.model.thermal import (
    ThermalChannel,
    ThermalInput,
    ThermalModel,
    ThermalTerm,
    evaluate,
    tool_tip_error,
)

pytestmark = pytest.mark.skipif(not clib.available(), reason="C library not built")
XLSX = Path(__file__).resolve().parents[3] / "third_party/spindle-thermal/data.xlsx"
N_ROWS = 1920  # 8 h at 15 s: the 1250 rpm cycle, on and off


@pytest.fixture(scope="module")
def record() -> tuple[np.ndarray, np.ndarray]:
    openpyxl = pytest.importorskip("openpyxl")
    if not XLSX.is_file():
        pytest.skip("third_party/spindle-thermal/data.xlsx not present")
    wb = openpyxl.load_workbook(XLSX, read_only=True, data_only=True)
    rows = []
    for i, r in enumerate(wb.worksheets[0].iter_rows(values_only=True)):
        if i == 0:
            assert str(r[0]).strip() == "時間(s)" and str(r[1]) == "spindle(RPM)"
            continue
        rows.append(r)
        if len(rows) == N_ROWS:
            break
    a = np.array(rows, dtype=float)
    t = a[:, 0]
    x = np.column_stack([a[:, 7:23], a[:, 1]])  # t1..t16, then the speed
    return t, x


def _model() -> ThermalModel:
    inputs = tuple(ThermalInput(f"t{k + 1}", reference=26.0, valid_min=0.0, valid_max=80.0,
                                max_step=3.0) for k in range(16)) + (
        ThermalInput("spindle", kind="speed", reference=0.0, valid_min=0.0, valid_max=12000.0,
                     max_step=12000.0),)
    chans = (
        ThermalChannel("ch5", "z", (ThermalTerm(4, 600.0, -3.1), ThermalTerm(8, 2400.0, -1.7),
                                    ThermalTerm(16, 1500.0, -4.2), ThermalTerm(0, 0.0, 0.8))),
        ThermalChannel("ch1", "x", (ThermalTerm(1, 900.0, 1.9), ThermalTerm(16, 3000.0, 2.5))),
        ThermalChannel("ch3", "y", (ThermalTerm(2, 300.0, -2.2), ThermalTerm(11, 5000.0, 1.1))),
        ThermalChannel("tilt_a", "a", (ThermalTerm(5, 1200.0, 4.0),)),
        ThermalChannel("tilt_b", "b", (ThermalTerm(6, 1800.0, -3.0), ThermalTerm(16, 700.0, 1.5))),
    )
    return ThermalModel(inputs=inputs, channels=chans, max_gap_s=60.0, fade_s=30.0)


@pytest.fixture(scope="module")
def loaded() -> tuple[bytes, ThermalModel]:
    blob = write_thermal_blob(write_blob(golden.full_table(np.random.default_rng(1))), _model())
    model = read_thermal_blob(blob)[1]
    assert model is not None
    return blob, model


def test_c_matches_the_reference_on_the_real_record(record, loaded) -> None:
    t, x = record
    blob, model = loaded
    tz = int.from_bytes(blob[44:48], "little", signed=True) * 1e-6
    ct = clib.CThermal(blob)
    assert (ct.n_inputs, ct.n_channels) == (17, 5)
    dt = np.diff(t, prepend=t[0])
    # f32: the reference at the float32 inputs; one apply() per sample of a fade's length
    xf = x.astype(np.float32).astype(float)
    ref = evaluate(model, t, xf)
    got = ct.run_f32(dt, xf, period_s=30.0)
    assert np.max(np.abs(got["channels"] - ref)) < 2e-3 + 2e-5 * np.max(np.abs(ref))
    tips = np.array([tool_tip_error(model, r, tz) for r in ref])
    assert np.max(np.abs(got["tip"] - tips)) < 5e-3
    assert not np.any(got["flags"] & 0x0F)
    # q: integers, m degC / rpm, ms
    milli = np.column_stack([np.round(x[:, :16] * 1000), np.round(x[:, 16])]).astype(np.int64)
    xq = milli.astype(float)
    xq[:, :16] /= 1000.0
    refq = evaluate(model, t, xq)
    gotq = ct.run_q(np.round(dt * 1000).astype(np.int64), milli, period_s=30.0)
    assert np.max(np.abs(gotq["channels"] - refq)) < 3e-3
    assert np.ptp(ref[:, 0]) > 5.0  # the record does move the model (not a trivial pass)


def test_sensor_fault_on_the_real_record(record, loaded) -> None:
    t, x = record
    blob, model = loaded
    ct = clib.CThermal(blob)
    dt = np.diff(t, prepend=t[0])
    valid = np.full(len(t), (1 << 17) - 1)
    xf = x.copy()
    valid[600:640] &= ~(1 << 4)       # t5 open for 10 minutes
    xf[900:905, 8] = -200.0           # t9 reads a short
    clean = ct.run_f32(dt, x, period_s=1.0, applies=15)
    faulty = ct.run_f32(dt, xf, valid=valid, period_s=1.0, applies=15)
    assert np.all(faulty["flags"][600:640] & 0x01) and np.all(faulty["flags"][900:905] & 0x02)
    assert np.all(faulty["flags"][600:640] & 0x20)  # held
    # the channel that does not read t5 or t9 (x: t2 and the speed) never noticed
    assert np.array_equal(faulty["channels"][:, 1], clean["channels"][:, 1])
    # z reads t5: it held and faded out (its tip part shrinks), then came back
    assert abs(faulty["tip"][639, 2]) < 0.5 * abs(clean["tip"][639, 2])
    assert abs(faulty["tip"][-1, 2] - clean["tip"][-1, 2]) < 0.05 * abs(clean["tip"][-1, 2]) + 0.1
    # no jump: per sample (15 evaluations) the faulted output moves no more than the
    # clean one plus 15 fade steps of the largest channel contribution
    step_clean = np.max(np.abs(np.diff(clean["tip"], axis=0)), axis=0)
    step_faulty = np.max(np.abs(np.diff(faulty["tip"], axis=0)), axis=0)
    bound = step_clean + 15 / 30 * np.max(np.abs(clean["tip"]), axis=0) + 1e-3
    assert np.all(step_faulty <= bound), (step_clean, step_faulty)
