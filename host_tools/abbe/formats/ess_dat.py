"""Reader of the ISO 230-2 ``.dat`` format of the ESS ecmc tools (key=value lines).

Format (docs/formats.md, "ISO 230-2 .dat"): lines ``KEY=value``; ``#`` starts a
comment line; blank lines are ignored. Keys:

* ``TGT_DATA[i]``: target i (i = 1..POSITIONS), in UNIT
* ``REF_DATA_FWD[i,c]`` / ``REF_DATA_BWD[i,c]``: reference reading at target i in
  cycle (run) c = 1..CYCLES, forward (increasing) / backward approach, in UNIT
* ``CYCLES`` (default 5), ``POSITIONS`` (default 8), ``UNIT`` (``mm`` default, or ``um``)
* informational: ``TEST_DATA``, ``DEC``, ``REF_PV``, ``TEST_PV``, ``TGT_SET_PV``

Deviation = reference reading - target, converted to um. Any other key, a
duplicated key, a missing or out-of-range index, or a non-numeric/non-finite value
raises AbbeInputError naming file, line and key.
"""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path

import numpy as np

from abbe.errors import AbbeInputError, parse_int, parse_number
from abbe.formats.deviations import PositioningData
from abbe.formats.limits import DAT_MAX_BYTES, DAT_MAX_CYCLES, DAT_MAX_POSITIONS
from abbe.formats.text import read_text

_KEY = re.compile(r"^([A-Z_][A-Z0-9_]*)(?:\[\s*([0-9]{1,9})\s*(?:,\s*([0-9]{1,9})\s*)?\])?$")
#: Largest |target| or |reading| (mm) accepted.
MAX_POSITION_MM = 1e5
_INFO = {"TEST_DATA", "DEC", "REF_PV", "TEST_PV", "TGT_SET_PV"}
_UNITS_TO_UM = {"mm": 1000.0, "um": 1.0}


def looks_like_dat(path: Path) -> bool:
    """True if the first non-blank, non-comment line is ``KEY=...`` with an upper-case key."""
    try:  # never block on a FIFO nor read a device: the reader refuses those itself
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except (OSError, ValueError):
        return False
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return False
        head = os.read(fd, 65536)
    except OSError:
        return False
    finally:
        os.close(fd)
    text = head.removeprefix(b"\xef\xbb\xbf").decode("utf-8", errors="replace")
    for raw in text.replace("\r", "\n").split("\n"):
        s = raw.strip()
        if not s or s.startswith("#"):
            continue
        return bool(re.match(r"^[A-Z_][A-Z0-9_]*(\[[^\]]*\])?\s*=", s))
    return False


def read_dat(path: str | Path) -> PositioningData:
    """Read an ecmc ISO 230-2 ``.dat`` file into :class:`PositioningData` (um).

    Targets are returned ascending (a descending TGT_DATA list is reordered);
    targets must be strictly monotonic.
    """
    path = Path(path)
    fname = str(path)
    tf = read_text(path, what=".dat file", max_bytes=DAT_MAX_BYTES)

    scalars: dict[str, tuple[str, int]] = {}
    tgt: dict[int, tuple[str, int]] = {}
    ref: dict[str, dict[tuple[int, int], tuple[str, int]]] = {"FWD": {}, "BWD": {}}
    for no, rawline in tf.lines():
        s = rawline.strip(" \t")
        if not s or s.startswith("#"):
            continue
        if "=" not in s:
            raise AbbeInputError("expected KEY=value", file=fname, line=no)
        key, value = (p.strip(" \t") for p in s.split("=", 1))
        m = _KEY.match(key)
        if not m:
            raise AbbeInputError("malformed key: expected NAME, NAME[i] or NAME[i,c]",
                                 file=fname, line=no, field=key)
        name, i, c = m.group(1), m.group(2), m.group(3)

        def num() -> str:
            return value

        if name == "TGT_DATA" and i is not None and c is None:
            if int(i) in tgt:
                raise AbbeInputError(f"duplicated key (first at line {tgt[int(i)][1]})",
                                     file=fname, line=no, field=key)
            tgt[int(i)] = (num(), no)
        elif name in ("REF_DATA_FWD", "REF_DATA_BWD") and i is not None and c is not None:
            d = ref[name[-3:]]
            k = (int(i), int(c))
            if k in d:
                raise AbbeInputError(f"duplicated key (first at line {d[k][1]})", file=fname,
                                     line=no, field=key)
            d[k] = (num(), no)
        elif i is None and (name in _INFO or name in ("UNIT", "CYCLES", "POSITIONS")):
            if name in scalars:
                raise AbbeInputError(f"duplicated key (first at line {scalars[name][1]})",
                                     file=fname, line=no, field=key)
            scalars[name] = (value, no)
        else:
            raise AbbeInputError("unknown key; expected TGT_DATA[i], REF_DATA_FWD[i,c], "
                                 "REF_DATA_BWD[i,c], UNIT, CYCLES, POSITIONS, DEC, TEST_DATA, "
                                 "REF_PV, TEST_PV, TGT_SET_PV", file=fname, line=no, field=key)

    def count(name: str, default: int) -> int:
        if name not in scalars:
            return default
        v, no = scalars[name]
        hi = DAT_MAX_CYCLES if name == "CYCLES" else DAT_MAX_POSITIONS
        return parse_int(v, file=fname, line=no, field=name, lo=1, hi=hi)

    if "DEC" in scalars:  # informational, but a number: garbage there is refused too
        parse_int(scalars["DEC"][0], file=fname, line=scalars["DEC"][1], field="DEC", lo=0, hi=30)
    cycles = count("CYCLES", 5)
    positions = count("POSITIONS", 8)
    unit, unit_line = scalars.get("UNIT", ("mm", None))
    if unit not in _UNITS_TO_UM:
        raise AbbeInputError(f"unsupported unit {unit!r}; expected mm or um", file=fname,
                             line=unit_line, field="UNIT")
    scale = _UNITS_TO_UM[unit]
    if cycles < 2:
        raise AbbeInputError("ISO 230-2 needs at least 2 cycles", file=fname,
                             line=scalars["CYCLES"][1], field="CYCLES")

    for i, (_, no) in tgt.items():
        if i < 1 or i > positions:
            raise AbbeInputError(f"index {i} outside 1..POSITIONS ({positions})", file=fname,
                                 line=no, field=f"TGT_DATA[{i}]")
    for i in range(1, positions + 1):  # stops at the first gap: <= len(tgt) + 1 steps
        if i not in tgt:
            raise AbbeInputError(f"missing target TGT_DATA[{i}] (POSITIONS = {positions})",
                                 file=fname, field=f"TGT_DATA[{i}]")
    for d, vals in ref.items():
        for (i, c), (_, no) in vals.items():
            if not (1 <= i <= positions and 1 <= c <= cycles):
                raise AbbeInputError(f"index outside POSITIONS ({positions}) x CYCLES ({cycles})",
                                     file=fname, line=no, field=f"REF_DATA_{d}[{i},{c}]")
        if len(vals) < positions * cycles:  # then a gap exists within len(vals) + 1 steps
            for i in range(1, positions + 1):
                for c in range(1, cycles + 1):
                    if (i, c) not in vals:
                        raise AbbeInputError(
                            "missing reading (unequal run counts: every target needs CYCLES "
                            "readings per direction)", file=fname, field=f"REF_DATA_{d}[{i},{c}]")

    lim = MAX_POSITION_MM * 1000.0 / scale  # in the file's unit

    def value(text: str, no: int, key: str) -> float:
        return parse_number(text, file=fname, line=no, field=key, lo=-lim, hi=lim, unit=unit)

    targets = np.array([value(*tgt[i], f"TGT_DATA[{i}]") for i in range(1, positions + 1)])
    steps = np.diff(targets)
    order = np.arange(positions)
    if positions > 1 and np.all(steps < 0):
        order = order[::-1]
    elif positions > 1 and not np.all(steps > 0):
        k = int(np.flatnonzero(steps <= 0)[0]) + 2
        what = "duplicated" if steps[k - 2] == 0 else "unsorted"
        raise AbbeInputError(f"{what} target {targets[k - 1]}: targets must be strictly "
                             "monotonic", file=fname, line=tgt[k][1], field=f"TGT_DATA[{k}]")

    def grid(d: str) -> np.ndarray:
        v = np.array([[value(*ref[d][(i, c)], f"REF_DATA_{d}[{i},{c}]")
                       for i in range(1, positions + 1)] for c in range(1, cycles + 1)])
        return ((v - targets[None, :]) * scale)[:, order]

    return PositioningData(source=fname, targets_mm=targets[order] * scale / 1000.0,
                           up_um=grid("FWD"), down_um=grid("BWD"),
                           sha256=tf.sha256)
