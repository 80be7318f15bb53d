"""The five-axis vocabulary: ISO 230-7 names, the trunnion geometry, the errors and the
rigid-body helpers that the trunnion model (:mod:`abbe.model.five_axis`) and the kinematic
chain (:mod:`abbe.model.chain`) share (units as in :mod:`abbe.model.five_axis`: mm, um,
urad, degrees). A module of its own so that the chain, which the trunnion model now
runs through, imports nothing that imports it back.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from abbe.model.table import AxisTable, FourierBlock, Table, basis_matrix

#: Supported kinematics -> (tilt axis, rotary table axis).
KINEMATICS: dict[str, tuple[str, str]] = {"xyzac-trt": ("A", "C"), "xyzbc-trt": ("B", "C")}
#: Unit direction of each rotary axis (A about X, B about Y, C about Z).
AXIS_DIRECTION: dict[str, tuple[float, float, float]] = {
    "A": (1.0, 0.0, 0.0), "B": (0.0, 1.0, 0.0), "C": (0.0, 0.0, 1.0)}
#: ISO 230-1 location errors per rotary axis: two positions (um), two tilts
#: (urad), the angular zero (urad), in this order.
LOCATION_ERRORS: dict[str, tuple[str, str, str, str, str]] = {
    "C": ("EX0C", "EY0C", "EA0C", "EB0C", "EC0C"),
    "A": ("EY0A", "EZ0A", "EB0A", "EC0A", "EA0A"),
    "B": ("EX0B", "EZ0B", "EA0B", "EC0B", "EB0B"),
}
#: Error motion components: translations X, Y, Z (um), rotations A, B, C (urad).
MOTION_COMPONENTS: tuple[str, ...] = ("X", "Y", "Z", "A", "B", "C")
#: The squareness errors of the linear axes as Eq. 3 holds them (urad).
SQUARENESS: tuple[str, str, str] = ("sxy", "sxz", "syz")
#: Lowest harmonic of an error motion per component relative to the axis: a
#: first harmonic of a radial or tilt motion is indistinguishable from the
#: location of the average line (ISO 230-7 puts it there), so those series
#: start at 2; the axial and angular motions start at 1. No constant term: a
#: constant is a location error (or, axially, no error at all).
def lowest_harmonic(axis: str, comp: str) -> int:
    """1 for the axial and angular components of ``axis``, 2 for radial and tilt."""
    own = {"A": ("X", "A"), "B": ("Y", "B"), "C": ("Z", "C")}[axis]
    return 1 if comp in own else 2


def motion_name(axis: str, comp: str) -> str:
    """ISO 230-7 name of an error motion: ``EXC(C)`` for comp X of C."""
    return f"E{comp}{axis}({axis})"


@dataclass(frozen=True)
class TrunnionGeometry:
    """Nominal geometry of a table-table machine, in LinuxCNC trt terms.

    kind: ``xyzac-trt`` or ``xyzbc-trt``; rot_point_mm: the C axis centre
    (x/y/z-rot-point), mm; offset_mm: tilt axis centre relative to the C centre
    (AC: (0, y-offset, z-offset); BC: (x-offset, 0, z-offset)), mm;
    tool_length_mm: the tool length (the Abbe lever of the linear axes'
    angular errors), mm; travel_deg: axis -> (min, max) degrees.
    """

    kind: str
    rot_point_mm: tuple[float, float, float]
    offset_mm: tuple[float, float, float]
    tool_length_mm: float
    travel_deg: dict[str, tuple[float, float]]

    @property
    def tilt(self) -> str:
        return KINEMATICS[self.kind][0]

    @property
    def rotaries(self) -> tuple[str, str]:
        """(tilt axis, table axis), outer first."""
        return KINEMATICS[self.kind]

    def pivot(self, axis: str) -> np.ndarray:
        """Nominal point of ``axis``' line (mm, machine coordinates at zero angles)."""
        p = np.asarray(self.rot_point_mm, dtype=np.float64)
        return p if axis == "C" else p + np.asarray(self.offset_mm, dtype=np.float64)


@dataclass
class FiveAxisErrors:
    """Every error of the five-axis model.

    location: ISO name -> value (um or urad; absent = 0); motions: (axis, comp)
    -> Fourier coefficients ``[sin k, cos k for k = 1..H]`` (um / urad, the
    Fourier block's order; harmonics below :func:`lowest_harmonic` must be 0);
    squareness: sxy, sxz, syz (urad, Eq. 3's sign); linear: a 3-axis table of
    the linear axes' errors or None.
    """

    location: dict[str, float] = field(default_factory=dict)
    motions: dict[tuple[str, str], np.ndarray] = field(default_factory=dict)
    squareness: tuple[float, float, float] = (0.0, 0.0, 0.0)
    linear: Table | None = None


def fourier_rows(angle_deg: np.ndarray, harmonics: int) -> np.ndarray:
    """Fourier rows ``sin k t, cos k t`` (k = 1..H, period 360 deg) at ``angle_deg``.

    The fit's Fourier block (:func:`abbe.model.table.basis_matrix`) with a period of
    360 degrees, phase 0 at 0 degrees; angles are not clamped (the series is periodic).
    """
    t = np.mod(np.asarray(angle_deg, dtype=np.float64).reshape(-1), 360.0)
    if harmonics == 0:
        return np.zeros((t.size, 0))
    ax = AxisTable(travel_mm=(0.0, 360.0), blocks=(FourierBlock(360.0, 0.0, harmonics), None))
    return basis_matrix(ax, t)


def motion_values(errs: FiveAxisErrors, axis: str, angle_deg: np.ndarray) -> np.ndarray:
    """(N, 6) error motions of ``axis`` at ``angle_deg``: X, Y, Z um, A, B, C urad."""
    t = np.asarray(angle_deg, dtype=np.float64).reshape(-1)
    out = np.zeros((t.size, 6))
    for j, comp in enumerate(MOTION_COMPONENTS):
        c = errs.motions.get((axis, comp))
        if c is not None and len(c):
            out[:, j] = fourier_rows(t, len(c) // 2) @ np.asarray(c, dtype=np.float64)
    return out


def _loc(errs: FiveAxisErrors, axis: str) -> tuple[np.ndarray, np.ndarray, float]:
    """(delta um, phi urad, zero urad) of ``axis``' location errors as vectors."""
    names = LOCATION_ERRORS[axis]
    v = [float(errs.location.get(n, 0.0)) for n in names]
    k = "XYZ".index({"A": "X", "B": "Y", "C": "Z"}[axis])
    others = [i for i in range(3) if i != k]
    delta, phi = np.zeros(3), np.zeros(3)
    delta[others] = v[0:2]
    phi[others] = v[2:4]
    return delta, phi, v[4]


# ---------------------------------------------------------------- exact (homogeneous)


def _rot(t: np.ndarray, i: int) -> np.ndarray:
    """(N, 3, 3) rotations by angles ``t`` (rad) about the machine axis ``i`` (0 x, 1 y, 2 z)."""
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


def _rx(t: np.ndarray) -> np.ndarray:
    return _rot(t, 0)


def _ry(t: np.ndarray) -> np.ndarray:
    return _rot(t, 1)


def _rz(t: np.ndarray) -> np.ndarray:
    return _rot(t, 2)


_ROT = {"A": _rx, "B": _ry, "C": _rz}


def small_rotation(v_rad: np.ndarray) -> np.ndarray:
    """(N, 3, 3) ``Rx(a) Ry(b) Rz(c)`` for rotation vectors (N, 3) in rad."""
    v = np.asarray(v_rad, dtype=np.float64).reshape(-1, 3)
    return _rx(v[:, 0]) @ _ry(v[:, 1]) @ _rz(v[:, 2])


def _homog(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    n = R.shape[0]
    T = np.zeros((n, 4, 4))
    T[:, :3, :3] = R
    T[:, :3, 3] = t
    T[:, 3, 3] = 1.0
    return T


def _trans(t: np.ndarray, n: int) -> np.ndarray:
    return _homog(np.broadcast_to(np.eye(3), (n, 3, 3)).copy(), np.broadcast_to(t, (n, 3)))


def linear_axis_errors(geom: TrunnionGeometry, errs: FiveAxisErrors,
                       pos_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tool position (N, 3) um and orientation (N, 3) urad errors of the linear axes.

    Eq. 3 of the 3-axis table (its own reference and tool offset) plus the five-axis
    squareness; orientation ``E_Z(e) - E_X(e) - E_Y(e)`` per component.
    """
    from abbe.model.reference import all_terms, combine_eq3

    pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
    n = pos.shape[0]
    dpos, drot = np.zeros((n, 3)), np.zeros((n, 3))
    if errs.linear is not None:
        t = errs.linear
        e = all_terms(t, pos)
        dpos += combine_eq3(e, pos, t.reference_mm, t.tool_offset_mm, t.squareness_urad)
        for j, term in enumerate(("ex", "ey", "ez")):
            drot[:, j] = e[("Z", term)] - e[("X", term)] - e[("Y", term)]
    sxy, sxz, syz = (float(v) for v in errs.squareness)
    if sxy or sxz or syz:
        ref = np.asarray(geom.rot_point_mm, dtype=np.float64)
        x, y, z = ((pos - ref) * 1e-3).T  # mm * urad = nm -> um
        dpos[:, 0] += y * sxy - z * sxz
        dpos[:, 1] += -z * syz
    return dpos, drot


def rotvec(R: np.ndarray) -> np.ndarray:
    """(N, 3) rotation vectors (rad) of rotation matrices (N, 3, 3) (angles < pi)."""
    tr = np.clip((np.trace(R, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    th = np.arccos(tr)
    w = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], -1)
    s = np.sin(th)
    f = np.where(s > 1e-12, th / np.where(s > 1e-12, 2.0 * s, 1.0), 0.5)
    return w * f[:, None]
