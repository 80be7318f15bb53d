"""Helpers shared by the fit-side tests (laser, iso230_2, fit, cmd_fit)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cases.synthetic_laser import write_laser_csv

from real_data import ESS_DAT  # noqa: F401  (re-exported: the ESS record beside the checkout)


def small_laser(path: Path, n_runs: int = 3, targets: np.ndarray | None = None,
                seed: int = 0) -> Path:
    """A valid small laser CSV (targets 0..100 mm step 10 unless given)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 101.0, 10.0) if targets is None else targets
    chans = ("linear", "straight_h", "straight_v", "pitch", "yaw", "roll")
    readings = {c: rng.normal(0, 1, (n_runs, 2, t.size)) for c in chans}
    write_laser_csv(path, t, readings)
    return path


def lines_of(path: Path) -> list[str]:
    return path.read_text().splitlines()


def write_lines(path: Path, lines: list[str]) -> Path:
    path.write_text("\n".join(lines) + "\n")
    return path


def write_positioning_dat(path: Path, v: np.ndarray, targets: np.ndarray) -> Path:
    """An ISO 230-2 positioning run in the ESS .dat format (docs/formats.md), written from
    deviations v[cycle, direction (0 forward, 1 backward), target] in um at targets in mm
    (the reference reading is the target plus its deviation, in mm)."""
    lines = ["UNIT=mm", f"CYCLES={v.shape[0]}", f"POSITIONS={targets.size}"]
    lines += [f"TGT_DATA[{i + 1}]={t:g}" for i, t in enumerate(targets)]
    for c in range(v.shape[0]):
        for i, t in enumerate(targets):
            lines.append(f"REF_DATA_FWD[{i + 1},{c + 1}]={t + v[c, 0, i] * 1e-3:.9f}")
            lines.append(f"REF_DATA_BWD[{i + 1},{c + 1}]={t + v[c, 1, i] * 1e-3:.9f}")
    return write_lines(path, lines)
