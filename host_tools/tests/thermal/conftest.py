"""Shared fixtures of the thermal tests: the real record read once, its fit once, the
independent synthetic record generated once (the tests stay in seconds)."""

from __future__ import annotations

import pytest
from thermal_helpers import REAL_MACHINE, REAL_XLSX, machine_text


@pytest.fixture(scope="session")
def real_spec():
    from abbe.formats.machine import load_machine
    return load_machine(REAL_MACHINE).extra["thermal"]


@pytest.fixture(scope="session")
def real_record():
    from abbe.formats.thermal_record import read_thermal_xlsx
    return read_thermal_xlsx(REAL_XLSX)


@pytest.fixture(scope="session")
def real_fit(real_record, real_spec):
    from abbe.analysis.thermal.pipeline import fit_record
    return fit_record(real_record, real_spec)


@pytest.fixture(scope="session")
def synthetic(tmp_path_factory):
    """(folder, truth): the independent generator's record (cases/thermal_independent.py)
    and a machine file naming it."""
    from cases.thermal_independent import generate
    d = tmp_path_factory.mktemp("thermal_syn")
    csv, truth, _ = generate(seed=3, noise_um=0.3)
    (d / "record.csv").write_text(csv)
    (d / "machine.toml").write_text(machine_text("record.csv", {"chz": "z", "chx": "x"}))
    return d, truth
