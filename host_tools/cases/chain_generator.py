"""Independent generator of five-axis sphere measurements for any kinematic chain.

Written from the chain description in ISO 230-1 terms, NOT from abbe's model code (it
imports nothing from abbe): it reads the machine file's ``[chain]`` with tomllib and
builds every axis as a rotation about its *actual axis average line*:

* the nominal line of a rotary axis passes through its pivot P along the unit vector
  k of its machine axis (A: X, B: Y, C: Z); the actual line is shifted by the
  position location errors (ISO 230-7: for C, EX0C and EY0C along X and Y) and tilted
  by the orientation location errors (for C, EA0C about X and EB0C about Y): its
  direction is k + (tilt vector) x k, normalised;
* the axis turns by ``s * t + E0`` (s the nominal direction's sign, E0 the zero
  location error, e.g. EC0C, about the positive machine axis) about that actual line:
  Rodrigues' formula in a 4 x 4 matrix ``[R, p - R p; 0, 1]`` with p a point of the
  actual line;
* workpiece-side axes are composed from the base to the workpiece, tool-side axes
  from the linear axes to the tool; the tool-side pivots travel with the linear axes.

Error motions (ISO 230-1 / 230-7: the six components of an axis' error motion, e.g.
for C the radial EXC, EYC, the axial EZC, the tilt EAC, EBC and the angular ECC, each a
function of the commanded angle t): after the rotation about the actual line, the
carried part is further moved by a small rigid motion in the machine's (non-rotating)
axes about the point of the actual line next to the pivot - the homogeneous transform
``Tr(p + t_err) Rot(r_err) Tr(-p)`` with ``Rot`` the exact rotation by the vector r_err
(Rodrigues) - each component a sum of sines ``sum_k amp_k sin(k t + phase_k)`` (um /
urad). ISO 230-7 puts the first harmonic of a radial or tilt motion into the axis
average line (its location), so those start at the second harmonic; the axial and
angular ones at the first; none has a constant.

Instruments (the same meaning as abbe's, coded here again): a touch probe reports the
machine position (the linear axes) where the actual tip is on the actual sphere centre; an
R-test nest under tool-centre-point control reads the actual sphere centre minus the
actual nest, in the nest's nominal frame (um), zeroed at its first reading.
A rotary ballbar (ISO 10791-6 style) reads the distance between a ball on the table and a
ball in the spindle held, under tool-centre-point control, where the nominal kinematics put
it: the controller drives the linear axes to ``W_nom(tool ball) - T_nom(tip)`` (the ball
``tip`` mm from the controlled point at zero angles), the actual ball is where the actual
tool-side axes put the ball's actual place in the spindle (``tip`` + its cup's run-out, in
the spindle's frame: a head turns it), the actual table ball where the actual workpiece-side
axes put it; the reading is the distance minus the nominal one (um) minus the bar's
length calibration error.

Usage: imported by cases/chain_suite.py (bench/bench_chain.py) and by the tests.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

_AXIS = {"A": 0, "B": 1, "C": 2}
_XYZ = "XYZ"


@dataclass(frozen=True)
class GenAxis:
    name: str
    sign: float
    pivot: np.ndarray
    travel: tuple[float, float]


@dataclass(frozen=True)
class GenChain:
    """Rotary axes next to the workpiece first (``work``), next to the linear axes first
    (``tool``), all rotary axes in alphabetical order (the angle columns)."""

    work: tuple[GenAxis, ...]
    tool: tuple[GenAxis, ...]
    names: tuple[str, str]

    def axis(self, n: str) -> GenAxis:
        return next(a for a in self.work + self.tool if a.name == n)


def read_chain(path: Path) -> GenChain:
    """The ``[chain]`` of a machine file (no validation beyond what the generator needs)."""
    data = tomllib.loads(Path(path).read_text(encoding="utf-8"))["chain"]
    order = data["order"]
    first_lin = min(i for i, n in enumerate(order) if n in _XYZ)
    axes = {}
    for n in order:
        if n in _AXIS:
            a = data[n]
            axes[n] = GenAxis(n, 1.0 if a["direction"].startswith("+") else -1.0,
                              np.array(a["pivot_mm"], dtype=float), tuple(a["travel_deg"]))
    work = tuple(axes[n] for n in order[:first_lin])
    tool = tuple(axes[n] for n in order[first_lin + 3:])
    names = tuple(sorted(axes))
    return GenChain(work, tool, (names[0], names[1]))


def location_names(axis: str) -> tuple[str, str, str, str, str]:
    """ISO 230-7 location errors of ``axis``: the two positions across it, the two tilts
    across it, its zero - e.g. C: EX0C, EY0C, EA0C, EB0C, EC0C."""
    i = _AXIS[axis]
    across = [j for j in range(3) if j != i]
    return (f"E{_XYZ[across[0]]}0{axis}", f"E{_XYZ[across[1]]}0{axis}",
            f"E{'ABC'[across[0]]}0{axis}", f"E{'ABC'[across[1]]}0{axis}", f"E{axis}0{axis}")


def _rodrigues(k: np.ndarray, angle: float) -> np.ndarray:
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * K @ K


@dataclass(frozen=True)
class ErrorMotion:
    """One component of an axis' error motion: ``sum_k amp[k] sin(k t + phase[k])`` with t
    the commanded angle (um for X Y Z, urad for A B C)."""

    amp: dict[int, float]
    phase: dict[int, float]

    def at(self, angle_deg: float) -> float:
        t = np.deg2rad(angle_deg)
        return float(sum(a * np.sin(k * t + self.phase[k]) for k, a in self.amp.items()))


def first_harmonic(axis: str, comp: str) -> int:
    """ISO 230-7: radial and tilt motions start at the 2nd harmonic (the 1st is the axis
    average line's location), axial and angular ones at the 1st."""
    along = _XYZ.index(comp) if comp in _XYZ else "ABC".index(comp)  # its machine axis
    return 1 if along == _AXIS[axis] else 2


def _small_motion(p: np.ndarray, trans_um: np.ndarray, rot_urad: np.ndarray) -> np.ndarray:
    """4 x 4 ``Tr(p + t) Rot(r) Tr(-p)``: rotation by the vector r (exact) about p, then t."""
    r = rot_urad * 1e-6
    th = float(np.linalg.norm(r))
    R = _rodrigues(r / th, th) if th > 0 else np.eye(3)
    M = np.eye(4)
    M[:3, :3] = R
    M[:3, 3] = p + trans_um * 1e-3 - R @ p
    return M


def axis_matrix(ax: GenAxis, angle_deg: float, loc: dict[str, float] | None,
                motions: dict[str, ErrorMotion] | None = None) -> np.ndarray:
    """4 x 4 motion of ``ax`` at ``angle_deg``: rotation about its actual line, then its
    error motion (``motions``: "C.X" .. "C.C" -> component, see module)."""
    i = _AXIS[ax.name]
    k = np.zeros(3)
    k[i] = 1.0
    p = ax.pivot.astype(float).copy()
    zero = 0.0
    if loc:
        n = location_names(ax.name)
        across = [j for j in range(3) if j != i]
        tilt = np.zeros(3)
        for m, j in enumerate(across):
            p[j] += loc.get(n[m], 0.0) * 1e-3
            tilt[j] = loc.get(n[2 + m], 0.0) * 1e-6
        k = k + np.cross(tilt, k)
        k = k / np.linalg.norm(k)
        zero = loc.get(n[4], 0.0) * 1e-6
    R = _rodrigues(k, ax.sign * np.deg2rad(angle_deg) + zero)
    M = np.eye(4)
    M[:3, :3] = R
    M[:3, 3] = p - R @ p
    mine = {c: m for c, m in (motions or {}).items() if c.split(".")[0] == ax.name}
    if mine:
        v = np.array([mine[f"{ax.name}.{c}"].at(angle_deg) if f"{ax.name}.{c}" in mine else 0.0
                      for c in "XYZABC"])
        M = _small_motion(p, v[:3], v[3:]) @ M
    return M


def _angles(ch: GenChain, pair: np.ndarray) -> dict[str, float]:
    return {ch.names[0]: float(pair[0]), ch.names[1]: float(pair[1])}


def work_matrix(ch: GenChain, pair: np.ndarray, loc: dict[str, float] | None,
                motions: dict[str, ErrorMotion] | None = None) -> np.ndarray:
    """Workpiece -> machine: the outermost axis' matrix on the left."""
    a = _angles(ch, pair)
    M = np.eye(4)
    for ax in reversed(ch.work):  # outermost first
        M = M @ axis_matrix(ax, a[ax.name], loc, motions)
    return M


def tool_matrix(ch: GenChain, pair: np.ndarray, loc: dict[str, float] | None,
                motions: dict[str, ErrorMotion] | None = None) -> np.ndarray:
    """Tool -> linear axes' frame, relative to the controlled point."""
    a = _angles(ch, pair)
    M = np.eye(4)
    for ax in ch.tool:
        M = M @ axis_matrix(ax, a[ax.name], loc, motions)
    return M


def _pt(M: np.ndarray, p: np.ndarray) -> np.ndarray:
    return M[:3, :3] @ p + M[:3, 3]


def probe_centres(ch: GenChain, loc: dict[str, float], sphere: np.ndarray, offset_mm: np.ndarray,
                  tip: np.ndarray, angles: np.ndarray, noise_um: float,
                  rng: np.random.Generator,
                  motions: dict[str, ErrorMotion] | None = None) -> np.ndarray:
    """(M, 3) machine positions (mm) at which the stylus tip is on the sphere's centre."""
    out = []
    for pair in angles:
        centre = _pt(work_matrix(ch, pair, loc, motions), sphere + offset_mm)
        out.append(centre - _pt(tool_matrix(ch, pair, loc, motions), tip))  # actual tip on it
    c = np.array(out)
    return c + rng.normal(0.0, noise_um * 1e-3, c.shape)


def rtest_readings(ch: GenChain, loc: dict[str, float], sphere: np.ndarray, offset_mm: np.ndarray,
                   tip: np.ndarray, angles: np.ndarray, noise_um: float,
                   rng: np.random.Generator,
                   motions: dict[str, ErrorMotion] | None = None) -> np.ndarray:
    """(M, 3) R-test readings (um, nest frame) under tool-centre-point control."""
    out = []
    for pair in angles:
        q = _pt(work_matrix(ch, pair, None), sphere) - _pt(tool_matrix(ch, pair, None), tip)
        nest = q + _pt(tool_matrix(ch, pair, loc, motions), tip)
        centre = _pt(work_matrix(ch, pair, loc, motions), sphere + offset_mm)
        out.append(tool_matrix(ch, pair, None)[:3, :3].T @ (centre - nest) * 1e3)
    r = np.array(out)
    r = r - r[0] + rng.normal(0.0, noise_um, r.shape)
    r[0] = 0.0
    return r


def ballbar_readings(ch: GenChain, loc: dict[str, float], table: np.ndarray,
                     table_offset_mm: np.ndarray, tool: np.ndarray, tip: np.ndarray,
                     cup_mm: np.ndarray, angles: np.ndarray, length_error_um: float,
                     noise_um: float, rng: np.random.Generator,
                     motions: dict[str, ErrorMotion] | None = None) -> np.ndarray:
    """(M,) rotary ballbar readings (um): actual distance of the balls minus their nominal
    distance, minus the bar's length error, plus noise (see module)."""
    length = float(np.linalg.norm(tool - table))
    out = []
    for pair in angles:
        q = _pt(work_matrix(ch, pair, None), tool) - _pt(tool_matrix(ch, pair, None), tip)
        ball = q + _pt(tool_matrix(ch, pair, loc, motions), tip + cup_mm)
        centre = _pt(work_matrix(ch, pair, loc, motions), table + table_offset_mm)
        out.append((float(np.linalg.norm(ball - centre)) - length) * 1e3 - length_error_um)
    r = np.array(out)
    return r + rng.normal(0.0, noise_um, r.shape)


def ballbar_paths(ch: GenChain, n_full: int = 12, n_part: int = 9) -> list[tuple[str, np.ndarray]]:
    """(label, angle pairs) of the ballbar tests: each rotary axis turning (a full turn in
    ``360 / n_full`` steps, or 80 % of its travel within +-90 deg in ``n_part`` steps) and
    back, the other held at two angles (0 and 90 deg for a full-turn axis, 0 and half its
    largest angle otherwise)."""
    out = []
    for i, n in enumerate(ch.names):
        other = ch.names[1 - i]
        lo, hi = ch.axis(n).travel
        if hi - lo >= 360.0:
            go = np.arange(n_full + 1) * 360.0 / n_full
        else:
            lo, hi = max(lo, -90.0), min(hi, 90.0)
            mid, half = (lo + hi) / 2.0, (hi - lo) / 2.0 * 0.8
            go = np.linspace(mid - half, mid + half, n_part)
        path = np.r_[go, go[-2::-1]]
        olo, ohi = ch.axis(other).travel
        holds = (0.0, 90.0) if ohi - olo >= 360.0 else (
            0.0, 0.5 * (max(olo, -90.0) if abs(max(olo, -90.0)) > abs(min(ohi, 90.0))
                        else min(ohi, 90.0)))
        for h in holds:
            pair = np.zeros((path.size, 2))
            pair[:, i] = path
            pair[:, 1 - i] = h
            out.append((f"{n}{int(round(h))}", pair))
    return out


def random_location(ch: GenChain, rng: np.random.Generator, um: float = 20.0,
                    urad: float = 50.0) -> dict[str, float]:
    """Random location errors: positions N(0, um), tilts and zeros N(0, urad)."""
    out = {}
    for n in ch.names:
        for i, e in enumerate(location_names(n)):
            out[e] = float(rng.normal(0.0, um if i < 2 else urad))
    return out


def random_motions(ch: GenChain, rng: np.random.Generator, harmonics: int = 2,
                   um: float = 1.0, urad: float = 4.0) -> dict[str, ErrorMotion]:
    """Random error motions of both rotary axes: every component, each harmonic from its
    first (:func:`first_harmonic`) to ``harmonics`` with an amplitude U(0, um / urad) and a
    uniform phase."""
    out = {}
    for n in ch.names:
        for c in "XYZABC":
            ks = range(first_harmonic(n, c), harmonics + 1)
            if not ks:
                continue
            size = um if c in _XYZ else urad
            out[f"{n}.{c}"] = ErrorMotion({k: float(rng.uniform(0.0, size)) for k in ks},
                                          {k: float(rng.uniform(0.0, 2.0 * np.pi)) for k in ks})
    return out


def grid(ch: GenChain, n_first: int = 5, n_second: int = 6) -> np.ndarray:
    """Angle pairs: a full turn equally spaced, or 80 % of the travel (within +-90 deg)."""
    cols = []
    for n, k in zip(ch.names, (n_first, n_second)):
        lo, hi = ch.axis(n).travel
        if hi - lo >= 360.0:
            cols.append(np.arange(k) * 360.0 / k + 15.0)
        else:
            lo, hi = max(lo, -90.0), min(hi, 90.0)
            mid, half = (lo + hi) / 2.0, (hi - lo) / 2.0 * 0.8
            cols.append(np.linspace(mid - half, mid + half, k))
    A, B = np.meshgrid(cols[0], cols[1], indexing="ij")
    return np.column_stack([A.ravel(), B.ravel()])
