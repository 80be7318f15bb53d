"""Reader of Renishaw ballbar files as Ballbar 5 / Ballbar 20 save them (``.b5r``, XML).

Renishaw does not publish the format. abbe reads it as three real files published in
RynShuster/WatchTower (testData/BallBar: Ballbar 20 and Ballbar 5 files) show it, and the
element names of the public parsers (docs/formats.md, "Renishaw ballbar .b5r", B1..B9,
with what was checked against Renishaw's own results in those files):

* radius ``TEST_RADIUS`` or ``NOMINAL_LENGTH`` (mm without ``DT``), feed
  ``PROGRAMMED_FEEDRATE`` (mm/min); the earlier assumed spellings ``RADIUS`` and
  ``FEEDRATE`` (with ``DT``) are read too, and two spellings present must agree;
* the runs ``RUN_RESULTS/BALLBAR_RUN`` with ``RUN_DIRECTION`` (CCW then CW), the run's
  ``SAMPLE_RATE`` (Hz), ``START_INDEX`` / ``END_INDEX`` (the data arc's first and last
  sample) and ``READINGS`` (mm, bar length minus the nominal length); the data arc from
  ``START_ANGLE`` over (``END_ANGLE`` - ``START_ANGLE``) mod 360 deg (360 when equal),
  angle from the A axis toward the B axis, the CW run over the same arc backwards; the
  trace's data arc is [START_ANGLE, START_ANGLE + 360) (:attr:`BallbarTrace.data_from_deg`);
* or, in the layout abbe assumed before real files were public, ``SAMPLE_RATE`` /
  ``OVERRUN_ARC`` with unit types and ``RUN DIRECTION=`` with ``DATA``;
* planes (A, B) = (X, Y), (Z, X), (Y, Z); a plane written the other way round is refused.

Elements abbe does not use are ignored; in those it uses, anything it cannot
interpret (a unit type, a direction, a plane, a count) is refused with what it found.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.parsers import expat

import numpy as np

from abbe.errors import AbbeInputError, parse_int, parse_number, parse_number_column
from abbe.formats.ballbar_csv import BallbarTrace, validate_trace
from abbe.formats.limits import B5R_MAX_BYTES, B5R_MAX_SAMPLES, MAX_NESTING
from abbe.formats.text import read_text

#: The unit types (``DT``) of the public parsers, with their unit; abbe converts the
#: ones it uses, and refuses any other.
UNIT_TYPES: dict[str, str] = {
    "UT_LENGTH_MM": "mm", "UT_LENGTH_UM": "um", "UT_LENGTH_M": "m", "UT_FEEDRATE": "mm/min",
    "UT_SQUARENESS": "um/m", "UT_SERVO_MISMATCH": "ms", "UT_ANGLE": "deg", "UT_RANKING": "",
    "UT_PERCENT": "%", "UT_SCALE_ERROR": "ppm", "UT_SPEED": "mm/s", "UT_FREQUENCY": "Hz"}
#: abbe's planes as (A axis, B axis): theta runs from A toward B (docs/formats.md).
PLANES = {("X", "Y"): "XY", ("Z", "X"): "ZX", ("Y", "Z"): "YZ"}
_META = ("OPERATOR", "DATE_STARTED", "DATE_COMPLETED", "SERIAL_NUMBER", "LAST_CALIBRATED",
         "PART_NUMBER")
#: White space in XML (XML 1.0, production S): nothing else is stripped from a value.
_XML_WS = " \t\r\n"
_SAFE = re.compile(r"<!(DOCTYPE|ENTITY)", re.IGNORECASE)


@dataclass
class _El:
    tag: str
    attrs: dict[str, str]
    line: int
    text: list[str] = field(default_factory=list)
    children: list["_El"] = field(default_factory=list)

    def iter(self):
        yield self
        for c in self.children:
            yield from c.iter()


@dataclass
class B5rTest:
    """A ballbar test from a ``.b5r`` file: the trace (abbe's convention) and its set-up.

    plane: ``XY`` / ``ZX`` / ``YZ``; radius_mm; feed_mm_min; sample_rate_hz;
    overrun_deg: each feed arc; metadata: the test's names and dates (strings);
    features: Renishaw's own results, NAME -> (value, unit).
    """

    trace: BallbarTrace
    plane: str
    radius_mm: float
    feed_mm_min: float
    sample_rate_hz: float
    overrun_deg: float
    metadata: dict[str, str]
    features: dict[str, tuple[float, str]]
    lines: dict[str, int]
    #: How the file spells the elements abbe reads under two names (RADIUS -> TEST_RADIUS).
    names: dict[str, str] = field(default_factory=dict)


def _parse_xml(text: str, fname: str) -> _El:
    m = _SAFE.search(text)
    if m:
        line = text.count("\n", 0, m.start()) + 1
        raise AbbeInputError(f"<!{m.group(1)}> in a .b5r file: document types and entities are "
                             "not read (they could expand without bound)", file=fname, line=line)
    p = expat.ParserCreate()
    stack: list[_El] = []
    root: list[_El] = []

    def start(tag: str, attrs: dict[str, str]) -> None:
        if len(stack) >= MAX_NESTING:
            raise AbbeInputError(f"XML nested deeper than {MAX_NESTING} levels", file=fname,
                                 line=p.CurrentLineNumber, field=tag)
        el = _El(tag, dict(attrs), p.CurrentLineNumber)
        if stack:
            stack[-1].children.append(el)
        else:
            root.append(el)
        stack.append(el)

    def end(tag: str) -> None:
        stack.pop()

    def data(s: str) -> None:
        if stack:
            stack[-1].text.append(s)

    p.StartElementHandler = start
    p.EndElementHandler = end
    p.CharacterDataHandler = data
    try:
        p.Parse(text, True)
    except expat.ExpatError as exc:
        raise AbbeInputError(f"not well-formed XML: {expat.ErrorString(exc.code)}", file=fname,
                             line=exc.lineno) from None
    return root[0]


def _features(root: _El) -> list[tuple[_El, str]]:
    """Every FEATURE with where it stands: Renishaw's diagnostics (and a FEATURE outside
    any ANALYSIS or run) by its NAME; a run's results as ``CCW/NAME``; another
    analysis's as ``ANALYSIS NAME[ version]/NAME`` (the real files repeat names there)."""
    out: list[tuple[_El, str]] = []

    def walk(el: _El, where: str) -> None:
        for c in el.children:
            if c.tag == "FEATURE":
                out.append((c, where))
            elif c.tag == "ANALYSIS":
                name = c.attrs.get("NAME", "")
                ver = c.attrs.get("version", "")
                walk(c, "" if name == "RENISHAW_DIAGNOSTICS" else
                     f"{name}{' ' + ver if ver else ''}/")
            elif c.tag == "BALLBAR_RUN":
                d = [x for x in c.children if x.tag == "RUN_DIRECTION"]
                walk(c, (_text(d[0]).upper() if d else "RUN") + "/")
            else:
                walk(c, where)
    walk(root, "")
    return out


def _text(el: _El) -> str:
    """An element's text without the XML white space around it (space, tab, CR, LF) --
    only that: ``str.strip()`` would also drop Unicode spaces (a no-break space after a
    number), which are not white space in XML and make the cell something else."""
    return "".join(el.text).strip(_XML_WS)


def _child(run: _El, tag: str, fname: str) -> _El:
    got = [c for c in run.children if c.tag == tag]
    if len(got) != 1:
        raise AbbeInputError(f"a <{run.tag}> holds one <{tag}>, this one {len(got)}", file=fname,
                             line=got[1].line if len(got) > 1 else run.line, field=tag)
    return got[0]


def _real_runs(els: dict[str, list[_El]], root: _El, fname: str, radius: float, feed: float,
               lines: dict[str, int]) -> tuple[BallbarTrace, float, float]:
    """The runs as Renishaw's Ballbar 5 / 20 write them (real files, docs/formats.md B3r):
    ``RUN_RESULTS/BALLBAR_RUN`` with ``RUN_DIRECTION``, ``SAMPLE_RATE`` (Hz),
    ``START_INDEX`` / ``END_INDEX`` (first and last sample of the data arc) and
    ``READINGS`` (mm: bar length minus the nominal length), the data arc from
    ``START_ANGLE`` over (``END_ANGLE`` - ``START_ANGLE``) mod 360 (360 when equal) deg
    from the A axis toward the B axis, the CW run over the same arc backwards."""
    runs = els["BALLBAR_RUN"]
    dirs = []
    for r in runs:
        dirs.append(_text(_child(r, "RUN_DIRECTION", fname)).upper())
    if dirs != ["CCW", "CW"]:
        raise AbbeInputError(f"runs {dirs}: expected one BALLBAR_RUN with RUN_DIRECTION CCW "
                             "then one with CW", file=fname, line=runs[0].line,
                             field="RUN_DIRECTION")

    for r in runs:
        if not any(c.tag == "READINGS" for c in r.children):
            raise AbbeInputError("this BALLBAR_RUN holds no <READINGS>: the file carries "
                                 "Renishaw's results only, not the samples abbe evaluates",
                                 file=fname, line=r.line, field="READINGS")

    def angle(tag: str) -> float:
        got = els.get(tag, [])
        if len(got) != 1:
            raise AbbeInputError(f"expected one <{tag}>, found {len(got)}", file=fname,
                                 line=got[1].line if len(got) > 1 else root.line, field=tag)
        el = got[0]
        lines[tag] = el.line
        return parse_number(_text(el), file=fname, line=el.line, field=tag,
                            lo=-360.0, hi=720.0, unit="deg")
    start, end = angle("START_ANGLE"), angle("END_ANGLE")
    arc = (end - start) % 360.0
    if arc < 1e-9:
        arc = 360.0
    over = angle("OVERSHOOT_ANGLE") if "OVERSHOOT_ANGLE" in els else 0.0
    d_all, a_all, r_all, t_all, l_all = [], [], [], [], []
    t0 = 0.0
    fs_first = 0.0
    for run, d in zip(runs, ("ccw", "cw")):
        de = _child(run, "READINGS", fname)
        sr = _child(run, "SAMPLE_RATE", fname)
        fs = parse_number(_text(sr), file=fname, line=sr.line, field="SAMPLE_RATE",
                          lo=1.0, hi=1e5, unit="Hz")
        fs_first = fs_first or fs
        cells = [c for c in re.split(r"[ \t\r\n]+", "".join(de.text)) if c]
        if len(cells) > B5R_MAX_SAMPLES:
            raise AbbeInputError(f"{len(cells)} samples: the limit is {B5R_MAX_SAMPLES}",
                                 file=fname, line=de.line, field="READINGS")
        idx = []
        for tag in ("START_INDEX", "END_INDEX"):
            el = _child(run, tag, fname)
            idx.append(parse_int(_text(el), file=fname, line=el.line,
                                 field=tag, lo=0, hi=max(len(cells) - 1, 0)))
        si, ei = idx
        if ei - si < 8:
            raise AbbeInputError(f"END_INDEX {ei} must be at least 8 samples after START_INDEX "
                                 f"{si}", file=fname, line=_child(run, "END_INDEX", fname).line,
                                 field="END_INDEX")
        step = arc / (ei - si)              # deg per sample on the data arc (the actual feed)
        implied = math.radians(step * fs) * radius * 60.0
        if not 0.8 <= implied / feed <= 1.25:
            raise AbbeInputError(
                f"{ei - si} samples at {fs:g} Hz over the {arc:g} deg data arc is "
                f"{implied:.1f} mm/min on R = {radius:g} mm, the programmed feed is {feed:g}: "
                "sample rate, indices or feed are not consistent", file=fname, line=sr.line,
                field="SAMPLE_RATE")
        vals = parse_number_column(cells, np.full(len(cells), de.line), file=fname,
                                   field="READINGS", lo=-100.0, hi=100.0) * 1e3
        i = np.arange(vals.size, dtype=np.float64)
        ang = start + (i - si) * step if d == "ccw" else start + arc - (i - si) * step
        if d == "ccw":
            # Angles are defined modulo 360: the turn that puts the start of the data arc
            # into [0, 360); the trace's data arc is [START_ANGLE, START_ANGLE + 360).
            shift = -360.0 * math.floor(start / 360.0)
        ang = ang + shift
        t = i / fs
        # Feed-arc samples beyond [-360, 720) deg (more than a turn from abbe's data arc,
        # e.g. the last of a 180 deg overshoot after a data arc from 180 deg) are never
        # evaluated and outside a trace's angle range: they are left out.
        keep = (ang >= -360.0) & (ang < 720.0)
        d_all.append(np.full(int(keep.sum()), d))
        a_all.append(ang[keep])
        r_all.append(vals[keep])
        t_all.append(t0 + t[keep])
        l_all.append(np.full(int(keep.sum()), de.line))
        t0 += t[-1] + 1.0 / fs
    tr = BallbarTrace(direction=np.concatenate(d_all), angle_deg=np.concatenate(a_all),
                      radial_um=np.concatenate(r_all), time_s=np.concatenate(t_all), file=fname,
                      line_no=np.concatenate(l_all), data_from_deg=start + shift)
    return tr, fs_first, over


def _assumed_runs(els, root, fname, radius, feed, deg_per_s, one, num, dt
                  ) -> tuple[BallbarTrace, float, float]:
    """The runs in the layout abbe assumed before real files were public (B3a/B4a):
    ``SAMPLE_RATE`` and ``OVERRUN_ARC`` with unit types, ``RUN DIRECTION=`` with ``DATA``."""
    fs = num(one("SAMPLE_RATE"), {"UT_FREQUENCY": 1.0}, 1.0, 1e5, "Hz")
    over = num(one("OVERRUN_ARC"), {"UT_ANGLE": 1.0}, 0.0, 360.0, "deg")
    runs = els.get("RUN", [])
    dirs = [r.attrs.get("DIRECTION", "").strip(_XML_WS).upper() for r in runs]
    if dirs != ["CCW", "CW"]:
        at = runs[0] if runs else root
        raise AbbeInputError(f"runs {dirs}: expected one RUN DIRECTION=\"CCW\" then one "
                             "RUN DIRECTION=\"CW\" (or Ballbar 20's RUN_RESULTS/BALLBAR_RUN)",
                             file=fname, line=at.line, field="RUN")
    total = 360.0 + 2.0 * over
    d_all, a_all, r_all, t_all, l_all = [], [], [], [], []
    t0 = 0.0
    for run, d in zip(runs, ("ccw", "cw")):
        data = [c for c in run.children if c.tag == "DATA"]
        if len(data) != 1:
            raise AbbeInputError(f"a RUN holds one <DATA> element, this one {len(data)}",
                                 file=fname, line=run.line, field="DATA")
        de = data[0]
        scale = dt(de, {"UT_LENGTH_UM": 1.0, "UT_LENGTH_MM": 1e3})
        cells = [c for c in re.split(r"[ \t\r\n]+", "".join(de.text)) if c]
        if len(cells) > B5R_MAX_SAMPLES:
            raise AbbeInputError(f"{len(cells)} samples: the limit is {B5R_MAX_SAMPLES}",
                                 file=fname, line=de.line, field="DATA")
        n_need = int(math.floor(total / deg_per_s * fs + 1e-6)) + 1
        if len(cells) != n_need:
            raise AbbeInputError(f"{len(cells)} samples, but {total:g} deg at {feed:g} mm/min "
                                 f"on R = {radius:g} mm sampled at {fs:g} Hz needs {n_need}",
                                 file=fname, line=de.line, field="DATA")
        vals = parse_number_column(cells, np.full(len(cells), de.line), file=fname,
                                   field="DATA", lo=-1e5 / scale, hi=1e5 / scale) * scale
        t = np.arange(vals.size) / fs
        ang = -over + deg_per_s * t
        if d == "cw":
            ang = 360.0 + over - deg_per_s * t
        d_all.append(np.full(vals.size, d))
        a_all.append(ang)
        r_all.append(vals)
        t_all.append(t0 + t)
        l_all.append(np.full(vals.size, de.line))
        t0 += t[-1] + 1.0 / fs
    tr = BallbarTrace(direction=np.concatenate(d_all), angle_deg=np.concatenate(a_all),
                      radial_um=np.concatenate(r_all), time_s=np.concatenate(t_all), file=fname,
                      line_no=np.concatenate(l_all))
    return tr, fs, over


def read_b5r(path: str | Path) -> B5rTest:
    """Read and validate a ``.b5r`` ballbar file into a :class:`B5rTest` (see module doc).

    Refused (file, line, element): XML that is not well-formed or declares a document
    type or entities; a missing or duplicated element abbe uses; a unit type abbe cannot
    interpret; a plane other than XY / ZX / YZ in abbe's axis order; runs other than one
    CCW then one CW; a number that is not finite or outside its range; a run too short
    for its feed arcs and data arc; then every check of a ballbar trace.
    """
    fname = str(path)
    tf = read_text(path, what=".b5r file", max_bytes=B5R_MAX_BYTES)
    root = _parse_xml(tf.text, fname)
    els: dict[str, list[_El]] = {}
    for el in root.iter():
        els.setdefault(el.tag, []).append(el)
    lines: dict[str, int] = {}

    def one(tag: str) -> _El:
        got = els.get(tag, [])
        if not got:
            raise AbbeInputError(f"missing element <{tag}>", file=fname, line=root.line, field=tag)
        if len(got) > 1:
            raise AbbeInputError(f"<{tag}> appears {len(got)} times (first at line "
                                 f"{got[0].line})", file=fname, line=got[1].line, field=tag)
        lines[tag] = got[0].line
        return got[0]

    def dt(el: _El, allowed: dict[str, float]) -> float:
        u = el.attrs.get("DT")
        if u is None:
            raise AbbeInputError(f"<{el.tag}> has no unit type DT; expected one of "
                                 f"{', '.join(allowed)}", file=fname, line=el.line, field=el.tag)
        if u not in allowed:
            known = "" if u in UNIT_TYPES else " (a unit type abbe does not know)"
            raise AbbeInputError(f"unit type {u!r}{known}: expected one of {', '.join(allowed)}",
                                 file=fname, line=el.line, field=el.tag)
        return allowed[u]

    def num(el: _El, allowed: dict[str, float], lo: float, hi: float, unit: str) -> float:
        scale = dt(el, allowed)
        v = parse_number(_text(el), file=fname, line=el.line, field=el.tag,
                         lo=lo / scale, hi=hi / scale)
        return v * scale

    plane_el = one("PLANE")
    a_el, b_el = one("A_AXIS_NAME"), one("B_AXIS_NAME")
    ab = (_text(a_el).upper(), _text(b_el).upper())
    tp = plane_el.attrs.get("TEST_PLANE", "").strip(_XML_WS).upper()
    if ab not in PLANES:
        raise AbbeInputError(f"plane with A axis {ab[0]!r} and B axis {ab[1]!r}: abbe's planes "
                             "are (A, B) = (X, Y), (Z, X), (Y, Z) with the angle from A toward "
                             "B; this order is not interpreted", file=fname, line=a_el.line,
                             field="A_AXIS_NAME")
    plane = PLANES[ab]
    if tp != plane:
        raise AbbeInputError(f"TEST_PLANE {tp!r} does not match the axes A = {ab[0]}, "
                             f"B = {ab[1]} (plane {plane})", file=fname, line=plane_el.line,
                             field="TEST_PLANE")
    def spelled(tags: tuple[str, ...], allowed: dict[str, float], lo: float, hi: float,
                unit: str) -> float:
        """One value under either spelling (the real files' or abbe's earlier one): an
        element without DT is in ``unit``; two spellings must agree."""
        got = [t for t in tags if t in els]
        if not got:
            raise AbbeInputError(f"missing element <{tags[0]}> (or <{'>, <'.join(tags[1:])}>)",
                                 file=fname, line=root.line, field=tags[0])
        vals = []
        for t in got:
            el = one(t)
            if "DT" in el.attrs:
                vals.append(num(el, allowed, lo, hi, unit))
            else:
                vals.append(parse_number(_text(el), file=fname, line=el.line,
                                         field=t, lo=lo, hi=hi, unit=unit))
        for t, v in zip(got[1:], vals[1:]):
            if abs(v - vals[0]) > 1e-9 * max(1.0, abs(vals[0])):
                raise AbbeInputError(f"<{t}> {v:g} {unit} and <{got[0]}> {vals[0]:g} {unit} "
                                     "disagree", file=fname, line=lines[t], field=t)
        lines[tags[0]] = lines[got[0]]
        names[tags[0]] = got[0]
        return vals[0]

    names: dict[str, str] = {}
    length_mm = {"UT_LENGTH_MM": 1.0, "UT_LENGTH_M": 1e3}
    radius = spelled(("RADIUS", "TEST_RADIUS", "NOMINAL_LENGTH"), length_mm, 1.0, 2000.0, "mm")
    feed = spelled(("FEEDRATE", "PROGRAMMED_FEEDRATE"), {"UT_FEEDRATE": 1.0}, 1.0, 1e5, "mm/min")
    deg_per_s = math.degrees(feed / 60.0 / radius)
    if "BALLBAR_RUN" in els:
        tr, fs, over = _real_runs(els, root, fname, radius, feed, lines)
    else:
        tr, fs, over = _assumed_runs(els, root, fname, radius, feed, deg_per_s, one, num, dt)
    if "BALLBAR_RUN" in els:
        validate_trace(tr, {"direction": "RUN_DIRECTION", "angle": "READINGS",
                            "radial": "READINGS", "time": "READINGS"})
    else:
        validate_trace(tr, {"direction": "RUN", "angle": "DATA", "radial": "DATA", "time": "DATA"})

    meta: dict[str, str] = {}
    for tag in _META:
        if tag in els:
            meta[tag.lower()] = " ".join("".join(els[tag][0].text).split())
    for tag in ("TEST_SPEC", "MACHINE_TESTED"):
        if tag in els and "NAME" in els[tag][0].attrs:
            meta[tag.lower()] = els[tag][0].attrs["NAME"]
    for sw in els.get("SOFTWARE", [])[:1]:   # Ballbar 5 / 20: EQUIPMENT/SOFTWARE TITLE, VERSION
        parts = [" ".join("".join(c.text).split()) for c in sw.children
                 if c.tag in ("TITLE", "VERSION")]
        meta["software"] = " ".join(p for p in parts if p)
    feats: dict[str, tuple[float, str]] = {}
    for fe, where in _features(root):
        name = fe.attrs.get("NAME", "")
        u = fe.attrs.get("DT", "")
        if u not in UNIT_TYPES:
            raise AbbeInputError(f"unit type {u!r} of FEATURE {name!r} is not one abbe knows: "
                                 f"{', '.join(UNIT_TYPES)}", file=fname, line=fe.line,
                                 field="FEATURE")
        value = (parse_number(_text(fe), file=fname, line=fe.line,
                              field=f"FEATURE {name}"), UNIT_TYPES[u])
        feats.setdefault(f"{where}{name}", value)
    return B5rTest(trace=tr, plane=plane, radius_mm=radius, feed_mm_min=feed, sample_rate_hz=fs,
                   overrun_deg=over, metadata=meta, features=feats, lines=lines, names=names)


def check_against(test: B5rTest, bt: Any, machine_file: str) -> None:
    """The machine file's ballbar section must describe the test the file holds."""
    for what, mine, theirs, tag in (("plane", bt.plane, test.plane, "PLANE"),
                                    ("radius_mm", bt.radius_mm, test.radius_mm, "RADIUS"),
                                    ("feed_mm_min", bt.feed_mm_min, test.feed_mm_min, "FEEDRATE")):
        same = mine == theirs if isinstance(mine, str) else abs(mine - theirs) <= 1e-6 * abs(theirs)
        if not same:
            spelt = test.names.get(tag, tag)
            raise AbbeInputError(f"{machine_file} says ballbar.{bt.name}.{what} = {mine!r}, the "
                                 f"file's <{spelt}> says {theirs!r}", file=test.trace.file,
                                 line=test.lines.get(tag), field=spelt)
