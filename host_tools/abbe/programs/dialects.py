"""A :class:`abbe.programs.plan.Program` written as each controller wants it
(docs/programs.md, "Dialects": the assumptions behind each).

| dialect | start | dwell | comment | stop | end |
|---|---|---|---|---|---|
| linuxcnc | ``G21 G90 G94 G17`` | ``G4 P<s>`` | ``(...)`` | ``M0`` | ``M2`` |
| grblhal | ``G21 G90 G94 G17`` | ``G4 P<s>`` | ``(...)`` | ``M0`` | ``M2`` |
| fanuc | ``%``, ``O0001``, ``G21 G90 G94 G17`` | ``G04 X<s>`` | ``(...)`` upper case | ``M00`` | ``M30``, ``%`` |
| sinumerik | ``G71 G90 G94 G17`` | ``G4 F<s>`` | ``; ...`` | ``M0`` | ``M30`` |
| heidenhain | ``BEGIN PGM``, ``TOOL CALL 0 Z`` | ``CYCL DEF 9`` | ``; ...`` | ``STOP`` | ``END PGM`` |

Spindle (ISO 230-3 tests): ``M3 S<rpm>`` / ``M5`` (Fanuc ``M03`` / ``M05``); Heidenhain
``TOOL CALL 0 Z S<rpm>`` then ``L M3``, ``L M5`` (not checked on a TNC).

Arcs: G2 / G3 with the centre as I, J, K relative to the arc's start (the default of
all four G-code dialects); Heidenhain: ``CC`` (the centre) then ``C`` with ``DR+`` /
``DR-``. Every coordinate has a decimal point (a Fanuc ``X100`` is 100 increments).
"""

from __future__ import annotations

from abbe.programs.plan import Arc, Comment, Dwell, Move, Program, Spindle, Stop
from abbe.model.geometry import PLANE_AXES
from abbe.model.table import AXES

DIALECTS: tuple[str, ...] = ("linuxcnc", "grblhal", "fanuc", "sinumerik", "heidenhain")
#: G-code plane selection per abbe plane (theta from the first axis to the second: G3 = CCW).
GPLANE = {"XY": "G17", "ZX": "G18", "YZ": "G19"}
#: Heidenhain: the tool axis that makes ``plane`` the working plane.
TOOL_AXIS = {"XY": "Z", "ZX": "Y", "YZ": "X"}
#: Arc centre words, per axis index.
IJK = ("I", "J", "K")


def _num(v: float) -> str:
    s = f"{v:.4f}"
    return "0.0000" if s == "-0.0000" else s


def _clean(text: str, upper: bool = False) -> str:
    """Comment text a controller accepts: no parentheses or semicolons inside."""
    t = "".join(ch if ch.isprintable() and ch not in "()" else " " for ch in text)
    return t.upper() if upper else t


class _Writer:
    """Modal state: write only the axes that change (all of them on the first move)."""

    def __init__(self) -> None:
        self.pos: tuple[float, float, float] | None = None

    def words(self, pos: tuple[float, float, float], fmt) -> str:
        out = []
        for k, a in enumerate(AXES):
            if self.pos is None or _num(self.pos[k]) != _num(pos[k]):
                out.append(fmt(a, pos[k]))
        self.pos = pos
        return " ".join(out)


def _gcode(prog: Program, dialect: str) -> list[str]:
    fanuc = dialect == "fanuc"
    sin = dialect == "sinumerik"
    up = fanuc
    lines: list[str] = []

    def comment(t: str) -> str:
        return f"; {_clean(t)}" if sin else f"({_clean(t, up)})"

    if fanuc:
        lines += ["%", "O0001 " + comment("ABBE " + prog.title)]
    else:
        lines.append(comment("abbe: " + prog.title))
    for k, v in prog.params.items():
        lines.append(comment(f"{k} = {v}"))
    lines.append(comment("machine coordinates: run with a zero work offset, G54 = 0"))
    units = "G71" if sin else "G21"
    lines.append(f"{units} G90 G94 {GPLANE[prog.plane]}")
    g1, g2, g3 = ("G01", "G02", "G03") if fanuc else ("G1", "G2", "G3")
    w = _Writer()
    feed = None

    def f_word(f: float) -> str:
        nonlocal feed
        if feed is not None and _num(f) == _num(feed):
            return ""
        feed = f
        return f" F{f:.1f}"

    for st in prog.steps:
        if isinstance(st, Comment):
            lines.append(comment(st.text))
        elif isinstance(st, Move):
            words = w.words(st.pos, lambda a, v: f"{a}{_num(v)}")
            if words:
                lines.append(f"{g1} {words}{f_word(st.feed)}")
        elif isinstance(st, Arc):
            start = w.pos
            assert start is not None
            a, b = PLANE_AXES[st.plane]
            end = " ".join(f"{AXES[k]}{_num(st.pos[k])}" for k in (a, b))
            ij = " ".join(f"{IJK[k]}{_num(st.centre[k] - start[k])}" for k in (a, b))
            w.pos = st.pos
            lines.append(f"{g3 if st.ccw else g2} {end} {ij}{f_word(st.feed)}")
        elif isinstance(st, Dwell):
            lines.append({"fanuc": f"G04 X{st.seconds:.3f}",
                          "sinumerik": f"G4 F{st.seconds:.3f}"}.get(dialect,
                                                                    f"G4 P{st.seconds:.3f}"))
        elif isinstance(st, Stop):
            lines.append(("M00 " if fanuc else "M0 ") + comment(st.text))
        elif isinstance(st, Spindle):
            lines.append(f"M03 S{st.rpm:.0f}" if fanuc else f"M3 S{st.rpm:.0f}") if st.rpm > 0 \
                else lines.append("M05" if fanuc else "M5")
    lines.append("M30" if fanuc or sin else "M2")
    if fanuc:
        lines.append("%")
    return lines


def _heidenhain(prog: Program) -> list[str]:
    body: list[str] = [f"; abbe: {_clean(prog.title)}"]
    body += [f"; {_clean(f'{k} = {v}')}" for k, v in prog.params.items()]
    body.append("; machine coordinates: run with the datum at the machine origin")
    body.append(f"TOOL CALL 0 {TOOL_AXIS[prog.plane]}")
    w = _Writer()

    def coord(a: str, v: float) -> str:
        s = _num(v)
        return f"{a}{s if s.startswith('-') else '+' + s}"

    for st in prog.steps:
        if isinstance(st, Comment):
            body.append(f"; {_clean(st.text)}")
        elif isinstance(st, Move):
            words = w.words(st.pos, coord)
            if words:
                body.append(f"L {words} F{st.feed:.0f}")
        elif isinstance(st, Arc):
            a, b = PLANE_AXES[st.plane]
            body.append("CC " + " ".join(coord(AXES[k], st.centre[k]) for k in (a, b)))
            w.pos = st.pos
            body.append("C " + " ".join(coord(AXES[k], st.pos[k]) for k in (a, b))
                        + f" DR{'+' if st.ccw else '-'} F{st.feed:.0f}")
        elif isinstance(st, Dwell):
            body += ["CYCL DEF 9.0 DWELL TIME", f"CYCL DEF 9.1 DWELL {st.seconds:.3f}"]
        elif isinstance(st, Stop):
            body += [f"; {_clean(st.text)}", "STOP"]
        elif isinstance(st, Spindle):
            body += ([f"TOOL CALL 0 {TOOL_AXIS[prog.plane]} S{st.rpm:.0f}", "L M3"] if st.rpm > 0
                     else ["L M5"])
    lines = ["BEGIN PGM ABBE MM"] + body + ["END PGM ABBE MM"]
    return [f"{i} {ln}" for i, ln in enumerate(lines)]


def render(prog: Program, dialect: str) -> str:
    """The program text in ``dialect`` (one of :data:`DIALECTS`), LF line ends."""
    if dialect == "heidenhain":
        lines = _heidenhain(prog)
    elif dialect in DIALECTS:
        lines = _gcode(prog, dialect)
    else:
        raise ValueError(dialect)
    return "\n".join(lines) + "\n"
