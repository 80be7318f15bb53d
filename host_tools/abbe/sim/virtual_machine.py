"""The virtual machine: exact (nonlinear) kinematics of a 3-axis vertical machining centre.

Kinematic chain (notes.md §1, paper Eq. 2): workpiece side bed -> Y -> X ->
workpiece, tool side bed -> Z -> spindle -> tool. With x, y, z the machine
position relative to the reference point (mm), each axis j contributes a motion
(translation along its axis) followed by its error transform
``v -> R_j v + d_j`` (paper Table 3), where R_j is the **exact** rotation matrix of
the rotation vector (eps_jx, eps_jy, eps_jz) (Rodrigues, ``scipy.spatial.transform``)
and d_j = (d_x(j), d_y(j), d_z(j)) with the squareness terms
``d_x(y) - y S_xy``, ``d_x(z) - z S_xz``, ``d_y(z) - z S_yz``:

    P_W = (0, y, 0) + d_Y + R_Y ((x, 0, 0) + d_X + R_X w),   w = (-x, -y, z) + t
    P_T = (0, 0, z) + d_Z + R_Z t
    E   = P_T - P_W           (ideal: P_T = P_W = (0, 0, z) + t)

t = tool offset (tool tip relative to the spindle reference point). Dropping
products of errors gives exactly Eq. 3 with the Abbe terms (abbe.model.reference);
the difference is second order (|eps|^2 L, |eps| |d|: nanometres on a VMC).
E is the error of the tool relative to the workpiece along the machine axes:
the tool tip is at ``commanded + E`` in the workpiece frame (a ballbar sees
``u_r . E``, notes.md §4).

On top of the 18 terms (:mod:`abbe.sim.truth`) the own positioning term of each axis
gains the state- and time-dependent effects: backlash (direction state s in
[-1, 1]), thermal drift T(t), a scale change from a given campaign time, and a
per-visit repeatability scatter. Servo lag acts on the axis positions
(abbe.sim.instruments), not on the error terms.
Units: mm, um, urad, s.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from abbe.model.table import AXES, LINEAR_TERMS, OWN_SIGN, OWN_TERM
from abbe.sim.truth import MachineTruth

__all__ = ["VirtualMachine", "rotation_matrices", "rotation_vectors"]


def rotation_matrices(rotvec_urad: np.ndarray) -> np.ndarray:
    """Exact rotation matrices (N, 3, 3) of rotation vectors (N, 3) in urad."""
    rv = np.asarray(rotvec_urad, dtype=np.float64).reshape(-1, 3) * 1e-6
    return Rotation.from_rotvec(rv).as_matrix()


def rotation_vectors(mats: np.ndarray) -> np.ndarray:
    """Rotation vectors (N, 3) in urad of rotation matrices (N, 3, 3)."""
    return Rotation.from_matrix(np.asarray(mats).reshape(-1, 3, 3)).as_rotvec() * 1e6


def _mv(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Batched matrix-vector product (N,3,3) x (N,3) (no BLAS: reproducible)."""
    return np.einsum("nij,nj->ni", m, v)


class VirtualMachine:
    """A virtual machine defined by a :class:`~abbe.sim.truth.MachineTruth`.

    All methods are vectorised over N samples: positions (N, 3) machine
    coordinates in mm; ``dir_state`` (N, 3) backlash direction state (None: 0,
    i.e. the middle of the lost motion); ``time_s`` (N,) campaign time in s
    (None: thermal drift and scale change off); ``jitter_um`` (N, 3) extra
    own-positioning deviation (repeatability), um.
    """

    def __init__(self, truth: MachineTruth) -> None:
        self.truth = truth
        self.ref = np.asarray(truth.reference_mm, dtype=np.float64)

    # ------------------------------------------------------------------ terms

    def own_extra_um(self, pos_mm: np.ndarray, dir_state: np.ndarray | None = None,
                     time_s: np.ndarray | None = None,
                     jitter_um: np.ndarray | None = None) -> np.ndarray:
        """Effects added to each axis' own positioning term, (N, 3) um."""
        pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
        n = pos.shape[0]
        e = self.truth.effects
        out = np.zeros((n, 3))
        sig = np.array([OWN_SIGN[a] for a in AXES], dtype=np.float64)
        if dir_state is not None and e.backlash_on():
            s = np.asarray(dir_state, dtype=np.float64).reshape(-1, 3)
            b = np.stack([e.lost_motion_um(j, pos[:, j], self.truth.axes[a].travel_mm)
                          for j, a in enumerate(AXES)], axis=1)
            out += -sig * s * b / 2.0
        rel = pos - self.ref
        if time_s is not None:
            t = np.broadcast_to(np.asarray(time_s, dtype=np.float64).reshape(-1), (n,))
            if e.thermal_on():
                dT = (self.truth.temperature_c(t) - e.thermal_start_c)[:, None]
                out += np.asarray(e.thermal_expansion_ppm_per_k) * dT * rel * 1e-3
                out += np.asarray(e.thermal_offset_um_per_k) * dT
            if any(v != 0 for v in e.scale_change_ppm):
                on = (t >= e.scale_change_from_s)[:, None]
                out += np.where(on, np.asarray(e.scale_change_ppm) * rel * 1e-3, 0.0)
        if jitter_um is not None:
            out += np.asarray(jitter_um, dtype=np.float64).reshape(-1, 3)
        return out

    def axis_errors(self, pos_mm: np.ndarray, dir_state: np.ndarray | None = None,
                    time_s: np.ndarray | None = None, jitter_um: np.ndarray | None = None,
                    squareness: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Per-axis translation (3, N, 3) mm and rotation matrices (3, N, 3, 3).

        Translation of axis j = (d_x(j), d_y(j), d_z(j)) incl. own-term effects
        and the squareness terms of Y and Z (paper Table 3).
        """
        pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
        n = pos.shape[0]
        extra = self.own_extra_um(pos, dir_state, time_s, jitter_um)
        trans = np.zeros((3, n, 3))
        rots = np.zeros((3, n, 3, 3))
        for j, a in enumerate(AXES):
            lin = np.stack([self.truth.term_values(a, t, pos[:, j]) for t in LINEAR_TERMS], axis=1)
            lin[:, LINEAR_TERMS.index(OWN_TERM[a])] += extra[:, j]
            ang = np.stack([self.truth.term_values(a, t, pos[:, j]) for t in ("ex", "ey", "ez")],
                           axis=1)
            trans[j] = lin * 1e-3
            rots[j] = rotation_matrices(ang)
        if squareness:
            sxy, sxz, syz = (v * 1e-6 for v in self.truth.effects.squareness_urad)
            rel = pos - self.ref
            trans[1][:, 0] -= rel[:, 1] * sxy
            trans[2][:, 0] -= rel[:, 2] * sxz
            trans[2][:, 1] -= rel[:, 2] * syz
        return trans, rots

    # ------------------------------------------------------------------ chain

    def tool_error_um(self, pos_mm: np.ndarray, dir_state: np.ndarray | None = None,
                      time_s: np.ndarray | None = None, tool_offset_mm: np.ndarray | None = None,
                      jitter_um: np.ndarray | None = None) -> np.ndarray:
        """Exact error (dX, dY, dZ) of the tool tip relative to the workpiece, (N, 3) um.

        ``tool_offset_mm`` (3,) defaults to the machine's true tool offset
        (declared + unmodelled).
        """
        pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
        n = pos.shape[0]
        t = np.asarray(self.truth.true_tool_offset_mm() if tool_offset_mm is None
                       else tool_offset_mm, dtype=np.float64).reshape(3)
        trans, rots = self.axis_errors(pos, dir_state, time_s, jitter_um)
        rel = pos - self.ref
        x, y, z = rel.T
        w = np.stack([-x, -y, z], axis=1) + t
        zeros = np.zeros(n)
        inner = np.stack([x, zeros, zeros], axis=1) + trans[0] + _mv(rots[0], w)
        p_w = np.stack([zeros, y, zeros], axis=1) + trans[1] + _mv(rots[1], inner)
        tt = np.broadcast_to(t, (n, 3))
        p_t = np.stack([zeros, zeros, z], axis=1) + trans[2] + _mv(rots[2], tt)
        return (p_t - p_w) * 1e3

    def carriage_pose(self, axis: str, pos_mm: np.ndarray, point_mm: np.ndarray,
                      dir_state: np.ndarray | None = None, time_s: np.ndarray | None = None,
                      jitter_um: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Pose deviation of a point fixed on the moving carriage of ``axis``.

        For X or Y: ``point_mm`` (3,) is a point in X-table coordinates (the
        chain's workpiece frame, relative to the reference point; the table point
        under the tool at relative position (x, y, z) is (-x, -y, z)); the pose is
        relative to the bed. For Z: ``point_mm`` is a point in spindle coordinates
        (relative to the spindle reference point), the pose relative to the X table
        (a laser head standing on the table).

        Returns (deviation (N, 3) um of the point from its ideal position, rotation
        vector (N, 3) urad of the carriage), both in machine axes.
        """
        pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
        n = pos.shape[0]
        r = np.broadcast_to(np.asarray(point_mm, dtype=np.float64).reshape(3), (n, 3))
        trans, rots = self.axis_errors(pos, dir_state, time_s, jitter_um)
        rel = pos - self.ref
        x, y, z = rel.T
        zeros = np.zeros(n)
        if axis in ("X", "Y"):
            inner = np.stack([x, zeros, zeros], axis=1) + trans[0] + _mv(rots[0], r)
            p = np.stack([zeros, y, zeros], axis=1) + trans[1] + _mv(rots[1], inner)
            ideal = np.stack([x, y, zeros], axis=1) + r
            rot = np.einsum("nij,njk->nik", rots[1], rots[0])
            return (p - ideal) * 1e3, rotation_vectors(rot)
        if axis == "Z":
            # Spindle point in the bed frame, then expressed in the table frame:
            # table pose T(v) = (x, y, 0) + d_Y + R_Y ((x..)...) -- use the
            # workpiece-side transform of the table origin point.
            p_t = np.stack([zeros, zeros, z], axis=1) + trans[2] + _mv(rots[2], r)
            o = np.stack([x, zeros, zeros], axis=1) + trans[0]
            table_origin = np.stack([zeros, y, zeros], axis=1) + trans[1] + _mv(rots[1], o)
            r_table = np.einsum("nij,njk->nik", rots[1], rots[0])
            # Table coordinates of the spindle point: R_table^T (p_t - origin).
            local = np.einsum("nji,nj->ni", r_table, p_t - table_origin)
            ideal_local = np.stack([-x, -y, z], axis=1) + r
            rot = np.einsum("nji,njk->nik", r_table, rots[2])
            return (local - ideal_local) * 1e3, rotation_vectors(rot)
        raise ValueError(f"unknown axis {axis!r}")
