"""Positioning data from a file: ESS ecmc ``.dat`` or a laser CSV, chosen by content.

Deviations (measured minus target) in um, targets in mm.
"""

from __future__ import annotations

from pathlib import Path

from abbe.formats import ess_dat, laser_csv
from abbe.formats.deviations import PositioningData


def load_positioning(path: str | Path) -> PositioningData:
    """Positioning data from a file: ESS ecmc ``.dat`` (key=value) or a laser CSV.

    The format is chosen by content: a file whose first non-comment line is
    ``KEY=value`` is read as ``.dat`` (:mod:`abbe.formats.ess_dat`); otherwise as a laser CSV,
    of which only run, direction, target_mm and linear_um are required (the
    ``linear_um`` reading, instrument sign, is the deviation).
    """
    path = Path(path)
    if ess_dat.looks_like_dat(path):
        return ess_dat.read_dat(path)
    d = laser_csv.read_laser_csv(path, channels=("linear",))
    lin = d.channels["linear"]
    return PositioningData(source=str(path), targets_mm=d.targets_mm, up_um=lin[:, 0, :],
                           down_um=lin[:, 1, :], sha256=d.sha256)
