"""Judge a fitted five-axis table against the independent generator's truth (issue 33).

The table (``model_five.bin`` written by ``abbe fit``, never the truth) is evaluated by the
C library (``abbe.model.clib.CFiveModel``, ``abbe_five_error_eval_f32``) at poses outside
the measurement plan: random workpiece points on the table and random tilt / C angles.
The truth is the generator's own kinematics (``cases.five_axis_independent.Campaign``:
Rodrigues about its actual axis lines): at joints ``q`` (mm) and angles, the workpiece
point nominally at the tool is ``w = T_nom^-1 q`` and actually at ``T_act w``, so the tool
tip's true error relative to the workpiece is ``E = q - T_act w`` (um; the generator has
no linear-axis errors). The compensated residual is ``E - E_table``.

No measurement plan of a single sphere with an unknown place can see where the workpiece
sits on the table: a rigid placement of it (``G``: rotation ``omega``, translation ``tau``
in workpiece coordinates) moves ``T_act w`` by ``R (omega x w + tau)`` to first order, and a
workpiece datum (probing the part) absorbs it. So the residual is judged after the best
such placement is fitted out (6 unknowns, linear least squares over every pose), and the
uncompensated error the same way. Units: mm in, um out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cases.five_axis_independent import Campaign, rodrigues


@dataclass
class Heldout:
    """Tool tip position errors at held-out poses (um): uncompensated RMS raw and with the
    best rigid workpiece placement fitted out, the same of what the table leaves; the
    poses' count."""

    uncompensated_rms_um: float
    uncompensated_rigid_rms_um: float
    residual_rms_um: float
    residual_rigid_rms_um: float
    poses: int

    @property
    def ratio(self) -> float:
        """What the table leaves (placement out) over the uncompensated error (raw RMS)."""
        return self.residual_rigid_rms_um / self.uncompensated_rms_um


def poses(camp: Campaign, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` held-out poses: workpiece points (N, 3) mm in a cylinder of 150 mm radius,
    0..150 mm above the C axis' centre, and angles (N, 2) deg (tilt within +-80 deg, C
    anywhere): not the plan's grid (4 tilts x 8 C angles, one sphere)."""
    rng = np.random.default_rng(1_000_003 + seed)
    r = 150.0 * np.sqrt(rng.uniform(0.0, 1.0, n))
    u = rng.uniform(0.0, 2.0 * math.pi, n)
    w = camp.pivot_c + np.column_stack([r * np.cos(u), r * np.sin(u), rng.uniform(0.0, 150.0, n)])
    ang = np.column_stack([rng.uniform(-80.0, 80.0, n), rng.uniform(0.0, 360.0, n)])
    return w, ang


def true_errors(camp: Campaign, w: np.ndarray, ang: np.ndarray, t_s: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(joints q (N, 3) mm, true tool tip error (N, 3) um, nominal rotations (N, 3, 3))."""
    q = np.array([camp.nominal(wi, a, c) for wi, (a, c) in zip(w, ang)])
    act = np.array([camp.actual(wi, a, c, t_s) for wi, (a, c) in zip(w, ang)])
    kt = np.eye(3)[0 if camp.tilt == "A" else 1]
    R = np.array([rodrigues(kt, math.radians(a)) @ rodrigues(np.array([0.0, 0.0, 1.0]),
                                                             math.radians(c)) for a, c in ang])
    return q, (q - act) * 1e3, R


def rigid_residual(d_um: np.ndarray, w: np.ndarray, R: np.ndarray, centre: np.ndarray
                   ) -> np.ndarray:
    """``d`` less its best fit by a rigid placement of the workpiece (module docstring):
    ``R_i (omega x (w_i - centre) + tau)``, least squares over every pose."""
    v = w - centre
    A = np.zeros((len(w), 3, 6))
    skew = np.zeros((len(w), 3, 3))  # omega x v = -[v]x omega
    skew[:, 0, 1], skew[:, 0, 2] = v[:, 2], -v[:, 1]
    skew[:, 1, 0], skew[:, 1, 2] = -v[:, 2], v[:, 0]
    skew[:, 2, 0], skew[:, 2, 1] = v[:, 1], -v[:, 0]
    A[:, :, :3] = R @ skew
    A[:, :, 3:] = R
    A2 = A.reshape(-1, 6)
    sol, *_ = np.linalg.lstsq(A2, d_um.reshape(-1), rcond=None)
    return (d_um.reshape(-1) - A2 @ sol).reshape(-1, 3)


def rms(r: np.ndarray) -> float:
    """RMS 3-D length (um)."""
    return float(np.sqrt(np.mean(np.sum(r ** 2, axis=1))))


def judge(camp: Campaign, blob: bytes, n: int = 200, seed: int = 0, t_s: float = 900.0
          ) -> Heldout:
    """The fitted table ``blob`` through the C library against the campaign's truth at ``n``
    held-out poses, at campaign time ``t_s`` (the generator's pivot drifts)."""
    from abbe.model.clib import CFiveModel

    w, ang = poses(camp, n, seed)
    q, e_true, R = true_errors(camp, w, ang, t_s)
    e_table = CFiveModel(blob).error_f32(q, ang)[0]
    left = e_true - e_table
    return Heldout(rms(e_true), rms(rigid_residual(e_true, w, R, camp.pivot_c)), rms(left),
                   rms(rigid_residual(left, w, R, camp.pivot_c)), n)
