"""Kinematic chain of the independent generator (notes.md §1), as 4x4 transforms.

Workpiece side: bed -> Y carriage -> X table -> workpiece; tool side: bed -> Z ram
-> spindle -> tool. Each axis is a nominal translation followed by its error
motion, the homogeneous transform [R | t + d] with R = Rz(eps_z) Ry(eps_y) Rx(eps_x)
(Euler composition of the three small rotations) and d its translation errors; the
squareness enters as d_x(y) - y S_xy, d_x(z) - z S_xz, d_y(z) - z S_yz. With
(x, y, z) the position relative to the reference point and t the tool offset, the
table point that ideally meets the tool is q = (-x, -y, z) + t, and

    E = H_Z(z) t - H_Y(y) H_X(x) q     (tool relative to workpiece, along the axes)

Positions mm; the returned errors um, rotations urad.
"""

from __future__ import annotations

import numpy as np

from cases.independent.physics import AXES, OWN_TERM, Machine


def _euler(rx: np.ndarray, ry: np.ndarray, rz: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotation matrices Rz Ry Rx of angles in rad."""
    cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
    n = rx.size
    R = np.empty((n, 3, 3))
    R[:, 0, 0] = cz * cy
    R[:, 0, 1] = cz * sy * sx - sz * cx
    R[:, 0, 2] = cz * sy * cx + sz * sx
    R[:, 1, 0] = sz * cy
    R[:, 1, 1] = sz * sy * sx + cz * cx
    R[:, 1, 2] = sz * sy * cx - cz * sx
    R[:, 2, 0] = -sy
    R[:, 2, 1] = cy * sx
    R[:, 2, 2] = cy * cx
    return R


def _small_angles(R: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_euler` (N, 3) rad."""
    ry = -np.arcsin(np.clip(R[:, 2, 0], -1, 1))
    rx = np.arctan2(R[:, 2, 1], R[:, 2, 2])
    rz = np.arctan2(R[:, 1, 0], R[:, 0, 0])
    return np.stack([rx, ry, rz], axis=1)


def axis_transforms(m: Machine, pos_mm: np.ndarray, state: np.ndarray | None,
                    time_s: np.ndarray | None) -> dict[str, np.ndarray]:
    """(N, 4, 4) transform of each axis carriage at the positions (N, 3) mm."""
    pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
    n = pos.shape[0]
    rel = pos - np.asarray(m.reference)
    sxy, sxz, syz = (v * 1e-6 for v in m.effects.squareness_urad)
    out = {}
    for j, a in enumerate(AXES):
        p = pos[:, j]
        d = np.stack([m.geometric(a, t, p) for t in ("dx", "dy", "dz")], axis=1) * 1e-3
        own = "xyz".index(OWN_TERM[a][1])
        d[:, own] += m.own_dynamic(a, p, None if state is None else state[:, j], time_s) * 1e-3
        if a == "Y":
            d[:, 0] -= rel[:, 1] * sxy
        if a == "Z":
            d[:, 0] -= rel[:, 2] * sxz
            d[:, 1] -= rel[:, 2] * syz
        ang = [m.geometric(a, t, p) * 1e-6 for t in ("ex", "ey", "ez")]
        H = np.zeros((n, 4, 4))
        H[:, :3, :3] = _euler(*ang)
        H[:, :3, 3] = d
        H[:, j, 3] += rel[:, j]
        H[:, 3, 3] = 1.0
        out[a] = H
    return out


def _apply(H: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("nij,nj->ni", H[:, :3, :3], v) + H[:, :3, 3]


def tool_error_um(m: Machine, pos_mm: np.ndarray, state: np.ndarray | None = None,
                  time_s: np.ndarray | None = None) -> np.ndarray:
    """E (N, 3) um of the tool tip relative to the workpiece at axis positions (N, 3) mm,
    with the true tool offset (declared + unmodelled)."""
    pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
    n = pos.shape[0]
    H = axis_transforms(m, pos, state, time_s)
    t = np.asarray(m.declared_tool_mm) + np.asarray(m.effects.tool_offset_mm)
    rel = pos - np.asarray(m.reference)
    q = np.stack([-rel[:, 0], -rel[:, 1], rel[:, 2]], axis=1) + t
    tool = _apply(H["Z"], np.broadcast_to(t, (n, 3)).copy())
    work = _apply(H["Y"], _apply(H["X"], q))
    return (tool - work) * 1e3


def carriage_reading(m: Machine, axis: str, pos_mm: np.ndarray, state: np.ndarray | None,
                     time_s: np.ndarray | None, jitter_um: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """What a 6D laser sees of the moving carriage of ``axis`` (receiver at the point under
    the spindle reference point for X/Y, on the spindle for Z with the head on the
    table): deviation (N, 3) um of the receiver from its ideal position and the
    carriage's small rotation angles (N, 3) urad, in machine axes (not yet zeroed)."""
    pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
    n = pos.shape[0]
    H = axis_transforms(m, pos, state, time_s)
    if jitter_um is not None:
        for j, a in enumerate(AXES):
            H[a][:, j, 3] += jitter_um[:, j] * 1e-3
    rel = pos - np.asarray(m.reference)
    zero = np.zeros((n, 3))
    if axis in ("X", "Y"):
        HW = np.einsum("nij,njk->nik", H["Y"], H["X"])
        recv = _apply(HW, zero)
        ideal = np.stack([rel[:, 0], rel[:, 1], np.zeros(n)], axis=1)
        return (recv - ideal) * 1e3, _small_angles(HW[:, :3, :3]) * 1e6
    HW = np.einsum("nij,njk->nik", H["Y"], H["X"])
    Rw = HW[:, :3, :3]
    tip = _apply(H["Z"], zero)
    local = np.einsum("nji,nj->ni", Rw, tip - HW[:, :3, 3])
    ideal = np.stack([-rel[:, 0], -rel[:, 1], rel[:, 2]], axis=1)
    rot = np.einsum("nji,njk->nik", Rw, H["Z"][:, :3, :3])
    return (local - ideal) * 1e3, _small_angles(rot) * 1e6
