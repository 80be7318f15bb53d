"""A printer's bed map and skew artefacts fitted into a table, with held-out figures.

A bed mesh (Klipper) or height map (RepRapFirmware) is the Z error of the nozzle
over the bed, h(x, y) in mm (positive: the bed stands high, the firmware lifts the
nozzle by h). abbe's model holds what the axes cause: the Z straightness of X,
d_z(x), and of Y, d_z(y), so h is fitted as

    h(x, y) ~ c + d_z(x) + d_z(y)          (dZ = -d_z(x) - d_z(y), Eq. 3; um in the table)

with Chebyshev series whose degrees are chosen by leave-one-out cross-validation
over the measured points. What a separable model cannot hold (a warped bed: the
part of h that is not a sum of a function of x and one of y) is reported as such,
with its size. The held-out figure is leave-one-out: each interior point predicted
from the others by abbe's fit, and by what the firmware's own mesh would do
without it (bilinear interpolation at twice the spacing from its four diagonal
neighbours), on the same points.

Skew artefacts (the diagonals AC, BD and side AD of a square, per plane) give the
squareness: Klipper's calc_skew_factor t, with S_xy = t_xy, S_xz = -t_xz,
S_yz = -t_yz (Eq. 3's signs: dX = y S_xy - z S_xz, dY = -z S_yz), urad; its 95 %
interval from the length measurement's uncertainty (default 0.02 mm per length,
a caliper), propagated by the derivatives of the formula.

Units: positions mm, heights mm in the maps, um / urad in the results.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from abbe.errors import AbbeInputError
from abbe.formats.printer_maps import HeightMap, SkewArtefact
from abbe.model.table import AxisTable, Table

MAX_DEGREE = 7


@dataclass
class AxisProfile:
    """d_z of one axis: Chebyshev degree, coefficients (um, relative to the reference),
    travel (mm) and the largest 95 % half-width of the profile over the travel (um)."""

    axis: str
    degree: int
    coef_um: np.ndarray
    travel_mm: tuple[float, float]
    u95_um: float


@dataclass
class PrinterFit:
    """What :func:`fit_printer` found (see the module docstring)."""

    source: str
    points: int
    x: AxisProfile
    y: AxisProfile
    offset_um: float
    fit_rms_um: float
    nonseparable_rms_um: float
    heldout_points: int
    heldout_rms_um: float
    firmware_heldout_rms_um: float
    raw_rms_um: float
    squareness_urad: dict[str, float] = field(default_factory=dict)
    squareness_u95_urad: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    #: the artefact lengths' standard uncertainty the squareness's U comes from (mm)
    length_u_mm: float | None = None

    def to_json(self) -> dict:
        def prof(p: AxisProfile) -> dict:
            return {"axis": p.axis, "degree": p.degree, "travel_mm": list(p.travel_mm),
                    "coef_um": [float(c) for c in p.coef_um], "u95_um": p.u95_um}
        return {
            "source": self.source, "points": self.points,
            "dz_of_x": prof(self.x), "dz_of_y": prof(self.y), "offset_um": self.offset_um,
            "fit_rms_um": self.fit_rms_um,
            "nonseparable_rms_um": self.nonseparable_rms_um,
            "heldout": {"points": self.heldout_points, "abbe_rms_um": self.heldout_rms_um,
                        "firmware_mesh_rms_um": self.firmware_heldout_rms_um,
                        "uncorrected_rms_um": self.raw_rms_um,
                        "method": "leave one interior point out; the firmware's mesh "
                                  "interpolates it bilinearly from its four diagonal "
                                  "neighbours (twice the spacing)"},
            "squareness_urad": self.squareness_urad,
            "squareness_u95_urad": self.squareness_u95_urad,
            # U (k = 2), the certificate's convention (docs/uncertainty.md): u95 = 1.96 u
            "squareness_U_urad": {k: 2.0 * v / 1.96 for k, v in self.squareness_u95_urad.items()},
            "uncertainty": {"k": 2, "method": "GUM first order: each artefact length's standard "
                            "uncertainty through the derivatives of the skew formula",
                            "budget": {"length_u_mm": self.length_u_mm},
                            "not_included": "the held-out RMS figures are comparisons of "
                                            "models on the same probe points, given without U"},
            "notes": self.notes,
        }


def _u(p: np.ndarray, lo: float, hi: float) -> np.ndarray:
    return (2.0 * np.clip(p, lo, hi) - lo - hi) / (hi - lo)


def _design(xy: np.ndarray, dx: int, dy: int, tx, ty) -> np.ndarray:
    """Columns: 1, T_1..T_dx of x, T_1..T_dy of y (T_0 shared as the offset)."""
    cx = np.polynomial.chebyshev.chebvander(_u(xy[:, 0], *tx), dx)[:, 1:]
    cy = np.polynomial.chebyshev.chebvander(_u(xy[:, 1], *ty), dy)[:, 1:]
    return np.column_stack([np.ones(len(xy)), cx, cy])


def _loo(A: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Leave-one-out residuals of the least squares fit z ~ A b (hat-matrix identity)."""
    Q, _ = np.linalg.qr(A)
    h = np.sum(Q * Q, axis=1)
    coef, *_ = np.linalg.lstsq(A, z, rcond=None)
    r = z - A @ coef
    return r / np.maximum(1.0 - h, 1e-12)


def fit_height_map(hm: HeightMap) -> PrinterFit:
    """The separable fit of a height map (module docstring)."""
    xy, z_mm = hm.points()
    z = z_mm * 1e3  # um
    tx = (float(hm.x_mm[0]), float(hm.x_mm[-1]))
    ty = (float(hm.y_mm[0]), float(hm.y_mm[-1]))
    nx, ny = len(hm.x_mm), len(hm.y_mm)
    best = None
    for dx in range(1, min(MAX_DEGREE, nx - 1) + 1):
        for dy in range(1, min(MAX_DEGREE, ny - 1) + 1):
            A = _design(xy, dx, dy, tx, ty)
            if A.shape[1] >= len(z) - 1:
                continue
            score = float(np.mean(_loo(A, z) ** 2))
            if best is None or score < best[0] - 1e-12:
                best = (score, dx, dy)
    if best is None:
        raise AbbeInputError(f"{len(z)} points are too few for a fit", file=hm.source)
    _, dx, dy = best
    A = _design(xy, dx, dy, tx, ty)
    coef, *_ = np.linalg.lstsq(A, z, rcond=None)
    r = z - A @ coef
    dof = max(len(z) - A.shape[1], 1)
    s2 = float(r @ r) / dof
    cov = s2 * np.linalg.pinv(A.T @ A)
    # each axis' profile relative to the middle of its travel (the table's reference)
    def profile(axis, idx, deg, trav):
        c = np.zeros(deg + 1)
        c[1:] = coef[idx]
        grid = np.linspace(trav[0], trav[1], 101)
        V = np.polynomial.chebyshev.chebvander(_u(grid, *trav), deg)
        ref = np.polynomial.chebyshev.chebvander(np.array([0.0]), deg)[0]
        c[0] = -float(ref[1:] @ c[1:])
        J = V[:, 1:] - ref[None, 1:]
        C = cov[np.ix_(idx, idx)]
        u95 = float(1.96 * np.sqrt(np.max(np.einsum("ij,jk,ik->i", J, C, J))))
        return AxisProfile(axis, deg, c, trav, u95)
    ix = list(range(1, 1 + dx))
    iy = list(range(1 + dx, 1 + dx + dy))
    px, py = profile("X", ix, dx, tx), profile("Y", iy, dy, ty)
    offset = float(z.mean())
    loo = _loo(A, z)
    # interior points of the full grid with all four diagonal neighbours measured
    held_abbe, held_fw, held_raw = [], [], []
    Z = hm.z_mm * 1e3
    index = {(round(float(a), 9), round(float(b), 9)): k for k, (a, b) in enumerate(xy)}
    for j in range(1, ny - 1):
        for i in range(1, nx - 1):
            nb = [Z[j - 1, i - 1], Z[j - 1, i + 1], Z[j + 1, i - 1], Z[j + 1, i + 1]]
            if not (np.isfinite(Z[j, i]) and all(np.isfinite(nb))):
                continue
            k = index[(round(float(hm.x_mm[i]), 9), round(float(hm.y_mm[j]), 9))]
            held_abbe.append(loo[k])
            held_fw.append(Z[j, i] - float(np.mean(nb)))
            held_raw.append(Z[j, i] - offset)
    def rms(v):
        return float(np.sqrt(np.mean(np.square(v)))) if len(v) else float("nan")
    notes = list(hm.notes)
    if not held_abbe:
        notes.append("no interior point with four measured diagonal neighbours: no held-out figure")
    return PrinterFit(
        source=hm.source + (f" [{hm.name}]" if hm.name else ""), points=int(len(z)),
        x=px, y=py, offset_um=offset, fit_rms_um=rms(r), nonseparable_rms_um=rms(r),
        heldout_points=len(held_abbe), heldout_rms_um=rms(held_abbe) if held_abbe else 0.0,
        firmware_heldout_rms_um=rms(held_fw) if held_fw else 0.0,
        raw_rms_um=rms(held_raw) if held_raw else rms(z - offset), notes=notes)


def squareness_from_artefacts(arts: list[SkewArtefact], u_length_mm: float = 0.02
                              ) -> tuple[dict[str, float], dict[str, float]]:
    """S (urad) per plane and its 95 % half-width (module docstring)."""
    sign = {"XY": 1.0, "XZ": -1.0, "YZ": -1.0}
    out, u95 = {}, {}
    for a in arts:
        t = a.tangent()
        grads = []
        for k in ("ac_mm", "bd_mm", "ad_mm"):
            h = 1e-6
            b = SkewArtefact(a.plane, a.ac_mm, a.bd_mm, a.ad_mm, a.line)
            setattr(b, k, getattr(b, k) + h)
            grads.append((b.tangent() - t) / h)
        out[a.plane] = sign[a.plane] * t * 1e6
        u95[a.plane] = 1.96 * u_length_mm * math.sqrt(sum(g * g for g in grads)) * 1e6
    return out, u95


def table_of(fit: PrinterFit, z_travel_mm: tuple[float, float],
             squareness_urad: dict[str, float] | None = None) -> Table:
    """The fitted profiles (and squareness) as a table: X and Y carry d_z, Z nothing;
    the reference point is the middle of the map (z at the middle of its travel)."""
    def axis(p: AxisProfile) -> AxisTable:
        return AxisTable(travel_mm=p.travel_mm, trend_degree=p.degree,
                         coef={"dz": np.asarray(p.coef_um, dtype=float)})
    sq = squareness_urad or {}
    ref = ((fit.x.travel_mm[0] + fit.x.travel_mm[1]) / 2,
           (fit.y.travel_mm[0] + fit.y.travel_mm[1]) / 2,
           (z_travel_mm[0] + z_travel_mm[1]) / 2)
    return Table(axes={"X": axis(fit.x), "Y": axis(fit.y),
                       "Z": AxisTable(travel_mm=z_travel_mm)},
                 reference_mm=ref,
                 squareness_urad=(sq.get("XY", 0.0), sq.get("XZ", 0.0), sq.get("YZ", 0.0)))
