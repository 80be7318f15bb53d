"""The five-axis error model of a table-table (trunnion) machine: exact and linearised.

Geometry (docs/concepts.md, "Five-axis machines"): the workpiece sits on a
rotary table C, carried by a tilting trunnion A (LinuxCNC ``xyzac-trt``) or B
(``xyzbc-trt``); the linear axes X, Y, Z carry the tool. In LinuxCNC's trt
terms the C axis centre is the rotation point ``(x, y, z)-rot-point`` and the
tilt axis passes through the rotation point plus the offsets (``y-offset``,
``z-offset`` for A, ``x-offset``, ``z-offset`` for B). A workpiece point ``w``
(mm, workpiece coordinates = machine coordinates at A = C = 0) is at machine
position ``T_tilt(a) T_C(c) w``; tool-centre-point control puts the tool tip at
that position.

Errors (ISO 230-1 / 230-7 notation; linear errors um, angles urad):

* location errors of each axis average line (:data:`LOCATION_ERRORS`):
  position (``EX0C``, ``EY0C``), orientation (``EA0C``, ``EB0C``) and angular
  zero (``EC0C``); the line is moved as a rigid body about its nominal pivot:
  ``T_R(t) = Tr(P) D E(t) Rot(t + E0) D^-1 Tr(-P)``, ``D = Tr(delta) Rot(phi)``;
* error motions (:data:`MOTIONS`, ``EXC(C)`` .. ``ECC(C)``): a small rigid
  motion ``E(t) = Tr(EXC, EYC, EZC) Rot(EAC, EBC, ECC)`` at the pivot, in the
  carrying frame, each a Fourier series in the angle of period 360 degrees
  (the fit's Fourier block, :func:`abbe.model.table.basis_matrix`);
* the linear axes: a 3-axis :class:`abbe.model.table.Table` through Eq. 3
  (:func:`abbe.model.reference.all_terms`, :func:`combine_eq3`) plus the
  squareness of the five-axis fit; the tool's orientation error is
  ``E_Z(e) - E_X(e) - E_Y(e)`` (the tool lever terms of Eq. 3).

The error of the tool relative to the workpiece, in machine coordinates at the
commanded point, is position ``p_tool,actual - T_act T_nom^-1 p_tool,nominal``
(um) and orientation ``rotvec(R_tool R_nom R_act^T)`` (urad) - what a compensation
must take away. :func:`tool_error_exact` evaluates it with homogeneous
transforms (small rotations as ``Rx Ry Rz`` products); :func:`tool_error_linear`
is its first-order form (the five-axis analogue of Eq. 3; checked symbolically
in tests/model/test_five_axis.py). :func:`linearisation_bound` measures their
difference over a travel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from abbe.model.chain import nominal_joints as _chain_joints
from abbe.model.chain import tool_error_exact as _chain_exact
from abbe.model.chain import trunnion_chain, workpiece_transform
from abbe.model.five_axis_base import (  # noqa: F401  (re-exported: the public names)
    KINEMATICS,
    AXIS_DIRECTION,
    LOCATION_ERRORS,
    MOTION_COMPONENTS,
    SQUARENESS,
    lowest_harmonic,
    motion_name,
    TrunnionGeometry,
    FiveAxisErrors,
    fourier_rows,
    motion_values,
    _loc,
    _rot,
    _rx,
    _ry,
    _rz,
    _ROT,
    small_rotation,
    _homog,
    _trans,
    linear_axis_errors,
    rotvec,
)


def axis_transform(geom: TrunnionGeometry, errs: FiveAxisErrors | None, axis: str,
                   angle_deg: np.ndarray) -> np.ndarray:
    """(N, 4, 4) transform of ``axis`` at ``angle_deg`` (child -> carrying frame), mm.

    ``errs`` None = nominal. ``Tr(P) D E(t) Rot(t + E0) D^-1 Tr(-P)``.
    """
    t = np.deg2rad(np.asarray(angle_deg, dtype=np.float64).reshape(-1))
    n = t.size
    P = geom.pivot(axis)
    if errs is None:
        rot = _homog(_ROT[axis](t), np.zeros((n, 3)))
        return _trans(P, n) @ rot @ _trans(-P, n)
    delta, phi, zero = _loc(errs, axis)
    rot = _homog(_ROT[axis](t + zero * 1e-6), np.zeros((n, 3)))
    D = _trans(delta * 1e-3, 1) @ _homog(small_rotation(phi * 1e-6), np.zeros((1, 3)))
    Dinv = np.linalg.inv(D)
    m = motion_values(errs, axis, angle_deg)
    E = _homog(small_rotation(m[:, 3:] * 1e-6), m[:, :3] * 1e-3)
    return _trans(P, n) @ D @ E @ rot @ Dinv @ _trans(-P, n)


def table_transform(geom: TrunnionGeometry, errs: FiveAxisErrors | None,
                    angles_deg: np.ndarray) -> np.ndarray:
    """(N, 4, 4) workpiece -> machine transform at angles (N, 2) = (tilt, C) degrees."""
    # The trunnion is one instance of the kinematic chain (C on the tilt axis, then X Y Z):
    # the chain's arithmetic is this model's, operation for operation (the same bits).
    return workpiece_transform(trunnion_chain(geom), errs, angles_deg)


def nominal_joints(geom: TrunnionGeometry, work_mm: np.ndarray, angles_deg: np.ndarray) -> np.ndarray:
    """(N, 3) machine positions (mm) of workpiece points under tool-centre-point control."""
    return _chain_joints(trunnion_chain(geom), work_mm, angles_deg)


def tool_error_exact(geom: TrunnionGeometry, errs: FiveAxisErrors, pos_mm: np.ndarray,
                     angles_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact error of the tool relative to the workpiece at machine positions (N, 3) mm
    and angles (N, 2) deg: position (N, 3) um, orientation (N, 3) urad, machine frame."""
    return _chain_exact(trunnion_chain(geom), errs, pos_mm, angles_deg)


# ------------------------------------------------------------------- linearised


def axis_twist(geom: TrunnionGeometry, errs: FiveAxisErrors, axis: str, angle_deg: np.ndarray,
               point_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First-order displacement (um) and rotation (urad) of a point carried by ``axis``.

    ``point_mm`` (N, 3): the point in the carrying frame after the nominal
    rotation. Displacement ``(I - R) delta + w x (p - P) + t``, rotation
    ``w = phi - R phi + E0 k + r`` (docs/concepts.md derives it).
    """
    t = np.deg2rad(np.asarray(angle_deg, dtype=np.float64).reshape(-1))
    R = _ROT[axis](t)
    delta, phi, zero = _loc(errs, axis)
    m = motion_values(errs, axis, angle_deg)
    k = np.asarray(AXIS_DIRECTION[axis])
    w = phi[None, :] - R @ phi + zero * k[None, :] + m[:, 3:]
    lever = (np.asarray(point_mm, dtype=np.float64).reshape(-1, 3) - geom.pivot(axis)) * 1e-3
    d = delta[None, :] - R @ delta + np.cross(w, lever) + m[:, :3]
    return d, w


def tool_error_linear(geom: TrunnionGeometry, errs: FiveAxisErrors, pos_mm: np.ndarray,
                      angles_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First-order :func:`tool_error_exact`: position um, orientation urad (N, 3 each).

    ``E = e_tool - R_tilt d_C - d_tilt``, ``w = w_tool - R_tilt w_C - w_tilt`` with
    the twists of :func:`axis_twist` (C's at the point before the tilt rotation).
    """
    q = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
    ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)
    tilt, table = geom.rotaries
    Rt = _ROT[tilt](np.deg2rad(ang[:, 0]))
    Pt = geom.pivot(tilt)
    inner = np.einsum("nji,nj->ni", Rt, q - Pt) + Pt  # R_tilt^T (q - P) + P
    dc, wc = axis_twist(geom, errs, table, ang[:, 1], inner)
    dt, wt = axis_twist(geom, errs, tilt, ang[:, 0], q)
    dl, rl = linear_axis_errors(geom, errs, q)
    pos = dl - np.einsum("nij,nj->ni", Rt, dc) - dt
    rot = rl - np.einsum("nij,nj->ni", Rt, wc) - wt
    return pos, rot


@dataclass(frozen=True)
class LinearisationBound:
    """Largest |exact - linear| over a travel grid for errors of a given size."""

    position_um: float
    orientation_urad: float
    n_points: int
    location_um: float
    location_urad: float

    def to_json(self) -> dict[str, float | int]:
        return {"position_um": self.position_um, "orientation_urad": self.orientation_urad,
                "n_points": self.n_points, "location_um": self.location_um,
                "location_urad": self.location_urad}


def linearisation_bound(geom: TrunnionGeometry, errs: FiveAxisErrors, work_box_mm: np.ndarray,
                        n: int = 9) -> LinearisationBound:
    """Max |exact - linear| for ``errs`` over the rotary travel (n x n angles) and the
    corners of the workpiece box ``work_box_mm`` ((2, 3): min, max corner, mm)."""
    tilt, table = geom.rotaries
    ta = np.linspace(*geom.travel_deg[tilt], n)
    tc = np.linspace(*geom.travel_deg[table], n)
    box = np.asarray(work_box_mm, dtype=np.float64)
    corners = np.array([[box[i, 0], box[j, 1], box[k, 2]] for i in (0, 1) for j in (0, 1)
                        for k in (0, 1)])
    A, C, W = np.meshgrid(ta, tc, np.arange(len(corners)), indexing="ij")
    ang = np.column_stack([A.ravel(), C.ravel()])
    w = corners[W.ravel()]
    q = nominal_joints(geom, w, ang)
    pe, re = tool_error_exact(geom, errs, q, ang)
    pl, rl = tool_error_linear(geom, errs, q, ang)
    lin = [abs(v) for k, v in errs.location.items() if k[1] in "XYZ"]
    ang_ = [abs(v) for k, v in errs.location.items() if k[1] in "ABC"]
    return LinearisationBound(float(np.max(np.abs(pe - pl))), float(np.max(np.abs(re - rl))),
                              len(q), max(lin, default=0.0), max(ang_, default=0.0))
