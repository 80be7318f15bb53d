"""Float64 reference evaluation of an abbe table (the C library is checked against it).

Implements docs/table-format.md "What the table means" literally, vectorised:

* fitted term values: basis rows x coefficients at the position clamped to the
  axis travel (end value held outside);
* the axis' own positioning term (d_x of X, d_y of Y, d_z of Z) gains backlash
  ``s * R(p) / 2``, with the total reversal ``R(p) = B + sum_k r_k T_k(u)`` (the
  reversal block at the clamped position, format 1.1; :func:`reversal_values`),
  and, with the unclamped position, thermal ``alpha * dT * (p - ref) + o * dT``;
* Eq. 3 of the paper (dZ typo corrected, notes.md §1) with x, y, z = p - reference
  (unclamped), plus squareness and the Abbe terms of the tool offset.

Call it on the quantized table (``quantize(t)`` or ``read_blob(write_blob(t))``)
to get what the library should compute. Units: positions mm, linear terms and
errors um, angles urad, temperatures deg C.
"""

from __future__ import annotations

import numpy as np

from abbe.model.table import AXES, TERMS, Table, basis_matrix

_OWN_TERM = {"X": "dx", "Y": "dy", "Z": "dz"}


def term_values(table: Table, axis: str, term: str, pos_mm: np.ndarray) -> np.ndarray:
    """Fitted value of ``term`` of ``axis`` at axis positions ``pos_mm`` (mm).

    um for dx/dy/dz, urad for ex/ey/ez; clamped to the travel; 0 if the term is
    absent. Backlash and thermal are not included (see :func:`extra_values`).
    """
    if axis not in AXES or term not in TERMS:
        raise ValueError(f"axis {axis!r} / term {term!r} unknown")
    p = np.asarray(pos_mm, dtype=np.float64).reshape(-1)
    ax = table.axes[axis]
    if term not in ax.coef:
        return np.zeros(p.shape)
    return basis_matrix(ax, p) @ np.asarray(ax.coef[term], dtype=np.float64)


def reversal_values(table: Table, axis: str, pos_mm: np.ndarray) -> np.ndarray:
    """The total reversal R(p) of ``axis``' own positioning term at ``pos_mm`` (mm), um.

    ``backlash_um`` plus the reversal block (format 1.1) at the position clamped
    to the travel: ISO 230-2's reversal (mean + approach minus mean - approach)
    as the model holds it; the term gets ``s * R(p) / 2``. What the C library's
    ``abbe_reversal_eval_*`` computes.
    """
    if axis not in AXES:
        raise ValueError(f"axis {axis!r} unknown")
    return table.axes[axis].reversal_um(pos_mm)


def extra_values(table: Table, axis: str, pos_mm: np.ndarray,
                 dir_state: np.ndarray | None = None,
                 temp_c: np.ndarray | None = None) -> np.ndarray:
    """Backlash + thermal addition to the own positioning term of ``axis``, um.

    ``dir_state`` in [-1, 1] (+1 moving +), ``temp_c`` the axis temperature in
    deg C; either None means 0 contribution. Backlash is ``s * R(p) / 2``
    (:func:`reversal_values`); thermal uses the unclamped position.
    """
    p = np.asarray(pos_mm, dtype=np.float64).reshape(-1)
    ax = table.axes[axis]
    out = np.zeros(p.shape)
    if dir_state is not None and ax.has_reversal():
        s = np.clip(np.asarray(dir_state, dtype=np.float64).reshape(-1), -1.0, 1.0)  # as the C library
        out += s * (ax.reversal_um(p) / 2.0)
    if temp_c is not None and (ax.thermal_expansion_ppm_per_k or ax.thermal_offset_um_per_k):
        dt = np.asarray(temp_c, dtype=np.float64).reshape(-1) - ax.thermal_tref_c
        ref = table.reference_mm[AXES.index(axis)]
        # ppm/K * K * mm = 1e-6 * mm = 1e-3 um
        out += ax.thermal_expansion_ppm_per_k * dt * (p - ref) * 1e-3
        out += ax.thermal_offset_um_per_k * dt
    return out


def all_terms(table: Table, pos_mm: np.ndarray, dir_state: np.ndarray | None = None,
              temp_c: np.ndarray | None = None) -> dict[tuple[str, str], np.ndarray]:
    """Every term (axis, term) at the positions (N, 3), own positioning terms
    including backlash and thermal. um / urad."""
    pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
    ds = None if dir_state is None else np.asarray(dir_state, dtype=np.float64).reshape(-1, 3)
    tc = None if temp_c is None else np.asarray(temp_c, dtype=np.float64).reshape(-1, 3)
    out: dict[tuple[str, str], np.ndarray] = {}
    for j, a in enumerate(AXES):
        for t in TERMS:
            out[(a, t)] = term_values(table, a, t, pos[:, j])
        out[(a, _OWN_TERM[a])] = out[(a, _OWN_TERM[a])] + extra_values(
            table, a, pos[:, j], None if ds is None else ds[:, j],
            None if tc is None else tc[:, j])
    return out


def spatial_error(table: Table, pos_mm: np.ndarray, dir_state: np.ndarray | None = None,
                  temp_c: np.ndarray | None = None) -> np.ndarray:
    """Spatial error (dX, dY, dZ) of the tool relative to the workpiece, um.

    ``pos_mm`` (N, 3) machine coordinates in mm; ``dir_state`` (N, 3) backlash
    direction state in [-1, 1] (None = 0); ``temp_c`` (N, 3) axis temperatures in
    deg C (None = no thermal contribution). Returns (N, 3) um.
    """
    pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
    e = all_terms(table, pos, dir_state, temp_c)
    return combine_eq3(e, pos, table.reference_mm, table.tool_offset_mm, table.squareness_urad)


def combine_eq3(e: dict[tuple[str, str], np.ndarray], pos_mm: np.ndarray,
                reference_mm: tuple[float, float, float] | np.ndarray,
                tool_offset_mm: tuple[float, float, float] | np.ndarray,
                squareness_urad: tuple[float, float, float] | np.ndarray) -> np.ndarray:
    """Eq. 3 (dZ typo corrected) plus squareness and the tool offset's Abbe terms.

    ``e[(axis, term)]``: term values (N,) at the points, um / urad, as
    :func:`all_terms` returns them (missing keys count as 0); ``pos_mm`` (N, 3) the
    machine positions whose offsets from ``reference_mm`` are the lever arms.
    Returns (dX, dY, dZ) (N, 3) um. Exposed so that a table held in another form
    (a controller's sampled columns) is combined by exactly the same equations.
    """
    pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
    ref = np.asarray(reference_mm, dtype=np.float64)
    # mm * urad = nm: scale by 1e-3 to um.
    x, y, z = ((pos - ref) * 1e-3).T
    tx, ty, tz = (np.asarray(tool_offset_mm, dtype=np.float64) * 1e-3)
    sxy, sxz, syz = (float(v) for v in squareness_urad)
    zero = np.zeros(pos.shape[0])

    def E(a: str, t: str) -> np.ndarray:
        return e.get((a, t), zero)

    dX = (-E("X", "dx") - E("Y", "dx") + E("Z", "dx")
          - y * (E("X", "ez") + E("Y", "ez")) - z * (E("X", "ey") + E("Y", "ey"))
          + y * sxy - z * sxz
          + ty * (E("X", "ez") + E("Y", "ez") - E("Z", "ez"))
          + tz * (E("Z", "ey") - E("X", "ey") - E("Y", "ey")))
    dY = (-E("X", "dy") - E("Y", "dy") + E("Z", "dy")
          + x * E("X", "ez") + z * (E("X", "ex") + E("Y", "ex")) - z * syz
          + tx * (E("Z", "ez") - E("X", "ez") - E("Y", "ez"))
          + tz * (E("X", "ex") + E("Y", "ex") - E("Z", "ex")))
    dZ = (-E("X", "dz") - E("Y", "dz") + E("Z", "dz")
          - x * E("X", "ey") + y * (E("X", "ex") + E("Y", "ex"))
          + tx * (E("X", "ey") + E("Y", "ey") - E("Z", "ey"))
          + ty * (E("Z", "ex") - E("X", "ex") - E("Y", "ex")))
    return np.stack([dX, dY, dZ], axis=1)


def out_of_travel(table: Table, pos_mm: np.ndarray) -> np.ndarray:
    """(N,) bool: some axis position lies outside its table travel."""
    pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
    out = np.zeros(pos.shape[0], dtype=bool)
    for j, a in enumerate(AXES):
        lo, hi = table.axes[a].travel_mm
        out |= (pos[:, j] < lo) | (pos[:, j] > hi)
    return out
