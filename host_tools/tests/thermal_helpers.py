"""Paths and small builders shared by the thermal tests (tests/thermal/)."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
REAL_XLSX = ROOT / "third_party" / "spindle-thermal" / "data.xlsx"
REAL_MACHINE = ROOT / "examples" / "spindle_thermal" / "machine.toml"
SENSORS = ("T1", "T2", "T3", "T4")


def machine_text(record: str, channels: dict[str, str]) -> str:
    """A machine file with a [thermal] section for a synthetic record."""
    lines = ['[machine]', 'name = "synthetic thermal"', '[axes.X]', 'travel_mm = [0.0, 500.0]',
             '[axes.Y]', 'travel_mm = [0.0, 400.0]', '[axes.Z]', 'travel_mm = [-300.0, 0.0]',
             '[reference]', 'point_mm = [10.0, 20.0, -30.0]', '[thermal]',
             f'record = "{record}"', 'identify_hours = [0.0, 24.0]',
             'validate_hours = [24.0, 48.1]', 'cycle_hours = 8.0', '[thermal.sensors]']
    lines += [f'{s} = "lumped node {s}"' for s in SENSORS]
    for ch, d in channels.items():
        lines += [f"[thermal.channels.{ch}]", f'direction = "{d}"', "nest_z_mm = 0.0"]
    return "\n".join(lines) + "\n"
