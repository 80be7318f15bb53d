"""Positioning data from a file: ESS ecmc ``.dat``, Renishaw ``.rtl`` or a laser CSV.

Deviations (measured minus target) in um, targets in mm, at 20 deg C where the
file says how (:mod:`abbe.formats.thermal20`).
"""

from __future__ import annotations

from pathlib import Path

from abbe.errors import AbbeInputError
from abbe.formats import ess_dat, laser_csv, renishaw_rtl
from abbe.formats.deviations import PositioningData
from abbe.formats.laser_file import csv_normalisation, rtl_normalisation


def load_positioning(path: str | Path, *, encoding: str | None = None) -> PositioningData:
    """Positioning data from a file: ESS ecmc ``.dat``, Renishaw ``.rtl`` or a laser CSV.

    The format is chosen by name and content: a ``.rtl`` name is a Renishaw export
    (:mod:`abbe.formats.renishaw_rtl`, a linear measurement); a file whose first
    non-comment line is ``KEY=value`` is read as ``.dat`` (:mod:`abbe.formats.ess_dat`);
    otherwise as a laser CSV, of which only run, direction, target_mm and linear_um
    are required (the ``linear_um`` reading, instrument sign, is the deviation). A
    CSV with ``temp_c`` and ``expansion_ppm_per_k`` is normalised to 20 deg C.
    ``encoding``: a ``.rtl`` file's text encoding (None: detected, see
    :func:`abbe.formats.renishaw_rtl.read_rtl`); not used for other files.
    """
    path = Path(path)
    if renishaw_rtl.looks_like_rtl(path):
        r = renishaw_rtl.read_rtl(path, encoding=encoding)
        if r.kind != "linear":
            raise AbbeInputError(f"measurement type {r.owner!r}: ISO 230-2 positioning needs a "
                                 "'Linear' measurement", file=str(path),
                                 line=r.key_lines.get("Owner"), field="Owner")
        if r.n_runs < 2:
            raise AbbeInputError(f"Run-count {2 * r.n_runs} is one bidirectional cycle: ISO 230-2 "
                                 "needs at least 2 cycles (Run-count 4; 5 cycles by the "
                                 "standard)", file=str(path), line=r.key_lines.get("Run-count"),
                                 field="Run-count")
        targets, up, down, _ = r.by_direction()
        return PositioningData(source=str(path), targets_mm=targets, up_um=up, down_um=down,
                               sha256=r.sha256, normalisation=rtl_normalisation(r),
                               notes=r.reading_notes())
    if ess_dat.looks_like_dat(path):
        return ess_dat.read_dat(path)
    d = laser_csv.read_laser_csv(path, channels=("linear",))
    norm, lin = csv_normalisation(d, d.channels["linear"])
    return PositioningData(source=str(path), targets_mm=d.targets_mm, up_um=lin[:, 0, :],
                           down_um=lin[:, 1, :], sha256=d.sha256, normalisation=norm)
