"""The machine file's [thermal] section: the example's declared mapping, and located errors."""

from __future__ import annotations

import pytest

from abbe.cli.entry import main
from abbe.errors import AbbeInputError
from abbe.formats.machine import load_machine
from thermal_helpers import REAL_MACHINE, machine_text


def test_example_mapping(real_spec):
    assert len(real_spec.sensors) == 16 and set(real_spec.channels) == {f"ch{k}" for k in range(1, 6)}
    pairs = {p.output: p for p in real_spec.tilt_pairs()}
    assert (pairs["b"].lower, pairs["b"].upper, pairs["b"].spacing_mm) == ("ch1", "ch2", 100.0)
    assert (pairs["a"].lower, pairs["a"].upper) == ("ch3", "ch4")
    assert "not documented" in real_spec.note
    assert real_spec.record.name == "data.xlsx" and real_spec.record.is_file()


@pytest.mark.parametrize("old,new,field", [
    ('validate_hours = [24.0, 48.1]', 'validate_hours = [20.0, 48.1]', "thermal.validate_hours"),
    ('direction = "z"', 'direction = "w"', "thermal.channels.chz.direction"),
    ('cycle_hours = 8.0', 'cycle_hours = 8.0\nspeed = 3', "thermal.speed"),
    ('identify_hours = [0.0, 24.0]', 'identify_hours = [24.0, 0.0]', "thermal.identify_hours"),
    ('nest_z_mm = 0.0', 'nest_z_mm = 0.0\ncalibration_U_pct = -1.0',
     "thermal.channels.chz.calibration_U_pct"),
    ('nest_z_mm = 0.0', 'nest_z_mm = 0.0\ncalibration_U_pct = nan',
     "thermal.channels.chz.calibration_U_pct"),
    ('cycle_hours = 8.0', 'cycle_hours = 8.0\ntemperature_calibration_U_pct = "1"',
     "thermal.temperature_calibration_U_pct"),
])
def test_errors_name_the_line(tmp_path, old, new, field):
    text = machine_text("r.csv", {"chz": "z"})
    assert old in text
    p = tmp_path / "m.toml"
    p.write_text(text.replace(old, new))
    with pytest.raises(AbbeInputError) as e:
        load_machine(p)
    assert e.value.field == field and e.value.line is not None
    assert p.read_text().splitlines()[e.value.line - 1].split("=")[0].strip() in field


def test_calibration_declared_or_class_default(tmp_path):
    text = machine_text("r.csv", {"chz": "z", "chx": "x"})
    p = tmp_path / "m.toml"
    p.write_text(text)
    spec = load_machine(p).extra["thermal"]
    assert spec.channels["chz"].calibration_U_pct == 1.0 and not spec.channels["chz"].calibration_declared
    assert spec.temperature_calibration_U_pct == 0.5 and not spec.temperature_calibration_declared
    p.write_text(text.replace('cycle_hours = 8.0', 'cycle_hours = 8.0\ntemperature_calibration_U_pct = 0.2')
                 .replace('direction = "z"\nnest_z_mm = 0.0',
                          'direction = "z"\nnest_z_mm = 0.0\ncalibration_U_pct = 0.3'))
    spec = load_machine(p).extra["thermal"]
    assert spec.channels["chz"].calibration_U_pct == 0.3 and spec.channels["chz"].calibration_declared
    assert not spec.channels["chx"].calibration_declared
    assert spec.temperature_calibration_U_pct == 0.2 and spec.temperature_calibration_declared


def test_undeclared_channel_is_exit_2(synthetic, tmp_path, capsys):
    folder, _ = synthetic
    m = tmp_path / "m.toml"
    m.write_text(machine_text(str(folder / "record.csv"), {"chz": "z"}))   # chx undeclared
    assert main(["thermal", "evaluate", str(m)]) == 2
    err = capsys.readouterr().err
    assert "chx is not declared" in err.replace("record's ", "") or "chx" in err
    assert f"{m}:" in err


def test_no_thermal_section_is_exit_2(tmp_path, capsys):
    p = tmp_path / "m.toml"
    p.write_text(REAL_MACHINE.read_text().split("[thermal]")[0])
    assert main(["thermal", "fit", str(p), "-o", str(tmp_path / "out")]) == 2
    assert "no [thermal] section" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_too_few_cycles_is_exit_2(synthetic, tmp_path, capsys):
    folder, _ = synthetic
    m = tmp_path / "m.toml"
    text = machine_text(str(folder / "record.csv"), {"chz": "z", "chx": "x"})
    m.write_text(text.replace("cycle_hours = 8.0", "cycle_hours = 16.0"))
    assert main(["thermal", "fit", str(m), "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "cycle_hours" in err and "at least 2" in err and f"{m}:" in err


def test_a_record_nothing_explains_is_exit_2(tmp_path, capsys):
    """Displacements of pure noise: no term passes the selection, nothing is written."""
    import numpy as np
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 48 * 3600.0, 60.0)
    temps = 20.0 + 0.01 * rng.normal(size=(t.size, 4))
    rows = ["time_s," + ",".join(f"{s}_c" for s in ("T1", "T2", "T3", "T4")) + ",chz_um"]
    for k in range(t.size):
        rows.append(f"{t[k]:.0f}," + ",".join(f"{v:.4f}" for v in temps[k])
                    + f",{rng.normal():.4f}")
    (tmp_path / "r.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "m.toml").write_text(machine_text("r.csv", {"chz": "z"}))
    assert main(["thermal", "fit", str(tmp_path / "m.toml"), "-o", str(tmp_path / "o")]) == 2
    assert "no input explains any channel" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
