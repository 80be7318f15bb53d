"""The measurement programs a campaign needs, as controller-neutral steps (docs/programs.md).

A :class:`Program` is a list of steps in machine coordinates (mm, mm/min, s, deg):

* ``Move(pos, feed)``: a straight feed move to ``pos`` (x, y, z);
* ``Arc(pos, centre, ccw, plane, feed)``: a circular feed move in ``plane`` ending at
  ``pos`` about ``centre``; ``ccw`` = increasing theta (abbe's convention, which is
  G3 in G17 / G18 / G19: docs/formats.md, "Conventions");
* ``Dwell(seconds)``: stand still (the instrument captures);
* ``Stop(text)``: a programmed stop (fit the ballbar);
* ``Comment(text)``.

Tests: ISO 230-2 positioning (linear or pendulum sequence, targets by
:func:`iso230_2_targets`), straightness and angular lines (the linear sequence: the
instrument reads another channel), and the ballbar circle of a machine file's
``[ballbar.NAME]`` section (feed-in arc, data arc, feed-out arc, CCW then CW).
Every point is checked against the axis travel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from abbe.errors import AbbeInputError
from abbe.model.geometry import PLANE_AXES
from abbe.model.table import AXES

TESTS: tuple[str, ...] = ("positioning", "straightness", "angular", "ballbar")
SEQUENCES: tuple[str, ...] = ("linear", "pendulum")


@dataclass(frozen=True)
class Move:
    pos: tuple[float, float, float]
    feed: float


@dataclass(frozen=True)
class Arc:
    pos: tuple[float, float, float]
    centre: tuple[float, float, float]
    ccw: bool
    plane: str
    feed: float


@dataclass(frozen=True)
class Dwell:
    seconds: float


@dataclass(frozen=True)
class Stop:
    text: str


@dataclass(frozen=True)
class Comment:
    text: str


@dataclass(frozen=True)
class Spindle:
    """Spindle clockwise at ``rpm`` (0: stop)."""

    rpm: float


Step = Move | Arc | Dwell | Stop | Comment | Spindle


@dataclass
class Program:
    """Steps plus what a checker needs: the plane (arcs), the targets and their capture
    order (positioning), the circle (ballbar), and the parameters for the header."""

    title: str
    plane: str
    steps: list[Step] = field(default_factory=list)
    #: positioning: the axis index, the targets (ascending) and the expected captures in
    #: order: (target index, approach +1 / -1, run); ballbar: None
    axis: int | None = None
    targets_mm: np.ndarray | None = None
    captures: list[tuple[int, int, int]] = field(default_factory=list)
    params: dict[str, float | str] = field(default_factory=dict)

    def points(self) -> np.ndarray:
        """Every commanded end point, (N, 3) mm."""
        return np.array([s.pos for s in self.steps if isinstance(s, (Move, Arc))])


def iso230_2_targets(lo: float, hi: float, n: int | None = None, seed: int = 0) -> np.ndarray:
    """Targets per ISO 230-2 over [lo, hi] mm: at least five per metre and at least five,
    P_i = (i - 1) p + r_i with the nominal interval p and r_i a different random offset
    at each target (here uniform in [-p/4, p/4], seeded; r = 0 at both ends) so that a
    periodic error (a ball-screw pitch) is not sampled at one phase. 0.001 mm grid."""
    length = hi - lo
    if n is None:
        n = max(5, math.ceil(5.0 * length / 1000.0) + 1)
    p = length / (n - 1)
    rng = np.random.default_rng(seed)
    r = rng.uniform(-0.25 * p, 0.25 * p, n)
    r[0] = r[-1] = 0.0
    t = np.round(lo + p * np.arange(n) + r, 3)
    t[0], t[-1] = lo, hi
    return t


def _check_travel(prog: Program, travel: dict[str, tuple[float, float]], where: str) -> None:
    pts = prog.points()
    for j, a in enumerate(AXES):
        lo, hi = travel[a]
        bad = np.flatnonzero((pts[:, j] < lo - 1e-9) | (pts[:, j] > hi + 1e-9))
        if bad.size:
            raise AbbeInputError(f"the program would move {a} to {pts[bad[0], j]:.4f} mm, outside "
                                 f"the travel [{lo:g}, {hi:g}] mm", field=where)


def line_program(test: str, axis: str, start_mm, end_mm, travel: dict[str, tuple[float, float]],
                 *, feed: float, dwell_s: float, overrun_mm: float, runs: int,
                 sequence: str = "linear", n_targets: int | None = None,
                 seed: int = 0) -> Program:
    """ISO 230-2 positioning (or a straightness / angular line) along ``axis`` between the
    machine file's line ends. The targets lie in the line's span shrunk where the overrun
    would leave the travel. Linear sequence: per run a ``+`` pass (targets ascending,
    approached from below), an overrun past the last target, a ``-`` pass, an overrun
    below the first. Pendulum: at each target (ascending) ``runs`` times approach from
    below, then from above. A dwell at each target for the capture."""
    j = AXES.index(axis)
    lo_l, hi_l = sorted((start_mm[j], end_mm[j]))
    t_lo, t_hi = travel[axis]
    lo, hi = max(lo_l, t_lo + overrun_mm), min(hi_l, t_hi - overrun_mm)
    if hi - lo < 1.0:
        raise AbbeInputError(f"the line {lo_l:g}..{hi_l:g} mm with an overrun of {overrun_mm:g} mm "
                             f"leaves under 1 mm inside the travel [{t_lo:g}, {t_hi:g}]",
                             field="--overrun-mm")
    targets = iso230_2_targets(lo, hi, n_targets, seed)
    base = list(start_mm)

    def at(x: float) -> tuple[float, float, float]:
        p = list(base)
        p[j] = float(x)
        return (p[0], p[1], p[2])

    title = {"positioning": f"ISO 230-2 positioning of {axis}",
             "straightness": f"straightness of {axis} (ISO 230-1)",
             "angular": f"angular errors (pitch, yaw, roll) of {axis} (ISO 230-1)"}[test]
    prog = Program(title=title, plane="XY", axis=j, targets_mm=targets,
                   params={"test": test, "axis": axis, "sequence": sequence, "runs": runs,
                           "feed_mm_min": feed, "dwell_s": dwell_s, "overrun_mm": overrun_mm,
                           "targets": len(targets)})
    s = prog.steps
    s.append(Comment(f"{title}: {len(targets)} targets, {runs} bidirectional runs, "
                     f"{sequence} sequence"))
    for k in range(0, len(targets), 8):  # short lines: grbl's line buffer is 256 characters
        s.append(Comment("targets mm: " + " ".join(f"{t:.3f}" for t in targets[k:k + 8])))
    s.append(Comment(f"dwell {dwell_s:g} s at each target for the capture; overrun "
                     f"{overrun_mm:g} mm; feed {feed:g} mm/min"))
    lo_o, hi_o = targets[0] - overrun_mm, targets[-1] + overrun_mm
    if sequence == "linear":
        s.append(Move(at(lo_o), feed))
        for r in range(1, runs + 1):
            s.append(Comment(f"run {r} +"))
            for i, x in enumerate(targets):
                s += [Move(at(x), feed), Dwell(dwell_s)]
                prog.captures.append((i, +1, r))
            s.append(Move(at(hi_o), feed))
            s.append(Comment(f"run {r} -"))
            for i in range(len(targets) - 1, -1, -1):
                s += [Move(at(targets[i]), feed), Dwell(dwell_s)]
                prog.captures.append((i, -1, r))
            s.append(Move(at(lo_o), feed))
    elif sequence == "pendulum":
        for i, x in enumerate(targets):
            s.append(Comment(f"target {i + 1}: {x:.3f} mm"))
            for r in range(1, runs + 1):
                s += [Move(at(x - overrun_mm), feed), Move(at(x), feed), Dwell(dwell_s)]
                prog.captures.append((i, +1, r))
                s += [Move(at(x + overrun_mm), feed), Move(at(x), feed), Dwell(dwell_s)]
                prog.captures.append((i, -1, r))
    else:
        raise AbbeInputError(f"unknown sequence {sequence!r}; expected one of "
                             f"{', '.join(SEQUENCES)}", field="--sequence")
    _check_travel(prog, travel, "--overrun-mm")
    return prog


def ballbar_program(name: str, plane: str, centre_mm, radius_mm: float, feed: float,
                    travel: dict[str, tuple[float, float]], *, feed_arc_deg: float,
                    pause_s: float) -> Program:
    """The ballbar test ``name``: move to the start of the feed-in arc (theta =
    -feed_arc_deg), stop to fit the ballbar, the CCW run from -feed_arc_deg to 360 +
    feed_arc_deg, a pause, the CW run back; arcs split at every quarter turn and at the
    data arc's ends (0 and 360 deg)."""
    a, b = PLANE_AXES[plane]
    c = np.asarray(centre_mm, dtype=np.float64)

    def pt(theta_deg: float) -> tuple[float, float, float]:
        p = c.copy()
        th = math.radians(theta_deg)
        p[a] += radius_mm * math.cos(th)
        p[b] += radius_mm * math.sin(th)
        return (float(p[0]), float(p[1]), float(p[2]))

    f = feed_arc_deg
    marks = [-f] + [q for q in (0.0, 90.0, 180.0, 270.0, 360.0) if -f < q < 360 + f] + [360 + f]
    marks = sorted(set(marks))
    # no arc longer than 90 deg: split the feed arcs too
    full: list[float] = [marks[0]]
    for m in marks[1:]:
        k = max(1, math.ceil((m - full[-1]) / 90.0 - 1e-9))
        full += [full[-1] + (m - full[-1]) * (i + 1) / k for i in range(k)]
    prog = Program(title=f"ballbar {name}: plane {plane}, R {radius_mm:g} mm, F {feed:g} mm/min",
                   plane=plane, params={"test": "ballbar", "name": name, "plane": plane,
                                        "radius_mm": radius_mm, "feed_mm_min": feed,
                                        "feed_arc_deg": feed_arc_deg, "pause_s": pause_s,
                                        "center_mm": " ".join(f"{v:g}" for v in c)})
    s = prog.steps
    cc = (float(c[0]), float(c[1]), float(c[2]))
    s.append(Comment(prog.title))
    s.append(Comment(f"centre {c[0]:.4f} {c[1]:.4f} {c[2]:.4f} mm; data arc 0..360 deg, feed "
                     f"arcs {feed_arc_deg:g} deg each side; CCW then CW"))
    s.append(Move(pt(full[0]), feed))
    s.append(Stop("fit the ballbar, start the capture, then cycle start"))
    s.append(Comment("CCW run"))
    for th in full[1:]:
        s.append(Arc(pt(th), cc, True, plane, feed))
    s.append(Dwell(pause_s))
    s.append(Comment("CW run"))
    for th in reversed(full[:-1]):
        s.append(Arc(pt(th), cc, False, plane, feed))
    _check_travel(prog, travel, f"ballbar.{name}")
    # the arcs between the points stay in the travel when the whole circle does
    for k, ax in ((a, AXES[a]), (b, AXES[b])):
        lo, hi = travel[ax]
        if c[k] - radius_mm < lo - 1e-9 or c[k] + radius_mm > hi + 1e-9:
            raise AbbeInputError(f"the circle leaves the {ax} travel [{lo:g}, {hi:g}] mm",
                                 field=f"ballbar.{name}.radius_mm")
    return prog
