"""Reader of the Renishaw laser ``.rtl`` text export (LaserXL / CARTO "rtl" files).

The format is not published by Renishaw; this reader follows the public parsers
(docs/formats.md, "Renishaw laser .rtl", lists each one and every assumption a real
file must confirm). A file is a sequence of sections, each opened by a line
``NAME::``, in this order: ``HEADER::``, ``TARGET DATA::``, ``USER-TEXT::``
(optional), ``RUNS::``, ``DEVIATIONS::``, ``ENVIRONMENT::`` (optional), ``EOF::``;
sections abbe does not use (``EQUIPMENT::`` in Renishaw's rotary exports, any other
``NAME::``) are skipped and reported (:attr:`RtlFile.sections_not_used`). Inside a section, ``Key : value`` lines (any spaces around the colon); the targets
(mm) as whitespace-separated numbers after ``Targets :``; the deviations as
``run target value`` rows after ``Run Target Data:``.

How the file is read (the assumptions, docs/formats.md):

* ``HEADER`` ``Owner`` names the measurement type: ``Linear`` (deviations um),
  ``Angular`` (um/m = urad) or ``Straightness`` (um); anything else is refused.
* ``RUNS`` ``Run-count`` counts passes: a bidirectional test of n runs has 2n.
  Odd passes visit the targets in the order of the target list, even passes in the
  reverse order (their rows list the target indices descending); so odd passes
  are ``+`` approaches when the list ascends, ``-`` when it descends.
* ``TARGET DATA`` ``Flags`` are four integers; the second is 0 for a bidirectional
  test (1: unidirectional, refused: ISO 230-2 needs both directions).
* ``ENVIRONMENT``: start and end values (and a flag) of air temperature (deg C),
  pressure (kPa), humidity (%), material temperatures 1..3 (deg C; -10 is an
  unconnected sensor), the environment factor, the expansion coefficient (ppm/K).

* The text is in the Windows code page Renishaw's software writes (the public Java
  parser reads WINDOWS-1250): UTF-8 when the bytes are valid UTF-8, else the declared
  code page (default cp1250); the numbers and keys are ASCII in every one of them.
  :attr:`RtlFile.encoding` says which was used.

Every problem raises :class:`abbe.errors.AbbeInputError` naming the file, the line
and the field (the key or section as the file spells it).
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from abbe.errors import AbbeInputError, parse_int, parse_number
from abbe.formats.limits import RTL_MAX_BYTES, RTL_MAX_PASSES, RTL_MAX_TARGETS
from abbe.formats.text import TextFile, read_bytes

#: Sections in the order a file holds them; (name, required).
SECTIONS: tuple[tuple[str, bool], ...] = (
    ("HEADER", True), ("TARGET DATA", True), ("USER-TEXT", False), ("RUNS", True),
    ("DEVIATIONS", True), ("ENVIRONMENT", False), ("EOF", True))
#: Measurement type (HEADER Owner) -> (abbe channel kind, unit of the deviations).
MEASUREMENT_TYPES: dict[str, tuple[str, str]] = {
    "Linear": ("linear", "um"), "Angular": ("angular", "urad"),
    "Straightness": ("straightness", "um")}
HEADER_KEYS = ("File type", "Owner", "Version no")
TARGET_KEYS = ("Filetype", "Target-count", "Targets", "Flags")
USER_KEYS = ("Machine", "Serial No", "Date", "By", "Axis", "Location", "TITLE")
RUNS_KEYS = ("Run-count",)
#: ENVIRONMENT key -> (unit, lo, hi, cells): start and end values, and a flag when 3 cells
#: (as in the public sample).
ENV_KEYS: dict[str, tuple[str, float, float, int]] = {
    "Air temp": ("deg C", -200.0, 200.0, 3), "Air press": ("kPa", 0.0, 2000.0, 3),
    "Air humid": ("%", 0.0, 100.0, 2), "Mat temp 1": ("deg C", -200.0, 200.0, 3),
    "Mat temp 2": ("deg C", -200.0, 200.0, 3), "Mat temp 3": ("deg C", -200.0, 200.0, 3),
    "Env factor": ("", -1e6, 1e6, 2), "Exp coeff": ("ppm/K", -1000.0, 1000.0, 3)}
ENV_OTHER = ("Date Time", "Final Data")
#: A material temperature sensor reading this (deg C) is not connected (public sample).
UNCONNECTED_C = -10.0
MAX_POSITION_MM = 1e5
MAX_READING = 1e5
#: Encodings a .rtl file may be declared in: UTF-8 and the code pages of the public
#: readers (cp1250: the Java parser; gbk: a public viewer's fallback; cp1252: Western).
RTL_ENCODINGS: tuple[str, ...] = ("utf-8", "cp1250", "cp1252", "gbk")
#: The code page taken when the bytes are not UTF-8 and none is declared (the Java parser's).
DEFAULT_CODE_PAGE = "cp1250"

_BLANK = re.compile(r"[ \t]+")


def _cells(s: str) -> list[str]:
    """Cells separated by ASCII spaces and tabs only (a no-break space is not a separator)."""
    return [c for c in _BLANK.split(s.strip(" \t")) if c]


_SECTION = re.compile(r"^([A-Z][A-Z0-9 _-]*)::\s*$")
_KEYVAL = re.compile(r"^([A-Za-z][A-Za-z0-9 .\-]*?)\s*:\s*(.*)$")


@dataclass
class RtlFile:
    """A parsed ``.rtl`` file.

    targets_mm: (T,) in the file's order; passes: (P, T) deviations in ``unit``,
    each pass in target-list order (index = target index - 1); ``kind``:
    ``linear`` / ``angular`` / ``straightness``; ``environment``: key -> (start,
    end) values; ``text``: the free-text fields (USER-TEXT and the others read).
    line_no: (P, T) source line of each deviation.
    """

    file: str
    owner: str
    kind: str
    unit: str
    targets_mm: np.ndarray
    passes: np.ndarray
    line_no: np.ndarray
    environment: dict[str, tuple[float, float]] = field(default_factory=dict)
    env_lines: dict[str, int] = field(default_factory=dict)
    text: dict[str, str] = field(default_factory=dict)
    sha256: str = ""
    #: The text encoding the file was read in (``utf-8``, ``cp1250``, ...) and how it
    #: was chosen (``detected``: valid UTF-8; ``default``: not UTF-8, the default code
    #: page; ``declared``).
    encoding: str = "utf-8"
    encoding_source: str = "detected"
    #: Sections abbe skipped (``EQUIPMENT``, ...): (name, line of its ``NAME::``).
    sections_not_used: list[tuple[str, int]] = field(default_factory=list)
    #: Source line of the keys abbe interprets (``Owner``, ``Run-count``, ``Targets``,
    #: ``Target-count``, ``Flags``): refusals made after reading can name it.
    key_lines: dict[str, int] = field(default_factory=dict)

    @property
    def n_runs(self) -> int:
        return int(self.passes.shape[0] // 2)

    def by_direction(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(targets ascending (T,), up (n, T), down (n, T), lines (n, 2, T)): the passes
        arranged as ``+`` / ``-`` approaches on ascending targets."""
        order = np.argsort(self.targets_mm)
        ascending_list = bool(self.targets_mm.size < 2 or self.targets_mm[1] > self.targets_mm[0])
        odd, even = self.passes[0::2][:, order], self.passes[1::2][:, order]
        lo, le = self.line_no[0::2][:, order], self.line_no[1::2][:, order]
        if ascending_list:
            return self.targets_mm[order], odd, even, np.stack([lo, le], axis=1)
        return self.targets_mm[order], even, odd, np.stack([le, lo], axis=1)

    def reading_notes(self) -> list[str]:
        """What a person should know about how the file was read (encoding, skipped sections)."""
        notes = []
        if self.encoding != "utf-8" or self.encoding_source == "declared":
            how = {"declared": "declared", "default": "not UTF-8; the default code page"}
            notes.append(f"text read as {self.encoding} ({how.get(self.encoding_source, self.encoding_source)})")
        if self.sections_not_used:
            notes.append("sections not used: " + ", ".join(
                f"{n}:: (line {ln})" for n, ln in self.sections_not_used))
        return notes

    def material_temp_c(self) -> float | None:
        """Mean of the connected material sensors' start and end values (deg C), or None."""
        vals = [v for k in ("Mat temp 1", "Mat temp 2", "Mat temp 3") if k in self.environment
                for v in self.environment[k] if v != UNCONNECTED_C]
        return float(np.mean(vals)) if vals else None


def looks_like_rtl(path: str | Path) -> bool:
    """True for a ``.rtl`` name (any case); the content is checked by :func:`read_rtl`."""
    return Path(path).suffix.lower() == ".rtl"


def _decode(raw: bytes, fname: str, encoding: str | None) -> tuple[TextFile, str, str]:
    """The file's text: UTF-8 when valid (a UTF-8 byte-order mark is dropped), else the
    declared code page or the default one; (text file, encoding, how chosen)."""
    digest = hashlib.sha256(raw).hexdigest()
    if encoding is not None:
        enc = encoding.lower().replace("_", "-")
        enc = {"windows-1250": "cp1250", "windows-1252": "cp1252", "utf8": "utf-8"}.get(enc, enc)
        if enc not in RTL_ENCODINGS:
            raise AbbeInputError(f"unknown encoding {encoding!r} for an .rtl file; expected one "
                                 f"of {', '.join(RTL_ENCODINGS)}", file=fname, field="encoding")
        candidates, how = [enc], "declared"
    else:
        candidates, how = ["utf-8", DEFAULT_CODE_PAGE], "detected"
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise AbbeInputError(".rtl file is UTF-16 text (a byte-order mark): save it as UTF-8 or "
                             "in its Windows code page", file=fname, line=1)
    for k, enc in enumerate(candidates):
        body = raw[3:] if enc == "utf-8" and raw.startswith(b"\xef\xbb\xbf") else raw
        try:
            text = body.decode(enc)
        except UnicodeDecodeError as exc:
            if k + 1 < len(candidates):
                continue
            pre = body[:exc.start]
            line = pre.count(b"\n") + pre.count(b"\r") - pre.count(b"\r\n") + 1
            raise AbbeInputError(
                f"byte 0x{body[exc.start]:02X} is not {enc} text"
                + ("" if how == "declared" else f" (nor UTF-8): declare the file's encoding, one "
                   f"of {', '.join(RTL_ENCODINGS)}"), file=fname, line=line) from None
        if k > 0:
            how = "default"
        nul = text.find("\0")
        if nul >= 0:
            line = (text.count("\n", 0, nul) + text.count("\r", 0, nul)
                    - text.count("\r\n", 0, nul) + 1)
            raise AbbeInputError("NUL byte: an .rtl file is text", file=fname, line=line)
        return (TextFile(name=fname, text=text, sha256=digest, size=len(raw)), enc, how)
    raise AssertionError("unreachable")


def read_rtl(path: str | Path, *, encoding: str | None = None) -> RtlFile:
    """Read and validate a Renishaw ``.rtl`` text export.

    ``encoding``: the file's text encoding (one of :data:`RTL_ENCODINGS`); None
    detects it: UTF-8 when the bytes are valid UTF-8, else :data:`DEFAULT_CODE_PAGE`.

    Refused (file, line, field): a line outside a section, an unknown, missing,
    duplicated or misplaced section, an unknown or duplicated key, an unknown
    measurement type (``Owner``), a unidirectional test, a target count or run count
    that does not match the data, targets not strictly monotonic, a deviation row
    naming a pass or target outside the counts, a pass visiting its targets in the
    wrong order or missing one, any number that is not finite or outside its range.
    """
    fname = str(path)
    raw_bytes = read_bytes(path, what=".rtl file", max_bytes=RTL_MAX_BYTES)
    tf, enc_used, enc_how = _decode(raw_bytes, fname, encoding)
    sections: dict[str, list[tuple[int, str]]] = {}
    sec_line: dict[str, int] = {}
    current: str | None = None
    skipping = False
    not_used: list[tuple[str, int]] = []
    order = [s for s, _ in SECTIONS]
    for no, raw in tf.lines():
        s = raw.strip(" \t")
        m = _SECTION.match(s)
        if m:
            name = " ".join(m.group(1).split())
            if name not in order:
                # A section abbe does not use (EQUIPMENT:: in rotary exports): its lines
                # are skipped, the section is reported; only after HEADER:: and before EOF::.
                if current is None:
                    raise AbbeInputError("an .rtl file starts with HEADER::", file=fname,
                                         line=no, field=name)
                if current == "EOF":
                    raise AbbeInputError("text after EOF::", file=fname, line=no, field=name)
                if len(not_used) >= 1000:
                    raise AbbeInputError("more than 1000 sections abbe does not use",
                                         file=fname, line=no, field=name)
                not_used.append((name, no))
                skipping = True
                continue
            skipping = False
            if name in sections:
                raise AbbeInputError(f"section {name}:: appears twice (first at line "
                                     f"{sec_line[name]})", file=fname, line=no, field=name)
            if current is None and name != "HEADER":
                raise AbbeInputError("an .rtl file starts with HEADER::", file=fname, line=no,
                                     field=name)
            if current is not None and order.index(name) < order.index(current):
                raise AbbeInputError(f"section {name}:: after {current}::: the sections come in "
                                     f"the order {', '.join(n + '::' for n in order)}",
                                     file=fname, line=no, field=name)
            current = name
            sections[name] = []
            sec_line[name] = no
            continue
        if not s or skipping:
            continue
        if current is None:
            raise AbbeInputError("text before the first section: an .rtl file starts with "
                                 "HEADER::", file=fname, line=no)
        if current == "EOF":
            raise AbbeInputError("text after EOF::", file=fname, line=no)
        sections[current].append((no, s))
    last = max(sec_line.values(), default=1)
    for name, required in SECTIONS:
        if required and name not in sections:
            raise AbbeInputError(f"missing section {name}::", file=fname, line=last, field=name)

    def keyvals(name: str, keys: tuple[str, ...], *, rows_after: str | None = None
                ) -> tuple[dict[str, tuple[str, int]], list[tuple[int, str]]]:
        """Key : value lines of a section; the lines after ``rows_after`` are data rows."""
        out: dict[str, tuple[str, int]] = {}
        rows: list[tuple[int, str]] = []
        in_rows = False
        for no, s in sections.get(name, []):
            if in_rows and (s[0].isdigit() or s[0] in "+-."):
                rows.append((no, s))
                continue
            m = _KEYVAL.match(s)
            if not m:
                raise AbbeInputError(f"expected 'Key : value' in {name}::", file=fname, line=no)
            key = " ".join(m.group(1).split())
            key = {k.lower(): k for k in keys}.get(key.lower(), key)  # "Air Press" = "Air press"
            if key not in keys:
                raise AbbeInputError(f"unknown key {key!r} in {name}::; expected one of "
                                     f"{', '.join(keys)}", file=fname, line=no, field=key)
            if key in out:
                raise AbbeInputError(f"duplicated key (first at line {out[key][1]})", file=fname,
                                     line=no, field=key)
            out[key] = (m.group(2).strip(" \t"), no)
            in_rows = key == rows_after
            if in_rows and out[key][0]:
                rows.append((no, out[key][0]))
        return out, rows

    def need(d: dict[str, tuple[str, int]], key: str, name: str) -> tuple[str, int]:
        if key not in d:
            raise AbbeInputError(f"missing key {key!r} in {name}::", file=fname,
                                 line=sec_line[name], field=key)
        return d[key]

    hdr, _ = keyvals("HEADER", HEADER_KEYS)
    ftype, fl = need(hdr, "File type", "HEADER")
    if ftype.lower() != "rtl":
        raise AbbeInputError(f"file type {ftype!r}: expected 'rtl'", file=fname, line=fl,
                             field="File type")
    owner, ol = need(hdr, "Owner", "HEADER")
    if owner not in MEASUREMENT_TYPES:
        raise AbbeInputError(f"measurement type {owner!r} is not one abbe can interpret; "
                             f"expected {', '.join(MEASUREMENT_TYPES)}", file=fname, line=ol,
                             field="Owner")
    kind, unit = MEASUREMENT_TYPES[owner]
    key_lines = {"Owner": ol}

    tgt, trows = keyvals("TARGET DATA", TARGET_KEYS, rows_after="Targets")
    cnt_text, cl = need(tgt, "Target-count", "TARGET DATA")
    n_t = parse_int(cnt_text, file=fname, line=cl, field="Target-count", lo=2, hi=RTL_MAX_TARGETS)
    need(tgt, "Targets", "TARGET DATA")
    targets: list[float] = []
    t_lines: list[int] = []
    for no, s in trows:
        for cell in _cells(s):
            if len(targets) >= n_t:
                raise AbbeInputError(f"more targets than Target-count ({n_t})", file=fname,
                                     line=no, field="Targets")
            targets.append(parse_number(cell, file=fname, line=no, field="Targets",
                                        lo=-MAX_POSITION_MM, hi=MAX_POSITION_MM, unit="mm"))
            t_lines.append(no)
    if len(targets) != n_t:
        raise AbbeInputError(f"{len(targets)} targets but Target-count is {n_t}", file=fname,
                             line=trows[-1][0] if trows else tgt["Targets"][1], field="Targets")
    tg = np.array(targets)
    step = np.diff(tg)
    bad = np.flatnonzero(step <= 0) if step[0] > 0 else np.flatnonzero(step >= 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise AbbeInputError(f"targets must be strictly monotonic: {tg[k]:g} mm follows "
                             f"{tg[k - 1]:g} mm", file=fname, line=t_lines[k],
                             field="Targets")
    key_lines.update({"Target-count": cl, "Targets": t_lines[0]})
    flags_text, fgl = need(tgt, "Flags", "TARGET DATA")
    key_lines["Flags"] = fgl
    flags = _cells(flags_text)
    if len(flags) != 4:
        raise AbbeInputError(f"expected four integers, got {flags_text!r}", file=fname,
                             line=fgl, field="Flags")
    fl_int = [parse_int(c, file=fname, line=fgl, field="Flags", lo=0, hi=1_000_000)
              for c in flags]
    if fl_int[1] != 0:
        raise AbbeInputError(f"flags {flags_text!r}: the second flag {fl_int[1]} is not 0 "
                             "(a unidirectional test?); ISO 230-2 needs bidirectional runs",
                             file=fname, line=fgl, field="Flags")

    user, _ = keyvals("USER-TEXT", USER_KEYS)
    runs, _ = keyvals("RUNS", RUNS_KEYS)
    rc_text, rcl = need(runs, "Run-count", "RUNS")
    n_p = parse_int(rc_text, file=fname, line=rcl, field="Run-count", lo=2, hi=RTL_MAX_PASSES)
    key_lines["Run-count"] = rcl
    if n_p % 2:
        raise AbbeInputError(f"Run-count {n_p} is odd: a bidirectional test has two passes "
                             "(runs) per cycle", file=fname, line=rcl, field="Run-count")

    dev, drows = keyvals("DEVIATIONS", ("Run Target Data",), rows_after="Run Target Data")
    need(dev, "Run Target Data", "DEVIATIONS")
    if len(drows) != n_p * n_t:
        raise AbbeInputError(f"{len(drows)} deviation rows, expected Run-count x Target-count "
                             f"= {n_p} x {n_t}", file=fname,
                             line=drows[-1][0] if drows else dev["Run Target Data"][1],
                             field="Run Target Data")
    vals = np.empty((n_p, n_t))
    lines = np.zeros((n_p, n_t), dtype=np.int64)
    for k, (no, s) in enumerate(drows):
        cells = _cells(s)
        if len(cells) != 3:
            raise AbbeInputError(f"expected 'run target value', got {len(cells)} cells",
                                 file=fname, line=no, field="Run Target Data")
        p = parse_int(cells[0], file=fname, line=no, field="run", lo=1, hi=n_p)
        t = parse_int(cells[1], file=fname, line=no, field="target", lo=1, hi=n_t)
        want_p = k // n_t + 1
        j = k % n_t
        want_t = j + 1 if want_p % 2 else n_t - j
        if p != want_p or t != want_t:
            raise AbbeInputError(
                f"expected run {want_p} target {want_t} here, got run {p} target {t}: a run's "
                "rows are contiguous, odd runs list targets 1..n, even runs n..1",
                file=fname, line=no, field="run" if p != want_p else "target")
        vals[p - 1, t - 1] = parse_number(cells[2], file=fname, line=no, field="value",
                                          lo=-MAX_READING, hi=MAX_READING, unit=unit)
        lines[p - 1, t - 1] = no

    env: dict[str, tuple[float, float]] = {}
    env_lines: dict[str, int] = {}
    envkv, _ = keyvals("ENVIRONMENT", tuple(ENV_KEYS) + ENV_OTHER)
    for key, (text, no) in envkv.items():
        if key == "Date Time":
            if not re.fullmatch(r'"[^"]*"[ \t]+"[^"]*"', text):
                raise AbbeInputError(f'expected two quoted dates "start" "end", got {text!r}',
                                     file=fname, line=no, field=key)
            continue
        if key == "Final Data":
            cells = _cells(text)
            if not 1 <= len(cells) <= 2:
                raise AbbeInputError(f"expected one or two integers, got {text!r}", file=fname,
                                     line=no, field=key)
            for c in cells:
                parse_int(c, file=fname, line=no, field=key, lo=0, hi=1_000_000)
            continue
        u, lo, hi, n_cells = ENV_KEYS[key]
        cells = _cells(text)
        if len(cells) != n_cells:
            raise AbbeInputError(f"expected start and end values{' and a flag' if n_cells == 3 else ''}"
                                 f" ({n_cells} numbers), got {text!r}", file=fname, line=no,
                                 field=key)
        a, b = (parse_number(c, file=fname, line=no, field=key, lo=lo, hi=hi, unit=u)
                for c in cells[:2])
        if len(cells) == 3:
            parse_int(cells[2], file=fname, line=no, field=key, lo=0, hi=1_000_000)
        env[key] = (a, b)
        env_lines[key] = no
    texts = {k: v for k, (v, _) in user.items()}
    texts.update({"Version no": hdr.get("Version no", ("", 0))[0],
                  "Filetype": tgt.get("Filetype", ("", 0))[0]})
    for k in ENV_OTHER:
        if k in envkv:
            texts[k] = envkv[k][0]
    return RtlFile(file=fname, owner=owner, kind=kind, unit=unit, targets_mm=tg, passes=vals,
                   line_no=lines, environment=env, env_lines=env_lines, text=texts,
                   sha256=tf.sha256, encoding=enc_used, encoding_source=enc_how,
                   sections_not_used=not_used, key_lines=key_lines)
