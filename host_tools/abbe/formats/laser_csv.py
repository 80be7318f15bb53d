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

import csv
import difflib
import hashlib
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from abbe.errors import AbbeInputError, parse_finite
from abbe.formats.machine import CHANNELS, LaserLine

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

    @property
    def n_runs(self) -> int:
        return int(self.line_no.shape[0])


def _suggest(name: str, options: list[str]) -> str:
    close = difflib.get_close_matches(name, options, n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def read_laser_csv(path: str | Path, *, channels: tuple[str, ...] = CHANNELS,
                   travel_mm: tuple[float, float] | None = None,
                   span_mm: tuple[float, float] | None = None) -> LaserData:
    """Read and validate a 6D laser CSV.

    ``channels``: instrument channels whose columns are required (the others are
    optional and read if present). ``travel_mm``: the axis travel (mm); a target
    outside it is an error. ``span_mm``: the line's (start, end) coordinate on its
    axis (mm, any order); a target outside it is an error.

    Checks: header (missing, unknown or misspelt columns, duplicates), every cell
    numeric and finite, ``run`` an integer 1..n, ``direction`` ``+``/``-``, each
    pass (run, direction) one contiguous block of rows, targets strictly
    ascending in ``+`` passes and descending in ``-`` passes, no duplicated
    target, every run having both passes over the same targets (equal run
    counts at every target).
    """
    path = Path(path)
    fname = str(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise AbbeInputError(f"cannot read laser CSV: {exc.strerror}", file=fname) from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise AbbeInputError("not UTF-8 text", file=fname) from None

    rows: list[tuple[int, list[str]]] = []
    for no, rec in enumerate(csv.reader(io.StringIO(text)), start=1):
        if not rec or all(not c.strip() for c in rec) or rec[0].lstrip().startswith("#"):
            continue
        rows.append((no, [c.strip() for c in rec]))
    if not rows:
        raise AbbeInputError("empty file: expected a header row", file=fname, line=1)

    hdr_line, header = rows[0]
    known = list(BASE_COLUMNS) + list(CHANNEL_COLUMNS.values()) + list(OPTIONAL_COLUMNS)
    col: dict[str, int] = {}
    for i, name in enumerate(header):
        if name not in known:
            raise AbbeInputError(f"unknown column{_suggest(name, known)}; expected columns "
                                 f"{', '.join(known)}", file=fname, line=hdr_line, field=name)
        if name in col:
            raise AbbeInputError("duplicated column", file=fname, line=hdr_line, field=name)
        col[name] = i
    required = list(BASE_COLUMNS) + [CHANNEL_COLUMNS[c] for c in channels]
    for name in required:
        if name not in col:
            raise AbbeInputError(f"missing column {name!r}{_suggest(name, header)}",
                                 file=fname, line=hdr_line, field=name)
    data_rows = rows[1:]
    if not data_rows:
        raise AbbeInputError("no data rows after the header", file=fname, line=hdr_line)

    value_cols = [c for c in header if c not in ("run", "direction")]
    n = len(data_rows)
    run = np.empty(n, dtype=np.int64)
    dirn = np.empty(n, dtype=np.int64)
    lines = np.empty(n, dtype=np.int64)
    vals = {c: np.empty(n) for c in value_cols}
    for k, (no, rec) in enumerate(data_rows):
        if len(rec) != len(header):
            raise AbbeInputError(f"row has {len(rec)} cells, the header has {len(header)}",
                                 file=fname, line=no)
        lines[k] = no
        r = rec[col["run"]]
        try:
            run[k] = int(r)
        except ValueError:
            raise AbbeInputError(f"expected a run number 1..n, got {r!r}", file=fname, line=no,
                                 field="run") from None
        if run[k] < 1:
            raise AbbeInputError(f"expected a run number >= 1, got {r!r}", file=fname, line=no,
                                 field="run")
        d = rec[col["direction"]]
        if d not in DIRECTIONS:
            raise AbbeInputError(f"expected '+' or '-', got {d!r}", file=fname, line=no,
                                 field="direction")
        dirn[k] = DIRECTIONS.index(d)
        for c in value_cols:
            vals[c][k] = parse_finite(rec[col[c]], file=fname, line=no, field=c)

    # Passes: contiguous blocks of equal (run, direction), in measured order.
    breaks = np.flatnonzero((np.diff(run) != 0) | (np.diff(dirn) != 0)) + 1
    starts = np.concatenate([[0], breaks])
    ends = np.concatenate([breaks, [n]])
    seen: dict[tuple[int, int], int] = {}
    passes: dict[tuple[int, int], np.ndarray] = {}
    tgt = vals["target_mm"]
    for s, e in zip(starts, ends):
        key = (int(run[s]), int(dirn[s]))
        if key in seen:
            raise AbbeInputError(
                f"run {key[0]} direction '{DIRECTIONS[key[1]]}' continues here after other "
                f"rows (first block at line {seen[key]}): each pass must be one contiguous "
                "block of rows in measured order", file=fname, line=int(lines[s]), field="run")
        seen[key] = int(lines[s])
        t = tgt[s:e]
        step = np.diff(t) if key[1] == 0 else -np.diff(t)
        for i in range(step.size):
            if abs(step[i]) <= TARGET_TOL_MM:
                raise AbbeInputError(f"duplicated target {t[i + 1]} mm in run {key[0]} "
                                     f"direction '{DIRECTIONS[key[1]]}'", file=fname,
                                     line=int(lines[s + i + 1]), field="target_mm")
            if step[i] < 0:
                order = "ascending" if key[1] == 0 else "descending"
                raise AbbeInputError(f"targets of a '{DIRECTIONS[key[1]]}' pass must be {order}: "
                                     f"{t[i + 1]} mm follows {t[i]} mm", file=fname,
                                     line=int(lines[s + i + 1]), field="target_mm")
        passes[key] = np.arange(s, e) if key[1] == 0 else np.arange(e - 1, s - 1, -1)

    runs = sorted({r for r, _ in passes})
    for want, r in enumerate(runs, start=1):
        if r != want:
            raise AbbeInputError(f"runs must be numbered 1..n without gaps: run {want} is missing",
                                 file=fname, line=seen[(r, 0)] if (r, 0) in seen else seen[(r, 1)],
                                 field="run")
    first = passes.get((1, 0))
    if first is None:
        raise AbbeInputError("run 1 has no '+' pass", file=fname, line=seen[(1, 1)],
                             field="direction")
    targets = tgt[first]
    T = targets.size
    for r in runs:
        for d in (0, 1):
            if (r, d) not in passes:
                other = seen[(r, 1 - d)]
                raise AbbeInputError(f"run {r} has no '{DIRECTIONS[d]}' pass: every run needs "
                                     "both directions (equal run counts at every target)",
                                     file=fname, line=other, field="direction")
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
                    file=fname, line=int(lines[row]), field="target_mm")

    order = np.array([[passes[(r, d)] for d in (0, 1)] for r in runs])  # (n_runs, 2, T)
    for lim, what in ((travel_mm, "the axis travel"), (span_mm, "the line's start..end")):
        if lim is None:
            continue
        lo, hi = min(lim), max(lim)
        bad = np.flatnonzero((tgt < lo - TARGET_TOL_MM) | (tgt > hi + TARGET_TOL_MM))
        if bad.size:
            k = int(bad[0])
            raise AbbeInputError(f"target {tgt[k]} mm is outside {what} [{lo}, {hi}] mm",
                                 file=fname, line=int(lines[k]), field="target_mm")

    chans = {ch: vals[c][order] for ch, c in CHANNEL_COLUMNS.items() if c in vals}
    return LaserData(
        file=path, targets_mm=targets.copy(), channels=chans,
        time_s=vals["time_s"][order] if "time_s" in vals else None,
        temp_c=vals["temp_c"][order] if "temp_c" in vals else None,
        line_no=lines[order], sha256=hashlib.sha256(raw).hexdigest())


def to_terms(data: LaserData, line: LaserLine) -> dict[str, np.ndarray]:
    """Step 1: instrument channels -> model terms of the line's axis, per the map.

    The map says reading = sign * term, so term = sign * reading. Returns
    term -> (n_runs, 2, T) in um (dx, dy, dz) or urad (ex, ey, ez); only mapped
    terms appear. A mapped channel missing from the file is an AbbeInputError.
    """
    out: dict[str, np.ndarray] = {}
    for ch, cm in line.map.items():
        if ch not in data.channels:
            raise AbbeInputError(f"the machine file maps channel {ch!r} but the file has no "
                                 f"column {CHANNEL_COLUMNS[ch]!r}", file=str(data.file), line=1,
                                 field=CHANNEL_COLUMNS[ch])
        out[cm.term] = cm.sign * data.channels[ch]
    return out
