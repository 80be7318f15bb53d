"""The true machine of the second independent generator: ISO 230-1 error motions
composed by exact homogeneous transforms.

Written from docs/concepts.md, docs/formats.md and docs/table-format.md only.
Each linear axis J carries six error motions (ISO 230-1 names, J = X, Y, Z):
EXJ, EYJ, EZJ (um) and EAJ, EBJ, ECJ (urad) -- in the model's words d_x(J),
d_y(J), d_z(J) and eps_Jx, eps_Jy, eps_Jz. Every motion is a sum of Gaussian
bumps plus (positioning only) a linear term, made zero at the reference point
(the model's frame, docs/concepts.md), and the straightness motions lose their
least-squares line over the fit's targets (the slope of a straightness trace is
squareness or set-up, docs/formats.md "Straightness detrending").

The chain (docs/table-format.md, Eq. 3's levers): the tool side moves the tool
tip t by Z's transform about the spindle reference; the workpiece side moves the
workpiece point under the tool by X's transform (lever (-x, -y, z) + t from the
carriage's centre of rotation) and then by Y's (lever (0, -y, z) + t). Each
transform is a 4x4 homogeneous matrix Tr(d) Rot(eps) about its centre, the
rotation exact (Rodrigues), so the first order is Eq. 3 and the rest is the
second order the linear model leaves out. Squareness tilts the direction of Y
(workpiece side, S_xy) and of Z (tool side, S_xz, S_yz).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

AXES = ("X", "Y", "Z")
#: model term order of one axis: d_x, d_y, d_z (um), e_x, e_y, e_z (urad)
TERMS = ("dx", "dy", "dz", "ex", "ey", "ez")


def rodrigues(v: np.ndarray) -> np.ndarray:
    """Exact rotation matrix of the rotation vector ``v`` (rad)."""
    th = float(np.linalg.norm(v))
    if th < 1e-300:
        return np.eye(3)
    k = v / th
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(th) * K + (1.0 - np.cos(th)) * (K @ K)


def hom(R: np.ndarray, d: np.ndarray) -> np.ndarray:
    """4x4 homogeneous transform x -> R x + d."""
    H = np.eye(4)
    H[:3, :3] = R
    H[:3, 3] = d
    return H


@dataclass
class Bumps:
    """f(p) = slope (p - ref) + sum a_k exp(-((p - c_k) / w_k)^2) - f0 (zero at ref)."""
    ref: float
    slope: float = 0.0
    a: np.ndarray = field(default_factory=lambda: np.zeros(0))
    c: np.ndarray = field(default_factory=lambda: np.zeros(0))
    w: np.ndarray = field(default_factory=lambda: np.ones(0))
    line: tuple[float, float] = (0.0, 0.0)     # a removed least-squares line (b0 + b1 p)

    def raw(self, p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, float)
        out = self.slope * (p - self.ref)
        for a, c, w in zip(self.a, self.c, self.w):
            out = out + a * np.exp(-((p - c) / w) ** 2)
        return out - (self.line[0] + self.line[1] * p)

    def __call__(self, p: np.ndarray) -> np.ndarray:
        return self.raw(p) - self.raw(np.array([self.ref]))[0]


@dataclass
class Machine:
    """A three-axis machine: travels, reference point, error motions, effects."""
    travel: dict[str, tuple[float, float]]
    ref: np.ndarray                              # reference point (mm)
    motions: dict[str, dict[str, Bumps]]         # axis -> term -> function (um / urad)
    tool_mm: np.ndarray                          # the true tool offset (mm)
    squareness_urad: dict[str, float] = field(default_factory=lambda: {"xy": 0.0, "xz": 0.0, "yz": 0.0})

    def motion(self, axis: str, term: str, p: np.ndarray) -> np.ndarray:
        return self.motions[axis][term](p)

    def error_um(self, pos_mm: np.ndarray, tool_mm: np.ndarray | None = None) -> np.ndarray:
        """Tool tip relative to the workpiece at the axis positions ``pos_mm`` (n x 3), um.

        Exact transforms of the error motions; (x, y, z) = position - reference.
        """
        pos = np.atleast_2d(np.asarray(pos_mm, float))
        t = self.tool_mm if tool_mm is None else np.asarray(tool_mm, float)
        out = np.empty((len(pos), 3))
        um = 1e-3
        ur = 1e-6
        sq = self.squareness_urad
        for i, q in enumerate(pos):
            x, y, z = q - self.ref
            ev = {a: np.array([float(self.motions[a][k](np.array([q[j]]))[0]) for k in TERMS])
                  for j, a in enumerate(AXES)}
            # workpiece side, X carriage: lever from its centre to the point under the tool
            lever_x = np.array([-x, -y, z]) + t
            TX = hom(rodrigues(ev["X"][3:] * ur), ev["X"][:3] * um)
            # displacement of the point by X: T_X(c + r) - (c + r) with c the centre
            rX = np.append(lever_x, 1.0)
            moved_x = (TX @ rX)[:3] - lever_x
            lever_y = np.array([0.0, -y, z]) + t
            TY = hom(rodrigues(ev["Y"][3:] * ur), ev["Y"][:3] * um)
            rY = np.append(lever_y + moved_x, 1.0)
            moved_w = (TY @ rY)[:3] - lever_y
            # Y's direction tilted by S_xy: the carriage moves the workpiece by -y along it
            moved_w = moved_w + (-y) * np.array([sq["xy"] * ur, 0.0, 0.0])
            # tool side, Z carriage about the spindle reference point; Z's direction tilted
            TZ = hom(rodrigues(ev["Z"][3:] * ur), ev["Z"][:3] * um)
            moved_t = (TZ @ np.append(t, 1.0))[:3] - t
            moved_t = moved_t + z * np.array([-sq["xz"] * ur, -sq["yz"] * ur, 0.0])
            out[i] = (moved_t - moved_w) / um
        return out


def random_machine(rng: np.random.Generator, tool_mm: np.ndarray) -> tuple[Machine, dict[str, np.ndarray]]:
    """A machine with smooth random error motions and the fit's laser targets per axis."""
    lx = float(rng.uniform(400, 800))
    ly = float(rng.uniform(300, 600))
    lz = float(rng.uniform(250, 450))
    x0 = float(np.round(rng.uniform(-50, 50), 1))
    travel = {"X": (x0, x0 + lx), "Y": (-ly, 0.0), "Z": (-lz, 0.0)}
    ref = np.array([rng.uniform(lo + 0.3 * (hi - lo), lo + 0.7 * (hi - lo))
                    for lo, hi in travel.values()])
    ref = np.round(ref, 3)
    targets: dict[str, np.ndarray] = {}
    motions: dict[str, dict[str, Bumps]] = {}
    for j, a in enumerate(AXES):
        lo, hi = travel[a]
        n = int(rng.integers(11, 22))
        base = np.linspace(lo, hi, n)
        jitter = rng.uniform(-0.3, 0.3, n) * (hi - lo) / (n - 1)
        jitter[0] = jitter[-1] = 0.0
        tg = np.round(np.sort(base + jitter), 3)
        # the reference coordinate must lie inside the measured targets (docs/formats.md)
        targets[a] = tg
        own = TERMS[j]
        motions[a] = {}
        for k in TERMS:
            nb = int(rng.integers(2, 5))
            ang = k.startswith("e")
            amp = rng.uniform(1.0, 6.0) if ang else (rng.uniform(1.0, 4.0) if k == own else rng.uniform(0.5, 3.0))
            f = Bumps(ref=float(ref[j]),
                      slope=float(rng.normal(0, 5e-3)) if k == own else 0.0,
                      a=rng.normal(0, amp, nb), c=rng.uniform(lo, hi, nb),
                      w=rng.uniform(0.2, 0.6, nb) * (hi - lo))
            if not ang and k != own:
                # straightness: no slope over the targets (it would be squareness)
                v = f.raw(tg)
                b1, b0 = np.polyfit(tg, v, 1)
                f.line = (float(b0), float(b1))
            motions[a][k] = f
    return Machine(travel=travel, ref=ref, motions=motions, tool_mm=np.asarray(tool_mm, float)), targets
