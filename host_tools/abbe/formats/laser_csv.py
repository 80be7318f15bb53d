"""6D laser CSV reader and the sign conversion from instrument channels to model terms.

File format (docs/formats.md, "6D laser CSV"): a header row
``run,direction,target_mm,linear_um,straight_h_um,straight_v_um,pitch_urad,yaw_urad,roll_urad``
(any column order) plus optional ``time_s,temp_c``; one row per reading, in the
order measured. ``run`` = 1..n; ``direction`` ``+`` (the pass visits the targets
ascending) or ``-`` (descending). Blank lines and lines starting with ``#`` are
ignored. Units: target mm, linear channels um, angular channels urad.

Every problem raises :class:`abbe.errors.AbbeInputError` naming the file, the
line (1-based, the header is line 1 unless comments precede it) and the column.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from abbe.errors import AbbeInputError
from abbe.formats.columns import LASER_ROLES, Columns, plan_columns
from abbe.formats.delimited import DEFAULT_DIALECT, Column, Header, read_columns
from abbe.formats.limits import LASER_CSV_MAX_BYTES, LASER_CSV_MAX_ROWS, LASER_MAX_RUNS
from abbe.formats.machine import CHANNELS, LaserLine
from abbe.formats.text import read_text

#: channel -> CSV column (with unit)
CHANNEL_COLUMNS: dict[str, str] = {
    "linear": "linear_um", "straight_h": "straight_h_um", "straight_v": "straight_v_um",
    "pitch": "pitch_urad", "yaw": "yaw_urad", "roll": "roll_urad",
}
BASE_COLUMNS: tuple[str, ...] = ("run", "direction", "target_mm")
OPTIONAL_COLUMNS: tuple[str, ...] = ("time_s", "temp_c")
DIRECTIONS: tuple[str, str] = ("+", "-")
#: Two targets closer than this (mm) are the same target.
TARGET_TOL_MM = 1e-6


@dataclass
class LaserData:
    """Readings of one laser CSV arranged by run, direction and target.

    targets_mm: (T,) ascending, mm. channels[ch]: (n_runs, 2, T) readings in the
    instrument's units and signs (um / urad); axis 1 is the direction
    (0 = ``+`` approach, 1 = ``-`` approach); targets are in ascending order on
    both directions. time_s, temp_c: same shape or None. line_no: (n_runs, 2, T)
    source line of each reading (for error messages).
    """

    file: Path
    targets_mm: np.ndarray
    channels: dict[str, np.ndarray]
    time_s: np.ndarray | None
    temp_c: np.ndarray | None
    line_no: np.ndarray
    sha256: str
    columns: Columns | None = None
    #: the material's expansion coefficient (ppm/K) when the file gives it (20 deg C
    #: normalisation, :mod:`abbe.formats.thermal20`), and the line giving it.
    expansion_ppm_per_k: float | None = None
    expansion_line: int | None = None
    #: what was done about 20 deg C (abbe.formats.thermal20.Normalisation), when known
    normalisation: Any = None

    @property
    def n_runs(self) -> int:
        return int(self.line_no.shape[0])


def read_laser_csv(path: str | Path, *, channels: tuple[str, ...] = CHANNELS,
                   travel_mm: tuple[float, float] | None = None,
                   span_mm: tuple[float, float] | None = None,
                   columns: Columns | None = None) -> LaserData:
    """Read and validate a 6D laser CSV (abbe's format, or as ``columns`` declares).

    ``channels``: instrument channels whose columns are required (the others are
    optional and read if present). ``travel_mm``: the axis travel (mm); a target
    outside it is an error. ``span_mm``: the line's (start, end) coordinate on its
    axis (mm, any order); a target outside it is an error. ``columns``: a declared
    instrument export (machine file ``[laser.A.columns]``, :mod:`abbe.formats.columns`):
    dialect, column names, units and signs; values are converted to mm / um / urad.

    Checks: header (missing, unknown or misspelt columns, duplicates), every cell
    a strict number in its range (:mod:`abbe.errors.numbers`), ``run`` an integer
    1..100, ``direction`` ``+``/``-``, each pass (run, direction) one contiguous
    block of rows, targets strictly ascending in ``+`` passes and descending in
    ``-`` passes, no duplicated target, every run having both passes over the
    same targets (equal run counts at every target). Bounds: file size, line
    length and rows (:mod:`abbe.formats.limits`).
    """
    path = Path(path)
    fname = str(path)
    dialect = columns.dialect if columns is not None else DEFAULT_DIALECT
    tf = read_text(path, what="laser CSV", max_bytes=LASER_CSV_MAX_BYTES,
                   encoding=dialect.encoding)
    need = ("run", "direction", "target") + tuple(channels)

    def plan(header: Header) -> dict[str, Column]:
        p = plan_columns(header, LASER_ROLES, columns, file=fname, need=need,
                         strict_names=True, default_dirs=DIRECTIONS)
        p["run"].hi = LASER_MAX_RUNS
        return p

    header, vals, lines = read_columns(tf, dialect, what="laser CSV",
                                       max_rows=LASER_CSV_MAX_ROWS, plan=plan)
    hdr_line = header.line
    if lines.size == 0:
        raise AbbeInputError("no data rows after the header", file=fname, line=hdr_line)
    n = int(lines.size)
    run = vals["run"]
    dirn = vals["direction"]

    # Passes: contiguous blocks of equal (run, direction), in measured order.
    breaks = np.flatnonzero((np.diff(run) != 0) | (np.diff(dirn) != 0)) + 1
    starts = np.concatenate([[0], breaks])
    ends = np.concatenate([breaks, [n]])
    seen: dict[tuple[int, int], int] = {}
    passes: dict[tuple[int, int], np.ndarray] = {}
    tgt = vals["target"]
    tcol = header.names[plan_index(header, columns, "target")]
    rcol = header.names[plan_index(header, columns, "run")]
    dcol = header.names[plan_index(header, columns, "direction")]
    for s, e in zip(starts, ends):
        key = (int(run[s]), int(dirn[s]))
        if key in seen:
            raise AbbeInputError(
                f"run {key[0]} direction '{DIRECTIONS[key[1]]}' continues here after other "
                f"rows (first block at line {seen[key]}): each pass must be one contiguous "
                "block of rows in measured order", file=fname, line=int(lines[s]), field=rcol)
        seen[key] = int(lines[s])
        t = tgt[s:e]
        step = np.diff(t) if key[1] == 0 else -np.diff(t)
        bad = np.flatnonzero((np.abs(step) <= TARGET_TOL_MM) | (step < 0))
        if bad.size:
            i = int(bad[0])
            if abs(step[i]) <= TARGET_TOL_MM:
                raise AbbeInputError(f"duplicated target {t[i + 1]:.6g} mm in run {key[0]} "
                                     f"direction '{DIRECTIONS[key[1]]}'", file=fname,
                                     line=int(lines[s + i + 1]), field=tcol)
            order = "ascending" if key[1] == 0 else "descending"
            raise AbbeInputError(f"targets of a '{DIRECTIONS[key[1]]}' pass must be {order}: "
                                 f"{t[i + 1]:.6g} mm follows {t[i]:.6g} mm", file=fname,
                                 line=int(lines[s + i + 1]), field=tcol)
        passes[key] = np.arange(s, e) if key[1] == 0 else np.arange(e - 1, s - 1, -1)

    runs = sorted({r for r, _ in passes})
    for want, r in enumerate(runs, start=1):
        if r != want:
            raise AbbeInputError(f"runs must be numbered 1..n without gaps: run {want} is missing",
                                 file=fname, line=seen[(r, 0)] if (r, 0) in seen else seen[(r, 1)],
                                 field=rcol)
    first = passes.get((1, 0))
    if first is None:
        raise AbbeInputError("run 1 has no '+' pass", file=fname, line=seen[(1, 1)],
                             field=dcol)
    targets = tgt[first]
    T = targets.size
    for r in runs:
        for d in (0, 1):
            if (r, d) not in passes:
                other = seen[(r, 1 - d)]
                raise AbbeInputError(f"run {r} has no '{DIRECTIONS[d]}' pass: every run needs "
                                     "both directions (equal run counts at every target)",
                                     file=fname, line=other, field=dcol)
            idx = passes[(r, d)]
            t = tgt[idx]
            if t.size != T or np.any(np.abs(t - targets) > TARGET_TOL_MM):
                # First difference in measured order: the row where it shows.
                rows_m = np.sort(idx)
                got = tgt[rows_m]
                want = targets if d == 0 else targets[::-1]
                n_cmp = min(got.size, want.size)
                diff = np.flatnonzero(np.abs(got[:n_cmp] - want[:n_cmp]) > TARGET_TOL_MM)
                if diff.size:
                    i = int(diff[0])
                    row = rows_m[i]
                    what = f"expected target {want[i]} mm here, got {got[i]} mm"
                elif got.size < want.size:
                    row = rows_m[-1]
                    what = f"target {want[got.size]} mm is missing after this row"
                else:
                    row = rows_m[want.size]
                    what = f"extra target {got[want.size]} mm"
                raise AbbeInputError(
                    f"run {r} direction '{DIRECTIONS[d]}' has {t.size} targets, run 1 '+' has "
                    f"{T}: {what} (every run must visit the same targets: equal run counts)",
                    file=fname, line=int(lines[row]), field=tcol)

    order = np.array([[passes[(r, d)] for d in (0, 1)] for r in runs])  # (n_runs, 2, T)
    for lim, what in ((travel_mm, "the axis travel"), (span_mm, "the line's start..end")):
        if lim is None:
            continue
        lo, hi = min(lim), max(lim)
        bad = np.flatnonzero((tgt < lo - TARGET_TOL_MM) | (tgt > hi + TARGET_TOL_MM))
        if bad.size:
            k = int(bad[0])
            raise AbbeInputError(f"target {tgt[k]:.6g} mm is outside {what} [{lo:g}, {hi:g}] mm",
                                 file=fname, line=int(lines[k]), field=tcol)

    chans = {ch: vals[ch][order] for ch in CHANNEL_COLUMNS if ch in vals}
    alpha, alpha_line = None, None
    if "expansion" in vals:
        e = vals["expansion"]
        diff = np.flatnonzero(e != e[0])
        ecol = header.names[plan_index(header, columns, "expansion")]
        if diff.size:
            raise AbbeInputError(f"the expansion coefficient is a property of the material: "
                                 f"{e[diff[0]]:g} here, {e[0]:g} on the first row",
                                 file=fname, line=int(lines[diff[0]]), field=ecol)
        if "temp" not in vals:
            raise AbbeInputError("an expansion coefficient without a temp_c column: the "
                                 "20 deg C normalisation needs the material temperature",
                                 file=fname, line=hdr_line, field=ecol)
        alpha, alpha_line = float(e[0]), int(lines[0])
    return LaserData(
        file=path, targets_mm=targets.copy(), channels=chans,
        time_s=vals["time"][order] if "time" in vals else None,
        temp_c=vals["temp"][order] if "temp" in vals else None,
        line_no=lines[order], sha256=tf.sha256, columns=columns,
        expansion_ppm_per_k=alpha, expansion_line=alpha_line)


def plan_index(header: Header, columns: Columns | None, role: str) -> int:
    """Index in the header of the column holding ``role``."""
    name = (columns.fields[role].column if columns is not None and role in columns.fields
            else LASER_ROLES[role].default)
    return header.names.index(name)


def to_terms(data: LaserData, line: LaserLine) -> dict[str, np.ndarray]:
    """Step 1: instrument channels -> model terms of the line's axis, per the map.

    The map says reading = sign * term, so term = sign * reading. Returns
    term -> (n_runs, 2, T) in um (dx, dy, dz) or urad (ex, ey, ez); only mapped
    terms appear. A mapped channel missing from the file is an AbbeInputError.
    """
    out: dict[str, np.ndarray] = {}
    for ch, cm in line.map.items():
        if ch not in data.channels:
            col = (data.columns.fields[ch].column if data.columns is not None
                   and ch in data.columns.fields else CHANNEL_COLUMNS[ch])
            raise AbbeInputError(f"the machine file maps channel {ch!r} but the file has no "
                                 f"column {col!r}", file=str(data.file), line=1, field=col)
        out[cm.term] = cm.sign * data.channels[ch]
    return out
