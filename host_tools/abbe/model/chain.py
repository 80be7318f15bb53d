"""One kinematic chain for every five-axis kind: exact and linearised error model.

The chain (docs/concepts.md, "Five-axis machines: the kinematic chain"; the machine
file's ``[chain]``, docs/formats.md) lists the axes in ISO 230-1 / ISO 10791-1 style
from the workpiece to the tool: the three linear axes as one contiguous block and two
rotary axes, each rotary axis before the block on the workpiece side (it carries the
workpiece), each after it on the tool side (it carries the spindle). Every rotary axis
has a name (A about X, B about Y, C about Z), a nominal direction (+1 or -1 along its
machine axis: LinuxCNC's maxkins turns B the other way) and a pivot: a point of its
nominal line in machine coordinates with every axis at zero, where the controlled
point (the tool tip the controller programs, at zero rotary angles) is the machine
origin of the tool side. A tool-side pivot therefore travels with the linear axes:
at machine position ``q`` the line passes through ``q + pivot``.

Kinds: ``table-table`` (both rotaries on the workpiece side: LinuxCNC ``xyzac-trt``,
``xyzbc-trt``, ``xyzab-tdr``), ``head-head`` (both on the tool side: ``5axiskins``),
``head-table`` (one each: ``maxkins``).

Angles are given as (N, 2) arrays with the rotary axes in alphabetical order (A before
B before C): (A, C) and (B, C) for the trunnions, as :mod:`abbe.model.five_axis` has them.

Transforms (mm): an axis at angle t moves what it carries by
``Tr(P) D E(t) Rot_i(s t + E0) D^-1 Tr(-P)`` (the trunnion model's formula, with s the
direction's sign; ``E0`` and every location error are about and along the positive
machine axes, so ISO 230-7's names keep their meaning whatever the direction). The
workpiece point w sits at ``T_W(angles) w`` with ``T_W = T_outer ... T_inner`` (the axis
next to the workpiece applied first); the tool tip at ``q + T_T(angles) tip`` with
``T_T = T_first ... T_last`` (the axis next to the tool applied first), ``tip`` (mm) the
tool tip relative to the controlled point at zero angles (0 for the tool the controller
programs; a longer stylus or an R-test nest further down is ``(0, 0, -extra)``).
Tool-centre-point control: ``q = T_W,nom w - T_T,nom tip``.

The error of the tool relative to the workpiece (the trunnion model's definition, in
machine coordinates at the commanded point): ``p_tool,act - T_W,act T_W,nom^-1 p_tool,nom``
(um) and ``rotvec(R_tool,act R_tool,nom^T R_M^T)`` (urad), where the linear axes add their
position error at q and their orientation error turns the tool side about q
(:func:`abbe.model.five_axis.linear_axis_errors`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from abbe.model.five_axis_base import (AXIS_DIRECTION, LOCATION_ERRORS, FiveAxisErrors,
                                  TrunnionGeometry, _homog, _loc, _trans, linear_axis_errors,
                                  motion_values, rotvec, small_rotation)

#: The linear axes and the rotary axis names with the machine axis each turns about.
LINEAR_AXES: tuple[str, str, str] = ("X", "Y", "Z")
ROTARY_MACHINE_AXIS: dict[str, int] = {"A": 0, "B": 1, "C": 2}
#: Kinds of chain by where its two rotary axes sit.
KINDS: tuple[str, str, str] = ("table-table", "head-table", "head-head")


@dataclass(frozen=True)
class ChainAxis:
    """One axis of the chain: ``name`` (X Y Z A B C), ``direction`` (+1 / -1 along the
    machine axis it moves along or turns about), for a rotary axis its ``pivot_mm``
    (machine coordinates, all axes at zero; tool side relative to the controlled point)
    and ``travel`` (deg for a rotary axis, mm for a linear one)."""

    name: str
    direction: int = 1
    pivot_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    travel: tuple[float, float] = (-360.0, 360.0)

    @property
    def rotary(self) -> bool:
        return self.name in ROTARY_MACHINE_AXIS


@dataclass(frozen=True)
class KinematicChain:
    """A five-axis machine as a chain of axes from the workpiece to the tool (see module).

    name: a label (``xyzac-trt``, ``5axiskins`` ...); axes: the five axes, workpiece
    first; tool_length_mm: the Abbe lever of the linear axes' angular errors (mm);
    reference_mm: the point the squareness of the linear axes is taken about (mm;
    the trunnions' rotation point).
    """

    name: str
    axes: tuple[ChainAxis, ...]
    tool_length_mm: float = 0.0
    reference_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        problem = chain_problem([a.name for a in self.axes])
        if problem:
            raise ValueError(problem)
        for a in self.axes:
            if a.direction not in (1, -1):
                raise ValueError(f"axis {a.name}: direction must be +1 or -1, got {a.direction}")

    # -------------------------------------------------------------- structure

    @property
    def _first_linear(self) -> int:
        return min(i for i, a in enumerate(self.axes) if not a.rotary)

    @property
    def workpiece_side(self) -> tuple[str, ...]:
        """Rotary axes carrying the workpiece, the one next to the workpiece first."""
        return tuple(a.name for a in self.axes[: self._first_linear])

    @property
    def tool_side(self) -> tuple[str, ...]:
        """Rotary axes carrying the tool, the one next to the linear axes first."""
        return tuple(a.name for a in self.axes[self._first_linear + 3:])

    @property
    def rotaries(self) -> tuple[str, str]:
        """The two rotary axes in the angle columns' order (alphabetical)."""
        r = sorted(a.name for a in self.axes if a.rotary)
        return (r[0], r[1])

    @property
    def kind(self) -> str:
        n = len(self.workpiece_side)
        return {2: "table-table", 1: "head-table", 0: "head-head"}[n]

    @property
    def rot_point_mm(self) -> tuple[float, float, float]:
        """Alias of ``reference_mm`` (what :func:`linear_axis_errors` reads)."""
        return self.reference_mm

    @property
    def travel_deg(self) -> dict[str, tuple[float, float]]:
        return {a.name: a.travel for a in self.axes if a.rotary}

    def axis(self, name: str) -> ChainAxis:
        return next(a for a in self.axes if a.name == name)

    def side(self, name: str) -> str:
        """``workpiece`` or ``tool``."""
        return "workpiece" if name in self.workpiece_side else "tool"

    def pivot(self, name: str) -> np.ndarray:
        return np.asarray(self.axis(name).pivot_mm, dtype=np.float64)

    def location_names(self) -> tuple[str, ...]:
        """ISO 230-7 names of the chain's location errors (10), angle-column order."""
        return tuple(n for ax in self.rotaries for n in LOCATION_ERRORS[ax])


def chain_problem(names: list[str]) -> str:
    """Why a list of axis names (workpiece to tool) is not a five-axis chain, or ""."""
    if sorted(n for n in names if n in LINEAR_AXES) != list(LINEAR_AXES) \
            or len([n for n in names if n in LINEAR_AXES]) != 3:
        return "expected each of X, Y, Z exactly once"
    rot = [n for n in names if n in ROTARY_MACHINE_AXIS]
    if len(rot) != 2 or rot[0] == rot[1]:
        return "expected two different rotary axes (A, B or C)"
    if len(names) != 5 or any(n not in LINEAR_AXES and n not in ROTARY_MACHINE_AXIS for n in names):
        return "expected five axes: X, Y, Z and two of A, B, C"
    idx = [i for i, n in enumerate(names) if n in LINEAR_AXES]
    if idx != list(range(idx[0], idx[0] + 3)):
        return ("expected the linear axes X, Y, Z next to each other (rotary axes before "
                "them carry the workpiece, after them the tool)")
    return ""


def trunnion_chain(geom: TrunnionGeometry) -> KinematicChain:
    """The chain of a LinuxCNC trt machine: workpiece on C, C on the tilt axis, then X Y Z."""
    tilt, table = geom.rotaries
    p_c = tuple(float(v) for v in geom.pivot(table))
    p_t = tuple(float(v) for v in geom.pivot(tilt))
    return KinematicChain(
        geom.kind,
        (ChainAxis(table, 1, p_c, geom.travel_deg[table]),  # type: ignore[arg-type]
         ChainAxis(tilt, 1, p_t, geom.travel_deg[tilt]),  # type: ignore[arg-type]
         ChainAxis("X", 1, (0.0, 0.0, 0.0), (0.0, 0.0)),  # linear travel: [axes.*]
         ChainAxis("Y", 1, (0.0, 0.0, 0.0), (0.0, 0.0)),
         ChainAxis("Z", 1, (0.0, 0.0, 0.0), (0.0, 0.0))),
        geom.tool_length_mm, tuple(float(v) for v in geom.rot_point_mm))  # type: ignore[arg-type]


# ---------------------------------------------------------------- exact (homogeneous)


def _rot_i(t: np.ndarray, i: int) -> np.ndarray:
    """(N, 3, 3) rotations by ``t`` (rad) about machine axis ``i`` (0 x, 1 y, 2 z)."""
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    c, s = np.cos(t), np.sin(t)
    j, k = (i + 1) % 3, (i + 2) % 3
    R = np.zeros((t.size, 3, 3))
    R[:, i, i] = 1.0
    R[:, j, j] = c
    R[:, k, k] = c
    R[:, j, k] = -s
    R[:, k, j] = s
    return R


def axis_transform(chain: KinematicChain, errs: FiveAxisErrors | None, name: str,
                   angle_deg: np.ndarray) -> np.ndarray:
    """(N, 4, 4) transform of rotary axis ``name`` at ``angle_deg`` (child -> carrying frame).

    ``Tr(P) D E(t) Rot(s t + E0) D^-1 Tr(-P)``; ``errs`` None = nominal. With s = +1 the
    arithmetic is the trunnion model's, operation for operation (the same bits)."""
    ax = chain.axis(name)
    i = ROTARY_MACHINE_AXIS[name]
    t = np.deg2rad(np.asarray(angle_deg, dtype=np.float64).reshape(-1))
    if ax.direction != 1:
        t = -t
    n = t.size
    P = chain.pivot(name)
    if errs is None:
        rot = _homog(_rot_i(t, i), np.zeros((n, 3)))
        return _trans(P, n) @ rot @ _trans(-P, n)
    delta, phi, zero = _loc(errs, name)
    rot = _homog(_rot_i(t + zero * 1e-6, i), np.zeros((n, 3)))
    D = _trans(delta * 1e-3, 1) @ _homog(small_rotation(phi * 1e-6), np.zeros((1, 3)))
    Dinv = np.linalg.inv(D)
    m = motion_values(errs, name, angle_deg)
    E = _homog(small_rotation(m[:, 3:] * 1e-6), m[:, :3] * 1e-3)
    return _trans(P, n) @ D @ E @ rot @ Dinv @ _trans(-P, n)


def _angle_columns(chain: KinematicChain, angles_deg: np.ndarray) -> dict[str, np.ndarray]:
    ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)
    r = chain.rotaries
    return {r[0]: ang[:, 0], r[1]: ang[:, 1]}


def workpiece_transform(chain: KinematicChain, errs: FiveAxisErrors | None,
                        angles_deg: np.ndarray) -> np.ndarray:
    """(N, 4, 4) workpiece -> machine frame (identity for a head-head chain)."""
    cols = _angle_columns(chain, angles_deg)
    n = next(iter(cols.values())).size
    T = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    side = chain.workpiece_side
    if not side:
        return T
    T = axis_transform(chain, errs, side[-1], cols[side[-1]])
    for name in reversed(side[:-1]):  # outer first: T_outer @ ... @ T_inner
        T = T @ axis_transform(chain, errs, name, cols[name])
    return T


def tool_transform(chain: KinematicChain, errs: FiveAxisErrors | None,
                   angles_deg: np.ndarray) -> np.ndarray:
    """(N, 4, 4) tool frame -> frame of the linear axes, relative to the controlled point
    (identity for a table-table chain)."""
    cols = _angle_columns(chain, angles_deg)
    n = next(iter(cols.values())).size
    T = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    for name in chain.tool_side:  # T_first @ ... @ T_last
        T = T @ axis_transform(chain, errs, name, cols[name])
    return T


def _apply(T: np.ndarray, p: np.ndarray) -> np.ndarray:
    return np.einsum("nij,nj->ni", T[:, :3, :3], p) + T[:, :3, 3]


def nominal_joints(chain: KinematicChain, work_mm: np.ndarray, angles_deg: np.ndarray,
                   tip_mm: np.ndarray | tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """(N, 3) machine positions (mm) putting the tool tip ``tip_mm`` on workpiece points
    under tool-centre-point control: ``T_W,nom w - T_T,nom tip``."""
    w = np.asarray(work_mm, dtype=np.float64).reshape(-1, 3)
    Tw = workpiece_transform(chain, None, angles_deg)
    Tt = tool_transform(chain, None, angles_deg)
    tip = np.broadcast_to(np.asarray(tip_mm, dtype=np.float64), w.shape)
    return _apply(Tw, w) - _apply(Tt, tip)


def tool_tip(chain: KinematicChain, errs: FiveAxisErrors | None, pos_mm: np.ndarray,
             angles_deg: np.ndarray,
             tip_mm: np.ndarray | tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """(N, 3) machine position (mm) of the tool tip at machine positions ``pos_mm``:
    ``q + e_lin(q) + R_lin T_T tip`` (``errs`` None: nominal, ``q + T_T,nom tip``)."""
    q = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
    tip = np.broadcast_to(np.asarray(tip_mm, dtype=np.float64), q.shape)
    Tt = tool_transform(chain, errs, angles_deg)
    if errs is None:
        return q + _apply(Tt, tip)
    dl, rl = linear_axis_errors(chain, errs, q)  # type: ignore[arg-type]
    return q + dl * 1e-3 + np.einsum("nij,nj->ni", small_rotation(rl * 1e-6), _apply(Tt, tip))


def tool_error_exact(chain: KinematicChain, errs: FiveAxisErrors, pos_mm: np.ndarray,
                     angles_deg: np.ndarray,
                     tip_mm: np.ndarray | tuple[float, float, float] = (0.0, 0.0, 0.0)
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Exact error of the tool relative to the workpiece at machine positions (N, 3) mm
    and angles (N, 2) deg: position (N, 3) um, orientation (N, 3) urad, machine frame."""
    q = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
    tip = np.broadcast_to(np.asarray(tip_mm, dtype=np.float64), q.shape)
    Ta = workpiece_transform(chain, errs, angles_deg)
    Tn = workpiece_transform(chain, None, angles_deg)
    M = Ta @ np.linalg.inv(Tn)
    Tta = tool_transform(chain, errs, angles_deg)
    Ttn = tool_transform(chain, None, angles_deg)
    dl, rl = linear_axis_errors(chain, errs, q)  # type: ignore[arg-type]
    Rl = small_rotation(rl * 1e-6)
    p_nom = q + _apply(Ttn, tip)
    p_act = q + dl * 1e-3 + np.einsum("nij,nj->ni", Rl, _apply(Tta, tip))
    moved = np.einsum("nij,nj->ni", M[:, :3, :3], p_nom) + M[:, :3, 3]
    Rtool = Rl @ Tta[:, :3, :3] @ np.transpose(Ttn[:, :3, :3], (0, 2, 1))
    Rrel = Rtool @ np.transpose(M[:, :3, :3], (0, 2, 1))
    return (p_act - moved) * 1e3, rotvec(Rrel) * 1e6


# ------------------------------------------------------------------- linearised


def axis_twist(chain: KinematicChain, errs: FiveAxisErrors, name: str, angle_deg: np.ndarray,
               point_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First-order displacement (um) and rotation (urad) of a point carried by ``name``.

    ``point_mm`` (N, 3): the point in the carrying frame after the nominal rotation.
    ``d = (I - R) delta + w x (p - P) + t``, ``w = phi - R phi + E0 k + r`` with R the
    nominal rotation (direction included) and k the positive machine axis."""
    i = ROTARY_MACHINE_AXIS[name]
    t = np.deg2rad(np.asarray(angle_deg, dtype=np.float64).reshape(-1)) * chain.axis(name).direction
    R = _rot_i(t, i)
    delta, phi, zero = _loc(errs, name)
    m = motion_values(errs, name, angle_deg)
    k = np.asarray(AXIS_DIRECTION[name])
    w = phi[None, :] - R @ phi + zero * k[None, :] + m[:, 3:]
    lever = (np.asarray(point_mm, dtype=np.float64).reshape(-1, 3) - chain.pivot(name)) * 1e-3
    d = delta[None, :] - R @ delta + np.cross(w, lever) + m[:, :3]
    return d, w


def _side_twist(chain: KinematicChain, errs: FiveAxisErrors, order: tuple[str, ...],
                cols: dict[str, np.ndarray], point: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First-order displacement / rotation of ``point`` carried by the axes ``order``
    (outermost first): ``sum R_outer d_i(x_i)``, ``x_i`` the point after the nominal
    transforms of axis i and the axes it carries."""
    n = point.shape[0]
    d_sum, w_sum = np.zeros((n, 3)), np.zeros((n, 3))
    R_outer = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    for j, name in enumerate(order):
        x = point
        for inner in reversed(order[j:]):  # innermost applied first, then up to axis j
            x = _apply(axis_transform(chain, None, inner, cols[inner]), x)
        d, w = axis_twist(chain, errs, name, cols[name], x)
        d_sum += np.einsum("nij,nj->ni", R_outer, d)
        w_sum += np.einsum("nij,nj->ni", R_outer, w)
        R_outer = R_outer @ axis_transform(chain, None, name, cols[name])[:, :3, :3]
    return d_sum, w_sum


def tool_error_linear(chain: KinematicChain, errs: FiveAxisErrors, pos_mm: np.ndarray,
                      angles_deg: np.ndarray,
                      tip_mm: np.ndarray | tuple[float, float, float] = (0.0, 0.0, 0.0)
                      ) -> tuple[np.ndarray, np.ndarray]:
    """First-order :func:`tool_error_exact`: position um, orientation urad (N, 3 each).

    ``E = e_lin + r_lin x (T_T,nom tip) + d_T - d_W``, ``W = r_lin + w_T - w_W``: the
    tool side's and the workpiece side's twists summed outermost first."""
    q = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
    tip = np.broadcast_to(np.asarray(tip_mm, dtype=np.float64), q.shape).copy()
    cols = _angle_columns(chain, angles_deg)
    Tw = workpiece_transform(chain, None, angles_deg)
    w_pt = np.einsum("nji,nj->ni", Tw[:, :3, :3], q + _apply(tool_transform(chain, None, angles_deg),
                                                              tip) - Tw[:, :3, 3])
    dW, wW = _side_twist(chain, errs, tuple(reversed(chain.workpiece_side)), cols, w_pt)
    dT, wT = _side_twist(chain, errs, chain.tool_side, cols, tip)
    dl, rl = linear_axis_errors(chain, errs, q)  # type: ignore[arg-type]
    lever = _apply(tool_transform(chain, None, angles_deg), tip) * 1e-3
    return dl + np.cross(rl, lever) + dT - dW, rl + wT - wW
